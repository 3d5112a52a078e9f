"""Tests of core/rotations.py: conversions round-trip, slerp, torch/numpy agreement."""

import numpy as np
import pytest
import torch

from core.rotations import (
    axis_angle_to_matrix,
    axis_angle_to_matrix_torch,
    axis_angle_to_quat,
    matrix_to_axis_angle,
    matrix_to_quat,
    quat_slerp,
    quat_to_axis_angle,
    quat_to_matrix,
)


def _random_aa(n, rng, max_angle=np.pi - 1e-3):
    axis = rng.normal(size=(n, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    return axis * rng.uniform(0, max_angle, size=(n, 1))


def _special_aa():
    """Angles at 0, tiny, and near pi about assorted axes."""
    axes = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1], [-0.3, 0.5, -0.8]], dtype=np.float64)
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    angles = [0.0, 1e-12, 1e-8, 1e-6, 1e-4, 0.5, np.pi - 1e-3, np.pi - 1e-6]
    return np.concatenate([axes * a for a in angles])


def _naive_rodrigues(aa):
    """Per-vector reference: R = I + sin(t) K + (1 - cos(t)) K^2 from a unit axis."""
    out = []
    for v in aa:
        t = np.linalg.norm(v)
        if t == 0:
            out.append(np.eye(3))
            continue
        k = v / t
        K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
        out.append(np.eye(3) + np.sin(t) * K + (1 - np.cos(t)) * K @ K)
    return np.array(out)


def test_matrix_matches_naive_rodrigues():
    aa = np.concatenate([_random_aa(50, np.random.default_rng(0)), _special_aa()])
    np.testing.assert_allclose(axis_angle_to_matrix(aa), _naive_rodrigues(aa), atol=1e-12)


def test_matrices_are_rotations():
    R = axis_angle_to_matrix(_random_aa(100, np.random.default_rng(1)))
    np.testing.assert_allclose(R @ np.swapaxes(R, -1, -2), np.broadcast_to(np.eye(3), R.shape), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-12)


@pytest.mark.parametrize("source", ["random", "special"])
def test_aa_quat_aa_round_trip(source):
    aa = _random_aa(200, np.random.default_rng(2)) if source == "random" else _special_aa()
    q = axis_angle_to_quat(aa)
    np.testing.assert_allclose(np.linalg.norm(q, axis=-1), 1.0, atol=1e-12)
    np.testing.assert_allclose(quat_to_axis_angle(q), aa, atol=1e-9)


@pytest.mark.parametrize("source", ["random", "special"])
def test_aa_matrix_aa_round_trip(source):
    aa = _random_aa(200, np.random.default_rng(3)) if source == "random" else _special_aa()
    back = matrix_to_axis_angle(axis_angle_to_matrix(aa))
    # Near pi the axis is recovered from the matrix with ~sqrt(eps) accuracy; compare as rotations too.
    np.testing.assert_allclose(axis_angle_to_matrix(back), axis_angle_to_matrix(aa), atol=1e-9)
    np.testing.assert_allclose(back, aa, atol=2e-6)


def test_exactly_pi_round_trips_as_rotation():
    aa = np.array([[np.pi, 0, 0], [0, np.pi, 0], [0, 0, np.pi], np.array([1, -1, 1]) / np.sqrt(3) * np.pi])
    R = axis_angle_to_matrix(aa)
    back = matrix_to_axis_angle(R)
    np.testing.assert_allclose(np.linalg.norm(back, axis=-1), np.pi, atol=1e-9)
    np.testing.assert_allclose(axis_angle_to_matrix(back), R, atol=1e-9)
    # The axis is determined up to sign at pi.
    np.testing.assert_allclose(np.abs(back), np.abs(aa), atol=1e-9)


def test_angle_above_pi_wraps_to_the_same_rotation():
    aa = np.array([[0.0, 0.0, 1.5 * np.pi]])
    back = quat_to_axis_angle(axis_angle_to_quat(aa))
    np.testing.assert_allclose(back, [[0.0, 0.0, -0.5 * np.pi]], atol=1e-12)


def test_quat_matrix_round_trip_and_canonical_sign():
    aa = np.concatenate([_random_aa(200, np.random.default_rng(4)), _special_aa()])
    q = axis_angle_to_quat(aa)
    q2 = matrix_to_quat(axis_angle_to_matrix(aa))
    assert np.all(q2[:, 0] >= 0)
    # q and -q are the same rotation; at angle ~pi w ~ 0 so compare up to sign.
    sign = np.where(np.sum(q * q2, axis=-1, keepdims=True) < 0, -1.0, 1.0)
    np.testing.assert_allclose(sign * q2, q, atol=1e-9)


def test_quat_to_axis_angle_accepts_unnormalised_and_negative_w():
    aa = _random_aa(20, np.random.default_rng(5))
    q = axis_angle_to_quat(aa)
    np.testing.assert_allclose(quat_to_axis_angle(-3.0 * q), aa, atol=1e-9)


