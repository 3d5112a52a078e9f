"""Tests of other tools' motion files (formats/motion.py, formats/pickles.py): AIST++'s pickles, WHAM's and VIBE's
joblib results, PHALP's per-frame results, TRAM's pickled .npy, GVHMR's PyTorch file, read without running code in
them; Motion-X's .npy and SMPLCodec's .smpl."""

import importlib.util
import logging
import pickle
from pathlib import Path

import numpy as np
import pytest

from core.errors import InputError
from formats.motion import load_motion, tracked_people
from formats.pickles import load_pickle
from tests.formats.test_motion import _assert_one_line, _poses, _trans

DATA = Path(__file__).parent / "data"


def _fixture_people() -> dict:
    """The people the joblib fixtures hold (`data/make_joblib_fixtures.py`, written by joblib 1.6.0)."""
    spec = importlib.util.spec_from_file_location("make_joblib_fixtures", DATA / "make_joblib_fixtures.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.people()


@pytest.mark.parametrize("name", ["wham_like.pkl", "wham_like_zlib.pkl"])
def test_a_joblib_file_of_tracked_people_gives_the_longest_tracks_world_motion(name, caplog):
    """WHAM's joblib result of two tracked people reads the longest-tracked one's world motion (the other named),
    or the one given as person; an id it does not hold is one line naming those it does."""
    people = _fixture_people()
    read = load_pickle(DATA / name, "x", "a motion file")  # the arrays joblib wrote after its pickled header
    assert sorted(read) == sorted(people)
    for track, arrays in people.items():
        for key, value in arrays.items():
            assert read[track][key].dtype == value.dtype
            np.testing.assert_array_equal(read[track][key], value)
    with caplog.at_level(logging.WARNING):
        m = load_motion(DATA / name, fps=30)
    person = people[0]  # 6 frames against 4: WHAM's world motion, not its camera-frame 'pose' and 'trans'
    tracked = person["frame_ids"]  # 0, 1, 2, 4, 5, 6: frame 3 filled in (core.motion.fill_untracked)
    assert m.n_frames == 7
    np.testing.assert_array_equal(m.poses.reshape(7, 72)[tracked], person["pose_world"])
    np.testing.assert_array_equal(m.trans[tracked], person["trans_world"])
    np.testing.assert_allclose(m.trans[3], person["trans_world"][2:4].mean(axis=0), rtol=1e-6)
    np.testing.assert_allclose(m.betas, person["betas"].mean(axis=0), rtol=1e-6)
    text = caplog.text
    assert "holds 2 tracked people ('0' 6 frames, '7' 4 frames): reading '0', tracked longest (--person ID" in text
    assert m.person == "0" and tracked_people(DATA / name) == {"0": 6, "7": 4}
    assert "not tracked in 1 of the video's 7 frames from its first to its last (its frame numbers; 1 in a row" in text
    other = people[7]  # person='7' reads the other track, without a word of the first
    caplog.clear()
    with caplog.at_level(logging.WARNING):
        m = load_motion(DATA / name, fps=30, person="7")
    assert "tracked people" not in caplog.text and m.person == "7"
    np.testing.assert_array_equal(m.poses.reshape(m.n_frames, 72)[other["frame_ids"] - other["frame_ids"][0]],
                                  other["pose_world"])
    with pytest.raises(InputError) as info:
        load_motion(DATA / name, fps=30, person="2")
    _assert_one_line(info, name, "expected --person one of its 2 tracked people ('0' 6 frames, '7' 4 frames), got "
                                 "'2'")


def test_frame_ids_not_one_increasing_number_per_frame_are_left_unused_and_an_absurd_span_refused(tmp_path, caplog):
    poses = _poses(3, 72)
    for ids, told in ((np.array([0, 2, 1]), "expected 3 increasing frame numbers, one per frame, got (3,) of dtype "),
                      (np.arange(4), "got (4,)"), (np.array([0.0, 1.0, 2.0]), "dtype float64")):
        path = tmp_path / "m.pkl"
        path.write_bytes(pickle.dumps({"pose": poses, "trans": _trans(3), "frame_ids": ids}))
        caplog.clear()
        with caplog.at_level(logging.WARNING):
            m = load_motion(path, fps=30)
        assert m.n_frames == 3, m.n_frames
        assert "its frame numbers ('frame_ids') left unused: expected 3 increasing" in caplog.text, caplog.text
        assert told in caplog.text, caplog.text
    path.write_bytes(pickle.dumps({"pose": poses, "trans": _trans(3), "frame_ids": np.array([0, 1, 10 ** 9])}))
    with pytest.raises(InputError) as info:
        load_motion(path, fps=30)
    _assert_one_line(info, "m.pkl", "expected the frame numbers of a track in one video, got frames 0 to 1000000000 "
                                    "for 3")


def test_a_joblib_files_large_arrays_stay_in_the_file_until_asked_for(monkeypatch, tmp_path):
    """Over LAZY_BYTES (here every array), an uncompressed file's arrays are read when np.asarray asks: the per-frame
    vertices (most of a video's file) never are; what is read is what joblib wrote."""
    import formats.pickles as pickles

    monkeypatch.setattr(pickles, "LAZY_BYTES", 0)
    people = _fixture_people()
    read = load_pickle(DATA / "wham_like.pkl", "x", "a motion file")
    assert isinstance(read[0]["verts"], pickles.LazyArray) and len(read[0]["verts"]) == 6
    for key, value in people[7].items():
        np.testing.assert_array_equal(np.asarray(read[7][key]), value)
    m = load_motion(DATA / "wham_like.pkl", fps=30)
    np.testing.assert_array_equal(m.trans[people[0]["frame_ids"]], people[0]["trans_world"])
    cut = tmp_path / "cut.pkl"  # damaged: the file ends inside its arrays
    cut.write_bytes((DATA / "wham_like.pkl").read_bytes()[:3000])
    with pytest.raises(InputError) as info:
        load_motion(cut, fps=30)
    _assert_one_line(info, "cut.pkl", "cannot read it as a Python pickle (EOFError: ")


def test_an_aist_pickle_and_a_vibe_like_one_read_as_their_npz(tmp_path, caplog):
    poses = _poses(5, 72)
    aist = tmp_path / "gBR_sBM_cAll_d04_mBR0_ch01.pkl"  # AIST++'s motions: a dict pickled by Python 3
    with open(aist, "wb") as fh:
        pickle.dump({"smpl_loss": 1.5, "smpl_poses": poses, "smpl_trans": _trans(5) * 95.0,
                     "smpl_scaling": np.array([95.0], dtype=np.float32)}, fh)
    m = load_motion(aist, fps=60)
    np.testing.assert_array_equal(m.poses.reshape(5, 72), poses)
    np.testing.assert_allclose(m.trans, _trans(5), rtol=1e-6)
    vibe = tmp_path / "vibe_output.pkl"  # VIBE: {track: {'pose' (T, 72) in the camera's frame, ...}}, no translation
    with open(vibe, "wb") as fh:
        pickle.dump({1: {"pose": poses, "betas": np.zeros((5, 10)), "pred_cam": np.ones((5, 3)),
                         "frame_ids": np.arange(5)}}, fh, protocol=2)
    with caplog.at_level(logging.WARNING):
        m = load_motion(vibe, fps=25)
    np.testing.assert_array_equal(m.poses.reshape(5, 72), poses)
    assert np.all(m.trans == 0) and "no 'trans'" in caplog.text and "tracked people" not in caplog.text
    assert "not tracked" not in caplog.text and m.n_frames == 5  # its frames are consecutive


def test_a_gvhmr_torch_file_gives_its_world_parameters(tmp_path):
    torch = pytest.importorskip("torch")
    T = 4
    world = {"global_orient": torch.zeros(T, 3), "body_pose": torch.full((T, 63), 0.1),
             "transl": torch.tensor(_trans(T)), "betas": torch.zeros(T, 10)}
    incam = {**world, "body_pose": torch.full((T, 63), -0.2)}
    path = tmp_path / "hmr4d_results.pt"
    torch.save({"smpl_params_global": world, "smpl_params_incam": incam, "K_fullimg": torch.eye(3)[None],
                "kp2d": np.zeros((T, 17, 3), np.float32), "length": np.int64(T)}, path)  # numpy too: read
    m = load_motion(path, fps=30)
    assert m.poses.shape == (T, 55, 3)  # 21 body joints: SMPL-X's layout, its jaw, eyes and hands at rest
    np.testing.assert_allclose(m.poses[:, 1:22].reshape(T, 63), 0.1)
    np.testing.assert_allclose(m.trans, _trans(T))
    marker = tmp_path / "ran"
    payload = _RunsCode()
    payload.marker = str(marker)
    torch.save({"smpl_params_global": world, "hook": payload}, path)
    with pytest.raises(InputError) as info:
        load_motion(path, fps=30)
    _assert_one_line(info, "hmr4d_results.pt", "the pickle refers to '", "which a motion file does not use "
                                               "(refused)")  # builtins.getattr or pathlib.Path: the way to its touch
    assert not marker.exists()


class _RunsCode:
    def __reduce__(self):
        return (Path.touch, (Path(self.marker),))


def test_a_pickle_that_would_run_code_is_refused_without_running_it(tmp_path):
    marker = tmp_path / "ran"
    payload = _RunsCode()
    payload.marker = str(marker)
    path = tmp_path / "evil.pkl"
    with open(path, "wb") as fh:
        pickle.dump({"poses": _poses(2, 72), "x": payload}, fh)
    with pytest.raises(InputError) as info:
        load_motion(path, fps=30)
    _assert_one_line(info, "evil.pkl", "refers to 'pathlib.Path.touch'", "which a motion file does not use")
    assert not marker.exists()


@pytest.mark.parametrize("content, expected", [
    (pickle.dumps([1, 2, 3]), "expected a pickled dict of SMPL parameters ('poses', 'trans', ...; or one such dict "
                              "per tracked person), got list"),
    (pickle.dumps({"poses": _poses(3, 72)})[:40], "cannot read it as a Python pickle ("),
    (b"not a pickle at all", "expected a Python pickle, got text ('not a pickle at all'...)"),
    (b"\x01\x02 not a pickle at all", "cannot read it as a Python pickle (UnpicklingError: invalid load key, "),
    (pickle.dumps({"verts": np.zeros((2, 3))}), "expected a 'poses' array"),
    (pickle.dumps({"f0": {"time": 0, "tid": [1], "smpl": [None]}}), "got another structure (AttributeError: "),
    (pickle.dumps({"f0": {"time": 0, "tid": 5, "smpl": []}}), "got another structure (TypeError: "),
])
def test_a_broken_or_foreign_pickle_is_one_line(tmp_path, content, expected):
    path = tmp_path / "m.pkl"
    path.write_bytes(content)
    with pytest.raises(InputError) as info:
        load_motion(path, fps=30)
    _assert_one_line(info, "m.pkl", expected)


def test_a_damaged_torch_file_is_one_line(tmp_path):
    path = tmp_path / "hmr4d_results.pt"
    path.write_bytes(b"PK\x03\x04 truncated")
    with pytest.raises(InputError) as info:
        load_motion(path, fps=30)
    _assert_one_line(info, "hmr4d_results.pt", "cannot read it as a PyTorch file (")


def test_a_motion_x_array_reads_as_the_same_smplx_parameters_in_an_npz(tmp_path):
    """Motion-X's (T, 322) rows: root_orient, pose_body, pose_hand, pose_jaw, the face's expression and shape
    (unread), trans, betas."""
    T, rng = 4, np.random.default_rng(2)
    values = rng.normal(scale=0.2, size=(T, 322)).astype(np.float32)
    values[:, 312:] = rng.normal(size=10)  # one shape, repeated per frame
    np.save(tmp_path / "Act_Cute.npy", values)
    np.savez(tmp_path / "same.npz", root_orient=values[:, :3], pose_body=values[:, 3:66], pose_hand=values[:, 66:156],
             pose_jaw=values[:, 156:159], trans=values[:, 309:312], betas=values[0, 312:])
    a, b = load_motion(tmp_path / "Act_Cute.npy", fps=30), load_motion(tmp_path / "same.npz", fps=30)
    assert a.poses.shape == (T, 55, 3)
    for field in ("poses", "trans", "betas"):
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field))
    np.save(tmp_path / "wide.npy", values[:, :321])
    with pytest.raises(InputError) as info:
        load_motion(tmp_path / "wide.npy", fps=30)
    _assert_one_line(info, "wide.npy", "Motion-X's SMPL-X parameters as one .npy array of shape (T, 322), got a "
                                       "single .npy array of shape (4, 321)")
    np.save(tmp_path / "list.npy", np.array([[1, 2], "x"], dtype=object), allow_pickle=True)
    with pytest.raises(InputError) as info:
        load_motion(tmp_path / "list.npy", fps=30)
    _assert_one_line(info, "list.npy", "expected a pickled dict of SMPL parameters")


