"""`garment bake` with motions whose frame rate, translation or body shape is off, and --fps, --source-fps and
--betas values beyond reason: one line naming the file or option, nothing written; the betas warning once."""

import json
import logging
import warnings

import numpy as np

from tests.garmentcli.cli import invoke
from tests.garmentcli.conftest import write_motion


def assert_one_line_error(result, *needles):
    assert result.exit_code != 0, result.output
    assert result.exception is None or isinstance(result.exception, SystemExit), repr(result.exception)
    assert "Traceback" not in result.output
    line = result.output.strip().splitlines()[-1]
    for n in needles:
        assert n in line, (n, line)


def _bake(scene, motion, *options):
    return invoke(["bake", scene["garment"], motion, "--body", scene["body"], "--out", scene["out"], "--no-obj",
                   *options])


def test_a_frame_time_for_a_frame_rate_is_refused_and_1_hz_bakes(scene):
    """mocap_framerate = 1/60 (a BVH Frame Time) would make 10 frames 16,201: refused naming the file, the value
    and --source-fps; so is --source-fps 0.01667; --source-fps 60 bakes it, and a 1 Hz motion bakes."""
    from tests.garmentcli.conftest import write_motion

    d = scene["dir"]
    write_motion(d / "frametime.npz", n_frames=10, fps=1 / 60)
    r = _bake(scene, d / "frametime.npz")
    assert_one_line_error(r, "frametime.npz", "0.01667", "seconds per frame", "60 fps", "--source-fps")
    r = _bake(scene, d / "frametime.npz", "--source-fps", "0.01667")
    assert_one_line_error(r, "--source-fps", "0.01667", "seconds per frame", "59.99 fps")
    assert not scene["out"].exists()
    r = _bake(scene, d / "frametime.npz", "--source-fps", 60)
    assert r.exit_code == 0, r.output
    assert json.loads((scene["out"] / "shell_frametime" / "summary.json").read_text())["frames"] == 5
    write_motion(d / "slow.npz", n_frames=3, fps=1.0)
    r = _bake(scene, d / "slow.npz")
    assert r.exit_code == 0, r.output
    assert json.loads((scene["out"] / "shell_slow" / "summary.json").read_text())["frames"] == 61  # 2 s at 30 fps


def test_an_fps_that_makes_more_frames_than_fit_is_refused_before_resampling(scene, monkeypatch):
    """--fps 1000 on the 12-frame walk (60 fps) makes 184 frames, more than 1 MB free holds: refused naming --fps
    and the memory before anything is allocated (it was numpy's _ArrayMemoryError from resample); --fps beyond
    1000 (1e9 made 183,333,334 frames) is out of its range; --source-fps 1e-9 is refused as a frame time."""
    import psutil

    free = psutil.virtual_memory()._replace(available=1)
    with monkeypatch.context() as m:
        m.setattr(psutil, "virtual_memory", lambda: free)
        r = _bake(scene, scene["motion"], "--fps", "1000")
    assert_one_line_error(r, "walk.npz", "184 frames", "is free", "lower --fps 1000")
    assert_one_line_error(_bake(scene, scene["motion"], "--fps", "1e9"), "--fps", "1.0<=x<=1000.0")
    r = _bake(scene, scene["motion"], "--source-fps", "1e-9")
    assert_one_line_error(r, "--source-fps", "1e-09", "seconds per frame")
    assert not scene["out"].exists()


def test_motion_betas_the_body_lacks_are_warned_about_once_per_motion(scene, caplog):
    """16 betas on the 4-coefficient body: one warning per motion (it was one per posing of the body, 3-6 a bake),
    naming the motion and saying where its betas belong and how to leave them out; one copy in each summary."""
    from tests.garmentcli.conftest import write_motion

    d = scene["dir"]
    write_motion(d / "smplh.npz", n_values=156, betas=np.full(16, 0.5, np.float32))
    write_motion(d / "other.npz", betas=np.full(16, 0.5, np.float32))
    with caplog.at_level(logging.WARNING):
        r = _bake(scene, d / "smplh.npz", d / "other.npz")
    assert r.exit_code == 0, r.output
    said = [rec.getMessage() for rec in caplog.records if "betas given" in rec.getMessage()]
    assert len(said) == 2 and len({m for m in said}) == 2, said
    for name in ("smplh", "other"):
        summary = json.loads((scene["out"] / f"shell_{name}" / "summary.json").read_text())
        (warning,) = summary["warnings"]
        assert warning.startswith(f"motion '{d / name}.npz': 16 betas given, body 'tiny_body' has 4")
        assert "SMPL+H" in warning and "--betas mean ignores them" in warning and "\n" not in warning


