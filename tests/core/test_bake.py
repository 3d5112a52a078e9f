"""`core.bake.penetration_stats`: the bake's share of garment vertices inside the body, on a sample of frames."""

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
