"""Tests of core/motion.py: resampling, joint layouts, frame selection, settle blends."""

import logging
from dataclasses import replace

import numpy as np
import pytest

from core.errors import InputError
from core.motion import (Motion, parse_frame_range, poses_for_body, resample, select_frames, sequence_motion, settle,
                         validate_motion_values)
from core.rotations import axis_angle_to_matrix, axis_angle_to_quat, quat_to_axis_angle

AXIS = np.array([0.48, 0.6, 0.64])  # unit axis
OMEGA = 2.5  # rad/s


def _spinning_motion(fps, n_frames, n_joints=24):
    """Joint 1 spins at OMEGA rad/s about AXIS (beyond pi over the clip); trans moves linearly."""
    t = np.arange(n_frames) / fps
    poses = np.zeros((n_frames, n_joints, 3), dtype=np.float32)
    poses[:, 1] = (OMEGA * t)[:, None] * AXIS
    poses[:, 0] = [np.pi / 2, 0, 0]
    trans = np.stack([0.5 + 1.2 * t, -0.3 * t, 0.9 + 0.0 * t], axis=1).astype(np.float32)
    return Motion(poses=poses, trans=trans, fps=fps, name="spin")


def _random_motion(n_frames, n_joints, seed=0):
    rng = np.random.default_rng(seed)
    poses = rng.normal(scale=0.4, size=(n_frames, n_joints, 3)).astype(np.float32)
    trans = rng.normal(size=(n_frames, 3)).astype(np.float32)
    return Motion(poses=poses, trans=trans, fps=30.0, name="random")


@pytest.mark.parametrize("src_fps, dst_fps", [(120, 30), (100, 30), (59.94, 30), (30, 60), (24, 30)])
def test_resample_counts_times_and_exact_curves(src_fps, dst_fps):
    n = int(round(2.0 * src_fps)) + 1  # a little over 2 s
    m = _spinning_motion(float(src_fps), n)
    out = resample(m, float(dst_fps))
    duration = (n - 1) / src_fps
    expected_n = int(np.floor(duration * dst_fps + 1e-6)) + 1
    assert out.n_frames == expected_n
    assert out.fps == dst_fps
    assert out.duration_s <= duration + 1e-9
    assert duration - out.duration_s < 1.0 / dst_fps
    t = np.arange(expected_n) / dst_fps
    # Constant angular velocity about one axis is reproduced exactly by slerp.
    np.testing.assert_allclose(axis_angle_to_matrix(out.poses[:, 1]),
                               axis_angle_to_matrix((OMEGA * t)[:, None] * AXIS), atol=2e-6)
    np.testing.assert_allclose(out.poses[:, 0], np.broadcast_to([np.pi / 2, 0, 0], (expected_n, 3)), atol=1e-6)
    np.testing.assert_allclose(out.poses[:, 2:], 0.0, atol=1e-7)
    # Linear translation is interpolated exactly.
    np.testing.assert_allclose(out.trans, np.stack([0.5 + 1.2 * t, -0.3 * t, 0.9 + 0.0 * t], 1), atol=2e-6)
    assert out.poses.dtype == np.float32 and out.trans.dtype == np.float32


def test_resample_59_94_to_30_frame_count():
    out = resample(_spinning_motion(59.94, 600), 30.0)
    assert out.n_frames == 300  # 599 / 59.94 s = 9.993 s -> frames at 0 .. 299/30 s


def test_resample_same_fps_and_single_frame_are_unchanged():
    m = _random_motion(5, 24)
    same = resample(m, 30.0)
    np.testing.assert_array_equal(same.poses, m.poses)
    one = resample(_random_motion(1, 52), 120.0)
    assert one.n_frames == 1 and one.fps == 120.0


def test_resample_keeps_metadata_and_layout():
    m = _random_motion(31, 55)
    m = Motion(poses=m.poses, trans=m.trans, fps=30.0, betas=np.ones(10, np.float32), gender="female", name="x")
    out = resample(m, 60.0)
    assert out.poses.shape == (61, 55, 3)
    assert out.gender == "female" and out.name == "x"
    np.testing.assert_array_equal(out.betas, m.betas)
    # Source frames land on even output frames unchanged (as rotations).
    np.testing.assert_allclose(axis_angle_to_matrix(out.poses[::2]), axis_angle_to_matrix(m.poses), atol=1e-5)


