"""Stability at the extremes (issue 10, point 4): every case returns finite output, bounded (no
garment vertex further from the body than the garment's own size), or stops with a clear error.

Each motion case runs through LBS (on a 13k-vertex shell of the body), through the learned
model (a small network whose weights are perturbed at random, so its learned skinning and blend
shapes are far from zero, on a 384-vertex skirt): the model must stay bounded for any
weights, not only for well-trained ones; and through the simulator (the example skirt, 5
substeps), which may instead stop with a SimulationError naming the frame.
"""
import re
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import cKDTree

from core.body import default_body
from core.deform import LBSDeformer, LBSOptions
from core.errors import InputError
from core.garment import Garment, mesh_edges
from core.geometry import vertex_normals
from core.motion import Motion, Y_UP_TO_Z_UP, resample, settle
from core.motion import poses_for_body


@pytest.fixture(scope="module")
def body():
    return default_body()


def shell(body, offset=0.015, subdivisions=0, stride=1):
    """A garment: the body surface pushed out along its normals (optionally subdivided or thinned)."""
    v = (body.v_template + offset * vertex_normals(body.v_template, body.faces)).astype(np.float64)
    f = body.faces.copy()
    for _ in range(subdivisions):
        e = mesh_edges(f)
        mid = {tuple(k): len(v) + i for i, k in enumerate(e)}
        v = np.concatenate([v, (v[e[:, 0]] + v[e[:, 1]]) / 2])
        a, b, c = f[:, 0], f[:, 1], f[:, 2]
        m = lambda x, y: np.array([mid[(min(i, j), max(i, j))] for i, j in zip(x, y)])  # noqa: E731
        ab, bc, ca = m(a, b), m(b, c), m(c, a)
        f = np.concatenate([np.stack(t, 1) for t in ((a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca))])
    return Garment(v.astype(np.float32), f.astype(np.int64), name="shell")


def assert_finite_and_bounded(points, body, motion, stride=10):
    assert np.all(np.isfinite(points))
    size = float(np.ptp(points[0], axis=0).max())
    frames = np.arange(0, motion.n_frames, stride)
    body_pts, _ = body.pose(poses_for_body(motion, body.n_joints)[frames], motion.trans[frames], motion.betas)
    for t, bp in zip(frames, body_pts):
        d, _ = cKDTree(bp).query(points[t])
        assert d.max() < size, (t, d.max(), size)


def still(n, J=24):
    poses = np.zeros((n, J, 3), np.float32)
    poses[:, 0] = Y_UP_TO_Z_UP
    return poses


def perturbed_model_deformer(cache_dir, seed=0, scale=0.3):
    """A ModelDeformer over a small GarmentModel whose every parameter got N(0, scale^2) noise, with the
    shipped model's inputs (shape displacement, pose codes: betas of +-5 move the garment by decimetres)."""
    from core.model import ModelConfig
    from core.model_deform import ModelDeformer
    from tests.core.model_fixtures import perturbed_model

    model = perturbed_model(ModelConfig(hidden=16, heads=1, encoder_layers=1, level_layers=1, bottom_layers=1,
                                        levels=2, window=5, lstm_hidden=16, inducing_points=4, attention_heads=1,
                                        n_eigenvalues=8, n_landmarks=16, shape_input=1, pose_codes=1), scale, seed)
    return ModelDeformer(model, batch_frames=64, cache_dir=cache_dir, model_name="perturbed")


def deform_checked(deformer, garment, body, motion, stride=10):
    """The deformer's output, finite and bounded; None where the simulator stopped with a clear error instead."""
    from core.sim import SimDeformer, SimulationError

    try:
        out = deformer.deform(garment, body, motion)
    except SimulationError as exc:
        assert isinstance(deformer, SimDeformer) and re.search(r"frame \d+ of motion '.*' failed", str(exc)), exc
        return None
    assert_finite_and_bounded(out, body, motion, stride)
    return out


@pytest.fixture(scope="module", params=["lbs", "model", "sim"])
def case(request, body, tmp_path_factory):
    """(garment, deformer) for each method."""
    if request.param == "lbs":
        return shell(body), LBSDeformer()
    if request.param == "sim":
        from core.sim import SimDeformer, SimOptions
        from formats.obj import read_obj

        skirt = read_obj(Path(__file__).resolve().parents[2] / "examples" / "skirt.obj")
        return skirt, SimDeformer(options=SimOptions(substeps=5, settle_s=0.2))
    from tests.core.model_fixtures import tube

    v, f = tube(32, 12, radius=(0.2, 0.15), y=(-0.35, 0.05))  # a 384-vertex skirt around the hips
    return Garment(v, f, name="skirt"), perturbed_model_deformer(tmp_path_factory.mktemp("cache"))


@pytest.fixture(scope="module")
def garment(case):
    return case[0]


@pytest.fixture(scope="module")
def deformer(case):
    return case[1]


def test_extreme_betas(body, garment, deformer):
    for sign in (-5.0, 5.0):
        m = Motion(poses=still(2), trans=np.zeros((2, 3), np.float32), fps=30, betas=np.full(10, sign, np.float32))
        deform_checked(deformer, garment, body, m, stride=1)


def test_poses_at_and_beyond_joint_limits(body, garment, deformer):
    rng = np.random.default_rng(0)
    poses = still(20)
    poses[:, 1:] = rng.uniform(-1, 1, size=(20, 23, 3)) * np.linspace(0.5, 2 * np.pi, 20)[:, None, None]
    m = Motion(poses=poses.astype(np.float32), trans=np.zeros((20, 3), np.float32), fps=30)
    deform_checked(deformer, garment, body, m, stride=4)


