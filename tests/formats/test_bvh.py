"""Tests of formats/bvh.py: BVH files of the SMPL skeleton, written here as SMPL exporters write them (Euler angles
from scipy, offsets in centimetres, the root's position its rest pelvis plus the translation)."""

import logging

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from core.body import SMPL_JOINT_NAMES, SMPL_PARENTS, default_body
from core.errors import InputError
from core.rotations import axis_angle_to_matrix
from formats.motion import load_motion
from tests.formats.test_motion import _assert_one_line

#: smpl2bvh's names of SMPL's joints.
SMPL2BVH_NAMES = ("Pelvis", "Left_hip", "Right_hip", "Spine1", "Left_knee", "Right_knee", "Spine2", "Left_ankle",
                  "Right_ankle", "Spine3", "Left_foot", "Right_foot", "Neck", "Left_collar", "Right_collar", "Head",
                  "Left_shoulder", "Right_shoulder", "Left_elbow", "Right_elbow", "Left_wrist", "Right_wrist",
                  "Left_palm", "Right_palm")


def write_bvh(path, poses, trans, fps, names=SMPL2BVH_NAMES, order="ZYX", unit=0.01, rest=None, extra=False):
    """An exporter's BVH of (T, 24, 3) `poses` and (T, 3) `trans` (metres) on the embedded body's rest joints
    (`rest`: other rest joints, metres), in `unit`s; `order`: the Euler channels' order; `extra`: a finger joint
    SMPL lacks under the left hand."""
    joints = default_body().shaped(None)[1][:24] if rest is None else rest
    offsets = np.array([joints[0]] + [joints[k] - joints[SMPL_PARENTS[k]] for k in range(1, 24)]) / unit
    eulers = Rotation.from_rotvec(poses.reshape(-1, 3).astype(np.float64)).as_euler(order, degrees=True)
    eulers = eulers.reshape(len(poses), 24, 3)
    channels = " ".join(f"{a}rotation" for a in order)
    lines, sequence = ["HIERARCHY"], []

    def joint(k, depth):
        tab = "\t" * depth
        sequence.append(k)
        kind = "ROOT" if k == 0 else "JOINT"
        lines.append(f"{tab}{kind} {names[k]}")
        lines.append(f"{tab}{{")
        lines.append(f"{tab}\tOFFSET {' '.join(f'{x:.6f}' for x in offsets[k])}")
        pos = "Xposition Yposition Zposition " if k == 0 else ""
        lines.append(f"{tab}\tCHANNELS {6 if k == 0 else 3} {pos}{channels}")
        children = [c for c in range(24) if SMPL_PARENTS[c] == k]
        for c in children:
            joint(c, depth + 1)
        if extra and k == 22:
            lines.extend([f"{tab}\tJOINT left_index1", f"{tab}\t{{", f"{tab}\t\tOFFSET 3 0 0",
                          f"{tab}\t\tCHANNELS 3 {channels}", f"{tab}\t\tEnd Site", f"{tab}\t\t{{",
                          f"{tab}\t\t\tOFFSET 2 0 0", f"{tab}\t\t}}", f"{tab}\t}}"])
        if not children and not (extra and k == 22):
            lines.extend([f"{tab}\tEnd Site", f"{tab}\t{{", f"{tab}\t\tOFFSET 0 5 0", f"{tab}\t}}"])
        lines.append(f"{tab}}}")

    joint(0, 0)
    lines += ["MOTION", f"Frames: {len(poses)}", f"Frame Time: {1 / fps:.8f}"]
    for t in range(len(poses)):
        row = list(offsets[0] + trans[t] / unit)
        for k in sequence:
            row += list(eulers[t, k])
            if extra and k == 22:
                row += [10.0, 0.0, 0.0]
        lines.append(" ".join(f"{x:.6f}" for x in row))
    path.write_text("\n".join(lines) + "\n")
    return path


def _motion(T=5, seed=0):
    rng = np.random.default_rng(seed)
    poses = rng.normal(scale=0.4, size=(T, 24, 3)).astype(np.float32)
    trans = np.stack([np.linspace(0, 1, T), np.full(T, 0.9), np.linspace(0, -0.5, T)], 1).astype(np.float32)
    return poses, trans


@pytest.mark.parametrize("order, unit, names", [
    ("ZYX", 0.01, SMPL2BVH_NAMES),  # smpl2bvh
    ("ZXY", 0.0254, tuple(n.replace("left_", "L_").replace("right_", "R_").title() for n in SMPL_JOINT_NAMES)),
    ("XYZ", 1.0, tuple("m_avg_" + n for n in SMPL_JOINT_NAMES)),
    ("YZX", 0.001, SMPL_JOINT_NAMES),
])
def test_an_smpl_skeletons_bvh_reads_as_its_smpl_motion(tmp_path, order, unit, names):
    poses, trans = _motion()
    m = load_motion(write_bvh(tmp_path / "dance.bvh", poses, trans, 60, names, order, unit), world_checks=False)
    assert m.fps == pytest.approx(60) and m.poses.shape == (5, 24, 3)
    np.testing.assert_allclose(axis_angle_to_matrix(m.poses), axis_angle_to_matrix(poses), atol=1e-5)
    np.testing.assert_allclose(m.trans, trans, atol=1e-5)