@pytest.mark.parametrize("fps", [0.0, -30.0, float("nan"), float("inf")])
def test_resample_rejects_bad_fps(fps):
    with pytest.raises(InputError, match="--fps"):
        resample(_random_motion(3, 24), fps)


@pytest.mark.parametrize("src_joints, dst_joints", [(j, k) for j in (24, 52, 55) for k in (24, 52, 55)])
def test_poses_for_body(src_joints, dst_joints):
    m = _random_motion(4, src_joints, seed=src_joints)
    out = poses_for_body(m, dst_joints)
    assert out.shape == (4, dst_joints, 3) and out.dtype == np.float32
    np.testing.assert_array_equal(out[:, :22], m.poses[:, :22])
    if src_joints == dst_joints:
        np.testing.assert_array_equal(out, m.poses)
        return
    hand_start = {52: 22, 55: 25}
    if dst_joints == 24:
        np.testing.assert_array_equal(out[:, 22:], 0.0)  # SMPL hands zeroed
    elif src_joints == 24:
        np.testing.assert_array_equal(out[:, 22:], 0.0)  # nothing to map from SMPL's two hand joints
    else:
        s, t = hand_start[src_joints], hand_start[dst_joints]
        np.testing.assert_array_equal(out[:, t:t + 30], m.poses[:, s:s + 30])
        if dst_joints == 55:
            np.testing.assert_array_equal(out[:, 22:25], 0.0)  # jaw and eyes


def test_poses_for_body_returns_a_copy():
    m = _random_motion(2, 24)
    out = poses_for_body(m, 24)
    out[:] = 0
    assert np.any(m.poses != 0)


def test_poses_for_body_rejects_unknown_joint_count():
    with pytest.raises(InputError, match="30 joints"):
        poses_for_body(_random_motion(2, 24), 30)


@pytest.mark.parametrize("start, stop, expected", [(None, None, range(10)), (2, 5, range(2, 5)), (7, None, range(7, 10)),
                                                   (None, 3, range(3)), (-3, None, range(7, 10)), (5, 100, range(5, 10))])
def test_select_frames(start, stop, expected):
    m = _random_motion(10, 24)
    out = select_frames(m, start, stop)
    np.testing.assert_array_equal(out.poses, m.poses[list(expected)])
    np.testing.assert_array_equal(out.trans, m.trans[list(expected)])
    assert out.fps == m.fps


@pytest.mark.parametrize("start, stop", [(5, 5), (8, 2), (20, None), (None, -20)])
def test_select_frames_empty_selection_is_an_error(start, stop):
    with pytest.raises(InputError, match=r"--frames .*selects no frame.*10 frames"):
        select_frames(_random_motion(10, 24), start, stop)


@pytest.mark.parametrize("text, expected", [("0:120", (0, 120)), ("30:", (30, None)), (":50", (None, 50)),
                                            (":", (None, None)), (" 3 : 7 ", (3, 7)), ("-10:", (-10, None))])
def test_parse_frame_range(text, expected):
    assert parse_frame_range(text) == expected


@pytest.mark.parametrize("text", ["", "5", "1:2:3", "a:b", "1.5:3", "0:x"])
def test_parse_frame_range_errors(text):
    with pytest.raises(InputError, match="--frames") as info:
        parse_frame_range(text)
    assert "\n" not in str(info.value)


def _angle_between(aa0, aa1):
    """(..., ) rotation angle between axis-angle rotations."""
    q0, q1 = axis_angle_to_quat(aa0), axis_angle_to_quat(aa1)
    return 2 * np.arccos(np.clip(np.abs(np.sum(q0 * q1, -1)), 0, 1))


