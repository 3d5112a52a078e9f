"""Penetration push-out: a post-process that moves garment vertices inside the body to just outside it.

Any method's output can be pushed out (`bake --push-out`, and the `+push-out` rows of `garment
tradeoff`). A vertex whose signed distance to the posed body is below `margin` is moved to the closest
body point plus `margin` along the direction from the body to the vertex (outward for a vertex inside,
the vertex's own side for one within the margin outside). The cloth's own shape is not relaxed
afterwards: a pushed region can stretch by up to its depth of penetration.
"""

from __future__ import annotations

import numpy as np

from core.body import Body
from core.deform import Deformer
from core.garment import Garment
from core.geometry import TriangleMesh
from core.motion import Motion, poses_for_body

#: Distance outside the body a pushed vertex ends at (metres): within the 2 mm depth the penetration
#: statistics tolerate, so a pushed vertex never counts as inside.
PUSH_OUT_MARGIN_M = 0.001


def push_out(points: np.ndarray, body_points: np.ndarray, body_faces: np.ndarray,
             margin: float = PUSH_OUT_MARGIN_M) -> tuple[np.ndarray, np.ndarray]:
    """Move vertices closer than `margin` to the body's surface (or inside it) to `margin` outside.

    points: (T, V, 3) garment; body_points: (T, Vb, 3) posed body (closed, outward-oriented faces);
    body_faces: (Fb, 3). Returns (pushed points (T, V, 3) float32, moved (T,) vertex counts).
    """
    out = np.array(points, dtype=np.float32, copy=True)
    moved = np.zeros(len(out), dtype=np.int64)
    for t in range(len(out)):
        mesh = TriangleMesh(body_points[t], body_faces)
        p = out[t].astype(np.float64)
        res, signed = mesh.signed_closest(p, exact=False)
        sel = np.flatnonzero(signed < margin)
        if not len(sel):
            continue
        away = p[sel] - res.closest[sel]
        length = np.linalg.norm(away, axis=1, keepdims=True)
        direction = np.where(length > 1e-12, away / np.maximum(length, 1e-12), 0.0)
        direction *= np.where(signed[sel] < 0, -1.0, 1.0)[:, None]  # inside: from the vertex to the surface
        # A vertex exactly on the surface: the face's normal.
        flat = length[:, 0] <= 1e-12
        if flat.any():
            tri = body_points[t][body_faces[res.face_index[sel[flat]]]]
            n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
            direction[flat] = n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
        out[t, sel] = (res.closest[sel] + margin * direction).astype(np.float32)
        moved[t] = len(sel)
    return out, moved


class PushOutDeformer(Deformer):
    """Another deformer's output with `push_out` applied to every frame."""

    def __init__(self, inner: Deformer, margin: float = PUSH_OUT_MARGIN_M):
        super().__init__()
        self.inner, self.margin = inner, margin
        self.name = inner.name  # the method; the report says it was pushed out

    def prepare(self, garment: Garment, body: Body, source: str | None = None) -> None:
        self.inner.prepare(garment, body, source)

    def deform(self, garment: Garment, body: Body, motion: Motion) -> np.ndarray:
        self.inner.on_frames, self.inner.skips = self.on_frames, self.skips
        points = self.inner.deform(garment, body, motion)
        self.scene = self.inner.scene
        body_points, _ = body.pose(poses_for_body(motion, body.n_joints), motion.trans, motion.betas)
        pushed, moved = push_out(points, body_points, body.faces, self.margin)
        self.report = {**self.inner.report, "push_out": {"margin_m": self.margin,
                                                         "vertices_moved_per_frame_mean": float(moved.mean()),
                                                         "vertices_moved_per_frame_max": int(moved.max(initial=0))}}
        return pushed
