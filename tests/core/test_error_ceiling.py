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


def test_linear_baseline_features_and_ridge():
    T, J, fps = 4, 3, 30.0
    poses = np.zeros((T, J, 3))
    poses[:, 0, 2] = np.pi / 2  # root turned 90 degrees about Z
    poses[:, 1, 0] = np.linspace(0.0, 0.3, T)  # joint 1 bends at 3 rad/s about X (0.1 rad a frame)
    trans = np.zeros((T, 3))
    trans[:, 0] = np.arange(T) / fps  # 1 m/s along world X
    betas = np.array([1.0, -2.0])
    X = ec.pose_shape_features(poses, trans, betas, fps)
    assert X.shape == (T, 9 * J * 2 + 6 + 2 + 1)
    pose, rate = X[:, :9 * J].reshape(T, J, 3, 3), X[:, 9 * J:18 * J].reshape(T, J, 3, 3)
    assert np.allclose(pose[:, 2], 0.0) and np.allclose(pose[0, 1], 0.0)
    c, s = np.cos(0.2), np.sin(0.2)  # frame 2: 0.2 rad about X
    assert np.allclose(pose[2, 1] + np.eye(3), [[1, 0, 0], [0, c, -s], [0, s, c]])
    # d/dt (R - I) at angle a about X is 3 rad/s times [[0,0,0],[0,-sin,-cos],[0,cos,-sin]]; x0.1 scale, central difference
    a = 0.1
    assert np.allclose(rate[1, 1] / 0.1, 3.0 * np.array([[0, 0, 0], [0, -np.sin(a), -np.cos(a)], [0, np.cos(a), -np.sin(a)]]),
                       atol=0.05)
    # world +X seen from a root turned +90 degrees about Z is its -Y; no acceleration
    assert np.allclose(X[:, 18 * J:18 * J + 3] / 0.3, [0.0, -1.0, 0.0], atol=1e-9)
    assert np.allclose(X[:, 18 * J + 3:18 * J + 6], 0.0, atol=1e-9)
    assert np.allclose(X[:, -3:-1] / 0.3, betas) and np.all(X[:, -1] == 1.0)
    rng = np.random.default_rng(0)
    A, Y = rng.normal(size=(20, 4)), rng.normal(size=(20, 3))
    lam = 0.5  # the closed form against least squares on the stacked system [A; sqrt(lam) I]
    stacked = np.linalg.lstsq(np.r_[A, np.sqrt(lam) * np.eye(4)], np.r_[Y, np.zeros((4, 3))], rcond=None)[0]
    np.testing.assert_allclose(ec.ridge(A, Y, lam), stacked, atol=1e-10)