def test_settle_blends_from_rest_pose():
    m = _random_motion(6, 24, seed=3)
    K = 8
    out = settle(m, K)
    assert out.n_frames == m.n_frames + K and out.n_settle == K
    np.testing.assert_array_equal(out.poses[K:], m.poses)
    np.testing.assert_array_equal(out.trans[K:], m.trans)
    np.testing.assert_array_equal(out.trans[:K], np.repeat(m.trans[:1], K, 0))
    # First frame: rest pose except the root, which holds frame 0's orientation.
    np.testing.assert_allclose(out.poses[0, 1:], 0.0, atol=1e-7)
    np.testing.assert_allclose(_angle_between(out.poses[:K, 0], m.poses[0, 0]), 0.0, atol=1e-6)
    # The last blend frame is 1/K of the way short of frame 0, per joint.
    full = _angle_between(np.zeros(3), m.poses[0, 1:])
    np.testing.assert_allclose(_angle_between(out.poses[K - 1, 1:], m.poses[0, 1:]), full / K, atol=1e-5)
    # Each joint moves monotonically towards frame 0 in equal steps.
    d = _angle_between(out.poses[:K, 1:], m.poses[0, 1:][None])
    np.testing.assert_allclose(d, full[None] * (1 - np.arange(K)[:, None] / K), atol=1e-5)


def test_settle_zero_and_accumulation_and_errors():
    m = _random_motion(3, 52)
    assert settle(m, 0) is m
    twice = settle(settle(m, 2), 3)
    assert twice.n_settle == 5 and twice.n_frames == 8
    with pytest.raises(InputError, match="--settle"):
        settle(m, -1)


def test_motion_rejects_bad_shapes():
    with pytest.raises(InputError, match="24\\|52\\|55"):
        Motion(poses=np.zeros((3, 23, 3), np.float32), trans=np.zeros((3, 3), np.float32), fps=30.0)
    with pytest.raises(InputError, match="trans"):
        Motion(poses=np.zeros((3, 24, 3), np.float32), trans=np.zeros((2, 3), np.float32), fps=30.0)
    with pytest.raises(InputError, match="positive frame rate"):
        Motion(poses=np.zeros((3, 24, 3), np.float32), trans=np.zeros((3, 3), np.float32), fps=0.0)
    m = _random_motion(31, 24)
    assert m.layout == "smpl" and m.n_frames == 31 and m.duration_s == pytest.approx(1.0)


@pytest.mark.parametrize("key", ["poses", "trans"])
def test_validate_motion_values_names_first_bad_frame(key):
    m = _random_motion(6, 24)
    getattr(m, key)[4].flat[0] = np.nan
    getattr(m, key)[5].flat[0] = np.inf
    with pytest.raises(InputError, match=f"motion 'walk.npz': {key} contains NaN or Inf \\(first at frame 4\\)"):
        validate_motion_values(m, "walk.npz")
    validate_motion_values(_random_motion(6, 24), "ok.npz")


def test_resample_output_is_canonical_axis_angle():
    out = resample(_spinning_motion(120.0, 241), 30.0)
    assert np.all(np.linalg.norm(out.poses, axis=-1) <= np.pi + 1e-5)
    np.testing.assert_allclose(quat_to_axis_angle(axis_angle_to_quat(out.poses)), out.poses, atol=1e-5)


def test_settle_frames_survive_selection_and_resampling():
    from core.motion import Motion, resample, select_frames, settle

    m = Motion(poses=np.zeros((40, 24, 3), np.float32), trans=np.zeros((40, 3), np.float32), fps=120.0)
    s = settle(m, 10)
    assert s.n_settle == 10
    assert select_frames(s, 4, None).n_settle == 6
    assert select_frames(s, 12, None).n_settle == 0
    assert resample(s, 30.0).n_settle == 3


def test_sequence_motion_round_trips_a_stored_sequence_with_and_without_its_settle_frames(tmp_path):
    from formats.dataset import Sequence, read_sequence, write_sequence

    rng = np.random.default_rng(3)
    T, n_settle = 7, 3
    stored = Sequence(positions=rng.normal(size=(T, 5, 3)), poses=rng.normal(size=(T, 24, 3)),
                      trans=rng.normal(size=(T, 3)), betas=rng.normal(size=10), fps=30.0, n_settle=n_settle,
                      garment="skirt", garment_sha256="0" * 64, body="default")
    write_sequence(tmp_path / "s.npz", stored)
    seq = read_sequence(tmp_path / "s.npz")
    whole = sequence_motion(seq, "item")
    assert (whole.name, whole.n_frames, whole.n_settle, whole.fps) == ("item", T, n_settle, 30.0)
    np.testing.assert_allclose(whole.poses, stored.poses, atol=1e-6)
    np.testing.assert_allclose(whole.betas, stored.betas, atol=1e-6)
    given = sequence_motion(seq, drop_settle=True)
    assert (given.n_frames, given.n_settle) == (T - n_settle, 0)
    np.testing.assert_allclose(given.poses, stored.poses[n_settle:], atol=1e-6)
    np.testing.assert_allclose(given.trans, stored.trans[n_settle:], atol=1e-6)


