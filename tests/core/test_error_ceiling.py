"""benchmarks/error_ceiling.py's kernels: the per-vertex blend of the body's transforms, and its inverse."""

import importlib.util
from pathlib import Path

import numpy as np

from tests.meshes import tiny_body

_spec = importlib.util.spec_from_file_location(
    "error_ceiling", Path(__file__).resolve().parents[2] / "benchmarks" / "error_ceiling.py")
ec = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(ec)


def test_blend_matches_a_naive_loop_and_unskin_inverts_skin():
    body = tiny_body()
    rng = np.random.default_rng(0)
    T, V, J = 3, 5, body.n_joints
    poses = rng.normal(0.0, 0.6, (T, J, 3)).astype(np.float32)
    trans = rng.normal(0.0, 1.0, (T, 3)).astype(np.float32)
    w = rng.random((V, J))
    w /= w.sum(axis=1, keepdims=True)
    M = ec.blended_transforms(body, w, poses, trans, None)
    A = body.skinning_transforms(poses, trans, None).astype(np.float64)
    for t in range(T):
        for v in range(V):
            naive = sum(w[v, j] * A[t, j, :3, :] for j in range(J))
            np.testing.assert_allclose(M[t, v], naive, atol=1e-9)
    rest = rng.normal(0.0, 0.3, (V, 3))
    x = ec.skin(M, rest)
    np.testing.assert_allclose(x[1, 2], M[1, 2, :, :3] @ rest[2] + M[1, 2, :, 3], atol=1e-12)
    np.testing.assert_allclose(ec.unskin(M, x), np.broadcast_to(rest, x.shape), atol=1e-9)
    assert abs(ec.e_verts_mm(x + np.array([0.0, 0.003, 0.004]), x) - 5.0) < 1e-9  # a 5 mm shift everywhere
