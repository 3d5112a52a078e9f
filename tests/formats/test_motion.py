"""Tests of formats/motion.py: AMASS-style .npz reading, writing and validation."""

import io
import logging
import zipfile

import numpy as np
import pytest

from core.errors import InputError
from core.motion import Motion
from formats.motion import load_motion, save_motion


def _poses(T, n_values, seed=0):
    return np.random.default_rng(seed).normal(scale=0.3, size=(T, n_values)).astype(np.float32)


def _trans(T):
    return np.stack([np.linspace(0, 1, T), np.zeros(T), np.full(T, 0.9)], 1).astype(np.float32)


def _write(tmp_path, name="m.npz", **arrays):
    path = tmp_path / name
    np.savez(path, **arrays)
    return path


@pytest.mark.parametrize("n_values, n_joints", [(72, 24), (156, 52), (165, 55)])
def test_load_layouts(tmp_path, n_values, n_joints):
    poses = _poses(5, n_values)
    path = _write(tmp_path, poses=poses, trans=_trans(5), betas=np.arange(16, dtype=np.float64),
                  mocap_framerate=np.array(120.0), gender=np.array("female"))
    m = load_motion(path)
    assert m.poses.shape == (5, n_joints, 3) and m.poses.dtype == np.float32
    np.testing.assert_array_equal(m.poses.reshape(5, -1), poses)
    np.testing.assert_array_equal(m.trans, _trans(5))
    np.testing.assert_array_equal(m.betas, np.arange(16))
    assert m.fps == 120.0 and m.gender == "female" and m.name == "m"
    assert m.layout == {24: "smpl", 52: "smplh", 55: "smplx"}[n_joints]


def test_load_tjx3_poses(tmp_path):
    poses = _poses(4, 156).reshape(4, 52, 3)
    m = load_motion(_write(tmp_path, poses=poses, trans=_trans(4), mocap_framerate=30))
    np.testing.assert_array_equal(m.poses, poses)


@pytest.mark.parametrize("key", ["mocap_framerate", "mocap_frame_rate", "mocap_fps", "fps", "framerate", "frame_rate"])
def test_every_framerate_spelling(tmp_path, key):
    m = load_motion(_write(tmp_path, poses=_poses(3, 72), trans=_trans(3), **{key: np.array(59.94)}))
    assert m.fps == pytest.approx(59.94)


def test_fps_override_and_missing_framerate(tmp_path):
    path = _write(tmp_path, poses=_poses(3, 72), trans=_trans(3))
    with pytest.raises(InputError) as info:
        load_motion(path)
    msg = str(info.value)
    assert "mocap_framerate" in msg and "mocap_frame_rate" in msg and str(path) in msg and "\n" not in msg
    assert "--source-fps" in msg
    assert load_motion(path, fps=50.0).fps == 50.0
    path2 = _write(tmp_path, "n.npz", poses=_poses(3, 72), trans=_trans(3), mocap_framerate=120.0)
    assert load_motion(path2, fps=25).fps == 25.0


def test_smplx_split_keys(tmp_path):
    T = 6
    rng = np.random.default_rng(1)
    parts = {"root_orient": rng.normal(size=(T, 3)), "pose_body": rng.normal(size=(T, 63)),
             "pose_jaw": rng.normal(size=(T, 3)), "pose_eye": rng.normal(size=(T, 6)),
             "pose_hand": rng.normal(size=(T, 90))}
    m = load_motion(_write(tmp_path, trans=_trans(T), mocap_frame_rate=60.0, **parts))
    expected = np.concatenate([parts[k] for k in ("root_orient", "pose_body", "pose_jaw", "pose_eye", "pose_hand")], 1)
    assert m.poses.shape == (T, 55, 3)
    np.testing.assert_allclose(m.poses.reshape(T, -1), expected.astype(np.float32))


def test_smplx_split_keys_without_hands(tmp_path):
    T = 3
    m = load_motion(_write(tmp_path, root_orient=np.ones((T, 3)), pose_body=np.full((T, 63), 0.1),
                           trans=_trans(T), mocap_frame_rate=30))
    assert m.poses.shape == (T, 55, 3)
    np.testing.assert_allclose(m.poses[:, 0], 1.0)
    np.testing.assert_allclose(m.poses[:, 1:22], 0.1)
    np.testing.assert_array_equal(m.poses[:, 22:], 0.0)


@pytest.mark.parametrize("as_matrices", [False, True])
def test_smplx_forward_arguments_of_an_smpl_fit(tmp_path, as_matrices):
    """global_orient + body_pose of 23 joints + transl (+ per-frame betas), as pose estimators save the smplx
    library's arguments, as axis-angle or as rotation matrices (4D-Humans: (T, 1, 3, 3), (T, 23, 3, 3)): the SMPL
    layout, the same rotations."""
    from core.rotations import axis_angle_to_matrix

    T = 4
    poses = _poses(T, 72).reshape(T, 24, 3)
    glob, body = poses[:, :1], poses[:, 1:]
    if as_matrices:
        glob, body = axis_angle_to_matrix(glob), axis_angle_to_matrix(body)
    else:
        glob, body = glob.reshape(T, 3), body.reshape(T, 69)
    m = load_motion(_write(tmp_path, global_orient=glob, body_pose=body, transl=_trans(T),
                           betas=np.ones((T, 10)), mocap_fps=30))
    assert m.poses.shape == (T, 24, 3) and m.betas.shape == (10,)
    np.testing.assert_allclose(m.poses, poses, atol=1e-5)
    np.testing.assert_allclose(m.trans, _trans(T))