def test_a_tram_track_of_torch_tensors_saved_with_np_save_reads_without_running_code(tmp_path):
    """TRAM's hps_track_K.npy: np.save of a dict of torch tensors (pred_rotmat (T, 24, 3, 3), pred_trans (T, 1, 3),
    pred_shape, frame); its tensors rebuilt through torch.load(weights_only=True), a pickled callable refused."""
    torch = pytest.importorskip("torch")
    from core.rotations import axis_angle_to_matrix

    T, poses = 4, _poses(4, 72).reshape(4, 24, 3)
    track = {"pred_cam": torch.zeros(T, 3), "pred_shape": torch.full((T, 10), 0.5),
             "pred_rotmat": torch.tensor(axis_angle_to_matrix(poses)), "pred_trans": torch.tensor(_trans(T)[:, None]),
             "frame": torch.tensor([10, 11, 12, 14])}
    np.save(tmp_path / "hps_track_0.npy", track, allow_pickle=True)
    m = load_motion(tmp_path / "hps_track_0.npy", fps=30, world_checks=False)
    assert m.n_frames == 5  # frame 13 filled in
    np.testing.assert_allclose(axis_angle_to_matrix(m.poses[[0, 1, 2, 4]]), axis_angle_to_matrix(poses), atol=1e-5)
    np.testing.assert_allclose(m.trans[[0, 1, 2, 4]], _trans(T), atol=1e-6)
    np.testing.assert_allclose(m.betas, 0.5)
    marker = tmp_path / "ran"
    payload = _RunsCode()
    payload.marker = str(marker)
    np.save(tmp_path / "evil.npy", {"pred_rotmat": payload}, allow_pickle=True)
    with pytest.raises(InputError) as info:
        load_motion(tmp_path / "evil.npy", fps=30)
    _assert_one_line(info, "evil.npy", "refers to 'pathlib.Path.touch', which a motion file does not use")
    assert not marker.exists()


