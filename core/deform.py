"""Deformation methods behind one interface: `Deformer.deform(garment, body, motion) -> (T, V, 3)`.

`bake --method NAME` looks methods up in `DEFORMERS`. Every method returns the
garment's vertices per frame in the motion's world frame (Z-up, metres), float32,
and records in `report` what it did, and in `scene` the work its scene analysis
(`core.scene`) left out, for `summary.json`.
"""

from __future__ import annotations

import importlib
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import asdict, dataclass, replace

import numpy as np
import torch

from core.body import Body, skin_points
from core.garment import Garment
from core.motion import Motion, poses_for_body
from core.scene import (
    JOINT_WEIGHT_EPS,
    SKIPS,
    SceneAnalysis,
    active_joints,
    restrict_weights,
)
from core.skinning import LEG_SPREAD_M, bind_garment, shaped_garment, spread_leg_weights
from core.strain import limit_garment


class Deformer(ABC):
    """A garment deformation method."""

    name: str = ""

    def __init__(self):
        self.report: dict = {}
        #: Called with a count of output frames just finished (a share of each frame where the method passes over
        #: the frames more than once: the model's network, contact guard and strain limit), by methods slow enough
        #: to report progress within a motion.
        self.on_frames: Callable[[float], None] | None = None
        #: The skips of `core.scene` this method may apply (`bake --no-skip` removes some).
        self.skips: frozenset = frozenset(SKIPS)
        #: What the last `deform` skipped (core.scene.SceneAnalysis.report), for summary.json "scene".
        self.scene: dict = {}
        self._strain: dict = {}  # the last garment's StrainLimit (`limit_strain_of`)

    def limit_strain_of(self, points: np.ndarray, garment: Garment, rest: np.ndarray, limit: float | None,
                        on_frames: Callable[[int], None] | None = None) -> np.ndarray:
        """`points` (T, V, 3) of `garment` with no edge longer than `limit` times its length at `rest` (V, 3), the
        garment at rest on the motion's body shape (`core.strain.limit_garment`; None: as they are), the limit's
        entry added to `report`; `on_frames(n)` after each chunk of n frames."""
        if limit is None:
            return points
        points, strained = limit_garment(points, garment, rest, limit, self._strain, on_frames)
        self.report.update(strained)
        return points

    def prepare(self, garment: Garment, body: Body, source: str | None = None) -> None:
        """Per-(garment, body) work done once before any motion, validating the pair.

        Raises InputError naming `source` (the garment's file) when the pair cannot be used.
        """

    @abstractmethod
    def deform(self, garment: Garment, body: Body, motion: Motion) -> np.ndarray:
        """Garment vertices per frame: (T, V, 3) float32, metres, the motion's Z-up world."""


@dataclass(frozen=True)
class LBSOptions:
    """Options of the `lbs` method.

    smooth_iterations: passes of weight smoothing over the garment graph (0 = raw transfer).
    smooth_strength: blend towards the neighbour mean per pass, in (0, 1].
    batch_frames: frames skinned per batch (memory: batch * V * 12 floats). 32: its temporaries stay in cache
      (3,914 frames/s for a 3,960-vertex dress on a 2-core AMD EPYC, 2,290 at 512).
    strain_limit: no edge longer than this times its rest length (`core.strain`); None: off (the default: LBS
      is for speed: the limit costs it 3-7 ms/frame on average on real and synthetic motions).
    leg_spread_m: the weights of cloth skinned to the legs spread over about this much of the garment after the
      smoothing passes (`core.skinning.spread_leg_weights`: a skirt between the legs follows both); None: off.
    """

    smooth_iterations: int = 10
    smooth_strength: float = 0.5
    batch_frames: int = 32
    strain_limit: float | None = None
    leg_spread_m: float | None = LEG_SPREAD_M


class LBSDeformer(Deformer):
    """Linear blend skinning with weights transferred from the nearest body surface."""

    name = "lbs"

    def __init__(self, options: LBSOptions = LBSOptions()):
        super().__init__()
        self.options = options
        self._bindings: dict = {}

    def prepare(self, garment: Garment, body: Body, source: str | None = None) -> None:
        key = (garment.content_hash(), id(body))
        if key not in self._bindings:
            o = self.options
            binding = bind_garment(garment, body, o.smooth_iterations, o.smooth_strength, source=source)
            passes = 0
            if o.leg_spread_m:
                weights, passes = spread_leg_weights(binding.weights, garment, body, o.leg_spread_m)
                binding = replace(binding, weights=weights)
            self._bindings[key] = binding, passes

    def deform(self, garment: Garment, body: Body, motion: Motion) -> np.ndarray:
        o = self.options
        self.prepare(garment, body)
        binding, leg_passes = self._bindings[(garment.content_hash(), id(body))]
        betas = body.fit_betas(motion.betas)
        rest = shaped_garment(garment.vertices, binding, betas)
        poses = poses_for_body(motion, body.n_joints)
        A = body.skinning_transforms(poses, motion.trans, betas)
        scene = SceneAnalysis(self.skips)
        active = active_joints(binding.weights)
        scene.record("joints", not active.all(), used=int(active.sum()), joints=len(active),
                     weight_eps=JOINT_WEIGHT_EPS)
        if scene.enabled("joints") and not active.all():
            w, A = torch.from_numpy(restrict_weights(binding.weights, active)), A[:, active]
        else:
            w = torch.from_numpy(binding.weights)
        x = torch.from_numpy(rest.astype(np.float32))
        out = np.empty((motion.n_frames, garment.n_vertices, 3), dtype=np.float32)
        with torch.no_grad():
            for s in range(0, motion.n_frames, o.batch_frames):
                out[s:s + o.batch_frames] = skin_points(x, w, torch.from_numpy(A[s:s + o.batch_frames])).numpy()
        self.scene = scene.report
        self.report = {"method": self.name, "options": asdict(o), "leg_spread_passes": leg_passes,
                       "rest_body_distance_mm": {"median": float(np.median(binding.body_distance) * 1e3),
                                                 "max": float(binding.body_distance.max() * 1e3)}}
        return self.limit_strain_of(out, garment, rest, o.strain_limit)


def _lazy(module: str, name: str) -> Callable[..., Deformer]:
    """A factory importing `module.name` on use, so importing this module loads neither warp nor the network."""

    def make(*args, **kwargs) -> Deformer:
        return getattr(importlib.import_module(module), name)(*args, **kwargs)

    return make


#: Method name -> factory of its Deformer (`bake --method NAME`).
DEFORMERS: dict[str, Callable[..., Deformer]] = {
    "lbs": LBSDeformer,
    "model": _lazy("core.model_deform", "ModelDeformer"),
    "psd": _lazy("core.psd", "PSDDeformer"),
    "sim": _lazy("core.sim", "SimDeformer"),
}