def test_betas_beyond_float32_are_refused_without_numpy_warnings(scene):
    """--betas 1e40: the one error line, and no RuntimeWarning of numpy's overflowing cast before it."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        r = _bake(scene, scene["motion"], "--betas", "1e40")
    assert_one_line_error(r, "--betas", "expected finite numbers, got '1e40'")
    assert "RuntimeWarning" not in r.output


def test_betas_far_beyond_a_human_are_refused_and_extreme_ones_warned_about(scene, caplog):
    """Betas of 1e30 baked a garment 40 % inside the body without a word: beyond +-20 they are refused (another
    model's coefficients or a damaged file), beyond the +-5 the methods are tested at warned about; --betas too."""
    d = scene["dir"]
    base = ["--body", scene["body"], "--out", scene["out"]]
    huge = np.zeros(16, np.float32)
    huge[2] = 1e30
    write_motion(d / "huge.npz", betas=huge)
    assert_one_line_error(invoke(["bake", scene["garment"], d / "huge.npz", *base]), "huge.npz'",
                          "expected betas within +-20", "got 1e+30 at coefficient 2")
    assert_one_line_error(invoke(["bake", scene["garment"], scene["motion"], *base, "--betas", "0,-25"]),
                          "--betas", "got -25 at coefficient 1")
    assert not scene["out"].exists()
    extreme = np.zeros(16, np.float32)
    extreme[0] = 7.0
    write_motion(d / "extreme.npz", betas=extreme)
    with caplog.at_level("WARNING"):
        r = invoke(["bake", scene["garment"], d / "extreme.npz", *base])
    assert r.exit_code == 0, r.output
    assert any("beta 0 is 7, beyond the +-5 the methods are tested at" in m for m in caplog.messages)
    summary = json.loads((scene["out"] / "shell_extreme" / "summary.json").read_text())
    assert any("beta 0 is 7" in w for w in summary["warnings"])


def test_a_pose_estimators_smplx_arguments_bake_as_the_same_motion_in_amass_layout(scene):
    """The scene's walk saved as 4D-Humans saves an SMPL fit (global_orient (T, 1, 3, 3), body_pose
    (T, 23, 3, 3) rotation matrices, transl, per-frame betas, no frame rate: --source-fps) bakes the same garment
    as the AMASS file."""
    from core.rotations import axis_angle_to_matrix
    from formats.sequence import read_sequence

    d = scene["dir"]
    with np.load(scene["motion"]) as walk:
        poses, trans, betas = walk["poses"].reshape(-1, 24, 3), walk["trans"], walk["betas"]
        fps = float(walk["mocap_framerate"])
    T = len(poses)
    np.savez(d / "hmr.npz", global_orient=axis_angle_to_matrix(poses[:, :1]).astype(np.float32),
             body_pose=axis_angle_to_matrix(poses[:, 1:]).astype(np.float32), transl=trans,
             betas=np.tile(betas, (T, 1)))
    assert_one_line_error(_bake(scene, d / "hmr.npz"), "hmr.npz", "frame rate", "--source-fps")
    for motion, options in ((scene["motion"], ()), (d / "hmr.npz", ("--source-fps", fps))):
        r = invoke(["bake", scene["garment"], motion, "--body", scene["body"], "--out", scene["out"],
                    "--method", "lbs", *options])
        assert r.exit_code == 0, r.output
    a = read_sequence(scene["out"] / "shell_walk" / "obj").points
    b = read_sequence(scene["out"] / "shell_hmr" / "obj").points
    assert a.shape == b.shape
    np.testing.assert_allclose(a, b, atol=1e-5)


def test_a_y_up_motion_bakes_with_motion_up_y_as_its_z_up_original(scene, caplog):
    """The scene's Z-up walk turned into a Y-up world (as GVHMR or WHAM write): baked as it is it is warned about,
    naming --motion-up y; with --motion-up y it bakes the original's garment (recorded in summary.json); the Z-up
    original given --motion-up y is warned about as Z-up already."""
    from core.geometry import Y_UP_TO_Z_UP_MATRIX
    from core.rotations import axis_angle_to_matrix, matrix_to_axis_angle
    from formats.sequence import read_sequence

    d = scene["dir"]
    with np.load(scene["motion"]) as walk:
        arrays = dict(walk)
    poses = arrays["poses"].reshape(len(arrays["poses"]), -1, 3).astype(np.float64)
    back = Y_UP_TO_Z_UP_MATRIX.T  # the tiny body's pelvis is at the origin: trans turns alone
    poses[:, 0] = matrix_to_axis_angle(back @ axis_angle_to_matrix(poses[:, 0]))
    arrays.update(poses=poses.reshape(len(poses), -1).astype(np.float32),
                  trans=((arrays["trans"] + [0.3, -0.2, 0.1]) @ back.T).astype(np.float32))
    np.savez(d / "yup.npz", **arrays)
    np.savez(d / "zup.npz", **{**dict(np.load(scene["motion"])), "trans": arrays["trans"] @ back})
    out = {}
    for motion, options in (("zup", ()), ("yup", ("--motion-up", "y")), ("yup", ())):
        caplog.clear()
        with caplog.at_level(logging.WARNING):
            r = invoke(["bake", scene["garment"], d / f"{motion}.npz", "--body", scene["body"], "--method", "lbs",
                        "--out", d / f"out_{motion}{len(options)}", *options])
        assert r.exit_code == 0, r.output
        out[motion, bool(options)] = read_sequence(d / f"out_{motion}{len(options)}" / f"shell_{motion}" / "obj").points
        looks_y_up = "it looks Y-up" in caplog.text and "pass --motion-up y" in caplog.text
        assert looks_y_up == (motion == "yup" and not options), caplog.text
    summary = json.loads((d / "out_yup2" / "shell_yup" / "summary.json").read_text())
    assert summary["options"]["motion_up"] == "y" and summary["options"]["motion_up_as_read"] == "y"
    np.testing.assert_allclose(out["yup", True], out["zup", False], atol=1e-5)
    # --motion-up auto: each motion of a folder as its body stands, without a word of warning
    (d / "both").mkdir()
    for name in ("yup", "zup"):
        (d / "both" / f"{name}.npz").write_bytes((d / f"{name}.npz").read_bytes())
    caplog.clear()
    with caplog.at_level(logging.WARNING):
        r = invoke(["bake", scene["garment"], d / "both", "--body", scene["body"], "--method", "lbs", "--out",
                    d / "out_auto", "--motion-up", "auto"])
    assert r.exit_code == 0 and "motion-up" not in caplog.text, (r.output, caplog.text)
    for name, up in (("yup", "y"), ("zup", "z")):
        np.testing.assert_allclose(read_sequence(d / "out_auto" / f"shell_{name}" / "obj").points, out["zup", False],
                                   atol=1e-5)
        options = json.loads((d / "out_auto" / f"shell_{name}" / "summary.json").read_text())["options"]
        assert options["motion_up"] == "auto" and options["motion_up_as_read"] == up
    assert np.abs(out["yup", False] - out["zup", False]).max() > 0.1  # lying on its back
    with caplog.at_level(logging.WARNING):
        r = invoke(["bake", scene["garment"], scene["motion"], "--body", scene["body"], "--method", "lbs",
                    "--out", d / "out_wrong", "--motion-up", "y"])
    assert r.exit_code == 0 and "it looks Z-up already" in caplog.text and "leave out --motion-up y" in caplog.text


def test_a_motion_in_camera_coordinates_bakes_with_motion_up_minus_y_as_its_z_up_original(scene, caplog):
    """The scene's walk written in camera coordinates (head along -Y, as per-image pose estimators write the body):
    baked as it is, it is warned about naming --motion-up -y (it was baked standing on its head without a word);
    with --motion-up -y it bakes the original's garment; given --motion-up y it is warned about."""
    from core.motion import UP_TURNS
    from core.rotations import axis_angle_to_matrix, matrix_to_axis_angle
    from formats.sequence import read_sequence

    d = scene["dir"]
    with np.load(scene["motion"]) as walk:
        arrays = dict(walk)
    poses = arrays["poses"].reshape(len(arrays["poses"]), -1, 3).astype(np.float64)
    back = UP_TURNS["-y"].T  # the tiny body's pelvis is at the origin: trans turns alone
    poses[:, 0] = matrix_to_axis_angle(back @ axis_angle_to_matrix(poses[:, 0]))
    np.savez(d / "cam.npz", **{**arrays, "poses": poses.reshape(len(poses), -1).astype(np.float32),
                               "trans": (arrays["trans"] @ back.T).astype(np.float32)})
    out = {}
    for name, motion, options in (("walk", scene["motion"], ()), ("cam", d / "cam.npz", ("--motion-up", "-y")),
                                  ("cam", d / "cam.npz", ()), ("cam", d / "cam.npz", ("--motion-up", "y"))):
        caplog.clear()
        with caplog.at_level(logging.WARNING):
            r = invoke(["bake", scene["garment"], motion, "--body", scene["body"], "--method", "lbs",
                        "--out", d / f"o_{name}{options}", *options])
        assert r.exit_code == 0, r.output
        out[name, options] = read_sequence(next((d / f"o_{name}{options}").iterdir()) / "obj").points
        assert ("pass --motion-up -y" in caplog.text) == (name == "cam" and options != ("--motion-up", "-y"))
    np.testing.assert_allclose(out["cam", ("--motion-up", "-y")], out["walk", ()], atol=1e-5)
    assert np.abs(out["cam", ()] - out["walk", ()]).max() > 0.1  # on its head


def test_a_fitted_motions_betas_on_the_embedded_body_give_way_to_its_mean_shape(scene, caplog):
    """An SMPL fit's 10 betas (a pose estimator's) on the embedded body, whose 10 coefficients are anny's own
    basis: the count matches, so they shaped another person without a word. By default (--betas auto) the mean
    shape is baked, with one warning naming the motion, --body and --betas motion; --betas motion applies them,
    with a warning naming --body. Zero betas, --betas mean and a body file of the motion's model are quiet, and
    that body takes the motion's betas by default."""
    from core.body import default_body
    from garmentcli.common import prepare_motion
    from tests.garmentcli.conftest import write_motion

    d = scene["dir"]
    fit = np.linspace(-1, 1, 10).astype(np.float32)
    write_motion(d / "fit.npz", betas=fit)
    body = default_body()
    for motion, betas, on, said_what, baked in (
            ("fit", None, body, "baked on its mean shape", None), ("fit", "auto", body, "baked on its mean shape", None),
            ("fit", "motion", body, "--betas motion shapes it otherwise", fit), ("fit", "mean", body, "", None),
            ("walk", "auto", body, "", None), ("fit", "auto", scene["tiny"], "", fit)):
        caplog.clear()
        with caplog.at_level(logging.WARNING):
            prepared, _ = prepare_motion(str(d / f"{motion}.npz"), 30.0, None, 0, betas, body=on)
        said = [r.getMessage() for r in caplog.records if "fitted to another body model" in r.getMessage()]
        assert len(said) == int(bool(said_what)), (motion, betas, caplog.text)
        if said_what:
            assert said[0].startswith(f"motion '{d / 'fit.npz'}': its betas") and "--body" in said[0] \
                and said_what in said[0] and "betas given" not in caplog.text
        if baked is None:
            assert prepared.betas is None or not np.any(prepared.betas), (motion, betas)
        else:
            np.testing.assert_allclose(prepared.betas, baked[:len(prepared.betas)], rtol=1e-6)


def test_a_directory_of_pickled_and_smplx_argument_motions_bakes_each_as_its_amass_original(scene):
    """A folder holding the scene's walk as WHAM pickles its results ({track: {'pose_world', 'trans_world', ...}}),
    as the smplx arguments a fitter saves (global_orient, body_pose: such files used to be left out of a folder,
    which was refused as holding no motion), as Motion-X's (T, 322) .npy, as TRAM's hps_track_0.npy beside its
    camera.npy (no motion: left out), and a body shape alone (AMASS's shape.npz: left out) bakes the four motions,
    each the garment of the AMASS file."""
    import pickle

    import torch

    from formats.sequence import read_sequence

    d = scene["dir"] / "estimates"
    d.mkdir()
    with np.load(scene["motion"]) as walk:
        poses, trans, betas = walk["poses"].copy(), walk["trans"], walk["betas"]
        fps = float(walk["mocap_framerate"])
    poses[:, 66:] = 0  # the SMPL hand joints at rest, as SMPL-X's layout (Motion-X's) leaves them
    (scene["dir"] / "amass").mkdir()
    np.savez(scene["dir"] / "amass" / "walk.npz", poses=poses, trans=trans, betas=betas, mocap_framerate=fps)
    with open(d / "wham_output.pkl", "wb") as fh:
        pickle.dump({0: {"pose": np.zeros_like(poses), "trans": trans + 5, "pose_world": poses, "trans_world": trans,
                         "betas": np.tile(betas, (len(poses), 1)), "frame_ids": np.arange(len(poses))}}, fh)
    np.savez(d / "fit.npz", global_orient=poses[:, :3], body_pose=poses[:, 3:72], transl=trans, betas=betas)
    motion_x = np.zeros((len(poses), 322), dtype=np.float32)  # Motion-X's rows: the 22 body joints, hands at rest
    motion_x[:, :66], motion_x[:, 309:312], motion_x[:, 312:] = poses[:, :66], trans, betas[:10]
    np.save(d / "motionx.npy", motion_x)
    from core.rotations import axis_angle_to_matrix  # TRAM's track and camera, np.save of dicts of tensors

    np.save(d / "hps_track_0.npy", {"pred_rotmat": torch.tensor(axis_angle_to_matrix(poses.reshape(-1, 24, 3))),
                                    "pred_trans": torch.tensor(trans[:, None]), "pred_shape": torch.zeros(1, 10)},
            allow_pickle=True)
    np.save(d / "camera.npy", {"pred_cam_R": torch.eye(3)[None], "img_focal": 600.0}, allow_pickle=True)
    np.savez(d / "shape.npz", betas=betas, gender="neutral")
    for motion, options in ((scene["dir"] / "amass" / "walk.npz", ()), (d, ("--source-fps", fps))):
        r = invoke(["bake", scene["garment"], motion, "--body", scene["body"], "--out", scene["out"],
                    "--method", "lbs", *options])
        assert r.exit_code == 0, r.output
    baked = sorted(p.name for p in scene["out"].iterdir())
    assert baked == ["shell_fit", "shell_hps_track_0", "shell_motionx", "shell_walk", "shell_wham_output"], baked
    a = read_sequence(scene["out"] / "shell_walk" / "obj").points
    for name in ("shell_fit", "shell_hps_track_0", "shell_motionx", "shell_wham_output"):
        np.testing.assert_allclose(read_sequence(scene["out"] / name / "obj").points, a, atol=1e-5)


def test_a_bvh_fbx_gltf_or_usd_of_the_smpl_skeleton_or_another_rig_bakes_as_its_npz_and_a_non_humanoid_is_refused(
        scene, caplog):
    """The scene's walk exported as a BVH of SMPL's skeleton (as smpl2bvh writes one: centimetres, ZYX Euler
    angles; the AMASS world kept: --motion-up z) bakes the garment of the AMASS file; so does the walk turned Y-up
    on a skeleton of Mixamo's names (retargeted; read in the world its rest stands in, +Y, with --motion-up left
    out), as a BVH, an FBX, a glTF and a USD (an A-pose rig, pre-rotated joints), named or in a folder (an FBX,
    glTF or USD of no skeleton there left out); a skeleton with no knees is one line, nothing written."""
    from core.motion import Y_UP_TO_Z_UP_MATRIX
    from core.rotations import axis_angle_to_matrix, matrix_to_axis_angle
    from formats.sequence import read_sequence
    from tests.formats.test_bvh import write_bvh
    from tests.formats.test_fbx import rig_fbx
    from tests.formats.test_gltf import rig_gltf
    from tests.formats.test_collada import rig_dae
    from tests.formats.test_usdskel import rig_usd, write_usd_mesh

    with np.load(scene["motion"]) as walk:
        arrays = dict(walk)
    poses, trans, fps = arrays["poses"].reshape(-1, 24, 3), arrays["trans"], float(arrays["mocap_framerate"])
    poses[:, 22:] = 0  # Mixamo's hand joint is SMPL's wrist: it has no knuckles
    np.savez(scene["dir"] / "walk.npz", **{**arrays, "poses": poses.reshape(len(poses), -1)})
    bvh = write_bvh(scene["dir"] / "walk_bvh.bvh", poses, trans, fps)
    back = Y_UP_TO_Z_UP_MATRIX.T  # the tiny body's pelvis is at the origin: trans turns alone
    y_up = poses.astype(np.float64)
    y_up[:, 0] = matrix_to_axis_angle(back @ axis_angle_to_matrix(y_up[:, 0]))
    mixamo = ("Hips", "LeftUpLeg", "RightUpLeg", "Spine", "LeftLeg", "RightLeg", "Spine1", "LeftFoot", "RightFoot",
              "Spine2", "LeftToeBase", "RightToeBase", "Neck", "LeftShoulder", "RightShoulder", "Head", "LeftArm",
              "RightArm", "LeftForeArm", "RightForeArm", "LeftHand", "RightHand", "LeftHandIndex1",
              "RightHandIndex1")
    rig = write_bvh(scene["dir"] / "walk_rig.bvh", y_up, trans @ back.T, fps, names=mixamo)
    fbx = rig_fbx(scene["dir"] / "walk_fbx.fbx", y_up.astype(np.float32), trans @ back.T, fps=int(round(fps)))
    gltf = rig_gltf(scene["dir"] / "walk_gltf.glb", {"walk": (y_up, trans @ back.T)}, fps=int(round(fps)))
    for motion, options in ((scene["dir"] / "walk.npz", ()), (bvh, ("--motion-up", "z")), (rig, ()), (fbx, ()),
                            (gltf, ())):
        r = invoke(["bake", scene["garment"], motion, "--body", scene["body"], "--out", scene["out"],
                    "--method", "lbs", *options])
        assert r.exit_code == 0, r.output
    # smpl2bvh's BVH without --motion-up: read in the world its rest stands in (+Y), the warning names the fix
    with caplog.at_level(logging.WARNING):
        r = invoke(["bake", scene["garment"], bvh, "--body", scene["body"], "--out", scene["dir"] / "out_bvh_y",
                    "--method", "lbs", "--frames", "0:2"])
    assert r.exit_code == 0 and "read as +Y up (its rest skeleton stands along world +Y)" in caplog.text, caplog.text
    assert "it looks Z-up already" in caplog.text and "pass --motion-up z" in caplog.text, caplog.text
    assert "leave out" not in caplog.text and "given as" not in caplog.text, caplog.text
    for name in ("walk_bvh", "walk_rig", "walk_fbx", "walk_gltf"):
        np.testing.assert_allclose(read_sequence(scene["out"] / f"shell_{name}" / "obj").points,
                                   read_sequence(scene["out"] / "shell_walk" / "obj").points, atol=1e-4)
    summary = json.loads((scene["out"] / "shell_walk_rig" / "summary.json").read_text())
    assert summary["options"]["motion_up"] is None and summary["options"]["motion_up_as_read"] == "y"
    # an FBX of two takes (the walk, the walk 1 m along x): --take all bakes each into its own output
    takes = rig_fbx(scene["dir"] / "moves.fbx", None, None, fps=int(round(fps)),
                    takes={"Walk": (y_up, trans @ back.T), "Walk moved": (y_up, (trans + [1.0, 0, 0]) @ back.T)})
    r = invoke(["bake", scene["garment"], takes, "--body", scene["body"], "--out", scene["dir"] / "out_takes",
                "--method", "lbs", "--take", "all"])
    assert r.exit_code == 0, r.output
    assert "moves.fbx': 2 animations, each read (Walk, Walk moved)" in r.output
    walked = read_sequence(scene["out"] / "shell_walk" / "obj").points
    for take, suffix, shift in (("Walk", "Walk", 0.0), ("Walk moved", "Walk_moved", 1.0)):
        baked = scene["dir"] / "out_takes" / f"shell_moves_{suffix}"
        np.testing.assert_allclose(read_sequence(baked / "obj").points, walked + [shift, 0, 0], atol=1e-4)
        options = json.loads((baked / "summary.json").read_text())["options"]
        assert options["take"] == "all" and options["take_read"] == take
    r = invoke(["tradeoff", scene["garment"], takes, "--take", "all", "--out", scene["dir"] / "refused"])
    assert_one_line_error(r, "--take", "all (one output per animation) applies to bake and dataset only")
    # a folder of captures: its BVH, FBX, glTF, VRM Animation, UsdSkel and COLLADA motions baked, an FBX, a glTF, a
    # USD and a COLLADA of no skeleton (props, a garment) left out
    (scene["dir"] / "captures").mkdir()
    rig_gltf(scene["dir"] / "captures" / "walk_gltf.glb", {"walk": (y_up, trans @ back.T)}, fps=int(round(fps)))
    prop = rig_gltf(scene["dir"] / "captures" / "prop.glb", {"walk": (y_up, trans @ back.T)}, skin=False)
    prop.write_bytes(prop.read_bytes().replace(b':Hips"', b':Base"'))  # no skin, no hips: a prop's nodes
    rig_gltf(scene["dir"] / "captures" / "dance.vrma", {"walk": (y_up, trans @ back.T)}, skin=False, vrm=True,
             fps=int(round(fps)))  # a VRM Animation: no skin, its humanoid map
    rig_usd(scene["dir"] / "captures" / "walk_usd.usda", {"walk": (y_up, trans @ back.T)}, armature=False,
            fps=int(round(fps)))  # a UsdSkel animation (a Y-up stage in centimetres)
    write_usd_mesh(scene["dir"] / "captures" / "cloth.usda")  # a USD of no skeleton (a garment): left out
    dae = rig_dae(scene["dir"] / "captures" / "walk_dae.dae", y_up, trans @ back.T, fps=int(round(fps)))
    (scene["dir"] / "captures" / "walk_nodes.dae").write_text(  # joints of type NODE, named by its skin
        dae.read_text().replace('type="JOINT"', 'type="NODE"'))
    prop = rig_dae(scene["dir"] / "prop.dae", y_up, trans @ back.T, skin=False)  # no joint, no skin naming any
    (scene["dir"] / "captures" / "prop.dae").write_text(prop.read_text().replace('type="JOINT"', 'type="NODE"'))
    for f in (rig, fbx):
        (scene["dir"] / "captures" / f.name).write_bytes(f.read_bytes())
    (scene["dir"] / "captures" / "prop.fbx").write_bytes(fbx.read_bytes().replace(b"LimbNode", b"MeshNode"))
    r = invoke(["bake", scene["garment"], scene["dir"] / "captures", "--body", scene["body"], "--out",
                scene["dir"] / "out_captures", "--method", "lbs"])
    assert r.exit_code == 0, r.output
    assert sorted(p.name for p in (scene["dir"] / "out_captures").iterdir()) == [
        "shell_dance", "shell_walk_dae", "shell_walk_fbx", "shell_walk_gltf", "shell_walk_nodes", "shell_walk_rig",
        "shell_walk_usd"]
    for same in ("shell_dance", "shell_walk_usd", "shell_walk_dae", "shell_walk_nodes"):
        np.testing.assert_allclose(read_sequence(scene["dir"] / "out_captures" / same / "obj").points,
                                   read_sequence(scene["dir"] / "out_captures" / "shell_walk_gltf" / "obj").points,
                                   atol=1e-4)
    (scene["dir"] / "rig.bvh").write_text(rig.read_text().replace("LeftLeg", "LeftTentacle"))
    assert_one_line_error(_bake(scene, scene["dir"] / "rig.bvh"), "rig.bvh", "expected a humanoid skeleton",
                          "found no left knee (a joint named such as LeftLeg; it has Hips, LeftUpLeg")
    assert not scene["out"].joinpath("shell_rig").exists()


def test_motion_up_auto_reads_each_axis_the_body_stands_along_and_z_where_none(caplog):
    """`resolved_up`: +Z, +Y, -Y as the body stands in most frames; a body lying along X throughout is left Z-up,
    told at INFO, with the metres check `load_motion` leaves to it (a translation in centimetres warned about)."""
    from core.motion import Motion
    from core.rotations import matrix_to_axis_angle
    from garmentcli.common import resolved_up

    turns = {"z": [[1, 0, 0], [0, 0, -1], [0, 1, 0]], "y": np.eye(3), "-y": [[1, 0, 0], [0, -1, 0], [0, 0, -1]],
             None: [[0, -1, 0], [1, 0, 0], [0, 0, 1]]}  # the rest body's +Y turned onto +Z, +Y, -Y, -X
    for axis, turn in turns.items():
        poses = np.zeros((4, 24, 3), np.float32)
        poses[:, 0] = matrix_to_axis_angle(np.asarray(turn, np.float64))
        trans = np.zeros((4, 3), np.float32) + (90.0 if axis is None else 0.0)  # centimetres, where lying
        caplog.clear()
        with caplog.at_level(logging.INFO):
            got = resolved_up(Motion(poses=poses, trans=trans, fps=30.0), "m.npz", "auto")
        assert got == (axis or "z"), (axis, got)
        assert ("stands along no one world axis" in caplog.text) == (axis is None)
        assert ("expected metres" in caplog.text) == (axis is None)
    assert resolved_up(Motion(poses=poses, trans=trans, fps=30.0), "m.npz", "-y") == "-y"  # as given


def _wham_file(scene):
    """(path, fps) of a WHAM result of two tracked people: 0, the scene's walk; 3, that walk two frames shorter,
    1 m along x."""
    import pickle

    with np.load(scene["motion"]) as walk:
        poses, trans, fps = walk["poses"], walk["trans"], float(walk["mocap_framerate"])
    path = scene["dir"] / "wham_output.pkl"
    with open(path, "wb") as fh:
        pickle.dump({0: {"pose_world": poses, "trans_world": trans, "frame_ids": np.arange(len(poses))},
                     3: {"pose_world": poses[:-2], "trans_world": trans[:-2] + [1.0, 0, 0],
                         "frame_ids": np.arange(len(poses) - 2)}}, fh)
    return path, fps


def test_person_picks_a_track_of_a_file_of_tracked_people(scene):
    """A WHAM result of two tracked people: the longest-tracked bakes by default, --person 3 the other (the walk
    1 m along x: the garment 1 m along x), recorded in summary.json; an id not tracked is one line naming those
    that are, nothing written; metrics poses the body with --motion and --person as the bake did, and refuses
    --person without --motion."""
    from formats.sequence import read_sequence

    path, fps = _wham_file(scene)
    out = {}
    for name, options in (("longest", ()), ("three", ("--person", "3"))):
        r = invoke(["bake", scene["garment"], path, "--body", scene["body"], "--out", scene["dir"] / name,
                    "--method", "lbs", "--source-fps", fps, *options])
        assert r.exit_code == 0, r.output
        out[name] = read_sequence(scene["dir"] / name / "shell_wham_output" / "obj").points
    summary = json.loads((scene["dir"] / "three" / "shell_wham_output" / "summary.json").read_text())
    assert summary["options"]["person"] == "3" and summary["options"]["person_read"] == "3"
    summary = json.loads((scene["dir"] / "longest" / "shell_wham_output" / "summary.json").read_text())
    assert summary["options"]["person"] is None and summary["options"]["person_read"] == "0"
    n = len(out["three"])  # its two frames fewer, resampled at --fps
    assert n < len(out["longest"])
    np.testing.assert_allclose(out["three"], out["longest"][:n] + [1.0, 0, 0], atol=1e-5)
    r = _bake(scene, path, "--person", "9", "--source-fps", fps)
    assert_one_line_error(r, "wham_output.pkl", "expected --person one of its 2 tracked people ('0' ", "'3' ",
                          "got '9'")
    assert not scene["out"].exists()
    from core.model_deform import DEFAULT_MODEL

    for command in (["tradeoff"], ["attribute", DEFAULT_MODEL, "--frame", "1"]):  # the same option and reading
        r = invoke([*command, scene["garment"], path, "--body", scene["body"], "--out", scene["out"], "--person", "9"])
        assert_one_line_error(r, "wham_output.pkl", "expected --person one of its 2 tracked people", "got '9'")
    baked = scene["dir"] / "three" / "shell_wham_output"
    r = invoke(["metrics", baked, baked, "--person", "3"])
    assert_one_line_error(r, "--person", "applies only with --motion")
    r = invoke(["metrics", baked, baked, "--motion", path, "--body", scene["body"], "--source-fps", fps,
                "--person", "3"])  # the body posed as the bake posed it: person 3's frames
    assert r.exit_code == 0, r.output


def test_person_all_bakes_each_tracked_person_into_its_own_output(scene):
    """--person all: each track of a file of tracked people baked into <garment>_<motion>_person<ID> (the longest
    first, said), as --person ID bakes it, recorded in summary.json; a file of one person beside it bakes as it
    is; the commands of one scene (tradeoff, attribute, metrics) refuse all in one line (dataset plans each:
    test_dataset_cli)."""
    from formats.sequence import read_sequence

    path, fps = _wham_file(scene)
    r = invoke(["bake", scene["garment"], path, scene["motion"], "--body", scene["body"], "--out", scene["out"],
                "--method", "lbs", "--source-fps", fps, "--person", "all"])
    assert r.exit_code == 0, r.output
    assert "wham_output.pkl': 2 tracked people, each read (0, 3)" in r.output
    assert sorted(p.name for p in scene["out"].iterdir()) == ["shell_walk", "shell_wham_output_person0",
                                                              "shell_wham_output_person3"]
    for track in ("0", "3"):
        summary = json.loads((scene["out"] / f"shell_wham_output_person{track}" / "summary.json").read_text())
        assert summary["options"]["person"] == "all" and summary["options"]["person_read"] == track
    r = invoke(["bake", scene["garment"], path, "--body", scene["body"], "--out", scene["dir"] / "three",
                "--method", "lbs", "--source-fps", fps, "--person", "3"])
    assert r.exit_code == 0, r.output
    np.testing.assert_array_equal(read_sequence(scene["out"] / "shell_wham_output_person3" / "obj").points,
                                  read_sequence(scene["dir"] / "three" / "shell_wham_output" / "obj").points)
    summary = json.loads((scene["out"] / "shell_walk" / "summary.json").read_text())
    assert summary["options"]["person_read"] is None

    from core.model_deform import DEFAULT_MODEL

    for command in (["tradeoff", scene["garment"], path], ["attribute", DEFAULT_MODEL, scene["garment"], path],
                    ["metrics", scene["out"] / "shell_walk", scene["out"] / "shell_walk", "--motion", path]):
        r = invoke([*command, "--person", "all", "--out", scene["dir"] / "refused"])
        assert_one_line_error(r, "--person", "all (one output per tracked person) applies to bake and dataset only")
        assert not (scene["dir"] / "refused").exists()