@pytest.mark.parametrize("version, joints", [(0, 24), (1, 52), (2, 55)])
def test_an_smpl_codec_file_reads_as_the_amass_layout_of_its_model(tmp_path, version, joints):
    """Meshcapade's SMPLCodec `.smpl`: an npz of camelCase keys, the pose by part (SMPL: bodyPose of 24 joints;
    SMPL-H: 22 and the hands; SMPL-X: 22, headPose (jaw, eyes) and the hands), the order of AMASS's poses."""
    T, rng = 3, np.random.default_rng(version)
    poses = rng.normal(scale=0.2, size=(T, joints, 3)).astype(np.float32)
    body = 24 if version == 0 else 22
    parts = {"bodyPose": poses[:, :body]}
    if version == 2:
        parts["headPose"] = poses[:, 22:25]
    if version:
        parts["leftHandPose"], parts["rightHandPose"] = poses[:, -30:-15], poses[:, -15:]
    path = tmp_path / "avatar.smpl"
    with open(path, "wb") as fh:  # np.savez would add .npz to the name
        np.savez(fh, codecVersion=np.int32(2), smplVersion=np.int32(version), gender=np.int32(2),
                 shapeParameters=np.arange(16, dtype=np.float32) / 10, frameCount=np.int32(T),
                 frameRate=np.float32(120), bodyTranslation=_trans(T), **parts)
    m = load_motion(path)
    np.testing.assert_array_equal(m.poses, poses)
    np.testing.assert_array_equal(m.trans, _trans(T))
    np.testing.assert_array_equal(m.betas, np.arange(16, dtype=np.float32) / 10)
    assert m.fps == 120 and m.gender == "female"


