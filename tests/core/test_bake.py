"""`core.bake.penetration_stats`: the bake's share of garment vertices inside the body, on a sample of frames."""

from pathlib import Path

import numpy as np

import core.bake as B
from tests.meshes import icosphere


def _scene(T: int, V: int, inside_every: int):
    """A unit sphere as the body in every frame; V garment points at radius 1.1, every `inside_every`-th of frame t
    moved to radius 0.5 when t is odd."""
    verts, faces = icosphere(2)
    rng = np.random.default_rng(0)
    d = rng.normal(size=(V, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    points = np.repeat((1.1 * d)[None], T, axis=0)
    points[1::2, ::inside_every] = 0.5 * d[::inside_every]
    return points, np.repeat(verts[None], T, axis=0), faces


def test_penetration_stats_counts_the_vertices_inside_on_evenly_spaced_frames():
    points, body, faces = _scene(T=9, V=100, inside_every=4)
    s = B.penetration_stats(points, body, faces, max_frames=5)
    assert s["frames_checked"] == [0, 2, 4, 6, 8]  # even frames: nothing inside
    assert s["max_percent"] == 0.0
    s = B.penetration_stats(points, body, faces)
    assert s["frames_checked"] == list(range(9))
    assert s["percent_per_checked_frame"] == [0.0, 25.0] * 4 + [0.0]
    assert s["worst_frame"] == 1 and s["max_percent"] == 25.0 and abs(s["mean_percent"] - 100 / 9) < 1e-9


def test_a_large_garment_is_checked_on_fewer_frames(monkeypatch):
    """Frames x vertices stay within MAX_CHECKED_VERTEX_FRAMES (60 frames of a 53k-vertex garment cost 23 s of a
    bake whose LBS took 0.4 s), never under MIN_CHECKED_FRAMES frames."""
    monkeypatch.setattr(B, "MAX_CHECKED_VERTEX_FRAMES", 1000)
    points, body, faces = _scene(T=61, V=100, inside_every=2)
    assert len(B.penetration_stats(points, body, faces)["frames_checked"]) == 10
    points, body, faces = _scene(T=61, V=500, inside_every=2)
    assert B.penetration_stats(points, body, faces)["frames_checked"] == [0, 20, 40, 60]
    monkeypatch.setattr(B, "MAX_CHECKED_VERTEX_FRAMES", 10_000)
    assert len(B.penetration_stats(points, body, faces)["frames_checked"]) == 20


def test_the_body_at_the_checked_frames_alone_gives_the_same_statistics():
    """A bake that writes no body poses it at the checked frames only (a 50,000-frame --no-body bake held the body
    of every frame): the statistics are those of the whole posed body."""
    points, body, faces = _scene(T=121, V=100, inside_every=3)
    body = body * np.linspace(1.0, 1.2, 121)[:, None, None]  # a body of its own each frame
    whole = B.penetration_stats(points, body, faces)
    frames = B.checked_frames(121, 100)
    assert whole["frames_checked"] == frames.tolist() and len(frames) == B.MAX_CHECKED_FRAMES
    assert B.penetration_stats(points, body[frames], faces) == whole


def test_bake_item_without_the_body_measures_what_it_measures_with_it():
    from core.body import default_body
    from core.deform import LBSDeformer
    from core.motion import Motion
    from formats.obj import read_obj

    body = default_body()
    rng = np.random.default_rng(1)
    poses = rng.normal(scale=0.15, size=(70, body.n_joints, 3)).astype(np.float32)
    motion = Motion(poses=poses, trans=np.zeros((70, 3), np.float32), fps=30.0)
    garment = read_obj(Path(__file__).resolve().parents[2] / "examples" / "tshirt.obj")
    with_body = B.bake_item(garment, body, motion, LBSDeformer())
    without = B.bake_item(garment, body, motion, LBSDeformer(), with_body=False)
    assert without.body_points is None and with_body.body_points.shape[0] == 70
    assert without.summary["penetration"]["frames_checked"] == with_body.summary["penetration"]["frames_checked"]
    np.testing.assert_allclose(without.summary["penetration"]["percent_per_checked_frame"],
                               with_body.summary["penetration"]["percent_per_checked_frame"], atol=0.05)