@pytest.mark.parametrize("layout", ["smplx", "smpl", "smpl matrices"])
def test_a_per_image_estimate_without_a_frame_axis_reads_as_one_frame(tmp_path, caplog, layout):
    """SMPLer-X writes one file per image: global_orient (1, 3), transl (1, 3) and betas (1, 10), but body_pose
    (21, 3), the hands (15, 3) and the eyes (1, 3) without a frame axis. Its body_pose was read as 21 frames of one
    joint and refused; it is one frame, the same as the file with every frame axis, the hands not taken for PCA
    coefficients. Likewise an SMPL fit's (23, 3) and rotation matrices (1, 3, 3) with (23, 3, 3)."""
    from core.rotations import axis_angle_to_matrix

    rng = np.random.default_rng(4)
    joints = {"smplx": {"global_orient": 1, "body_pose": 21, "jaw_pose": 1, "leye_pose": 1, "reye_pose": 1,
                        "left_hand_pose": 15, "right_hand_pose": 15},
              "smpl": {"global_orient": 1, "body_pose": 23}}[layout.split()[0]]
    parts = {k: rng.normal(scale=0.3, size=(n, 3)).astype(np.float32) for k, n in joints.items()}
    if layout.endswith("matrices"):
        parts = {k: axis_angle_to_matrix(a.astype(np.float64)) for k, a in parts.items()}
    extra = {"transl": np.float32([[0.1, 0.2, 0.3]]), "betas": np.ones((1, 10), np.float32), "fps": 30}
    with caplog.at_level(logging.WARNING):
        one = load_motion(_write(tmp_path, "image.npz", **parts, **extra))
    framed = load_motion(_write(tmp_path, "framed.npz", **{k: a[None] for k, a in parts.items()}, **extra))
    assert one.poses.shape == framed.poses.shape == (1, 55 if layout == "smplx" else 24, 3)
    np.testing.assert_array_equal(one.poses, framed.poses)
    assert "PCA" not in caplog.text
    if not layout.endswith("matrices"):
        np.testing.assert_allclose(one.poses[0, 1:1 + joints["body_pose"]], parts["body_pose"])


def test_aist_keys_read_as_poses_and_a_translation_in_metres(tmp_path):
    """AIST++'s motions (pickles of smpl_poses, smpl_trans, smpl_scaling, smpl_loss) saved as .npz: smpl_poses are
    the poses, smpl_trans / smpl_scaling the translation in metres (the file's own is in the units of a body
    scaled about 98 times); they were refused as having no 'poses'. A scaling that is no positive number is
    refused naming it."""
    T = 5
    poses, trans = _poses(T, 72), _trans(T)
    m = load_motion(_write(tmp_path, "aist.npz", smpl_poses=poses, smpl_trans=trans * 98.0,
                           smpl_scaling=np.float32([98.0]), smpl_loss=np.float64(1.8)), fps=60.0)
    np.testing.assert_array_equal(m.poses.reshape(T, 72), poses)
    np.testing.assert_allclose(m.trans, trans, rtol=1e-6)
    unscaled = load_motion(_write(tmp_path, "plain.npz", smpl_poses=poses, smpl_trans=trans), fps=60.0)
    np.testing.assert_allclose(unscaled.trans, trans)
    for bad in (np.float32([0.0]), np.float32([1.0, 2.0]), np.float32([np.nan])):
        with pytest.raises(InputError) as info:
            load_motion(_write(tmp_path, "bad.npz", smpl_poses=poses, smpl_trans=trans, smpl_scaling=bad), fps=60.0)
        _assert_one_line(info, "bad.npz", "smpl_scaling", "one finite number > 0")


def test_poses_as_rotation_matrices(tmp_path):
    from core.rotations import axis_angle_to_matrix

    poses = _poses(3, 66).reshape(3, 22, 3)
    m = load_motion(_write(tmp_path, poses=axis_angle_to_matrix(poses), trans=_trans(3), mocap_framerate=30))
    assert m.poses.shape == (3, 24, 3)  # the 22 body joints, the hands at rest
    np.testing.assert_allclose(m.poses[:, :22], poses, atol=1e-5)
    with pytest.raises(InputError) as info:
        load_motion(_write(tmp_path, "bad.npz", poses=np.ones((3, 24, 3, 3)), trans=_trans(3), mocap_framerate=30))
    _assert_one_line(info, "bad.npz", "poses", "rotation matrices (orthonormal")


def test_smplx_forward_arguments_of_an_smplx_fit(tmp_path, caplog):
    """body_pose of 21 joints: SMPL-X's layout, jaw, eyes and hands in its order; hands as PCA coefficients
    (6 per hand) are warned about and left at rest."""
    T = 3
    rng = np.random.default_rng(2)
    parts = {"global_orient": rng.normal(size=(T, 3)), "body_pose": rng.normal(size=(T, 63)),
             "jaw_pose": rng.normal(size=(T, 3)), "leye_pose": rng.normal(size=(T, 3)),
             "reye_pose": rng.normal(size=(T, 3)), "left_hand_pose": rng.normal(size=(T, 45)),
             "right_hand_pose": rng.normal(size=(T, 15, 3))}
    m = load_motion(_write(tmp_path, transl=_trans(T), fps=30, expression=np.zeros((T, 10)), **parts))
    assert m.poses.shape == (T, 55, 3)
    np.testing.assert_allclose(m.poses.reshape(T, -1), np.concatenate([a.reshape(T, -1) for a in parts.values()], 1),
                               rtol=1e-6)
    pca = {**parts, "left_hand_pose": np.zeros((T, 6)), "right_hand_pose": np.zeros((T, 6))}
    with caplog.at_level(logging.WARNING):
        m = load_motion(_write(tmp_path, "pca.npz", transl=_trans(T), fps=30, **pca))
    assert "left_hand_pose has 6 values per frame, not 45: PCA coefficients" in caplog.text
    np.testing.assert_array_equal(m.poses[:, 25:], 0.0)
    np.testing.assert_allclose(m.poses[:, 22], parts["jaw_pose"], rtol=1e-6)


