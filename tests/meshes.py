"""Tiny synthetic meshes shared by the tests (built in code, no files)."""

from __future__ import annotations

import numpy as np


def icosphere(subdivisions: int = 2, radius: float = 1.0, center=(0.0, 0.0, 0.0)):
    """A closed, outward-oriented icosphere: verts (V, 3) float64, faces (F, 3) int64."""
    t = (1.0 + 5 ** 0.5) / 2.0
    v = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t], [0, -1, -t],
                  [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]], dtype=np.float64)
    f = np.array([[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
                  [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8],
                  [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]], dtype=np.int64)
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    for _ in range(subdivisions):
        edges = {}
        verts = list(v)

        def mid(a, b):
            key = (min(a, b), max(a, b))
            if key not in edges:
                m = (verts[a] + verts[b]) / 2.0
                verts.append(m / np.linalg.norm(m))
                edges[key] = len(verts) - 1
            return edges[key]

        nf = []
        for a, b, c in f:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            nf += [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
        v, f = np.array(verts), np.array(nf, dtype=np.int64)
    return v * radius + np.asarray(center, dtype=np.float64), f


def grid(nx: int = 6, ny: int = 6, size: float = 1.0):
    """A flat triangulated grid in the z=0 plane: verts ((nx+1)*(ny+1), 3), faces (2*nx*ny, 3), normals +Z."""
    xs, ys = np.meshgrid(np.linspace(0, size, nx + 1), np.linspace(0, size, ny + 1), indexing="ij")
    v = np.stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)], axis=1)
    idx = np.arange((nx + 1) * (ny + 1)).reshape(nx + 1, ny + 1)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    f = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return v, f.astype(np.int64)


def tiny_body(n_betas: int = 4, seed: int = 0, weight_falloff_m: float = 0.05, min_weight: float = 0.0):
    """A small SMPL-format body (24 joints, SMPL kinematic tree): an ellipsoid 'torso' of 642 vertices.

    weight_falloff_m: skinning weights fall off as exp(-distance / this); weights under min_weight are cut
    to 0 (as real bodies' are, a few joints per vertex).

    Joints sit at SMPL-like rest positions (Y-up, metres); skinning weights are a
    softmax of inverse distance to the joints; shapedirs are smooth random fields;
    no pose correctives. Good for exercising skinning code, not for looks.
    """
    from core.body import SMPL_PARENTS, body_from_arrays

    rng = np.random.default_rng(seed)
    v, f = icosphere(3)
    v = v * np.array([0.25, 0.8, 0.15])
    joints = np.array([
        [0, 0, 0], [0.08, -0.08, 0], [-0.08, -0.08, 0], [0, 0.1, 0], [0.09, -0.45, 0], [-0.09, -0.45, 0],
        [0, 0.22, 0], [0.09, -0.75, 0], [-0.09, -0.75, 0], [0, 0.3, 0], [0.09, -0.78, 0.05],
        [-0.09, -0.78, 0.05], [0, 0.45, 0], [0.07, 0.4, 0], [-0.07, 0.4, 0], [0, 0.6, 0], [0.15, 0.42, 0],
        [-0.15, 0.42, 0], [0.2, 0.42, 0], [-0.2, 0.42, 0], [0.23, 0.42, 0], [-0.23, 0.42, 0], [0.24, 0.42, 0],
        [-0.24, 0.42, 0]])
    d = np.linalg.norm(v[:, None] - joints[None], axis=-1)
    logits = -d / weight_falloff_m
    w = np.exp(logits - logits.max(axis=1, keepdims=True))
    w /= w.sum(axis=1, keepdims=True)
    w[w < min_weight] = 0.0
    w /= w.sum(axis=1, keepdims=True)
    # J_regressor: each joint the normalised weighted mean of its closest vertices reproduces the joint.
    Jr = np.zeros((24, len(v)))
    for j in range(24):
        near = np.argsort(d[:, j])[:6]
        Jr[j, near] = 1.0 / 6
    # Put the regressed joints exactly where we want them by shifting v_template's joint targets.
    shapedirs = np.stack([v * rng.uniform(0.01, 0.03) * (k + 1) / n_betas for k in range(n_betas)], axis=-1)
    return body_from_arrays({"v_template": v, "shapedirs": shapedirs, "posedirs": None, "J_regressor": Jr,
                             "weights": w, "parents": np.array(SMPL_PARENTS), "faces": f}, name="tiny")


def points_around(n: int, r_min: float, r_max: float, seed: int = 0) -> np.ndarray:
    """(n, 3) float64 points in random directions from the origin, at radii uniform in [r_min, r_max]."""
    rng = np.random.default_rng(seed)
    dirs = rng.normal(size=(n, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    return dirs * rng.uniform(r_min, r_max, size=n)[:, None]



def with_fingers(body, layout: str = "smplh", seed: int = 0) -> dict:
    """The arrays of an SMPL+H (52 joints) or SMPL-X (55: jaw and eyes on the head first) body file made from
    the 24-joint `body`: each hand joint's weight split among MANO's 15 finger joints (3 on each of 5 fingers
    from the wrist) by the vertices' height, their rest joints the hand's; random pose correctives where
    `seed` is not None (else none)."""
    n_face = 3 if layout == "smplx" else 0
    J = 22 + n_face + 30
    parents = list(body.parents[:22]) + [15] * n_face
    regressor = [body.J_regressor[j] for j in range(22)] + [body.J_regressor[15]] * n_face
    weights = np.zeros((body.n_vertices, J), np.float32)
    weights[:, :22] = body.weights[:, :22]
    for side, (wrist, hand) in enumerate(((20, 22), (21, 23))):
        start = 22 + n_face + 15 * side
        parents += [wrist if k == 0 else start + 3 * f + k - 1 for f in range(5) for k in range(3)]
        regressor += [body.J_regressor[hand]] * 15
        ids = np.flatnonzero(body.weights[:, hand] > 0)
        for j, chunk in enumerate(np.array_split(ids[np.argsort(body.v_template[ids, 1])], 15)):
            weights[chunk, start + j] = body.weights[chunk, hand]
    arrays = dict(v_template=body.v_template, shapedirs=body.shapedirs, f=body.faces.astype(np.uint32),
                  J_regressor=np.array(regressor, np.float32), weights=weights,
                  kintree_table=np.stack([np.array(parents), np.arange(J)]).astype(np.int64))
    if seed is not None:
        rng = np.random.default_rng(seed)
        arrays["posedirs"] = (1e-3 * rng.standard_normal((body.n_vertices, 3, 9 * (J - 1)))).astype(np.float32)
    return arrays
