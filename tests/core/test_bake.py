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


def _walk(fps: float = 30.0):
    from core.motiongen import MOTION_LIBRARY

    return MOTION_LIBRARY["walk"](fps=fps)


def test_a_jump_in_the_motion_is_found_where_it_is():
    """`motion_cuts`: a 10 m teleport of the root and a joint flipped 180 degrees between two frames, at the frame
    after the jump; a walk at 5, 30 or 240 fps has none, nor has a settle blend from the rest pose in one frame."""
    from dataclasses import replace

    from core.body import default_body
    from core.motion import CUT_SPEED_M_S, motion_cuts, settle

    body = default_body()
    for fps in (5.0, 30.0, 240.0):
        assert motion_cuts(_walk(fps), body) == []
    walk = _walk()
    assert motion_cuts(settle(walk, 1), body) == []
    trans = walk.trans.copy()
    trans[12:, 0] += 10.0
    assert motion_cuts(replace(walk, trans=trans), body) == [(12, "a joint moves 10.00 m in one frame (300 m/s)")]
    trans = walk.trans.copy()
    trans[12:, 0] += 0.9 * CUT_SPEED_M_S / 30.0  # fast, not impossible
    assert motion_cuts(replace(walk, trans=trans), body) == []
    poses = walk.poses.copy()
    poses[20:, 3] = [0.0, np.pi, 0.0]  # spine1 turned about its own axis, 180 degrees from frame 19 to 20
    poses[:20, 3] = 0.0
    assert motion_cuts(replace(walk, poses=poses), body) == [
        (20, f"the {body.joint_names[3]} turns 180 degrees in one frame (94 rad/s)")]
    assert [k for k, _ in motion_cuts(settle(replace(walk, poses=poses), 4), body)] == [24]


def test_a_bake_warns_of_a_jump_in_the_motion_and_of_a_strain_limit_it_could_not_keep(caplog):
    """A teleport is warned of once, naming the frame and the remedy (--frames); a strain limit that leaves
    an edge longer than it by more than STRAIN_LEFT_WARN_M is warned of with its counts, one within it not."""
    from dataclasses import replace

    from core.body import default_body
    from core.deform import LBSDeformer
    from formats.obj import read_obj

    body = default_body()
    walk = _walk()
    trans = walk.trans.copy()
    trans[12:, 0] += 10.0
    garment = read_obj(Path(__file__).resolve().parents[2] / "examples" / "skirt.obj")
    with caplog.at_level("WARNING", logger="core.bake"):
        B.bake_item(garment, body, replace(walk, trans=trans, name="glitch"), LBSDeformer(), check_penetration=False)
        B.bake_item(garment, body, walk, LBSDeformer(), check_penetration=False)
    assert [r.getMessage() for r in caplog.records] == [
        "motion 'glitch': the body jumps at written frame 12: a joint moves 10.00 m in one frame (300 m/s), a "
        "teleport or a cut or flip in the capture? The garment follows it in one frame; bake the parts apart with "
        "--frames (`garment info` names the jump's source frame)"]
    caplog.clear()
    report = {"strain_limit": {"limit": 1.5, "passes_max": 60, "frames_still_over": 38,
                               "edges_still_over_per_frame_max": 495, "excess_left_max_mm": 5.6}}
    with caplog.at_level("WARNING", logger="core.bake"):
        B._warn_strain_left(report, "model", 61)
        B._warn_strain_left({"strain_limit": {**report["strain_limit"], "excess_left_max_mm": 1.9}}, "model", 61)
        B._warn_strain_left({"strain_limit": {**report["strain_limit"], "frames_still_over": 0}}, "model", 61)
        B._warn_strain_left({}, "lbs", 61)
    assert [r.getMessage() for r in caplog.records] == [
        "method 'model': the strain limit (1.5x an edge's rest length) left edges longer than it in 38 of 61 frames "
        "deformed (up to 495 a frame, 5.6 mm beyond it) after its 60 passes: the pose stretches the cloth further "
        "than the limit undoes"]


def test_a_long_motion_is_searched_for_jumps_in_chunks_alike():
    """`motion_cuts` poses a long motion `chunk` frames at a time: a jump at a chunk's edge is found once."""
    from dataclasses import replace

    from core.body import default_body
    from core.motion import motion_cuts

    body = default_body()
    walk = _walk()
    trans = walk.trans.copy()
    trans[8:, 0] += 10.0
    trans[17:, 1] += 10.0
    glitch = replace(walk, trans=trans)
    whole = motion_cuts(glitch, body)
    assert [k for k, _ in whole] == [8, 17]
    for chunk in (1, 7, 8, 9, 16):
        assert motion_cuts(glitch, body, chunk=chunk) == whole