@pytest.mark.parametrize("arrays, fragments", [
    ({"global_orient": np.zeros((3, 3)), "body_pose": np.zeros((3, 60))}, ("body_pose", "23 (SMPL) or 21", "got 20")),
    ({"global_orient": np.zeros((3, 6)), "body_pose": np.zeros((3, 69))}, ("global_orient", "one joint", "got 2")),
    ({"global_orient": np.zeros((2, 3)), "body_pose": np.zeros((3, 69))}, ("global_orient has 2 frames", "3")),
    ({"global_orient": np.zeros((3, 1, 3, 3)), "body_pose": np.zeros((3, 23, 3, 3))},
     ("global_orient", "rotation matrices (orthonormal, determinant +1)")),
    ({"global_orient": np.tile(np.diag([1.0, 1.0, -1.0]), (3, 1, 1)), "body_pose": np.zeros((3, 69))},
     ("global_orient", "mirroring")),
    ({"global_orient": np.zeros((3, 2, 2, 2)), "body_pose": np.zeros((3, 69))}, ("global_orient", "(3, 2, 2, 2)")),
    ({"global_orient": np.zeros((3, 3)), "body_pose": np.zeros((3, 63)), "jaw_pose": np.zeros((3, 6))},
     ("jaw_pose", "1 joint(s)", "got 2")),
    ({"global_orient": np.zeros((3, 3)), "body_pose": np.zeros((3, 69)), "transl": np.zeros((3, 2))},
     ("transl", "(3, 3)", "(3, 2)")),
    # empty arrays (a reshape inferring -1 from nothing raised ValueError: found by fuzzing 3,000 files)
    ({"global_orient": np.zeros((0, 3)), "body_pose": np.zeros((0, 23, 3, 3))}, ("at least 1 frame", "got 0")),
    ({"global_orient": np.zeros((0, 3, 3)), "body_pose": np.zeros((0, 69))}, ("at least 1 frame", "got 0")),
    ({"global_orient": np.zeros((3, 3)), "body_pose": np.zeros((3, 0))}, ("body_pose", "got 0 joints")),
])
def test_smplx_forward_arguments_malformed_are_one_line(tmp_path, arrays, fragments):
    with pytest.raises(InputError) as info:
        load_motion(_write(tmp_path, mocap_framerate=30, **arrays))
    _assert_one_line(info, "m.npz", *fragments)


def test_poses_preferred_over_split_keys(tmp_path):
    m = load_motion(_write(tmp_path, poses=_poses(2, 72), root_orient=np.ones((2, 3)), pose_body=np.ones((2, 63)),
                           trans=_trans(2), mocap_framerate=30))
    assert m.poses.shape == (2, 24, 3)


def test_single_frame(tmp_path):
    m = load_motion(_write(tmp_path, poses=_poses(1, 72)[0], trans=np.array([0, 0, 0.9]), mocap_framerate=30))
    assert m.n_frames == 1 and m.trans.shape == (1, 3)
    m2 = load_motion(_write(tmp_path, "b.npz", poses=_poses(1, 156), trans=_trans(1), mocap_framerate=30))
    assert m2.n_frames == 1


def test_missing_trans_warns_and_uses_zeros(tmp_path, caplog):
    with caplog.at_level(logging.WARNING, logger="formats.motion"):
        m = load_motion(_write(tmp_path, poses=_poses(4, 72), mocap_framerate=30))
    np.testing.assert_array_equal(m.trans, np.zeros((4, 3)))
    assert any("trans" in r.getMessage() for r in caplog.records)


@pytest.mark.parametrize("raw, expected", [(np.array("male"), "male"), (np.array(b"female"), "female"),
                                           (np.array(["neutral"]), "neutral"), ("male", "male")])
def test_gender_forms(tmp_path, raw, expected):
    m = load_motion(_write(tmp_path, poses=_poses(2, 72), trans=_trans(2), mocap_framerate=30, gender=raw))
    assert m.gender == expected


@pytest.mark.parametrize("shape", [(4, 66), (4, 22, 3)])
def test_the_22_body_joints_alone_read_with_the_hands_at_rest(tmp_path, shape):
    """root_orient + pose_body concatenated (66 values, or (T, 22, 3)): the SMPL layout, its two hand joints
    (22, 23) at rest."""
    poses = _poses(4, 66).reshape(shape)
    m = load_motion(_write(tmp_path, poses=poses, trans=_trans(4), mocap_framerate=30))
    assert m.poses.shape == (4, 24, 3) and m.layout == "smpl"
    np.testing.assert_array_equal(m.poses[:, :22], poses.reshape(4, 22, 3))
    assert not m.poses[:, 22:].any()


def test_per_frame_betas_are_held_at_their_mean(tmp_path, caplog):
    """Video-based fits write betas per frame (T, S): the body takes their mean (not the T x S values flattened,
    as before), and frames that disagree by more than 0.1 are warned about; (1, S) is one row; another 2-D
    shape is refused."""
    rng = np.random.default_rng(1)
    steady = np.ones((5, 10)) + rng.normal(scale=0.01, size=(5, 10))
    with caplog.at_level(logging.WARNING):
        m = load_motion(_write(tmp_path, poses=_poses(5, 72), trans=_trans(5), mocap_framerate=30, betas=steady))
    np.testing.assert_allclose(m.betas, steady.mean(axis=0), rtol=1e-6)
    assert "per frame" not in caplog.text
    drifting = steady.copy()
    drifting[4, 3] += 0.5
    with caplog.at_level(logging.WARNING):
        m = load_motion(_write(tmp_path, "d.npz", poses=_poses(5, 72), trans=_trans(5), mocap_framerate=30,
                               betas=drifting))
    spread = np.abs(drifting - drifting.mean(axis=0)).max()  # 0.4, give or take the noise
    assert m.betas.shape == (10,) and f"betas are given per frame and differ by up to {spread:.2f}" in caplog.text
    m = load_motion(_write(tmp_path, "o.npz", poses=_poses(5, 72), trans=_trans(5), mocap_framerate=30,
                           betas=np.ones((1, 10))))
    assert m.betas.shape == (10,)
    with pytest.raises(InputError) as info:
        load_motion(_write(tmp_path, "w.npz", poses=_poses(5, 72), trans=_trans(5), mocap_framerate=30,
                           betas=np.ones((3, 10))))
    _assert_one_line(info, "w.npz", "one row per frame (5, S)", "got (3, 10)")