@pytest.mark.parametrize("src_fps, dst_fps, start, lead", [(60.0, 30.0, 31, 31), (60.0, 30.0, 40, 10),
                                                          (120.0, 24.0, 100, 47), (30.0, 60.0, 20, 7),
                                                          (59.94, 30.0, 50, 13), (30.0, 30.0, 12, 5)])
def test_preroll_leads_into_the_frames_asked_for_on_their_own_time_grid(src_fps, dst_fps, start, lead):
    """The frames written after a pre-roll are those a bake of --frames START:STOP alone writes (same times, same
    poses), whatever the frame rates; the pre-roll is the output frames before them."""
    from core.motion import preroll

    m = _spinning_motion(src_fps, int(round(3 * src_fps)))
    stop = start + int(round(src_fps))  # one second
    plain = resample(select_frames(m, start, stop), dst_fps)
    led = resample(preroll(m, start, stop, lead), dst_fps)
    n = led.n_lead
    assert n == int(np.floor(lead / src_fps * dst_fps + 1e-6)) and n >= 1
    assert led.n_frames - n == plain.n_frames
    np.testing.assert_allclose(axis_angle_to_matrix(led.poses[n:, 1]), axis_angle_to_matrix(plain.poses[:, 1]),
                               atol=2e-6)
    np.testing.assert_allclose(led.trans[n:], plain.trans, atol=2e-6)
    np.testing.assert_allclose(led.trans[n - 1], plain.trans[0] - np.array([1.2, -0.3, 0.0]) / dst_fps, atol=2e-6)


@pytest.mark.parametrize("src_fps, dst_fps, start, stop, context", [(60.0, 30.0, 31, 91, 4), (30.0, 60.0, 20, 50, 2),
                                                                    (59.94, 30.0, 50, 110, 2), (30.0, 30.0, 12, 40, 2),
                                                                    (120.0, 24.0, 100, 220, 5)])
def test_context_frames_either_side_leave_the_written_frames_those_of_the_range(src_fps, dst_fps, start, stop,
                                                                                 context):
    """A method's context (psd's rates) deforms source frames before and after --frames START:STOP, not written:
    after --fps the written frames are those of the range alone (same times, same poses), the lead and tail the
    output frames before and after them (`written` drops both); none before a motion's first frame or after its
    last, and no word said of them."""
    from core.motion import preroll, written

    m = _spinning_motion(src_fps, int(round(4 * src_fps)))
    plain = resample(select_frames(m, start, stop), dst_fps)
    ctx = resample(preroll(m, start, stop, 0, context=(context, context)), dst_fps)
    assert ctx.n_lead == int(np.floor(context / src_fps * dst_fps + 1e-6)) and ctx.n_tail >= 1
    assert ctx.n_written == plain.n_frames == ctx.n_frames - ctx.n_lead - ctx.n_tail
    shown = written(ctx)
    assert (shown.n_lead, shown.n_tail, shown.n_frames) == (0, 0, plain.n_frames)
    np.testing.assert_allclose(shown.trans, plain.trans, atol=2e-6)
    np.testing.assert_allclose(axis_angle_to_matrix(shown.poses[:, 1]), axis_angle_to_matrix(plain.poses[:, 1]),
                               atol=2e-6)
    at_ends = preroll(m, 0, None, 0, context=(context, context))
    assert (at_ends.n_lead, at_ends.n_tail, at_ends.n_frames) == (0, 0, m.n_frames)
    assert preroll(m, 3, 20, 4, context=(2, 2)).n_lead == 3  # the --preroll asked for, if longer (and clipped)
    assert preroll(m, 1, -1, 0, context=(2, 2)).n_tail == 1  # clipped at the last frame