def test_an_smpl_codec_file_of_another_model_or_a_misshapen_part_is_one_line(tmp_path):
    path = tmp_path / "avatar_skel.smpl"
    with open(path, "wb") as fh:
        np.savez(fh, smplVersion=np.int32(5), bodyPose=np.zeros((2, 46), np.float32), frameRate=np.float32(30))
    with pytest.raises(InputError) as info:
        load_motion(path)
    _assert_one_line(info, "avatar_skel.smpl", "expected an SMPL, SMPL-H or SMPL-X pose (smplVersion 0, 1 or 2), got "
                                               "smplVersion 5 (SKEL: its pose is no rotations of SMPL's joints)")
    with open(path, "wb") as fh:
        np.savez(fh, smplVersion=np.int32(2), bodyPose=np.zeros((2, 22, 3), np.float32),
                 leftHandPose=np.zeros((2, 12, 3), np.float32), frameRate=np.float32(30))
    with pytest.raises(InputError) as info:
        load_motion(path)
    _assert_one_line(info, "expected leftHandPose of shape (2, 15, 3), got (2, 12, 3)")


def test_a_phalp_result_gives_the_person_tracked_in_most_frames_as_smplx_arguments(tmp_path, caplog):
    """PHALP's and 4D-Humans' results: {frame: {'time', 'tid', 'smpl', 'camera', ... per detection}}; person 3 is
    seen in frames 0, 1, 3, 4 (frame 2 filled in), person 5 in frames 1 and 2 (read with person='5'; an id not
    tracked is one line naming those that are); masks and features left unread."""
    from core.rotations import axis_angle_to_matrix

    rng = np.random.default_rng(4)
    poses = rng.normal(scale=0.3, size=(5, 24, 3)).astype(np.float32)
    camera = np.stack([np.zeros(5), np.linspace(0, 0.2, 5), np.full(5, 4.0)], 1).astype(np.float32)
    frames = {}
    for t in range(5):
        people = [p for p, seen in ((5, t in (1, 2)), (3, t != 2)) if seen]
        frames[f"outputs/img/{t:06d}.jpg"] = {
            "time": t, "shot": 0, "tid": people, "mask": [{"size": [4, 4], "counts": b"abc"} for _ in people],
            "appe": [np.zeros(8, np.float32) for _ in people], "camera": [camera[t] + p for p in people],
            "smpl": [{"global_orient": axis_angle_to_matrix(poses[t, :1]),
                      "body_pose": axis_angle_to_matrix(poses[t, 1:]), "betas": np.zeros(10, np.float32)}
                     for p in people]}
    path = tmp_path / "demo_video.pkl"
    path.write_bytes(pickle.dumps(dict(reversed(list(frames.items())))))  # in any order: 'time' orders them
    with caplog.at_level(logging.WARNING):
        m = load_motion(path, fps=30, world_checks=False)
    seen = [0, 1, 3, 4]
    assert m.poses.shape == (5, 24, 3)
    np.testing.assert_allclose(axis_angle_to_matrix(m.poses[seen]), axis_angle_to_matrix(poses[seen]), atol=1e-5)
    np.testing.assert_allclose(m.trans[seen], camera[seen] + 3, atol=1e-6)
    np.testing.assert_allclose(m.trans[2], (camera[1] + camera[3]) / 2 + 3, atol=1e-6)
    assert "holds 2 tracked people ('3' 4 frames, '5' 2 frames): reading '3'" in caplog.text
    assert "not tracked in 1 of the video's 5 frames" in caplog.text
    assert m.person == "3" and tracked_people(path) == {"3": 4, "5": 2}
    m = load_motion(path, fps=30, world_checks=False, person="5")  # the other track: frames 1 and 2
    np.testing.assert_allclose(m.trans, camera[1:3] + 5, atol=1e-6)
    assert m.person == "5"
    one = tmp_path / "one.pkl"  # a file of one person's parameters: no tracks
    one.write_bytes(pickle.dumps({"poses": poses.reshape(5, 72), "trans": camera, "mocap_framerate": 30.0}))
    assert tracked_people(one) == {} and load_motion(one, world_checks=False).person is None
    with pytest.raises(InputError) as info:
        load_motion(path, fps=30, person="4")
    _assert_one_line(info, "demo_video.pkl", "expected --person one of its 2 tracked people ('3' 4 frames, '5' 2 "
                                             "frames), got '4'")