def test_poses_in_degrees_are_refused(tmp_path):
    """The example walk with its rotations in degrees: refused in one line; in radians it reads, and so does a
    motion whose root alone turns past 2 pi (an unnormalised axis-angle)."""
    from pathlib import Path

    walk = dict(np.load(Path(__file__).resolve().parents[2] / "examples" / "walk.npz"))
    degrees = dict(walk, poses=walk["poses"] * 180 / np.pi)
    with pytest.raises(InputError) as info:
        load_motion(_write(tmp_path, "deg.npz", **degrees))
    _assert_one_line(info, "deg.npz", "axis-angle radians", "in degrees? multiply poses by pi / 180")
    load_motion(_write(tmp_path, "rad.npz", **walk))
    turned = dict(walk, poses=walk["poses"].copy())
    root = turned["poses"][:, :3]  # the root's rotation vector one full turn longer: the same rotation
    root += 2 * np.pi * root / np.linalg.norm(root, axis=1, keepdims=True)
    assert np.linalg.norm(root, axis=1).min() > 2 * np.pi
    load_motion(_write(tmp_path, "turned.npz", **turned))


def test_betas_any_length_and_optional(tmp_path):
    m = load_motion(_write(tmp_path, poses=_poses(2, 72), trans=_trans(2), mocap_framerate=30, betas=np.ones(300)))
    assert m.betas.shape == (300,)
    m = load_motion(_write(tmp_path, "b.npz", poses=_poses(2, 72), trans=_trans(2), mocap_framerate=30))
    assert m.betas is None and m.gender is None


@pytest.mark.parametrize("n_joints", [24, 52, 55])
def test_round_trip(tmp_path, n_joints):
    rng = np.random.default_rng(n_joints)
    m = Motion(poses=rng.normal(size=(7, n_joints, 3)).astype(np.float32), trans=_trans(7), fps=59.94,
               betas=rng.normal(size=10).astype(np.float32), gender="male", name="x")
    path = tmp_path / "sub" / "out.npz"
    save_motion(path, m)
    back = load_motion(path)
    np.testing.assert_array_equal(back.poses, m.poses)
    np.testing.assert_array_equal(back.trans, m.trans)
    np.testing.assert_array_equal(back.betas, m.betas)
    assert back.fps == m.fps and back.gender == "male"
    # The file follows the AMASS convention.
    with np.load(path) as data:
        assert data["poses"].shape == (7, n_joints * 3) and data["poses"].dtype == np.float32
        assert float(data["mocap_framerate"]) == pytest.approx(59.94)
    save_motion(path, back)  # load -> save -> load again
    again = load_motion(path)
    np.testing.assert_array_equal(again.poses, m.poses)
    assert [p.name for p in path.parent.iterdir()] == ["out.npz"]  # no temp files left


def test_save_without_betas_or_gender(tmp_path):
    m = Motion(poses=np.zeros((2, 24, 3), np.float32), trans=np.zeros((2, 3), np.float32), fps=30.0)
    save_motion(tmp_path / "a.npz", m)
    back = load_motion(tmp_path / "a.npz")
    np.testing.assert_array_equal(back.betas, np.zeros(16))
    assert back.gender == "neutral"


def _assert_one_line(info, *fragments):
    msg = str(info.value)
    assert "\n" not in msg
    for f in fragments:
        assert f in msg, (f, msg)


def assert_each_refused(path, cases):
    """Each (content: bytes or text, expected fragment) of `cases` written to `path` and read as a motion: one
    line naming the file and saying the fragment."""
    for content, expected in cases:
        if isinstance(content, bytes):
            path.write_bytes(content)
        else:
            path.write_text(content)
        with pytest.raises(InputError) as info:
            load_motion(path)
        _assert_one_line(info, path.name, expected)


def test_missing_file(tmp_path):
    with pytest.raises(InputError) as info:
        load_motion(tmp_path / "nope.npz")
    _assert_one_line(info, "nope.npz", "not found")


def test_not_an_npz(tmp_path):
    path = tmp_path / "text.npz"
    path.write_text("hello, this is not an archive\n")
    with pytest.raises(InputError) as info:
        load_motion(path)
    _assert_one_line(info, "text.npz", "npz", "not one")
    # an FBX cut after its magic is a damaged FBX; markers are named for what they are, with what to do (pickles:
    # test_motion_pickles.py; BVH: test_bvh.py; FBX: test_fbx.py)
    (tmp_path / "walk.fbx").write_text("Kaydara FBX Binary  \x00")
    with pytest.raises(InputError) as info:
        load_motion(tmp_path / "walk.fbx")
    _assert_one_line(info, "walk.fbx", "its FBX records are damaged or cut short")
    (tmp_path / "walk.c3d").write_bytes(b"\x02\x50" + bytes(510))
    with pytest.raises(InputError) as info:
        load_motion(tmp_path / "walk.c3d")
    _assert_one_line(info, "walk.c3d", "motion capture markers (C3D/TRC), not a skeleton: fit SMPL to them first")