def test_180_degree_flips_between_frames(body, garment, deformer):
    poses = still(8)
    poses[1::2, 16] = [np.pi, 0, 0]  # left shoulder flips by 180 deg every frame
    poses[1::2, 1] = [0, 0, -np.pi]
    m = Motion(poses=poses, trans=np.zeros((8, 3), np.float32), fps=30)
    # resampling across antipodal rotations must not produce NaN (slerp of opposite quaternions)
    m60 = resample(m, 60.0)
    assert np.all(np.isfinite(m60.poses))
    deform_checked(deformer, garment, body, m60, stride=3)


def test_root_teleports_of_10_m(body, garment, deformer):
    trans = np.zeros((6, 3), np.float32)
    trans[::2] = [10.0, -10.0, 0.0]
    m = Motion(poses=still(6), trans=trans, fps=30)
    out = deform_checked(deformer, garment, body, m, stride=1)
    if isinstance(deformer, LBSDeformer):  # LBS is exactly translation-equivariant; the model sees the jump's speed
        np.testing.assert_allclose(out[0] - out[1], np.broadcast_to([10.0, -10.0, 0.0], out[0].shape), atol=1e-4)


@pytest.mark.parametrize("source_fps", [5.0, 240.0])
def test_very_low_and_high_input_frame_rates(body, garment, deformer, source_fps):
    n = int(source_fps * 2) + 1  # two seconds
    poses = still(n)
    poses[:, 18, 2] = np.linspace(0, 1.5, n)  # elbow bends
    m = resample(Motion(poses=poses, trans=np.zeros((n, 3), np.float32), fps=source_fps), 30.0)
    assert m.n_frames == 61
    np.testing.assert_allclose(np.linalg.norm(m.poses[-1, 18]), 1.5, atol=1e-5)
    deform_checked(deformer, garment, body, m, stride=10)


def test_10000_frames_error_does_not_grow(body, garment, deformer):
    """A periodic 10,000-frame motion: the last thousand frames equal frames 1,000-1,999 (no drift)."""
    from core.sim import SimDeformer

    if isinstance(deformer, SimDeformer):
        pytest.skip("the simulator takes about 0.2 s a frame here: 10,000 frames would be half an hour")
    n, period = 10_000, 100
    poses = still(n)
    phase = 2 * np.pi * np.arange(n) / period
    poses[:, 1, 0] = 0.5 * np.sin(phase)
    poses[:, 2, 0] = -0.5 * np.sin(phase)
    poses[:, 16, 2] = -0.6 + 0.3 * np.cos(phase)
    m = Motion(poses=poses, trans=np.zeros((n, 3), np.float32), fps=30)
    out = deformer.deform(garment, body, m)
    assert out.shape == (n, garment.n_vertices, 3) and np.all(np.isfinite(out))
    np.testing.assert_allclose(out[-1000:], out[1000:2000], atol=1e-4)  # 80 periods apart, windows full


@pytest.mark.parametrize("size", ["tiny", "huge"])
def test_garments_of_50_and_50000_vertices(body, size):
    if size == "tiny":
        # a 50-vertex band around the waist: two rings of 25, quads split in two
        full = shell(body)
        ring = full.vertices[np.abs(full.vertices[:, 1] - 0.1) < 0.01]
        centre = ring.mean(axis=0)
        angle = np.linspace(0, 2 * np.pi, 25, endpoint=False)
        radius = np.max(np.linalg.norm((ring - centre)[:, [0, 2]], axis=1)) + 0.01
        rings = [np.stack([centre[0] + radius * np.cos(angle), np.full(25, y), centre[2] + radius * np.sin(angle)], 1)
                 for y in (0.05, 0.12)]
        i = np.arange(25)
        j = (i + 1) % 25
        f = np.concatenate([np.stack([i, j, 25 + i], 1), np.stack([j, 25 + j, 25 + i], 1)])
        g = Garment(np.concatenate(rings).astype(np.float32), f, name="tiny")
        assert g.n_vertices == 50
    else:
        g = shell(body, subdivisions=1)
        assert g.n_vertices > 50_000
    m = Motion(poses=still(3), trans=np.zeros((3, 3), np.float32), fps=30)
    m.poses[1:, 16, 2] = -1.0
    out = LBSDeformer(LBSOptions(smooth_iterations=2)).deform(g, body, m)
    assert out.shape == (3, g.n_vertices, 3)
    assert_finite_and_bounded(out, body, m, stride=1)


def test_float32_and_float64_lbs_agree(body):
    import torch

    from core.body import lbs

    rng = np.random.default_rng(1)
    pose = torch.from_numpy(rng.normal(size=(3, 24, 3)) * 0.5)
    betas = torch.from_numpy(rng.normal(size=(3, 10)))
    v64, _ = lbs(betas, pose, *body.torch(torch.float64))
    v32, _ = lbs(betas.float(), pose.float(), *body.torch(torch.float32))
    assert (v64 - v32.double()).abs().max().item() < 1e-5  # metres: under 10 micrometres


def test_single_frame_motion(body, garment, deformer):
    m = Motion(poses=still(1), trans=np.zeros((1, 3), np.float32), fps=30)
    assert resample(m, 60.0).n_frames == 1
    s = settle(m, 5)
    out = deform_checked(deformer, garment, body, s, stride=1)
    assert out is not None and out.shape[0] == 6


def test_non_finite_motion_stops_with_a_clear_error():
    from core.motion import validate_motion_values

    poses = still(3)
    poses[2, 5, 1] = np.inf
    with pytest.raises(InputError, match="frame 2"):
        validate_motion_values(Motion(poses=poses, trans=np.zeros((3, 3), np.float32), fps=30), "inf.npz")
