"""Gradient attribution of the learned model's deformation (paper section 5, Eq. 16).

Path-integrated gradients (Aumann-Shapley values): for inputs x and a baseline x',

    phi_i = (x_i - x'_i) * integral_0^1 df/dx_i (x' + a (x - x')) da,

the integral taken by Gauss-Legendre quadrature with N_s nodes (default 50) on [0, 1].
Completeness: sum_i phi_i = f(x) - f(x') up to the quadrature error.

f is the predicted deformation at one frame: the mean, over the chosen vertices (all by
default), of |x_v - x_v^lbs|, where x_v is the network's output and x_v^lbs the garment
skinned with its transferred (prior) weights, no blend shapes, at the same frame. The
attributed inputs are the network's own inputs at that frame:

- pose: the temporal window (m frames) of joint rotations (axis-angle of joints 1..S-1), the
  up vector in the root frame and the root velocity (root frame, m/s);
- velocity: the window of per-joint pooled body velocities (root frame, m/s) and the up vector;
- body: the joint-to-body-vertex distances of the shaped body (the body-shape input);
- garment: the per-vertex garment features (rest position, normal, joint distances).

Baseline: the same body standing still in the rest pose (zero rotations and velocities, the
same up vector), the mean body shape (betas 0), and zero garment features. Skinning transforms
and the shaped rest garment stay those of the actual frame (they are geometry, not network inputs).
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, replace

import numpy as np
import torch

from core.body import SMPL_JOINT_NAMES, Body, skin_points
from core.errors import InputError
from core.model import GarmentInputs, GarmentModel, body_distances, motion_features, shaped_rest, window_index
from core.model_deform import network_shape
from core.motion import Motion, poses_for_body

DEFAULT_STEPS = 50


@dataclass(frozen=True, eq=False)
class Inputs:
    """The attributed inputs of one frame, float64: pose (m, P), velocity (m, Q), body (Nb, S), garment (V, F)."""

    pose: torch.Tensor
    velocity: torch.Tensor
    body: torch.Tensor
    garment: torch.Tensor

    NAMES = ("pose", "velocity", "body", "garment")

    def as_tuple(self) -> tuple[torch.Tensor, ...]:
        return tuple(getattr(self, n) for n in self.NAMES)


@dataclass(frozen=True)
class Attribution:
    """phi: Inputs of attributions (same shapes as the inputs); f_input, f_baseline: f(x), f(x'); steps: N_s."""

    phi: Inputs
    f_input: float
    f_baseline: float
    steps: int

    @property
    def total(self) -> float:
        return float(sum(p.sum() for p in self.phi.as_tuple()))

    @property
    def completeness_error(self) -> float:
        """|sum phi - (f(x) - f(x'))|."""
        return abs(self.total - (self.f_input - self.f_baseline))


class DeformationTarget:
    """f(inputs) for one frame of one garment on one body and motion; see the module docstring. `vertices_from`:
    how an error names where `vertices` came from (`--vertices 'region.txt'`)."""

    def __init__(self, model: GarmentModel, g: GarmentInputs, body: Body, motion: Motion, frame: int,
                 vertices: np.ndarray | None = None, trained_betas: tuple[np.ndarray, np.ndarray] | None = None,
                 vertices_from: str = "--vertices"):
        if not 0 <= frame < motion.n_frames:
            raise InputError(f"--frame: expected a frame in 0..{motion.n_frames - 1} of motion '{motion.name}', "
                             f"got {frame}")
        self.model = copy.deepcopy(model).double().eval()
        self.g = _as_double(g)
        betas = body.fit_betas(motion.betas)
        poses = poses_for_body(motion, body.n_joints)
        mf = motion_features(body, poses, motion.trans, betas, motion.fps)
        win = window_index(torch.tensor([frame]), model.config.window)[0]
        self.rest = shaped_rest(g, body, betas).double()
        # the shape the network is given, as a bake gives it
        seen, view = network_shape(g, body, betas, trained_betas)
        self.shape_rest = None if view is None else view.double()
        self.transforms = mf.transforms[frame:frame + 1].double()
        self.input = Inputs(pose=mf.pose[win].double(), velocity=mf.velocity[win].double(),
                            body=body_distances(body, seen).double(), garment=self.g.features.clone())
        S = model.config.n_joints
        pose0 = self.input.pose.clone()
        pose0[:, : 3 * (S - 1)] = 0.0  # rest pose; the up vector (next 3) kept
        pose0[:, 3 * (S - 1) + 3:] = 0.0  # root velocity
        vel0 = self.input.velocity.clone()
        vel0[:, : 3 * S] = 0.0  # still body; up vector kept
        self.baseline = Inputs(pose=pose0, velocity=vel0, body=body_distances(body, np.zeros_like(betas)).double(),
                               garment=torch.zeros_like(self.input.garment))
        with torch.no_grad():
            self.lbs = skin_points(self.rest, self.g.prior_weights, self.transforms)[0]
        n = g.n_vertices
        self.vertices = np.arange(n) if vertices is None else np.asarray(vertices, dtype=np.int64)
        if self.vertices.size == 0 or self.vertices.min() < 0 or self.vertices.max() >= n:
            raise InputError(f"{vertices_from}: expected vertex indices in 0..{n - 1}, got "
                             f"{self.vertices.size} indices" + (f" from {self.vertices.min()} to {self.vertices.max()}"
                                                                 if self.vertices.size else ""))

    def verts(self, x: Inputs) -> torch.Tensor:
        """The network's garment (V, 3) at this frame for inputs x (differentiable)."""
        g = replace(self.g, features=x.garment)
        fused = self.model.encode(g, x.body)
        return self.model.forward_frames(fused, g, self.rest, x.pose[None], x.velocity[None], self.transforms,
                                         shape_rest=self.shape_rest).verts[0]

    def per_vertex(self, x: Inputs) -> torch.Tensor:
        """|x_v - x_v^lbs| (V,) for inputs x (differentiable)."""
        return torch.linalg.norm(self.verts(x) - self.lbs, dim=-1)

    def __call__(self, x: Inputs) -> torch.Tensor:
        return self.per_vertex(x)[torch.as_tensor(self.vertices)].mean()


def gauss_legendre_01(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Nodes and weights of n-point Gauss-Legendre quadrature on [0, 1] (weights sum to 1)."""
    if n < 1:
        raise InputError(f"--steps: expected at least 1 quadrature node, got {n}")
    t, w = np.polynomial.legendre.leggauss(n)
    return (t + 1.0) / 2.0, w / 2.0


def midpoint_01(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Nodes and weights of the n-step midpoint Riemann sum on [0, 1]."""
    return (np.arange(n) + 0.5) / n, np.full(n, 1.0 / n)


def integrated_gradients(f, x: Inputs, baseline: Inputs, steps: int = DEFAULT_STEPS,
                         rule: str = "gauss-legendre") -> Attribution:
    """Aumann-Shapley attributions of scalar f at x from `baseline` (see the module docstring).

    rule: "gauss-legendre" (N_s = steps nodes) or "riemann" (midpoint sum of `steps` steps).
    """
    nodes, weights = gauss_legendre_01(steps) if rule == "gauss-legendre" else midpoint_01(steps)
    xs, bs = x.as_tuple(), baseline.as_tuple()
    grads = [torch.zeros_like(t) for t in xs]
    for a, w in zip(nodes, weights):
        point = [(b + float(a) * (t - b)).detach().requires_grad_(True) for t, b in zip(xs, bs)]
        value = f(Inputs(*point))
        for acc, gr in zip(grads, torch.autograd.grad(value, point, allow_unused=True)):
            if gr is not None:
                acc += float(w) * gr
    phi = Inputs(*[((t - b) * gr).detach() for t, b, gr in zip(xs, bs, grads)])
    with torch.no_grad():
        return Attribution(phi=phi, f_input=float(f(x)), f_baseline=float(f(baseline)), steps=steps)


def attribution_table(att: Attribution, n_joints: int, window: int) -> list[tuple[str, float]]:
    """Named input groups and their attributions, largest |value| first.

    Rotations and velocities are summed per joint over the window and the 3 components; the up
    vector, the root velocity, the body shape and the garment features are one group each.
    """
    names = list(SMPL_JOINT_NAMES[:n_joints]) + [f"joint_{j}" for j in range(len(SMPL_JOINT_NAMES), n_joints)]
    S = n_joints
    pose = att.phi.pose.numpy()
    vel = att.phi.velocity.numpy()
    rows = [(f"rotation {names[j]}", float(pose[:, 3 * (j - 1): 3 * j].sum())) for j in range(1, S)]
    rows.append(("up vector (pose encoder)", float(pose[:, 3 * (S - 1): 3 * (S - 1) + 3].sum())))
    rows.append(("root velocity", float(pose[:, 3 * (S - 1) + 3:].sum())))
    rows += [(f"body velocity {names[j]}", float(vel[:, 3 * j: 3 * j + 3].sum())) for j in range(S)]
    rows.append(("up vector (velocity encoder)", float(vel[:, 3 * S:].sum())))
    rows.append(("body shape", float(att.phi.body.sum())))
    rows.append(("garment features", float(att.phi.garment.sum())))
    return sorted(rows, key=lambda r: -abs(r[1]))


def _as_double(g: GarmentInputs) -> GarmentInputs:
    fields = {k: (v.double() if isinstance(v, torch.Tensor) and v.is_floating_point() else v)
              for k, v in g.__dict__.items()}
    fields["unpool_weight"] = [w.double() for w in g.unpool_weight]
    return GarmentInputs(**fields)
