"""`bake --method model`: the learned garment model as a `core.deform.Deformer`.

Runs a trained `core.model.GarmentModel` (loaded by `formats.checkpoint.load_model`)
on any garment authored on the body's rest pose: the rest-pose features are
computed once per (garment, body shape), frames are evaluated in batches.
"""

from __future__ import annotations

import logging
import time

import numpy as np
import torch

from core.body import Body
from core.deform import Deformer
from core.errors import InputError
from core.garment import Garment
from core.model import GarmentModel, body_distances, motion_features, shaped_rest, window_index
from core.model_data import prepare_garment
from core.motion import Motion, poses_for_body

log = logging.getLogger(__name__)


class ModelDeformer(Deformer):
    """The paper's network. model: a GarmentModel; batch_frames: frames per forward pass."""

    name = "model"

    def __init__(self, model: GarmentModel, batch_frames: int = 8, cache_dir=None, model_name: str = "model"):
        super().__init__()
        self.model = model.eval()
        self.batch_frames = batch_frames
        self.cache_dir = cache_dir
        self.model_name = model_name
        self._garments: dict = {}

    def prepare(self, garment: Garment, body: Body, source: str | None = None) -> None:
        if body.n_joints != self.model.config.n_joints:
            raise InputError(f"model '{self.model_name}': expected a body with {self.model.config.n_joints} joints, "
                             f"got '{body.name}' with {body.n_joints}")
        key = (garment.content_hash(), id(body))
        if key not in self._garments:
            self._garments[key] = prepare_garment(garment, body, self.model.config, self.cache_dir, source)

    def deform(self, garment: Garment, body: Body, motion: Motion) -> np.ndarray:
        self.prepare(garment, body)
        g = self._garments[(garment.content_hash(), id(body))].inputs
        betas = body.fit_betas(motion.betas)
        poses = poses_for_body(motion, body.n_joints)
        mf = motion_features(body, poses, motion.trans, betas, motion.fps)
        rest = shaped_rest(g, body, betas)
        out = np.empty((motion.n_frames, garment.n_vertices, 3), dtype=np.float32)
        t0 = time.perf_counter()
        with torch.no_grad():
            fused = self.model.encode(g, body_distances(body, betas))
            t1 = time.perf_counter()
            for s in range(0, motion.n_frames, self.batch_frames):
                fr = torch.arange(s, min(s + self.batch_frames, motion.n_frames))
                win = window_index(fr, self.model.config.window)
                res = self.model.forward_frames(fused, g, rest, mf.pose[win], mf.velocity[win], mf.transforms[fr])
                out[s:s + len(fr)] = res.verts.numpy()
        t2 = time.perf_counter()
        self.report = {"method": self.name, "model": self.model_name, "batch_frames": self.batch_frames,
                       "encode_seconds": t1 - t0, "seconds_per_frame_network": (t2 - t1) / max(motion.n_frames, 1)}
        return out


def load_model_deformer(path, **kwargs) -> ModelDeformer:
    """A ModelDeformer for the checkpoint at `path` (InputError naming it when unusable)."""
    from formats.checkpoint import load_model

    model, _ = load_model(path)
    return ModelDeformer(model, model_name=str(path), **kwargs)