def test_joints_smpl_lacks_are_left_at_rest_with_a_warning(tmp_path, caplog):
    poses, trans = _motion()
    with caplog.at_level(logging.WARNING):
        m = load_motion(write_bvh(tmp_path / "hands.bvh", poses, trans, 30, extra=True), world_checks=False)
    np.testing.assert_allclose(axis_angle_to_matrix(m.poses), axis_angle_to_matrix(poses), atol=1e-5)
    assert "1 joint(s) SMPL's body lacks left at rest (left_index1)" in caplog.text


def test_another_rig_another_rest_pose_or_a_broken_file_is_one_line(tmp_path):
    poses, trans = _motion(3)
    mixamo = ("Hips", "LeftUpLeg", "RightUpLeg", "Spine", "LeftLeg", "RightLeg", "Spine1", "LeftFoot", "RightFoot",
              "Spine2", "LeftToeBase", "RightToeBase", "Neck", "LeftShoulder", "RightShoulder", "Head", "LeftArm",
              "RightArm", "LeftForeArm", "RightForeArm", "LeftHand", "RightHand", "LeftHandIndex1",
              "RightHandIndex1")
    cases = [(dict(names=mixamo), "expected the joints of an SMPL skeleton (pelvis, left_hip, ... by name), lacks 14 "
                                  "of its 22 body joints (pelvis, left_hip, right_hip, left_knee, ...; it has Hips, "
                                  "LeftUpLeg, LeftLeg, LeftFoot, ...): a capture of another rig needs retargeting")]
    joints = default_body().shaped(None)[1][:24].copy()
    a_pose = joints.copy()  # the arms lowered 45 degrees about the shoulders
    for side, sign in (("left", 1), ("right", -1)):
        s = SMPL_JOINT_NAMES.index(f"{side}_shoulder")
        turn = Rotation.from_rotvec([0, 0, -sign * np.pi / 4])
        for k in (s + 2, s + 4, s + 6):  # elbow, wrist, hand
            a_pose[k] = joints[s] + turn.apply(joints[k] - joints[s])
    cases.append((dict(rest=a_pose), "bone 45 degrees from it (an A-pose, or another up axis?)"))
    swapped = list(SMPL2BVH_NAMES)
    swapped[4], swapped[7] = swapped[7], swapped[4]  # the knee under the ankle
    cases.append((dict(names=tuple(swapped)), "expected SMPL's hierarchy, got joint 'Left_ankle' under 'Left_hip'"))
    for kwargs, expected in cases:
        path = write_bvh(tmp_path / "rig.bvh", poses, trans, 30, **kwargs)
        with pytest.raises(InputError) as info:
            load_motion(path)
        _assert_one_line(info, "rig.bvh", expected)
    good = write_bvh(tmp_path / "good.bvh", poses, trans, 30).read_text()
    for text, expected in ((good.replace("Frames: 3", "Frames: 4"), "expected 4 frames of 75 channel values (300), "
                                                                       "got 225 values"),
                           (good[:good.index("MOTION")], "expected a BVH file (HIERARCHY, then MOTION), got no MOTION"),
                           (good.replace("Xposition", "Wposition"), "expected channels such as Xposition or "
                                                                    "Zrotation, got 'wposition'"),
                           (good.replace("Frame Time: 0.03333333", "Frame Time: 0"), "expected a Frame Time over 0"),
                           (good[:good.index("JOINT Left_knee")] + "MOTION\nFrames: 1\nFrame Time: 1\n0\n",
                            "expected a HIERARCHY of joints with balanced braces, got 2 unclosed"),
                           (good[:300] + "\nMOTION\n", "expected ROOT, JOINT, End Site, OFFSET, CHANNELS or a brace "
                                                        "in its HIERARCHY, got 'CHA'"),
                           (good.replace("OFFSET", "OFFSET x", 1), "expected a number for OFFSET, got 'x'"),
                           ("Not a BVH at all\n", "expected a BVH file (HIERARCHY, then MOTION), got a file that is "
                                                  "not one")):
        (tmp_path / "bad.bvh").write_text(text)
        with pytest.raises(InputError) as info:
            load_motion(tmp_path / "bad.bvh")
        _assert_one_line(info, "bad.bvh", expected)