def test_preroll_is_clipped_at_the_motion_start_and_excludes_settle():
    from core.motion import preroll

    m = _random_motion(30, 24)
    p = preroll(m, 10, 20, 4)
    assert (p.n_frames, p.n_lead) == (14, 4)
    np.testing.assert_array_equal(p.poses[4:], m.poses[10:20])
    np.testing.assert_array_equal(p.poses[:4], m.poses[6:10])
    assert preroll(m, 3, 20, 10).n_lead == 3  # only 3 frames before START
    assert preroll(m, 0, 20, 10).n_lead == 0 and preroll(m, 10, 20, 0).n_lead == 0
    assert preroll(m, -5, None, 2).n_lead == 2  # counted from the end, as --frames does
    assert select_frames(p, 2, None).n_lead == 2
    with pytest.raises(InputError, match="--settle and --preroll exclude each other"):
        settle(p, 3)
    with pytest.raises(InputError, match="selects no frame"):
        preroll(m, 40, 50, 5)


def test_frames_and_preroll_beyond_the_motion_are_said(caplog):
    """Python's slice clamps a STOP beyond the motion, a START before it and a pre-roll longer than the frames
    before START: each is said, naming the motion; a range within it and a pre-roll that fits say nothing."""
    from core.motion import preroll

    m = replace(_random_motion(30, 24), name="walk")
    with caplog.at_level(logging.WARNING, logger="core.motion"):
        assert preroll(m, 10, 20, 4).n_frames == 14 and preroll(m, -5, None, 2).n_lead == 2
        assert not caplog.records
        assert preroll(m, 5, 100, 0).n_frames == 25
        assert preroll(m, -40, 3, 0).n_frames == 3
        assert preroll(m, 3, 20, 10).n_lead == 3
        assert preroll(m, 0, 20, 10).n_lead == 0
    said = [r.getMessage() for r in caplog.records]
    assert len(said) == 4
    assert "--frames 5:100: STOP 100 lies beyond the 30 frames of motion 'walk'" in said[0]
    assert "--frames -40:3: START -40 lies before the first of the 30 frames of motion 'walk'" in said[1]
    assert "--preroll 10: motion 'walk' has only 3 frames before --frames START (frame 3): deformed 3" in said[2]
    assert "--preroll 10: motion 'walk' has no frame before --frames START (frame 0): the cloth starts at rest" in said[3]


@pytest.mark.parametrize("src_fps, dst_fps, lead", [(120.0, 30.0, 0), (59.94, 30.0, 0), (30.0, 60.0, 0),
                                                   (24.0, 30.0, 0), (60.0, 30.0, 7), (30.0, 30.0, 0), (60.0, 1e5, 3)])
def test_resampled_frame_count_is_the_frame_count_of_resample(src_fps, dst_fps, lead):
    """The count a caller checks against the memory free before resampling is the one resample makes; for --fps 1e9
    it is known without allocating anything."""
    from core.motion import preroll, resampled_frame_count

    m = _spinning_motion(src_fps, 40)
    m = preroll(m, lead, None, lead) if lead else m
    assert resampled_frame_count(m, dst_fps) == resample(m, dst_fps).n_frames
    assert resampled_frame_count(m, 1e9) >= int(m.duration_s * 1e9) - m.n_lead * 1e9 / src_fps  # nothing allocated
    assert resampled_frame_count(select_frames(m, 0, 1), 1e9) == 1  # one frame stays one


def test_resample_out_of_memory_is_one_line_naming_fps(monkeypatch):
    """Where the resampled arrays cannot be allocated, resample says so in one line naming --fps (no numpy
    _ArrayMemoryError traceback)."""
    import core.motion

    def no_memory(*args):
        raise MemoryError("Unable to allocate 1.2 TiB")

    monkeypatch.setattr(core.motion, "quat_slerp", no_memory)
    with pytest.raises(InputError) as info:
        resample(_spinning_motion(60.0, 12), 1e9)
    msg = str(info.value)
    assert "\n" not in msg and msg.startswith("--fps 1e+09") and "spin" in msg and "more memory than is free" in msg