def test_npy_instead_of_npz(tmp_path):
    path = tmp_path / "poses.npy"
    np.save(path, _poses(3, 72))
    with pytest.raises(InputError) as info:
        load_motion(path)
    _assert_one_line(info, "poses.npy", ".npz")


def test_corrupt_npz(tmp_path):
    good = _write(tmp_path, poses=_poses(50, 156), trans=_trans(50), mocap_framerate=30)
    bad = tmp_path / "bad.npz"
    bad.write_bytes(good.read_bytes()[: good.stat().st_size // 2])
    with pytest.raises(InputError) as info:
        load_motion(bad)
    _assert_one_line(info, "bad.npz")


def test_corrupt_member(tmp_path):
    path = tmp_path / "member.npz"
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("poses.npy", b"garbage that is not an npy header")
    with pytest.raises(InputError) as info:
        load_motion(path)
    _assert_one_line(info, "member.npz")


def test_missing_poses_keys(tmp_path):
    with pytest.raises(InputError) as info:
        load_motion(_write(tmp_path, trans=_trans(3), mocap_framerate=30))
    _assert_one_line(info, "m.npz", "poses", "root_orient", "global_orient")


@pytest.mark.parametrize("n_values", [69, 63, 168, 3, 64])
def test_wrong_values_per_frame(tmp_path, n_values):
    with pytest.raises(InputError) as info:
        load_motion(_write(tmp_path, poses=_poses(3, n_values), trans=_trans(3), mocap_framerate=30))
    _assert_one_line(info, "m.npz", "72", "156", "165", f"got {n_values}")


def test_wrong_joint_count_tjx3(tmp_path):
    with pytest.raises(InputError) as info:
        load_motion(_write(tmp_path, poses=np.zeros((3, 23, 3)), trans=_trans(3), mocap_framerate=30))
    _assert_one_line(info, "m.npz", "(3, 23, 3)")


def test_split_key_wrong_width(tmp_path):
    with pytest.raises(InputError) as info:
        load_motion(_write(tmp_path, root_orient=np.zeros((3, 3)), pose_body=np.zeros((3, 60)), mocap_framerate=30))
    _assert_one_line(info, "pose_body", "63", "60")


def test_trans_frame_count_mismatch(tmp_path):
    with pytest.raises(InputError) as info:
        load_motion(_write(tmp_path, poses=_poses(5, 72), trans=_trans(4), mocap_framerate=30))
    _assert_one_line(info, "m.npz", "trans", "4", "5")


def test_trans_wrong_width(tmp_path):
    with pytest.raises(InputError) as info:
        load_motion(_write(tmp_path, poses=_poses(5, 72), trans=np.zeros((5, 2)), mocap_framerate=30))
    _assert_one_line(info, "m.npz", "trans", "(5, 2)")


@pytest.mark.parametrize("key, value", [("poses", np.nan), ("poses", np.inf), ("trans", -np.inf)])
def test_nan_inf(tmp_path, key, value):
    arrays = {"poses": _poses(5, 72), "trans": _trans(5), "mocap_framerate": 30}
    arrays[key][3, 1] = value
    with pytest.raises(InputError) as info:
        load_motion(_write(tmp_path, **arrays))
    _assert_one_line(info, "m.npz", key, "NaN or Inf", "frame 3")


@pytest.mark.parametrize("key", ["poses", "trans", "betas"])
def test_values_beyond_float32_are_named_as_such(tmp_path, key):
    """A float64 value of 1e300 was called "NaN or Inf" (what it became in float32), which the file does not hold:
    it is named, with where it is."""
    arrays = {"poses": _poses(5, 72).astype(np.float64), "trans": _trans(5).astype(np.float64),
              "betas": np.zeros(10), "mocap_framerate": 30}
    arrays[key].reshape(arrays[key].shape[0], -1)[-1, -1] = -1e300
    with pytest.raises(InputError) as info:
        load_motion(_write(tmp_path, **arrays))
    _assert_one_line(info, "m.npz", f"expected '{key}' within float32's range (3.4e+38), got -1e+300 at index (")
    assert "NaN" not in str(info.value)


@pytest.mark.parametrize("fps", [0.0, -30.0, np.nan])
def test_non_positive_frame_rate(tmp_path, fps):
    with pytest.raises(InputError) as info:
        load_motion(_write(tmp_path, poses=_poses(2, 72), trans=_trans(2), mocap_framerate=fps))
    _assert_one_line(info, "m.npz", "positive frame rate", "mocap_framerate")
    with pytest.raises(InputError, match="positive frame rate"):
        load_motion(_write(tmp_path, "ok.npz", poses=_poses(2, 72), trans=_trans(2), mocap_framerate=30), fps=fps)


def test_a_frame_rate_beyond_any_capture_is_refused(tmp_path):
    """1e300 Hz was read as given: the whole motion within one output frame, its speed printed in 300 digits."""
    with pytest.raises(InputError) as info:
        load_motion(_write(tmp_path, poses=_poses(2, 72), trans=_trans(2), mocap_framerate=1e300))
    _assert_one_line(info, "m.npz", "mocap_framerate", "expected a frame rate of at most 10,000 Hz, got 1e+300")
    assert load_motion(_write(tmp_path, "fast.npz", poses=_poses(2, 72), trans=_trans(2), mocap_framerate=2000)).fps \
        == 2000


def test_integer_poses_are_read_with_a_warning(tmp_path, caplog):
    """Poses stored as int8 (whole radians: a writer truncated them) baked without a word; zeros stored as integers
    (a rest pose) are no cause for one."""
    import logging

    poses = (_poses(3, 72) * 3).astype(np.int8)
    assert poses.any()
    with caplog.at_level(logging.WARNING, logger="formats.motion"):
        m = load_motion(_write(tmp_path, poses=poses, trans=np.zeros((3, 3), np.int64), mocap_framerate=30))
    assert m.poses.dtype == np.float32
    assert "'poses' holds integers (dtype int8), not floating-point values" in caplog.text
    assert "'trans'" not in caplog.text


def test_zero_frames(tmp_path):
    with pytest.raises(InputError) as info:
        load_motion(_write(tmp_path, poses=np.zeros((0, 72)), trans=np.zeros((0, 3)), mocap_framerate=30))
    _assert_one_line(info, "m.npz", "at least 1 frame")


def test_non_numeric_poses(tmp_path):
    with pytest.raises(InputError) as info:
        load_motion(_write(tmp_path, poses=np.array([["a"] * 72]), trans=_trans(1), mocap_framerate=30))
    _assert_one_line(info, "m.npz", "poses")


def test_object_array_gender_is_skipped_but_object_poses_are_an_error(tmp_path, caplog):
    path = _write(tmp_path, poses=_poses(2, 72), trans=_trans(2), mocap_framerate=30,
                  gender=np.array(["male"], dtype=object))
    with caplog.at_level(logging.WARNING, logger="formats.motion"):
        assert load_motion(path).gender is None
    assert any("gender" in r.getMessage() for r in caplog.records)
    path = _write(tmp_path, "o.npz", poses=np.empty((2, 72), dtype=object), trans=_trans(2), mocap_framerate=30)
    with pytest.raises(InputError) as info:
        load_motion(path)
    _assert_one_line(info, "o.npz", "'poses'")


def test_a_y_up_motion_warns_and_a_z_up_one_or_one_lying_down_does_not(tmp_path, caplog):
    """A library walk (Z-up) with its root turned -90 degrees about X (what a Y-up exporter writes) warns,
    naming the file; the walk itself and a Z-up body lying on its back for most of a clip do not."""
    from dataclasses import replace

    from core.motiongen import MOTION_LIBRARY
    from core.rotations import axis_angle_to_matrix, matrix_to_axis_angle

    walk = MOTION_LIBRARY["walk_brisk"](fps=30.0)
    to_y_up = axis_angle_to_matrix(np.array([-np.pi / 2, 0.0, 0.0]))
    roots = axis_angle_to_matrix(walk.poses[:, 0].astype(np.float64))
    poses = walk.poses.copy()
    poses[:, 0] = matrix_to_axis_angle(to_y_up @ roots)
    lying = walk.poses.copy()
    lying[: int(0.8 * len(lying)), 0] = 0.0  # rest frame unturned: on its back in the Z-up world, head along +Y
    for name, motion in (("walk", walk), ("yup", replace(walk, poses=poses, trans=walk.trans @ to_y_up.T)),
                         ("lying", replace(walk, poses=lying))):
        save_motion(tmp_path / f"{name}.npz", motion)
        caplog.clear()
        with caplog.at_level(logging.WARNING):
            load_motion(tmp_path / f"{name}.npz")
        assert ("looks Y-up" in caplog.text) == (name == "yup"), (name, caplog.text)
        if name == "yup":
            assert "yup.npz" in caplog.text and "+90 degrees about X" in caplog.text


def test_camera_coordinates_and_a_bending_motion_are_told_by_the_axis_most_frames_stand_along(tmp_path, caplog):
    """A walk turned into camera coordinates (head along -Y, as per-image estimators write the body) was read
    without a word, standing on its head: it warns, naming --motion-up -y. A Z-up walk bending 45 degrees over in
    40 % of its frames (below the 90 % of frames the check used to need, as a real AMASS clip bending over) given
    as Y-up, and a Y-up walk given as camera coordinates, are warned about, naming the axis they stand along."""
    from dataclasses import replace

    from core.motion import UP_TURNS, warn_if_other_up
    from core.motiongen import MOTION_LIBRARY
    from core.rotations import axis_angle_to_matrix, matrix_to_axis_angle

    walk = MOTION_LIBRARY["walk_brisk"](fps=30.0)
    roots = axis_angle_to_matrix(walk.poses[:, 0].astype(np.float64))

    def turned(q, motion=walk):
        poses = motion.poses.copy()
        poses[:, 0] = matrix_to_axis_angle(q @ axis_angle_to_matrix(motion.poses[:, 0].astype(np.float64)))
        return replace(motion, poses=poses, trans=(motion.trans @ q.T).astype(np.float32))

    camera = turned(UP_TURNS["-y"].T)
    save_motion(tmp_path / "camera.npz", camera)
    with caplog.at_level(logging.WARNING):
        load_motion(tmp_path / "camera.npz")
    assert "camera.npz" in caplog.text and "stands along world -Y in 100 %" in caplog.text
    assert "camera coordinates" in caplog.text and "pass --motion-up -y" in caplog.text
    assert "looks Y-up" not in caplog.text
    bent = walk.poses.copy()
    n = int(0.4 * len(bent))
    bend = axis_angle_to_matrix(np.array([np.radians(45.0), 0.0, 0.0]))
    bent[:n, 0] = matrix_to_axis_angle(roots[:n] @ bend)  # leaning over, about the body's own X
    for name, motion, up, told in (("bent", replace(walk, poses=bent), "y", "leave out --motion-up y"),
                                   ("yup", turned(UP_TURNS["y"].T), "-y", "pass --motion-up y"),
                                   ("camera", camera, "y", "pass --motion-up -y")):
        caplog.clear()
        with caplog.at_level(logging.WARNING):
            assert warn_if_other_up(motion, name, up)
        assert told in caplog.text and f"'{name}'" in caplog.text, caplog.text
        assert not warn_if_other_up(turned(UP_TURNS[up].T), name, up)  # truly along `up`: no word


def test_trans_in_centimetres_warns_and_metres_or_a_teleport_do_not(tmp_path, caplog):
    """A walk's trans in centimetres (fast and far) or a standing motion's (far) warns; the walk in metres,
    and one 10 m root teleport in it, do not."""
    from dataclasses import replace

    from core.motiongen import MOTION_LIBRARY

    walk = MOTION_LIBRARY["walk_brisk"](fps=30.0)
    teleport = walk.trans.copy()
    teleport[len(teleport) // 2:, 0] += 10.0
    standing = np.repeat(walk.trans[:1], len(walk.trans), axis=0)
    cases = {"metres": walk.trans, "teleport": teleport, "cm": walk.trans * 100, "standing_cm": standing * 100}
    for name, trans in cases.items():
        save_motion(tmp_path / f"{name}.npz", replace(walk, trans=trans))
        caplog.clear()
        with caplog.at_level(logging.WARNING):
            load_motion(tmp_path / f"{name}.npz")
        assert ("centimetres" in caplog.text) == name.endswith("cm"), (name, caplog.text)
        if name == "cm":
            assert "cm.npz" in caplog.text and "scale it by 0.01" in caplog.text


def test_amass_smplx_stageii_file_with_a_pickled_marker_dict(tmp_path):
    """AMASS's SMPL-X (stage II) archives hold `markers_latent_vids`, a dict pickled into an object array that
    cannot be read without allow_pickle: the loader leaves it, and every other key it does not use, unread."""
    T = 4
    path = tmp_path / "A5_-_pick_up_box_stageii.npz"
    poses = np.zeros((T, 165), np.float32)
    poses[:, 0] = np.pi / 2
    np.savez(path, gender=np.array("female"), surface_model_type=np.array("smplx"),
             mocap_frame_rate=np.array(120.0), mocap_time_length=np.array(T / 120.0),
             markers_latent=np.zeros((53, 3)), latent_labels=np.array(["C7", "CLAV"] * 26 + ["LFHD"]),
             markers_latent_vids=np.array({"C7": 3832, "CLAV": 5533}, dtype=object),
             trans=np.zeros((T, 3)), poses=poses, betas=np.zeros(16), num_betas=np.array(16),
             root_orient=poses[:, :3], pose_body=poses[:, 3:66], pose_hand=poses[:, 75:], pose_jaw=poses[:, 66:69],
             pose_eye=poses[:, 69:75])
    m = load_motion(path)
    assert m.poses.shape == (T, 55, 3) and m.fps == 120.0 and m.gender == "female"


def test_a_frame_time_stored_as_the_frame_rate_is_refused(tmp_path):
    """A BVH-style Frame Time (seconds per frame) in mocap_framerate would turn 10 frames into 16,201: refused in
    one line naming the file, the value, the rate it stands for and --source-fps; so is such an override. 1 Hz
    (the slowest rate read) still reads."""
    path = _write(tmp_path, "frametime.npz", poses=_poses(10, 72), trans=_trans(10), mocap_framerate=1 / 60)
    with pytest.raises(InputError) as info:
        load_motion(path)
    _assert_one_line(info, "frametime.npz", "'mocap_framerate'", "0.01667", "seconds per frame", "60 fps",
                     "--source-fps")
    with pytest.raises(InputError, match="seconds per frame"):
        load_motion(_write(tmp_path, "ok.npz", poses=_poses(10, 72), trans=_trans(10), mocap_framerate=60.0), fps=0.5)
    assert load_motion(path, fps=60.0).fps == 60.0
    assert load_motion(_write(tmp_path, "slow.npz", poses=_poses(10, 72), trans=_trans(10), mocap_framerate=1.0)).fps == 1.0


def test_degrees_with_small_bends_are_refused_by_their_longest_rotation(tmp_path):
    """A motion in degrees whose joints bend 1-10 degrees and whose root turns 90 has under 20 % of its rotated
    joints past 2 pi, but a rotation of 90 (radians?): refused as degrees. The example motions and the built-in
    library, and a root one full turn longer (3 pi at most), read."""
    from pathlib import Path

    from core.motiongen import MOTION_LIBRARY
    from formats.motion import DEGREES_MAX_NORM, DEGREES_SHARE

    rng = np.random.default_rng(0)
    poses = np.zeros((60, 24, 3))
    poses[:, 0] = [90.0, 0.0, 0.0]
    axes = rng.normal(size=(60, 23, 3))
    poses[:, 1:] = axes / np.linalg.norm(axes, axis=-1, keepdims=True) * np.linspace(1.0, 7.0, 23)[:, None]
    norms = np.linalg.norm(poses, axis=-1)
    assert np.mean(norms[norms > 1e-6] > 2 * np.pi) < DEGREES_SHARE  # the share alone lets it pass
    with pytest.raises(InputError) as info:
        load_motion(_write(tmp_path, "idle_degrees.npz", poses=poses.reshape(60, 72), trans=_trans(60),
                           mocap_framerate=60.0))
    _assert_one_line(info, "idle_degrees.npz", "axis-angle radians", "the largest 90.0", "in degrees?")
    for path in sorted((Path(__file__).resolve().parents[2] / "examples").glob("*.npz")):
        if "poses" in np.load(path).files:
            load_motion(path)
    for name, make in MOTION_LIBRARY.items():
        assert np.linalg.norm(make(fps=30.0).poses, axis=-1).max() < DEGREES_MAX_NORM / 2, name


def test_a_glitch_frame_in_trans_far_from_the_origin_is_refused(tmp_path):
    """One frame of trans at 1e30 (the unit checks use medians, which it leaves alone) is refused naming the file
    and the frame; float64 past float32's range is refused without numpy's overflow warning; a root 9 km out
    reads."""
    import warnings

    trans = _trans(40).astype(np.float64)
    trans[5] = 1e30
    with pytest.raises(InputError) as info:
        load_motion(_write(tmp_path, "spike.npz", poses=_poses(40, 72), trans=trans, mocap_framerate=60.0))
    _assert_one_line(info, "spike.npz", "trans", "10 km", "frame 5")
    trans[5] = 1e40
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(InputError, match=r"within float32's range \(3.4e\+38\), got 1e\+40 at index \(5, 0\)"):
            load_motion(_write(tmp_path, "huge.npz", poses=_poses(40, 72), trans=trans, mocap_framerate=60.0))
    trans[5] = [9e3, 0.0, 0.0]
    load_motion(_write(tmp_path, "far.npz", poses=_poses(40, 72), trans=trans, mocap_framerate=60.0))


def _motion_arrays(T=4):
    return {"poses": _poses(T, 72), "trans": _trans(T), "mocap_framerate": np.array(60.0)}


def _zip_flags(raw: bytes, flag: int | None = None, method: int | None = None) -> bytes:
    """`raw` (a zip) with every member's general-purpose flag and/or compression method rewritten."""
    b = bytearray(raw)
    for signature, at in ((b"PK\x03\x04", 6), (b"PK\x01\x02", 8)):
        i = b.find(signature)
        while i >= 0:
            if flag is not None:
                b[i + at:i + at + 2] = flag.to_bytes(2, "little")
            if method is not None:
                b[i + at + 2:i + at + 4] = method.to_bytes(2, "little")
            i = b.find(signature, i + 4)
    return bytes(b)


def _stored(tmp_path) -> bytes:
    np.savez(tmp_path / "s.npz", **_motion_arrays())
    return (tmp_path / "s.npz").read_bytes()


def _damaged_deflate(tmp_path) -> bytes:
    np.savez_compressed(tmp_path / "c.npz", **_motion_arrays())
    b = bytearray((tmp_path / "c.npz").read_bytes())
    start = 30 + int.from_bytes(b[26:28], "little") + int.from_bytes(b[28:30], "little")  # poses' deflate stream
    for i in range(start + 5, start + 40):
        b[i] ^= 0x5A
    return bytes(b)


def _huge_header() -> bytes:
    header = b"{'descr': '<f4', 'fortran_order': False, 'shape': (100000000000, 72), }"
    header += b" " * (118 - len(header)) + b"\n"
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w") as z:
        z.writestr("poses.npy", b"\x93NUMPY\x01\x00" + len(header).to_bytes(2, "little") + header + bytes(64))
        z.writestr("mocap_framerate.npy", b"")
    return out.getvalue()


@pytest.mark.parametrize("make, message", [
    # each raised past the reader (zlib.error, RuntimeError, NotImplementedError, MemoryError): a traceback
    (_damaged_deflate, "could not read array 'poses' (Error -3 while decompressing data"),
    (lambda tmp_path: _zip_flags(_stored(tmp_path), flag=1), "could not read array 'poses' (File 'poses.npy' is "
     "encrypted"),
    (lambda tmp_path: _zip_flags(_stored(tmp_path), method=9), "could not read array 'poses' (That compression "
     "method is not supported)"),
    (lambda tmp_path: _huge_header(), "could not read array 'poses' (Unable to allocate"),
    # "PK" and then no zip: numpy tried to unpickle it, and the message spoke of pickles and allow_pickle
    (lambda tmp_path: b"PK\x07\x08" + bytes(40), "got a damaged or incomplete zip archive"),
])
def test_a_damaged_or_unusual_archive_is_one_line(tmp_path, make, message):
    path = tmp_path / "m.npz"
    path.write_bytes(make(tmp_path))
    with pytest.raises(InputError) as info:
        load_motion(path)
    assert str(info.value).startswith(f"motion '{path}': ") and message in str(info.value)
    assert "\n" not in str(info.value) and "pickle" not in str(info.value)


@pytest.mark.parametrize("key, value, message", [
    # complex values lost their imaginary part (a ComplexWarning on stderr), bool and dates read as 0/1 and seconds
    ("poses", _poses(4, 72).astype(np.complex64) + 1j, "expected numbers in 'poses', got dtype complex64"),
    ("poses", _poses(4, 72) > 0, "expected numbers in 'poses', got dtype bool"),
    ("poses", np.zeros((4, 72), "datetime64[s]"), "expected numbers in 'poses', got dtype datetime64[s]"),
    ("trans", _trans(4) + 0j, "expected numbers in 'trans', got dtype complex64"),
    ("betas", np.ones(10, bool), "expected numbers in 'betas', got dtype bool"),
    # a frame rate per take of a session: the first was taken, the others dropped
    ("mocap_framerate", np.array([60.0, 30.0, 120.0]), "expected one frame rate under 'mocap_framerate', got 3 "
     "different values (60.0, 30.0, 120.0)"),
    ("mocap_framerate", np.array(True), "expected a number under 'mocap_framerate', got True (dtype bool)"),
    ("mocap_framerate", np.array(60 + 1j), "expected a number under 'mocap_framerate'"),
])
def test_values_of_the_wrong_kind_are_refused_not_converted(tmp_path, key, value, message):
    path = _write(tmp_path, **{**_motion_arrays(), key: value})
    with pytest.raises(InputError) as info:
        load_motion(path)
    assert str(info.value).startswith(f"motion '{path}': {message}")


@pytest.mark.skipif(not __import__("os").path.exists("/proc/self/mem"), reason="Linux /proc")
def test_a_file_that_fails_to_read_is_one_line_naming_it():
    """/proc/self/mem is a file whose first read fails (EIO): an OSError without a file name, a traceback before."""
    with pytest.raises(InputError, match=r"motion '/proc/self/mem': cannot read it \(Input/output error\)"):
        load_motion("/proc/self/mem")
