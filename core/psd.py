"""Pose-space deformation fitted to one garment's simulations (`garment fit`, `bake --method psd`).

The simulator's frames of a garment, pulled back into the rest frame through each vertex's LBS blend
(M_t = sum_j w_j A_tj, the `lbs` method's weights), are rest-frame offsets o_t = M_t^-1 x_t - rest: the blend
shape that would reproduce the simulation with LBS. `fit_psd` fits them, by ridge regression, as a linear
function of the frame's pose (each joint's R - I and its rate), the root's velocity and acceleration in its
own frame and the body shape, in the span of their first principal components: SMPL's pose blend shapes,
fitted to cloth. One fit belongs to one garment (its mesh hash) on one body; it says nothing of others.

Measured (`garment fit examples/trousers.obj --data data/sim_v4`, README "A garment's own blend shapes"): on
the example trousers' four held-out test motions it keeps 34 % of LBS's error (14.2 against 41.7 mm), where
the learned model keeps 56 %; 55 % on a brisk walk, the hardest. It costs LBS's time plus one small matrix
product per frame.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import torch

from core.body import Body, blend_transforms, skin_points
from core.deform import Deformer, LBSOptions
from core.errors import InputError
from core.garment import Garment
from core.motion import Motion, poses_for_body
from core.pushout import body_anchors, guard_and_limit
from core.rotations import axis_angle_to_matrix
from core.skinning import bind_garment, shaped_garment
from core.strain import STRAIN_LIMIT

#: Principal offsets kept (the example garments: 32 leave 3-7 mm of the offsets unexplained, oracle-fitted).
DEFAULT_RANK = 64
#: Ridge weight (features of order 1; on the example garments' held-out motions 1 and 100 are 0.5 and 1.8 mm
#: worse than 10).
DEFAULT_RIDGE = 10.0


#: Frames either side of a frame that its features read (`pose_features`: the rates' central differences, the root's
#: acceleration the differences of its velocity's): a bake of a --frames range deforms as many beyond it where the
#: motion has them (`core.motion.preroll`'s context), so its frames are the whole motion's (one-sided differences
#: at a range's ends moved them by up to 3 cm, and a motion baked in parts jumped at each seam).
FEATURE_CONTEXT_FRAMES = 2


def pose_features(poses: np.ndarray, trans: np.ndarray, betas: np.ndarray, fps: float) -> np.ndarray:
    """(T, F) float64 per-frame regressors: per joint R - I (9 numbers), its rate per second (x0.1), the root's
    velocity and acceleration in the root's frame (x0.3), the betas (x0.3), and 1.

    poses: (T, J, 3) axis-angles, root first; trans: (T, 3); betas: (S,). Scales put each group near 1.
    """
    poses, trans = np.asarray(poses, np.float64), np.asarray(trans, np.float64)
    T = len(poses)
    R = axis_angle_to_matrix(poses.reshape(-1, 3)).reshape(T, -1, 3, 3)
    pose = (R - np.eye(3)).reshape(T, -1)

    def per_second(a):  # finite-difference rate; none for a single frame
        return np.gradient(a, axis=0) * fps if T > 1 else np.zeros_like(a)

    rate, vel = per_second(pose), per_second(trans)
    acc = per_second(vel)
    root_vel, root_acc = np.einsum("tji,tj->ti", R[:, 0], vel), np.einsum("tji,tj->ti", R[:, 0], acc)  # R0^T v
    shape = np.broadcast_to(np.asarray(betas, np.float64), (T, len(betas)))
    return np.concatenate([pose, 0.1 * rate, 0.3 * root_vel, 0.3 * root_acc, 0.3 * shape, np.ones((T, 1))], axis=1)


#: A garment's vertices within this (metres, on every axis) of those fitted to are the fitted garment's (`PSDFit.
#: fits_garment`): float32 centimetres and back move a metre by 3e-8 m.
FIT_SAME_GARMENT_M = 1e-5


def _smallest_corner_first(faces: np.ndarray) -> np.ndarray:
    """(F, 3) each face's corners turned (same winding) so that its smallest vertex index comes first."""
    turn = np.argmin(faces, axis=1)[:, None]
    return np.take_along_axis(faces, (turn + np.arange(3)) % 3, axis=1)