def test_a_3dpw_sequence_of_two_actors_reads_each_as_a_tracked_person(tmp_path, caplog):
    """3DPW's sequence pickles (Python 2's protocol 2) hold each parameter as a list of the actors' ('poses',
    'trans', 'betas', 'genders'; 'poses_60Hz' beside): the first actor read by default, the other named; --person 1
    the other; 30 fps (the video's) where the file names no rate; the same of arrays along a first axis."""
    rng = np.random.default_rng(16)
    T = 6
    poses = [rng.normal(scale=0.2, size=(T, 72)), rng.normal(scale=0.2, size=(T, 72))]
    trans = [np.zeros((T, 3)), np.ones((T, 3))]
    sequence = {"sequence": "courtyard_dancing_00", "genders": ["m", "f"], "poses": poses, "trans": trans,
                "betas": [np.zeros(10), np.full(10, 0.5)], "poses_60Hz": [np.repeat(p, 2, axis=0) for p in poses],
                "trans_60Hz": [np.repeat(t, 2, axis=0) for t in trans], "cam_poses": np.zeros((T, 4, 4)),
                "campose_valid": [np.ones(T, bool)] * 2, "img_frame_ids": np.arange(T)}
    path = tmp_path / "courtyard_dancing_00.pkl"
    path.write_bytes(pickle.dumps(sequence, protocol=2))
    with caplog.at_level(logging.WARNING):
        m = load_motion(path, world_checks=False)
    assert "holds 2 tracked people ('0' 6 frames, '1' 6 frames): reading '0'" in caplog.text
    assert m.fps == 30.0 and m.person == "0" and m.gender == "m" and tracked_people(path) == {"0": 6, "1": 6}
    np.testing.assert_allclose(m.poses.reshape(T, 72), poses[0], atol=1e-6)
    m = load_motion(path, world_checks=False, person="1")
    np.testing.assert_allclose(m.poses.reshape(T, 72), poses[1], atol=1e-6)
    assert m.gender == "f" and np.allclose(m.trans, 1.0) and np.allclose(m.betas, 0.5)
    stacked = {"poses": np.stack(poses), "trans": np.stack(trans), "mocap_framerate": 60.0}
    path.write_bytes(pickle.dumps(stacked))
    m = load_motion(path, world_checks=False, person="1")
    assert m.fps == 60.0 and m.person == "1"
    np.testing.assert_allclose(m.trans, 1.0)