def test_validate_motion_values_refuses_trans_beyond_10_km_naming_the_first_frame():
    """A glitch frame (1e30) is refused naming its frame; 10 m teleports and 9 km pass."""
    m = _random_motion(8, 24)
    trans = m.trans.copy()
    trans[3] = [1e30, 0.0, 0.0]
    trans[6] = [0.0, 2e4, 0.0]
    with pytest.raises(InputError) as info:
        validate_motion_values(Motion(poses=m.poses, trans=trans, fps=30.0), "spike.npz")
    msg = str(info.value)
    assert "\n" not in msg and "'spike.npz'" in msg and "at frame 3 (2 of 8 frames" in msg and "10 km" in msg
    trans = m.trans.copy()
    trans[::2] += [10.0, -10.0, 0.0]
    trans[5] = [9e3, 0.0, 0.0]
    validate_motion_values(Motion(poses=m.poses, trans=trans, fps=30.0), "teleport.npz")


@pytest.mark.parametrize("up", ["y", "-y"])
def test_y_up_to_z_up_turns_the_posed_body_exactly(up):
    """A motion of a Y-up world (or of camera coordinates, -Y up), turned: every posed vertex of the body (a shape
    away from the mean, the pelvis off the origin) lands where the +90-degree (-90) turn about X puts the Y-up
    pose's; the other joints are kept."""
    from core.motion import UP_TURNS, y_up_to_z_up
    from tests.meshes import tiny_body

    from dataclasses import replace

    body = tiny_body()
    body = replace(body, v_template=body.v_template + np.float32([0.01, -0.22, 0.03]))  # SMPL's pelvis offset
    rng = np.random.default_rng(3)
    betas = rng.normal(size=body.n_betas).astype(np.float32)
    poses = rng.normal(scale=0.4, size=(5, 24, 3)).astype(np.float32)
    trans = rng.normal(size=(5, 3)).astype(np.float32)
    y_up = Motion(poses=poses, trans=trans, fps=30.0, betas=betas)
    pelvis = body.shaped(betas)[1][0]
    assert np.linalg.norm(pelvis) > 0.01
    z_up = y_up_to_z_up(y_up, pelvis, up)
    before, _ = body.pose(y_up.poses, y_up.trans, betas)
    after, _ = body.pose(z_up.poses, z_up.trans, betas)
    turn = UP_TURNS[up]
    assert turn @ np.array([0.0, 1.0 if up == "y" else -1.0, 0.0]) == pytest.approx([0.0, 0.0, 1.0])
    np.testing.assert_allclose(after, before.astype(np.float64) @ turn.T, atol=2e-5)
    np.testing.assert_array_equal(z_up.poses[:, 1:], poses[:, 1:])


def test_fill_untracked_slerps_each_missing_frame_as_scipy_does_and_keeps_the_tracked_ones():
    """A track seen in video frames 5, 6, 9, 10, 14: frames 7-8 and 11-13 are filled in, each joint's rotation
    slerped (scipy's Slerp between the two tracked frames around it, a naive loop) and the translation linear."""
    from scipy.spatial.transform import Rotation, Slerp

    from core.motion import fill_untracked

    ids = np.array([5, 6, 9, 10, 14])
    m = _random_motion(len(ids), 24, seed=3)
    poses, trans = fill_untracked(m.poses, m.trans, ids)
    assert poses.shape == (10, 24, 3) and trans.shape == (10, 3) and poses.dtype == np.float32
    for k, frame in enumerate(range(5, 15)):
        i1 = int(np.searchsorted(ids, frame))
        if ids[i1] == frame:  # tracked: as read
            np.testing.assert_array_equal(poses[k], m.poses[i1])
            np.testing.assert_array_equal(trans[k], m.trans[i1])
            continue
        i0, a = i1 - 1, (frame - ids[i1 - 1]) / (ids[i1] - ids[i1 - 1])
        for j in range(24):
            ends = Rotation.from_rotvec(np.stack([m.poses[i0, j], m.poses[i1, j]]).astype(np.float64))
            want = Slerp([0.0, 1.0], ends)([a])
            got = Rotation.from_rotvec(poses[k, j][None].astype(np.float64))
            assert (want.inv() * got).magnitude()[0] < 1e-5, (frame, j)
        np.testing.assert_allclose(trans[k], (1 - a) * m.trans[i0] + a * m.trans[i1], atol=1e-6)