def same_mesh(vertices: np.ndarray, faces: np.ndarray, other_vertices: np.ndarray, other_faces: np.ndarray) -> bool:
    """Whether two meshes are one garment: the same faces, each maybe starting at another corner, and vertices
    within FIT_SAME_GARMENT_M (a unit round trip or an export moves them by float rounding, and a corner's turn
    changes no triangle)."""
    v, f = np.asarray(vertices, np.float64), np.asarray(faces, np.int64)
    ov, of = np.asarray(other_vertices, np.float64), np.asarray(other_faces, np.int64)
    return (v.shape == ov.shape and f.shape == of.shape
            and np.array_equal(_smallest_corner_first(f), _smallest_corner_first(of))
            and float(np.abs(v - ov).max(initial=0.0)) <= FIT_SAME_GARMENT_M)


def ridge_solve(X: np.ndarray, Y: np.ndarray, lam: float) -> np.ndarray:
    """argmin_W |X W - Y|^2 + lam |W|^2: (F, D)."""
    return np.linalg.solve(X.T @ X + lam * np.eye(X.shape[1]), X.T @ Y)


@dataclass(frozen=True, eq=False)
class PSDFit:
    """A garment's fitted blend shapes: offsets (T, V, 3) = (mean + (X W) basis) for features X (T, F).

    garment_sha256: the garment's `content_hash` it was fitted to; body: the body's name (body_sha256: its
    `content_hash`); n_joints, n_betas:
    the body's; mean: (3V,) float32; basis: (K, 3V) float32 orthonormal rows; weights: (F, K) float32;
    smooth_iterations / smooth_strength: the LBS binding's weight smoothing (`LBSOptions`); meta: how it was
    fitted (sequences, frames, ridge, errors).
    """

    garment_sha256: str
    body: str
    n_joints: int
    n_betas: int
    mean: np.ndarray
    basis: np.ndarray
    weights: np.ndarray
    smooth_iterations: int = LBSOptions.smooth_iterations
    smooth_strength: float = LBSOptions.smooth_strength
    meta: dict = field(default_factory=dict)
    body_sha256: str | None = None  # `Body.content_hash` of the body fitted on (None: a fit written before it was)
    #: The garment fitted to: (V, 3) float32 vertices and (F, 3) int64 faces (None: a fit written before they were).
    garment_vertices: np.ndarray | None = None
    garment_faces: np.ndarray | None = None

    def fits_garment(self, garment: Garment) -> bool:
        """Whether `garment` is the one fitted to: the same bytes (`garment_sha256`), or the same mesh
        (`same_mesh`)."""
        if garment.content_hash() == self.garment_sha256:
            return True
        if self.garment_vertices is None or self.garment_faces is None:
            return False
        return same_mesh(garment.vertices, garment.faces, self.garment_vertices, self.garment_faces)

    @property
    def rank(self) -> int:
        return int(self.basis.shape[0])

    def offsets(self, features: np.ndarray) -> np.ndarray:
        """(T, V, 3) float32 rest-frame offsets for features (T, F)."""
        coefficients = np.asarray(features, np.float32) @ self.weights
        return (self.mean + coefficients @ self.basis).reshape(len(features), -1, 3)


def blended_transforms(body: Body, weights: np.ndarray, poses, trans, betas) -> np.ndarray:
    """(T, V, 3, 4) float64: each vertex's LBS blend of the body's skinning transforms."""
    A = body.skinning_transforms(poses, trans, betas).astype(np.float64)
    return blend_transforms(torch.from_numpy(np.asarray(weights, dtype=np.float64)), torch.from_numpy(A)).numpy()


def unskin(M: np.ndarray, x: np.ndarray) -> np.ndarray:
    """The rest points (T, V, 3) that the blended transforms M (T, V, 3, 4) map to x (T, V, 3): M^-1 x."""
    return np.linalg.solve(M[..., :3], (x - M[..., 3])[..., None])[..., 0]


def _motion_inputs(body: Body, motion: Motion):
    """(betas (S,), poses (T, J, 3), features (T, F)) of a motion on `body`."""
    betas = body.fit_betas(motion.betas)
    poses = poses_for_body(motion, body.n_joints)
    return betas, poses, pose_features(poses, motion.trans, betas, motion.fps)