def test_an_emdb_sequence_reads_its_smpl_dict_and_keeps_the_files_gender(tmp_path):
    """EMDB's pickles: {'smpl': {'poses_root' (T, 3), 'poses_body' (T, 69), 'trans', 'betas'}, 'gender', 'camera',
    ...}: SMPL's 24 joints, the translation, the gender of the file beside the dict (no rate: --source-fps)."""
    rng = np.random.default_rng(17)
    T = 5
    root, body = rng.normal(scale=0.2, size=(T, 3)), rng.normal(scale=0.2, size=(T, 69))
    sequence = {"n_frames": T, "gender": "female", "name": "P1_14_outdoor_climb",
                "smpl": {"poses_root": root, "poses_body": body, "trans": np.ones((T, 3)), "betas": np.zeros(10)},
                "camera": {"intrinsics": np.eye(3), "extrinsics": np.zeros((T, 4, 4))},
                "good_frames_mask": np.ones(T, bool)}
    path = tmp_path / "P1_14_outdoor_climb_data.pkl"
    path.write_bytes(pickle.dumps(sequence))
    m = load_motion(path, fps=30, world_checks=False)
    assert m.poses.shape == (T, 24, 3) and m.gender == "female"
    np.testing.assert_allclose(m.poses.reshape(T, 72), np.concatenate([root, body], axis=1), atol=1e-6)
    np.testing.assert_allclose(m.trans, 1.0)
    with pytest.raises(InputError) as info:
        load_motion(path, world_checks=False)
    _assert_one_line(info, "P1_14_outdoor_climb_data.pkl", "--source-fps")


def test_a_pickle_or_torch_file_of_text_or_nothing_is_named_for_what_it_is(tmp_path):
    """An OBJ renamed .pt ended in torch's UnpicklingError cut off mid-word; an empty .pkl said 'EOFError: EOFError'."""
    (tmp_path / "shape.pt").write_text("v 0 0 0\nf 1 2 3\n")
    (tmp_path / "empty.pkl").write_bytes(b"")
    for name, needle in (("shape.pt", "expected a PyTorch file, got text ('v 0 0 0'...)"),
                         ("empty.pkl", "expected a Python pickle, got an empty file")):
        with pytest.raises(InputError) as info:
            load_motion(tmp_path / name)
        _assert_one_line(info, f"motion '{tmp_path / name}': {needle}")


def test_a_long_cause_is_cut_at_a_word():
    """A damaged file's cause was cut at 120 characters mid-word ('... If yo')."""
    from formats.motion import _short

    long = RuntimeError("PytorchStreamReader failed reading zip archive: failed finding central directory. This is "
                        "an internal miniz error. If you are seeing this, please report it")
    assert _short(long) == ("PytorchStreamReader failed reading zip archive: failed finding central directory. This "
                            "is an internal miniz error. If ...")
    assert _short(RuntimeError("short one\nsecond line")) == "short one"