def test_slerp_endpoints_and_midpoint():
    rng = np.random.default_rng(6)
    q0 = axis_angle_to_quat(_random_aa(30, rng))
    q1 = axis_angle_to_quat(_random_aa(30, rng))
    np.testing.assert_allclose(quat_slerp(q0, q1, np.zeros(30)), q0, atol=1e-12)
    end = quat_slerp(q0, q1, np.ones(30))
    np.testing.assert_allclose(np.abs(np.sum(end * q1, -1)), 1.0, atol=1e-12)  # q1 up to sign
    mid = quat_slerp(q0, q1, np.full(30, 0.5))
    # The midpoint is equally far (as a rotation) from both ends.
    d0 = np.arccos(np.clip(np.abs(np.sum(mid * q0, -1)), 0, 1))
    d1 = np.arccos(np.clip(np.abs(np.sum(mid * q1, -1)), 0, 1))
    np.testing.assert_allclose(d0, d1, atol=1e-9)


def test_slerp_about_one_axis_is_linear_in_angle():
    axis = np.array([0.6, 0.0, 0.8])
    q0 = axis_angle_to_quat(0.2 * axis)
    q1 = axis_angle_to_quat(2.2 * axis)
    t = np.linspace(0, 1, 11)
    out = quat_slerp(q0[None], q1[None], t)
    np.testing.assert_allclose(quat_to_axis_angle(out), (0.2 + 2.0 * t)[:, None] * axis, atol=1e-12)


def test_slerp_constant_angular_velocity_and_shorter_arc():
    rng = np.random.default_rng(7)
    q0 = axis_angle_to_quat(_random_aa(1, rng))[0]
    q1 = -axis_angle_to_quat(_random_aa(1, rng))[0]  # flipped sign: must still take the shorter arc
    t = np.linspace(0, 1, 21)
    out = quat_slerp(np.broadcast_to(q0, (21, 4)), np.broadcast_to(q1, (21, 4)), t)
    step = 2 * np.arccos(np.clip(np.abs(np.sum(out[1:] * out[:-1], -1)), 0, 1))
    total = 2 * np.arccos(np.clip(abs(np.dot(q0, q1)), 0, 1))
    assert total <= np.pi + 1e-12
    np.testing.assert_allclose(step, total / 20, atol=1e-9)


def test_slerp_of_nearly_equal_quaternions_is_finite():
    q0 = axis_angle_to_quat(np.array([0.3, 0.2, 0.1]))
    q1 = axis_angle_to_quat(np.array([0.3, 0.2, 0.1 + 1e-9]))
    out = quat_slerp(q0, q1, 0.5)
    assert np.all(np.isfinite(out))
    np.testing.assert_allclose(np.linalg.norm(out), 1.0, atol=1e-12)


@pytest.mark.parametrize("dtype", [torch.float64, torch.float32])
def test_torch_matrix_equals_numpy(dtype):
    aa = np.concatenate([_random_aa(100, np.random.default_rng(8)), _special_aa(), [[0.0, 0.0, 0.0]]])
    R_t = axis_angle_to_matrix_torch(torch.tensor(aa, dtype=dtype)).double().numpy()
    np.testing.assert_allclose(R_t, axis_angle_to_matrix(aa), atol=1e-12 if dtype == torch.float64 else 2e-6)


def test_torch_matrix_batched_shapes():
    aa = torch.zeros(2, 5, 3)
    assert axis_angle_to_matrix_torch(aa).shape == (2, 5, 3, 3)


def test_torch_gradients_finite_at_and_near_zero():
    aa = torch.tensor([[0.0, 0.0, 0.0], [1e-7, 0.0, 0.0], [1e-5, -2e-5, 3e-5], [0.3, -0.2, 0.1]],
                      dtype=torch.float64, requires_grad=True)
    R = axis_angle_to_matrix_torch(aa)
    (R * torch.arange(9, dtype=torch.float64).reshape(3, 3)).sum().backward()
    assert torch.all(torch.isfinite(aa.grad))
    # At zero, dR/d(aa) is the skew generator: check against a finite difference.
    g = torch.autograd.functional.jacobian(lambda a: axis_angle_to_matrix_torch(a), torch.zeros(3, dtype=torch.float64))
    expected = np.zeros((3, 3, 3))
    expected[2, 1, 0], expected[1, 2, 0] = 1, -1  # d/dx
    expected[0, 2, 1], expected[2, 0, 1] = 1, -1  # d/dy
    expected[1, 0, 2], expected[0, 1, 2] = 1, -1  # d/dz
    np.testing.assert_allclose(g.numpy(), expected, atol=1e-8)


def test_quat_to_matrix_is_rodrigues_and_inverts_matrix_to_quat():
    """A quaternion of any norm (w, x, y, z) gives the rotation its axis-angle gives; back through
    matrix_to_quat, the same unit quaternion (w >= 0)."""
    rng = np.random.default_rng(3)
    aa = np.concatenate([_random_aa(200, rng), _special_aa()])
    q = axis_angle_to_quat(aa)
    scale = rng.uniform(0.5, 2.0, size=(len(q), 1))
    np.testing.assert_allclose(quat_to_matrix(q * scale), axis_angle_to_matrix(aa), atol=1e-12)
    canonical = np.where(q[:, :1] < 0, -q, q)
    np.testing.assert_allclose(matrix_to_quat(quat_to_matrix(q)), canonical, atol=1e-9)