def fit_psd(garment: Garment, body: Body, sequences, rank: int = DEFAULT_RANK, ridge: float = DEFAULT_RIDGE,
            options: LBSOptions = LBSOptions()) -> PSDFit:
    """Fit `garment`'s blend shapes to simulated `sequences`: (Motion, positions (T, V, 3) world metres) pairs,
    the motion without settle frames. Raises InputError for no frames or positions of another shape."""
    from core.quality import joint_speed

    binding = bind_garment(garment, body, options.smooth_iterations, options.smooth_strength)
    offsets, features, speeds, shapes = [], [], [], [0.0]
    angles = np.zeros(body.n_joints)  # each joint's largest rotation over the frames fitted (`beyond_fit`)
    for motion, positions in sequences:
        positions = np.asarray(positions, np.float64)
        if positions.shape != (motion.n_frames, garment.n_vertices, 3):
            raise InputError(f"psd fit: expected positions ({motion.n_frames}, {garment.n_vertices}, 3) for "
                             f"'{motion.name}', got {positions.shape}")
        betas, poses, X = _motion_inputs(body, motion)
        M = blended_transforms(body, binding.weights, poses, motion.trans, betas)
        rest = shaped_garment(garment.vertices, binding, betas).astype(np.float64)
        offsets.append((unskin(M, positions) - rest).reshape(len(positions), -1))
        features.append(X)
        angles = np.maximum(angles, np.linalg.norm(poses, axis=-1).max(axis=0))
        speeds.append(joint_speed(body, motion))
        shapes.append(float(np.abs(betas).max(initial=0.0)))
    if not offsets:
        raise InputError("psd fit: expected simulated sequences of the garment, got none")
    O, X = np.concatenate(offsets), np.concatenate(features)
    mean = O.mean(axis=0)
    k = max(1, min(rank, len(O) - 1))
    basis = np.linalg.svd(O - mean, full_matrices=False)[2][:k]
    C = (O - mean) @ basis.T
    W = ridge_solve(X, C, ridge)
    fitted = (mean + (X @ W) @ basis) - O
    residual = float(np.linalg.norm(fitted.reshape(len(O), -1, 3), axis=-1).mean())
    return PSDFit(garment_sha256=garment.content_hash(), body=body.name, n_joints=body.n_joints,
                  n_betas=body.n_betas, mean=mean.astype(np.float32), basis=basis.astype(np.float32),
                  weights=W.astype(np.float32), smooth_iterations=options.smooth_iterations,
                  smooth_strength=options.smooth_strength,
                  meta={"sequences": len(offsets), "frames": len(O), "rank": k, "ridge": ridge,
                        "fit_residual_mm": residual * 1e3,
                        # what it was fitted on: the motions' joint speeds (`core.quality.joint_speed`), the
                        # largest beta (`beyond_fit`)
                        "speed_m_s": [min(speeds), max(speeds)], "betas_abs_max": max(shapes),
                        # and each joint's largest rotation, of the joints that move the garment (not the root)
                        "joint_angle_max_deg": {name: round(float(np.degrees(angles[j])), 2)
                                                for j, name in enumerate(body.joint_names)
                                                if j > 0 and binding.weights[:, j].max() > FIT_JOINT_WEIGHT}},
                  body_sha256=body.content_hash(),
                  garment_vertices=garment.vertices.astype(np.float32), garment_faces=garment.faces.astype(np.int64))


#: How far beyond a fit's training motions a motion may go before it is warned about: joint speeds this many
#: times below the slowest or above the fastest (as `core.quality.OUTSIDE_FACTOR`), betas this much larger.
FIT_SPEED_FACTOR = 1.25
FIT_BETAS_MARGIN = 1.0
#: A joint moves the garment where some vertex has more than this of its weight (its rotations recorded); a
#: motion that turns one of them more than FIT_ANGLE_MARGIN_DEG beyond the fitted frames' largest is warned about
#: (the arms raised on a fit of walks came 7.2 mm off where the cloth did not move).
FIT_JOINT_WEIGHT = 0.05
FIT_ANGLE_MARGIN_DEG = 20.0


def beyond_fit(fit: PSDFit, body: Body, motion: Motion) -> str:
    """Where `motion` lies beyond what `fit` was fitted on (its joint speed, a joint's rotation, its body shape), in
    words; "" where it does not, or the fit records nothing of it (an older fit). There a fit can do worse than
    LBS: its blend shapes answer poses and speeds it never saw."""
    from core.quality import joint_speed

    out = []
    if "speed_m_s" in fit.meta:
        lo, hi = fit.meta["speed_m_s"]
        speed = joint_speed(body, motion)
        if speed > hi * FIT_SPEED_FACTOR:
            out.append(f"its joints move at {speed:.2g} m/s, the fastest fitted {hi:.2g}")
        elif speed < lo / FIT_SPEED_FACTOR:
            out.append(f"its joints move at {speed:.2g} m/s, the slowest fitted {lo:.2g}")
    fitted = fit.meta.get("joint_angle_max_deg") or {}
    if fitted:
        turned = dict(zip(body.joint_names,
                          np.degrees(np.linalg.norm(poses_for_body(motion, body.n_joints), axis=-1).max(axis=0))))
        over = sorted(((turned[name] - most, name, most) for name, most in fitted.items()
                       if turned.get(name, -np.inf) > most + FIT_ANGLE_MARGIN_DEG), reverse=True)
        if over:
            excess, name, most = over[0]
            out.append(f"its {name} turns {most + excess:.0f} degrees, the most fitted {most:.0f}"
                       + (f" (and {len(over) - 1} more joint{'' if len(over) == 2 else 's'} beyond)"
                          if len(over) > 1 else ""))
    if "betas_abs_max" in fit.meta and motion.betas is not None:
        largest = float(np.abs(motion.betas).max(initial=0.0))
        if largest > fit.meta["betas_abs_max"] + FIT_BETAS_MARGIN:
            out.append(f"a beta of {largest:.2g}, the largest fitted {fit.meta['betas_abs_max']:.2g}")
    return "; ".join(out)


class PSDDeformer(Deformer):
    """LBS plus a garment's blend shapes fitted to its simulations (`fit_psd`): as fast as LBS, as near the
    simulator as its fit on motions like those it was fitted to."""

    name = "psd"

    def __init__(self, fit: PSDFit, source: str = "psd fit", contact_guard: bool = True,
                 strain_limit: float | None = STRAIN_LIMIT):
        super().__init__()
        self.fit = fit
        self.source = source
        #: Keep vertices outside the body faces they rest on, as the model does (`core.pushout.guard_sequence`):
        #: a fit's offsets carry a tight garment into the body on motions unlike its own.
        self.contact_guard = contact_guard
        #: No edge longer than this times its rest length, after the guard (`core.strain`), as the model; None: off.
        self.strain_limit = strain_limit
        self._bindings: dict = {}
        self._anchors: dict = {}  # the guard's anchors of the last garment and body shape (77 ms for the trousers)

    def prepare(self, garment: Garment, body: Body, source: str | None = None) -> None:
        key = (garment.content_hash(), id(body))
        if key in self._bindings:
            return
        self.check(garment, body, source)
        fit = self.fit
        self._bindings[key] = bind_garment(garment, body, fit.smooth_iterations, fit.smooth_strength, source=source)

    def check(self, garment: Garment, body: Body, source: str | None = None) -> None:
        """InputError unless the fit belongs to this garment (its mesh) and a body of its joint and beta counts."""
        fit = self.fit
        if not fit.fits_garment(garment):
            raise InputError(f"{self.source}: fitted to another garment (mesh {fit.garment_sha256[:12]}), not "
                             f"'{source or garment.name}' ({garment.content_hash()[:12]}): fit it with `garment fit`")
        if (body.n_joints, body.n_betas) != (fit.n_joints, fit.n_betas):
            raise InputError(f"{self.source}: fitted on body '{fit.body}' ({fit.n_joints} joints, {fit.n_betas} "
                             f"betas), got '{body.name}' ({body.n_joints}, {body.n_betas})")
        if fit.body_sha256 is not None and fit.body_sha256 != body.content_hash():
            raise InputError(f"{self.source}: fitted on body '{fit.body}' ({fit.body_sha256[:12]}), got another body "
                             f"'{body.name}' ({body.content_hash()[:12]}) of its joints and betas: fit it on this "
                             f"body's simulations with `garment fit`")

    def deform(self, garment: Garment, body: Body, motion: Motion) -> np.ndarray:
        self.prepare(garment, body)
        binding = self._bindings[(garment.content_hash(), id(body))]
        betas, poses, X = _motion_inputs(body, motion)
        rest = shaped_garment(garment.vertices, binding, betas).astype(np.float32)
        A = torch.from_numpy(body.skinning_transforms(poses, motion.trans, betas))
        w = torch.from_numpy(binding.weights)
        out = np.empty((motion.n_frames, garment.n_vertices, 3), dtype=np.float32)
        batch = LBSOptions.batch_frames
        with torch.no_grad():
            for s in range(0, motion.n_frames, batch):
                points = torch.from_numpy(rest + self.fit.offsets(X[s:s + batch]))
                out[s:s + batch] = skin_points(points, w, A[s:s + batch]).numpy()
        self.report = {"method": self.name, "fit": {"source": self.source, "rank": self.fit.rank,
                                                    **self.fit.meta}}
        anchors = None
        if self.contact_guard:  # reported as the model reports it
            key = (garment.content_hash(), id(body), np.asarray(betas).tobytes())
            if key not in self._anchors:
                self._anchors = {key: body_anchors(rest, garment.faces, body, betas)}
            anchors = self._anchors[key]
        out, guard = guard_and_limit(self, out, garment, rest, body, poses, motion.trans, betas, anchors,
                                     self.strain_limit)
        self.report.update(guard)
        return out
