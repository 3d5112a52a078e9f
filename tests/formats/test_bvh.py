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
from tests.formats.test_motion import _assert_one_line, assert_each_refused

#: smpl2bvh's names of SMPL's joints.
SMPL2BVH_NAMES = ("Pelvis", "Left_hip", "Right_hip", "Spine1", "Left_knee", "Right_knee", "Spine2", "Left_ankle",
                  "Right_ankle", "Spine3", "Left_foot", "Right_foot", "Neck", "Left_collar", "Right_collar", "Head",
                  "Left_shoulder", "Right_shoulder", "Left_elbow", "Right_elbow", "Left_wrist", "Right_wrist",
                  "Left_palm", "Right_palm")


def write_skeleton(path, names, parents, offsets, rotations, root, fps, order="ZYX", positions=None):
    """A BVH of a skeleton: `names`, `parents` (parents first), `offsets` (J, 3) in its unit, each joint's
    (T, J, 3, 3) rotation from its rest as Euler channels in `order` (scipy's intrinsic angles), the root's (T, 3)
    position; an End Site under every leaf; positions {joint: (T, 3)}: position channels of other joints too."""
    positions = {0: root, **(positions or {})}
    T, J = rotations.shape[:2]
    eulers = Rotation.from_matrix(rotations.reshape(-1, 3, 3)).as_euler(order, degrees=True).reshape(T, J, 3)
    channels = " ".join(f"{a}rotation" for a in order)
    lines, sequence = ["HIERARCHY"], []

    def joint(j, depth):
        tab = "\t" * depth
        sequence.append(j)
        lines.extend([f"{tab}{'ROOT' if parents[j] < 0 else 'JOINT'} {names[j]}", f"{tab}{{",
                      f"{tab}\tOFFSET {' '.join(f'{x:.6f}' for x in offsets[j])}",
                      f"{tab}\tCHANNELS {6 if j in positions else 3} "
                      f"{'Xposition Yposition Zposition ' if j in positions else ''}{channels}"])
        children = [c for c in range(J) if parents[c] == j]
        for c in children:
            joint(c, depth + 1)
        if not children:
            lines.extend([f"{tab}\tEnd Site", f"{tab}\t{{", f"{tab}\t\tOFFSET 0 5 0", f"{tab}\t}}"])
        lines.append(f"{tab}}}")

    joint(0, 0)
    lines += ["MOTION", f"Frames: {T}", f"Frame Time: {1 / fps:.8f}"]
    for t in range(T):
        row = []
        for j in sequence:
            row += list(positions[j][t]) if j in positions else []
            row += list(eulers[t, j])
        lines.append(" ".join(f"{x:.6f}" for x in row))
    path.write_text("\n".join(lines) + "\n")
    return path


def write_bvh(path, poses, trans, fps, names=SMPL2BVH_NAMES, order="ZYX", unit=0.01, rest=None, extra=False):
    """An exporter's BVH of (T, 24, 3) `poses` and (T, 3) `trans` (metres) on the embedded body's rest joints
    (`rest`: other rest joints, metres), in `unit`s; `order`: the Euler channels' order; `extra`: a finger joint
    SMPL lacks under the left hand, turned 10 degrees."""
    joints = default_body().shaped(None)[1][:24] if rest is None else rest
    offsets = np.array([joints[0]] + [joints[k] - joints[SMPL_PARENTS[k]] for k in range(1, 24)]) / unit
    rotations = axis_angle_to_matrix(poses.astype(np.float64))
    names, parents = list(names), list(SMPL_PARENTS)
    if extra:
        names.append("left_index1")
        parents.append(22)
        offsets = np.concatenate([offsets, [[3.0, 0.0, 0.0]]])
        turn = axis_angle_to_matrix(np.radians(10.0) * np.eye(3)["XYZ".index(order[0])])
        rotations = np.concatenate([rotations, np.broadcast_to(turn, (len(poses), 1, 3, 3))], axis=1)
    return write_skeleton(path, names, parents, offsets, rotations, offsets[0] + trans / unit, fps, order)


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


def _smpl_world(poses):
    """(T, 24, 3, 3) each SMPL joint's world rotation of `poses`."""
    local = axis_angle_to_matrix(poses.astype(np.float64))
    world = local.copy()
    for k in range(1, 24):
        world[:, k] = world[:, SMPL_PARENTS[k]] @ local[:, k]
    return world


def _a_posed(joints, degrees):
    """SMPL's rest `joints` with the arms lowered `degrees` about the shoulders (about the body's forward: left, from
    the right hip to the left, across up, from the pelvis to the head), and each arm joint's turn {SMPL joint:
    (3, 3)}."""
    up = joints[15] - joints[0]
    forward = np.cross(joints[1] - joints[2], up)
    forward /= np.linalg.norm(forward)
    out, turns = joints.copy(), {}
    for side, sign in (("left", 1), ("right", -1)):
        s = SMPL_JOINT_NAMES.index(f"{side}_shoulder")
        turn = axis_angle_to_matrix(-sign * np.radians(degrees) * forward)
        for k in (s, s + 2, s + 4, s + 6):  # shoulder, elbow, wrist, hand
            out[k] = joints[s] + turn @ (joints[k] - joints[s])
            turns[k] = turn
    return out, turns


def _along_x(rest, parents, rig, rng):
    """(J, 3, 3) each joint's frame in a rig whose bones lie along their joints' X (LAFAN1's, Maya's): X onto the
    bone to its first child (a leaf's: from its parent), turned at random about it; a joint SMPL lacks takes its
    parent's frame."""
    frames = np.empty((len(parents), 3, 3))
    for j, p in enumerate(parents):
        if rig[j][2] is None and p >= 0:
            frames[j] = frames[p]
            continue
        child = next((c for c, q in enumerate(parents) if q == j), None)
        bone = rest[child] - rest[j] if child is not None else rest[j] - rest[p]
        a = bone / np.linalg.norm(bone)
        b = rng.normal(size=3)
        b = b - (b @ a) * a
        b /= np.linalg.norm(b)
        frames[j] = np.stack([a, b, np.cross(a, b)], axis=1)
    return frames


def rig_motion(poses, trans, rig, unit=0.01, scale=1.0, a_pose=0.0, seed=0, along_x=False):
    """(names, parents, offsets, rotations (T, J, 3, 3) from the rest in the parent's frame, the root's (T, 3)
    position) of another rig moving as the SMPL motion (`poses`, `trans`) does: `rig` lists (name, parent's
    index, SMPL joint or None, where) per joint, parents first; a matched joint's bone turns as SMPL's, an extra
    one (where: (a, b, f), at f of the way from SMPL's rest joint a to b) turns with its parent, or at random
    where it has no children (fingers). Its rest: SMPL's, `scale`d, the arms lowered `a_pose` degrees, in
    `unit`s, every joint's frame the world's; `along_x`: every joint's frame `_along_x`'s instead, so that its
    zero pose folds the body as LAFAN1's does."""
    joints, turns = _a_posed(default_body().shaped(None)[1][:24].astype(np.float64) * scale, a_pose)
    rng = np.random.default_rng(seed)
    names = [r[0] for r in rig]
    parents = [r[1] for r in rig]
    rest = np.array([joints[k] if k is not None else joints[w[0]] + w[2] * (joints[w[1]] - joints[w[0]])
                     for _, _, k, w in rig])
    frames = _along_x(rest, parents, rig, rng) if along_x else np.broadcast_to(np.eye(3), (len(rig), 3, 3))
    offsets = np.array([frames[p].T @ (rest[j] - rest[p]) if p >= 0 else rest[j]
                        for j, p in enumerate(parents)]) / unit
    smpl = _smpl_world(poses)
    world = np.empty((len(poses), len(rig), 3, 3))
    for j, (_, p, k, _) in enumerate(rig):
        if k is not None:
            world[:, j] = smpl[:, k] @ turns.get(k, np.eye(3)).T @ frames[j]
        elif any(r[1] == j for r in rig):
            world[:, j] = world[:, p]
        else:
            world[:, j] = world[:, p] @ Rotation.random(random_state=rng).as_matrix()
    rotations = world.copy()
    for j, p in enumerate(parents):
        if p >= 0:
            rotations[:, j] = np.swapaxes(world[:, p], 1, 2) @ world[:, j]
    root = (joints[0] / scale + trans) * scale / unit  # SMPL's pelvis path, the rig's size
    return names, parents, offsets, rotations, root


def rig_bvh(path, poses, trans, rig, unit=0.01, scale=1.0, a_pose=0.0, seed=0, along_x=False, order="ZXY"):
    """A BVH at 30 fps of `rig_motion`'s rig, its Euler channels in `order`."""
    return write_skeleton(path, *rig_motion(poses, trans, rig, unit, scale, a_pose, seed, along_x), 30, order)


def _rig(entries):
    """rig_bvh's `rig` of (name, parent's name, SMPL joint or where) entries."""
    index = {e[0]: i for i, e in enumerate(entries)}
    return [(n, index[p] if p else -1, k if isinstance(k, int) else None, k if isinstance(k, tuple) else None)
            for n, p, k in entries]


#: Mixamo's rig (a namespace, 'LeftShoulder' its collar, 'LeftFoot' its ankle) with a CMU hip joint between the
#: hips and each thigh, a head-top joint and a finger.
MIXAMO = _rig([("mixamorig7:Hips", None, 0), ("mixamorig7:Spine", "mixamorig7:Hips", 3),
               ("mixamorig7:Spine1", "mixamorig7:Spine", 6), ("mixamorig7:Spine2", "mixamorig7:Spine1", 9),
               ("mixamorig7:Neck", "mixamorig7:Spine2", 12), ("mixamorig7:Head", "mixamorig7:Neck", 15),
               ("mixamorig7:HeadTop_End", "mixamorig7:Head", (12, 15, 2.0))]
              + [e for side, s in (("Left", 0), ("Right", 1)) for e in (
                  (f"mixamorig7:{side}Shoulder", "mixamorig7:Spine2", 13 + s),
                  (f"mixamorig7:{side}Arm", f"mixamorig7:{side}Shoulder", 16 + s),
                  (f"mixamorig7:{side}ForeArm", f"mixamorig7:{side}Arm", 18 + s),
                  (f"mixamorig7:{side}Hand", f"mixamorig7:{side}ForeArm", 20 + s),
                  (f"mixamorig7:{side}HandIndex1", f"mixamorig7:{side}Hand", (20 + s, 22 + s, 1.0)),
                  (f"{side[0]}HipJoint", "mixamorig7:Hips", (0, 1 + s, 0.5)),
                  (f"mixamorig7:{side}UpLeg", f"{side[0]}HipJoint", 1 + s),
                  (f"mixamorig7:{side}Leg", f"mixamorig7:{side}UpLeg", 4 + s),
                  (f"mixamorig7:{side}Foot", f"mixamorig7:{side}Leg", 7 + s),
                  (f"mixamorig7:{side}ToeBase", f"mixamorig7:{side}Foot", 10 + s))])


def _small_rig(names, sides):
    """A rig of one spine joint, no neck, collars or toes: `names` of pelvis, spine, head, then the left side's
    upper arm, forearm, hand, thigh, calf and foot, '{}' where `sides` (left's, right's) go."""
    pelvis, spine, head, *limbs = names
    entries = [(pelvis, None, 0), (spine, pelvis, 3), (head, spine, 15)]
    for side, s in zip(sides, (0, 1)):
        arm, forearm, hand, thigh, calf, foot = (n.format(side) for n in limbs)
        entries += [(arm, spine, 16 + s), (forearm, arm, 18 + s), (hand, forearm, 20 + s), (thigh, pelvis, 1 + s),
                    (calf, thigh, 4 + s), (foot, calf, 7 + s)]
    return _rig(entries)


def test_a_mixamo_rig_in_an_a_pose_of_other_bone_lengths_reads_as_the_smpl_motion_it_moves_as(tmp_path):
    """A rig's BVH (Mixamo's names and collars, CMU's hip joints, a head top and fingers SMPL lacks, 15 % longer
    bones, the arms resting 40 degrees lowered, centimetres) moving as an SMPL motion is retargeted to that motion:
    every body joint's rotation, the translation, its rest's up axis (+Y)."""
    poses, trans = _motion(6, seed=3)
    poses[:, 22:] = 0  # SMPL's knuckles: the rig has none
    m = load_motion(rig_bvh(tmp_path / "mixamo.bvh", poses, trans, MIXAMO, unit=0.01, scale=1.15, a_pose=40.0),
                    world_checks=False)
    assert m.fps == pytest.approx(30) and m.poses.shape == (6, 24, 3) and m.rest_up == "y"
    np.testing.assert_allclose(axis_angle_to_matrix(m.poses), axis_angle_to_matrix(poses), atol=1e-4)
    np.testing.assert_allclose(m.trans, trans, atol=1e-4)


#: SMPL's own skeleton as smpl2bvh names it, as a `rig_bvh` rig.
SMPL_RIG = _rig([(n, SMPL2BVH_NAMES[SMPL_PARENTS[k]] if k else None, k) for k, n in enumerate(SMPL2BVH_NAMES)])


@pytest.mark.parametrize("a_pose", [15.0, 25.0, 29.0])
def test_an_smpl_named_rig_resting_in_an_a_pose_reads_as_the_motion_it_moves_as(tmp_path, a_pose):
    """SMPL's skeleton and names with the arms resting lowered (an avatar's A-pose): its rotations are from that
    rest, not SMPL's T-pose; it was read as SMPL's as it is up to 30 degrees (every frame's arms `a_pose` degrees
    too high), and is retargeted as any other rig."""
    poses, trans = _motion(6, seed=5)
    m = load_motion(rig_bvh(tmp_path / "avatar.bvh", poses, trans, SMPL_RIG, unit=0.01, a_pose=a_pose),
                    world_checks=False)
    np.testing.assert_allclose(axis_angle_to_matrix(m.poses), axis_angle_to_matrix(poses), atol=1e-4)
    np.testing.assert_allclose(m.trans, trans, atol=1e-4)


@pytest.mark.parametrize("betas", [(3.0,), (-3.0,), (0.0, 3.0), (0.0, 0.0, -3.0, 3.0)])
def test_an_smpl_skeleton_of_another_shape_reads_as_it_is(tmp_path, betas):
    """The rest joints of a shaped SMPL body (its legs up to 11 degrees off the vertical) stay within the T-pose's
    bounds: read as they are (exactly), not retargeted."""
    poses, trans = _motion(4, seed=6)
    rest = default_body().shaped(np.array(betas))[1][:24].astype(np.float64)
    m = load_motion(write_bvh(tmp_path / "shaped.bvh", poses, trans, 30, rest=rest), world_checks=False)
    np.testing.assert_allclose(m.poses, poses, atol=1e-5)
    np.testing.assert_allclose(m.trans, trans, atol=1e-5)


@pytest.mark.parametrize("names, sides", [
    (("pelvis", "spine_01", "head", "upperarm_{}", "lowerarm_{}", "hand_{}", "thigh_{}", "calf_{}", "foot_{}"), "lr"),
    (("Bip01 Pelvis", "Bip01 Spine", "Bip01 Head", "Bip01 {} UpperArm", "Bip01 {} Forearm", "Bip01 {} Hand",
      "Bip01 {} Thigh", "Bip01 {} Calf", "Bip01 {} Foot"), "LR"),
])
def test_a_rig_of_fewer_joints_moves_smpls_joints_it_has_and_leaves_the_others_to_follow(tmp_path, names, sides):
    """A game engine's or 3ds Max Biped's rig (names with side suffixes, or spaces) of one spine joint and no
    neck, collars or toes, in inches: SMPL's joints it has take its rotations, the others their parent's (zero)."""
    poses, trans = _motion(4, seed=5)
    poses[:, [6, 9, 12, 13, 14, 10, 11, 22, 23]] = 0  # the joints the rig lacks
    m = load_motion(rig_bvh(tmp_path / "rig.bvh", poses, trans, _small_rig(names, sides), unit=0.0254),
                    world_checks=False)
    np.testing.assert_allclose(axis_angle_to_matrix(m.poses), axis_angle_to_matrix(poses), atol=1e-4)
    np.testing.assert_allclose(m.trans, trans, atol=1e-4)


#: LAFAN1's rig (Ubisoft's): 22 joints, its toes 'LeftToe'.
LAFAN1 = _rig([("Hips", None, 0), ("Spine", "Hips", 3), ("Spine1", "Spine", 6), ("Spine2", "Spine1", 9),
               ("Neck", "Spine2", 12), ("Head", "Neck", 15)]
              + [e for side, s in (("Left", 0), ("Right", 1)) for e in (
                  (f"{side}UpLeg", "Hips", 1 + s), (f"{side}Leg", f"{side}UpLeg", 4 + s),
                  (f"{side}Foot", f"{side}Leg", 7 + s), (f"{side}Toe", f"{side}Foot", 10 + s),
                  (f"{side}Shoulder", "Spine2", 13 + s), (f"{side}Arm", f"{side}Shoulder", 16 + s),
                  (f"{side}ForeArm", f"{side}Arm", 18 + s), (f"{side}Hand", f"{side}ForeArm", 20 + s))])


def _bone_directions(poses):
    """(T, 16, 3) the world direction of each of SMPL's bones down its chains (retarget.CHAIN_CHILD) in `poses`,
    the hands (to the knuckles, which LAFAN1 lacks) left out."""
    from core.retarget import CHAIN_CHILD

    joints = default_body().shaped(None)[1][:24].astype(np.float64)
    world = _smpl_world(poses)
    bones = np.stack([world[:, k] @ (joints[c] - joints[k]) for k, c in CHAIN_CHILD.items() if c < 22], axis=1)
    return bones / np.linalg.norm(bones, axis=-1, keepdims=True)


def test_a_rig_whose_zero_pose_folds_the_body_is_turned_from_its_straightest_frame(tmp_path, caplog):
    """LAFAN1's rig (every bone along its joint's X, turned at random about it: its zero pose folds the body, so no
    rest to turn SMPL's bones from) takes its straightest frame as its rest, warned: where that frame is SMPL's
    T-pose (the others' knees bent), the motion reads back exactly, also beside a straighter frame lying on the
    floor (the rest is a frame upright in the world most frames stand in); where no frame is, every bone of SMPL
    points as the rig's does in every frame (the twist about it is the actor's at that frame), also in a run
    where one knee or the other is bent in every frame (each bone taken from the frame it stands best in; such a
    clip was refused before)."""
    poses, trans = _motion(6, seed=7)
    poses[:, 22:] = 0
    poses[0] = 0
    poses[1:, 4:6] = [0.9, 0.0, 0.0]  # the knees bent after the first frame
    path = rig_bvh(tmp_path / "lafan.bvh", poses, trans, LAFAN1, unit=0.01, scale=0.95, along_x=True, order="ZYX")
    with caplog.at_level(logging.WARNING):
        m = load_motion(path, world_checks=False)
    assert "the rig's zero pose does not stand (its 'LeftUpLeg' leg" in caplog.text
    assert "each bone is turned from the frame it stands best in" in caplog.text
    assert "frame 0 the straightest" in caplog.text
    assert m.rest_up == "y"
    np.testing.assert_allclose(axis_angle_to_matrix(m.poses), axis_angle_to_matrix(poses), atol=1e-4)
    np.testing.assert_allclose(m.trans, trans, atol=1e-4)

    poses, trans = _motion(6, seed=7)  # upright: the T-pose, knees bent, and a frame lying straighter on its back
    poses[:, 22:] = 0
    poses[:, 0] = 0
    poses[0, 1:] = 0
    poses[1:, 4:6] = [0.9, 0.0, 0.0]
    poses[2] = 0
    poses[2, 0], poses[2, 1], poses[2, 2] = [np.pi / 2, 0, 0], [0, 0, -0.1], [0, 0, 0.1]  # legs 7.8 degrees, not 9.1
    m = load_motion(rig_bvh(tmp_path / "lafan.bvh", poses, trans, LAFAN1, along_x=True, order="ZYX"),
                    world_checks=False)
    assert m.rest_up == "y"  # turned from the upright T-pose, not from the frame lying down
    np.testing.assert_allclose(axis_angle_to_matrix(m.poses), axis_angle_to_matrix(poses), atol=1e-4)

    poses, trans = _motion(6, seed=8)
    poses[:, 0] = 0  # upright, so that some frame stands
    poses[:, [1, 2, 4, 5]] *= 0.3
    m = load_motion(rig_bvh(tmp_path / "lafan.bvh", poses, trans, LAFAN1, along_x=True, seed=2),
                    world_checks=False)
    np.testing.assert_allclose(_bone_directions(m.poses), _bone_directions(poses), atol=1e-4)
    assert not np.allclose(axis_angle_to_matrix(m.poses), axis_angle_to_matrix(poses), atol=1e-2)  # the twists

    poses, trans = _motion(8, seed=9)  # a run: one knee or the other bent in every frame, no frame stands
    poses[:, 0] = 0
    poses[:, [1, 2, 4, 5]] *= 0.2
    poses[0::2, 4] = [1.2, 0.0, 0.0]
    poses[1::2, 5] = [1.2, 0.0, 0.0]
    caplog.clear()
    with caplog.at_level(logging.WARNING):
        m = load_motion(rig_bvh(tmp_path / "run.bvh", poses, trans, LAFAN1, along_x=True, seed=3),
                        world_checks=False)
    assert "frame 4 the straightest, legs within 52 degrees" in caplog.text  # every frame with a knee bent
    np.testing.assert_allclose(_bone_directions(m.poses), _bone_directions(poses), atol=1e-4)
    np.testing.assert_allclose(m.trans, trans, atol=1e-4)


def hinge_motion(T=60, seed=5):
    """(poses, trans) of a clip whose arms never hang or reach out (held forward and down) and whose knees and
    elbows bend as hinges, each to another angle in every frame (the hips and spine turning a little)."""
    rng = np.random.default_rng(seed)
    poses = np.zeros((T, 24, 3))
    poses[:, [1, 2, 3, 6, 9]] = rng.normal(0.0, 0.12, (T, 5, 3))
    bend = np.linspace(0.15, 1.3, T)
    poses[:, 4, 0], poses[:, 5, 0] = bend, bend[::-1]  # the knees, about x
    poses[:, 16] = [0.0, -1.1, -0.6] + rng.normal(0.0, 0.1, (T, 3))  # the arms held forward and down
    poses[:, 17] = [0.0, 1.1, 0.6] + rng.normal(0.0, 0.1, (T, 3))
    poses[:, 18, 1], poses[:, 19, 1] = -bend[::-1] - 0.2, bend + 0.2  # the elbows, about -y and +y
    return poses, np.zeros((T, 3)) + [0.0, 0.0, 0.95]


def hinged_limbs_off(got, want) -> float:
    """Degrees, at most over frames, between the thighs', shins', upper arms' and forearms' rotations in the world
    of two SMPL motions."""
    limbs = [1, 2, 4, 5, 16, 17, 18, 19]
    cosine = (np.einsum("tjab,tjab->tj", _smpl_world(got)[:, limbs], _smpl_world(want)[:, limbs]) - 1.0) / 2.0
    return float(np.degrees(np.arccos(np.clip(cosine, -1.0, 1.0))).max())


def test_knees_and_elbows_that_hinge_twist_their_limbs_as_the_actor_s(tmp_path, monkeypatch):
    """On a LAFAN1-like rig (its zero pose folded) of a clip whose arms never hang or reach out (held forward) and
    whose knees and elbows bend as hinges, each to another angle in every frame: the thighs, shins, upper arms and
    forearms turn as the actor's, twist and all (the hinges' axes fitted to the bends: within 1e-5 degrees),
    where each bone's frame alone gives twists up to 75 degrees off; a clip of limbs that do not hinge (turning
    every way), or too short to tell, keeps those."""
    import core.retarget as retarget

    rng = np.random.default_rng(5)
    poses, trans = hinge_motion()
    T = len(poses)
    path = rig_bvh(tmp_path / "hinges.bvh", poses, trans, LAFAN1, along_x=True, seed=4)

    def limbs_off(m):
        return hinged_limbs_off(m.poses, poses)

    assert limbs_off(load_motion(path, world_checks=False)) < 1e-3

    # knees and elbows turning every way (a patch of bends, no hinge's plane) over as many frames, the first
    # frame SMPL's T-pose: left as that frame gives them, so the motion reads back exactly
    blob = rng.normal(0.0, 0.3, (T, 24, 3))
    blob[:, 0], blob[0], blob[:, 22:] = 0.0, 0.0, 0.0
    blob[1:, 4:6, 0] = np.abs(blob[1:, 4:6, 0]) + 0.5
    m = load_motion(rig_bvh(tmp_path / "blob.bvh", blob, trans, LAFAN1, along_x=True, seed=4), world_checks=False)
    np.testing.assert_allclose(axis_angle_to_matrix(m.poses), axis_angle_to_matrix(blob), atol=1e-4)

    monkeypatch.setattr(retarget, "_hinged", lambda *args: {})
    assert limbs_off(load_motion(path, world_checks=False)) > 5.0


def test_a_folded_rig_with_a_nan_in_a_frame_is_one_line(tmp_path):
    """A LAFAN1-like rig's clip (each bone turned from its best frame, its hinges fitted) with one channel value
    NaN in one frame is refused in one line naming that frame, as any motion of NaNs is (the frame's views were
    once fed to the hinges' fit, which raised LinAlgError)."""
    poses, trans = hinge_motion()
    path = rig_bvh(tmp_path / "nan.bvh", poses, trans, LAFAN1, along_x=True, seed=4)
    lines = path.read_text().splitlines()
    at = next(k for k, line in enumerate(lines) if line.startswith("Frame Time")) + 5
    values = lines[at].split()
    values[10] = "nan"
    lines[at] = " ".join(values)
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError) as info:
        load_motion(path, world_checks=False)
    _assert_one_line(info, "nan.bvh", "poses contains NaN or Inf (first at frame 4)")


def test_position_channels_of_joints_below_the_root_move_them(tmp_path):
    """A rig whose root is a joint at the floor and whose hips carry the motion's translation in their own
    position channels (as game engines' and some exporters' BVHs are), every other joint's position channels its
    OFFSET: the translation is the hips' path, as without the floor joint."""
    poses, trans = _motion(5, seed=11)
    poses[:, 22:] = 0
    names, parents, offsets, rotations, root = rig_motion(poses, trans, MIXAMO)
    J = len(names)
    floor = [("Root", -1)] + [(n, p + 1) for n, p in zip(names, parents)]
    rotations = np.concatenate([np.broadcast_to(np.eye(3), (len(poses), 1, 3, 3)), rotations], axis=1)
    offsets = np.concatenate([[[0.0, 0.0, 0.0]], offsets])
    positions = {j + 1: np.broadcast_to(offsets[j + 1], (len(poses), 3)) for j in range(1, J)}
    positions[1] = root  # the hips' path, under the floor joint at the origin
    path = write_skeleton(tmp_path / "floor.bvh", [n for n, _ in floor], [p for _, p in floor], offsets, rotations,
                          np.zeros((len(poses), 3)), 30, "ZXY", positions)
    m = load_motion(path, world_checks=False)
    np.testing.assert_allclose(axis_angle_to_matrix(m.poses), axis_angle_to_matrix(poses), atol=1e-4)
    np.testing.assert_allclose(m.trans, trans, atol=1e-4)


def test_a_rig_standing_along_z_tells_its_up_axis(tmp_path):
    """A rig whose rest stands along +Z (its offsets turned +90 degrees about X) is read with rest_up 'z', which
    `--motion-up auto` or left out takes (`resolved_up`); one along +Y, 'y'; a --motion-up given wins."""
    from garmentcli.common import resolved_up

    poses, trans = _motion(3)
    text = rig_bvh(tmp_path / "rig.bvh", poses, trans, MIXAMO).read_text()
    lines = []
    for line in text.splitlines():
        if line.strip().startswith("OFFSET"):
            x, y, z = map(float, line.split()[1:])
            line = f"OFFSET {x} {-z} {y}"
        lines.append(line)
    (tmp_path / "z.bvh").write_text("\n".join(lines) + "\n")
    m = load_motion(tmp_path / "z.bvh", world_checks=False)
    assert m.rest_up == "z" and resolved_up(m, "z.bvh", "auto") == "z" and resolved_up(m, "z.bvh", None) == "z"
    assert resolved_up(m, "z.bvh", "y") == "y"
    m = load_motion(tmp_path / "rig.bvh", world_checks=False)  # Y-up: read so where --motion-up is left out
    assert m.rest_up == "y" and resolved_up(m, "rig.bvh", None) == "y" and resolved_up(m, "rig.bvh", "z") == "z"


def test_a_skeleton_no_humanoid_a_rest_not_standing_or_limbs_out_of_order_is_one_line(tmp_path):
    poses, trans = _motion(3)
    mixamo = rig_bvh(tmp_path / "good.bvh", poses, trans, MIXAMO).read_text()
    cases = [(mixamo.replace("mixamorig7:LeftLeg", "mixamorig7:LeftTentacle"),
              "expected a humanoid skeleton (hips, legs, spine, head and arms by the names of SMPL's, Mixamo's, "
              "CMU's, Biped's or a like rig), found no left knee (a joint named such as LeftLeg; it has "
              "mixamorig7:Hips, mixamorig7:Spine, mixamorig7:Spine1, mixamorig7:Spine2, ...): retarget it to one"),
             (mixamo.replace("mixamorig7:Head\n", "mixamorig7:Skull\n"),
              "expected a humanoid skeleton with a joint named 'Head', found none among its 27 joints"),
             (mixamo.replace("mixamorig7:LeftLeg", "mixamorig7:X").replace("mixamorig7:LeftUpLeg",
                                                                           "mixamorig7:LeftLeg")
              .replace("mixamorig7:X", "mixamorig7:LeftUpLeg"),
              "expected 'mixamorig7:LeftLeg' (SMPL's left_knee) under 'mixamorig7:LeftUpLeg' (its left_hip), got "
              "it elsewhere")]
    lying = []  # the legs' rest bones along +Z: a zero pose that does not stand
    for line in mixamo.splitlines():
        if line.strip().startswith("OFFSET") and lying and ("Leg" in lying[-2] or "Foot" in lying[-2]):
            x, y, z = map(float, line.split()[1:])
            line = f"OFFSET {x} {z} {-y}"
        lying.append(line)
    cases.append(("\n".join(lying) + "\n", "expected a rest pose (all rotations zero) or a frame that stands, got "
                                            "its 'mixamorig7:LeftUpLeg' leg 98 degrees from down at rest and, in its "
                                            "straightest frame (0), a leg 106 degrees from down"))
    assert_each_refused(tmp_path / "rig.bvh", cases)


def test_a_broken_bvh_is_one_line(tmp_path):
    poses, trans = _motion(3)
    good = write_bvh(tmp_path / "good.bvh", poses, trans, 30).read_text()
    for text, expected in ((good.replace("Frames: 3", "Frames: 4"), "expected 4 frames of 75 channel values (300), "
                                                                       "got 225 values"),
                           (good[:good.index("MOTION")], "expected a BVH file (HIERARCHY, then MOTION), got no MOTION"),
                           (good.replace("Xposition", "Wposition"), "expected channels such as Xposition or "
                                                                    "Zrotation, got 'wposition'"),
                           (good.replace("Frame Time: 0.03333333", "Frame Time: 0"), "expected a Frame Time over 0"),
                           (good[:good.index("JOINT Left_knee")] + "MOTION\nFrames: 1\nFrame Time: 1\n0\n",
                            "expected a HIERARCHY of joints with balanced braces, got 2 unclosed"),
                           # cut inside a keyword (at a fixed offset the numbers' widths moved the cut: a signed
                           # zero on another CPU made it 'CH')
                           (good[:good.index("CHANNELS", 250) + 3] + "\nMOTION\n", "expected ROOT, JOINT, End Site, "
                                                        "OFFSET, CHANNELS or a brace in its HIERARCHY, got 'CHA'"),
                           (good.replace("OFFSET", "OFFSET x", 1), "expected a number for OFFSET, got 'x'"),
                           ("Not a BVH at all\n", "expected a BVH file (HIERARCHY, then MOTION), got a file that is "
                                                  "not one"),
                           (good[:good.index("Frames:")] + "Frames: 0\nFrame Time: 0.033333\n",
                            "expected at least 1 frame after MOTION, got 'Frames: 0' (a skeleton exported without"),
                           (good.replace("Frame Time: 0.03333333\n", ""),
                            "expected 'Frames: N' and 'Frame Time: S' (seconds per frame) after MOTION, found only "
                            "'Frames'"),
                           (good.replace("Frames: 3", "Frames: three"), "expected a whole number of frames after "
                                                                        "'Frames:', got 'three'"),
                           (good.replace("Frame Time: 0.03333333", "Frame Time: 33.333333"),
                            "expected its Frame Time in seconds per frame (0.0333333 at 30 fps), got 33.3333: "
                            "milliseconds (30 fps)? pass the motion's frame rate with --source-fps")):
        (tmp_path / "bad.bvh").write_text(text)
        with pytest.raises(InputError) as info:
            load_motion(tmp_path / "bad.bvh")
        _assert_one_line(info, "bad.bvh", expected)


def test_a_frame_time_of_a_few_digits_is_its_common_rate_and_no_frame_is_lost(tmp_path):
    """Blender writes Frame Time 0.033333, CMU 0.0083333: read as 30.0003 and 120.0005 fps, a bake at 30 lost the
    last frame (39 of 40) and moved every frame; they are 30 and 120 (a rate off every common one, or near one but
    not its frame time to the digits written, stays its own).
    A UTF-8 byte-order mark, CRLF lines and the header's lines in the other order read as the plain file."""
    from core.motion import resample

    poses, trans = _motion(40)
    text = write_bvh(tmp_path / "walk.bvh", poses, trans, 30).read_text()
    # 0.03353438 (8 digits) is 29.82 fps, within 0.5 % of 29.97 but not its frame time to the digits written: it
    # was snapped (a minute's last frame 0.3 s off); 0.033367 (6 digits) is 29.97's.
    for frame_time, fps, frames_at_30 in (("0.033333", 30.0, 40), ("0.0083333", 120.0, 10), ("0.0345", 1 / 0.0345,
                                                                                               41),
                                          ("0.03353438", 1 / 0.03353438, 40), ("0.033367", 29.97, 40),
                                          ("0.0041666", 240.0, 5), ("0.011111", 90.0, 14)):  # capture systems'
        (tmp_path / "walk.bvh").write_text(text.replace("Frame Time: 0.03333333", f"Frame Time: {frame_time}"))
        m = load_motion(tmp_path / "walk.bvh", world_checks=False)
        assert m.fps == pytest.approx(fps, rel=1e-12) and resample(m, 30.0).n_frames == frames_at_30
        np.testing.assert_array_equal(resample(m, m.fps).poses, m.poses)
    plain = load_motion(tmp_path / "walk.bvh", world_checks=False)
    header = "Frames: 40\nFrame Time: 0.0345"
    assert header in text.replace("Frame Time: 0.03333333", "Frame Time: 0.0345")
    for variant in (b"\xef\xbb\xbf" + (tmp_path / "walk.bvh").read_bytes(),
                    (tmp_path / "walk.bvh").read_bytes().replace(b"\n", b"\r\n"),
                    (tmp_path / "walk.bvh").read_bytes().replace(b"Frames: 40\nFrame Time: 0.0345",
                                                                 b"Frame Time : 0.0345\nFrames : 40")):
        (tmp_path / "variant.bvh").write_bytes(variant)
        got = load_motion(tmp_path / "variant.bvh", world_checks=False)
        np.testing.assert_array_equal(got.poses, plain.poses)
        assert got.fps == plain.fps


def test_a_rig_is_retargeted_chunk_by_chunk_as_at_once(tmp_path, monkeypatch):
    """Frames retargeted a few at a time (`core.retarget.CHUNK_FRAMES`: memory) give the same motion to the bit,
    for a standing rig and for one turned from its straightest frame."""
    import core.retarget

    poses, trans = _motion(7, seed=14)
    poses[:, 0] = 0
    poses[:, [1, 2, 4, 5]] *= 0.3
    paths = [rig_bvh(tmp_path / "mixamo.bvh", poses, trans, MIXAMO, a_pose=30.0),
             rig_bvh(tmp_path / "lafan.bvh", poses, trans, LAFAN1, along_x=True, order="ZYX")]
    whole = [load_motion(p, world_checks=False) for p in paths]
    monkeypatch.setattr(core.retarget, "CHUNK_FRAMES", 3)
    for p, m in zip(paths, whole):
        chunked = load_motion(p, world_checks=False)
        np.testing.assert_array_equal(chunked.poses, m.poses)
        np.testing.assert_array_equal(chunked.trans, m.trans)


def _swing_twist(R: np.ndarray, axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(T, 3, 3) rotations as (swing (T, 3, 3), twist angle (T,) radians about the unit `axis`): R = swing @ twist."""
    q = Rotation.from_matrix(R).as_quat()  # x y z w
    q = np.where(q[:, 3:] < 0, -q, q)
    angle = 2 * np.arctan2(q[:, :3] @ axis, q[:, 3])
    return R @ np.swapaxes(Rotation.from_rotvec(angle[:, None] * axis).as_matrix(), 1, 2), angle


def test_a_limb_split_into_twist_segments_in_its_chain_turns_as_its_last_segment(tmp_path):
    """Rigify's deform bones (DEF-upper_arm.L > DEF-upper_arm.L.001 > DEF-forearm.L > ...; Daz's lShldrBend >
    lShldrTwist, Meta's WristTwist alike): the first segment carries the bone's swing and half its twist, the
    second the whole. SMPL's shoulder, elbow, hip and knee took the first segment's rotation, half the twist going
    to the next joint (8 degrees on a walk, 41 on a bent, rolled arm): now exact."""
    poses, trans = _motion(6, seed=17)
    poses[:, 22:] = 0
    poses[:, [10, 11]] = 0  # the toes: the rig's toe has no bone beyond
    joints = default_body().shaped(None)[1][:24].astype(np.float64)
    smpl = _smpl_world(poses)
    local = axis_angle_to_matrix(poses.astype(np.float64))
    entries = [("DEF-spine", None, 0), ("DEF-spine.001", "DEF-spine", 3), ("DEF-spine.002", "DEF-spine.001", 6),
               ("DEF-spine.003", "DEF-spine.002", 9), ("DEF-spine.004", "DEF-spine.003", 12),
               ("DEF-spine.006", "DEF-spine.004", 15)]
    for side, o in (("L", 0), ("R", 1)):
        entries += [(f"DEF-shoulder.{side}", "DEF-spine.003", 13 + o)]
        for first, second, parent, k, end in (("upper_arm", "forearm", f"DEF-shoulder.{side}", 16 + o, 18 + o),
                                              ("forearm", "hand", f"DEF-upper_arm.{side}.001", 18 + o, 20 + o),
                                              ("thigh", "shin", "DEF-spine", 1 + o, 4 + o),
                                              ("shin", "foot", f"DEF-thigh.{side}.001", 4 + o, 7 + o)):
            entries += [(f"DEF-{first}.{side}", parent, ("half", k, end)),
                        (f"DEF-{first}.{side}.001", f"DEF-{first}.{side}", ("whole", k, end))]
        entries += [(f"DEF-hand.{side}", f"DEF-forearm.{side}.001", 20 + o),
                    (f"DEF-foot.{side}", f"DEF-shin.{side}.001", 7 + o), (f"DEF-toe.{side}", f"DEF-foot.{side}", 10 + o)]
    names = [e[0] for e in entries]
    parents = [names.index(e[1]) if e[1] else -1 for e in entries]
    rest, world = [], np.empty((len(poses), len(entries), 3, 3))
    for j, (_, _, how) in enumerate(entries):
        if isinstance(how, int):
            rest.append(joints[how])
            world[:, j] = smpl[:, how]
            continue
        part, k, end = how
        rest.append(joints[k] if part == "half" else (joints[k] + joints[end]) / 2)
        axis = (joints[end] - joints[k]) / np.linalg.norm(joints[end] - joints[k])
        swing, angle = _swing_twist(local[:, k], axis)
        twist = Rotation.from_rotvec(((0.5 if part == "half" else 1.0) * angle)[:, None] * axis).as_matrix()
        world[:, j] = smpl[:, SMPL_PARENTS[k]] @ swing @ twist
    rest = np.array(rest)
    rotations = world.copy()
    for j, p in enumerate(parents):
        if p >= 0:
            rotations[:, j] = np.swapaxes(world[:, p], 1, 2) @ world[:, j]
    offsets = np.array([rest[j] - rest[p] if p >= 0 else rest[j] for j, p in enumerate(parents)]) / 0.01
    path = write_skeleton(tmp_path / "rigify.bvh", names, parents, offsets, rotations, (joints[0] + trans) / 0.01, 30)
    m = load_motion(path, world_checks=False)
    np.testing.assert_allclose(axis_angle_to_matrix(m.poses)[:, :22], axis_angle_to_matrix(poses)[:, :22], atol=1e-4)


def _named_rig(spine, side_names, helpers=()):
    """A `_rig` of a pelvis-spine-neck-head chain `spine` [(name, SMPL joint or where)] and each side's limbs
    `side_names` (format strings of the side's letter: collar, upper arm, forearm, hand, thigh, shin, foot, toe),
    `helpers` [(format name, parent's format name, where)] leaves beside them."""
    entries = [(n, spine[i - 1][0] if i else None, k) for i, (n, k) in enumerate(spine)]
    chest, pelvis = spine[-3][0], spine[0][0]
    for side, o in (("L", 0), ("R", 1)):
        collar, arm, forearm, hand, thigh, shin, foot, toe = (n.format(side) for n in side_names)
        entries += [(collar, chest, 13 + o), (arm, collar, 16 + o), (forearm, arm, 18 + o), (hand, forearm, 20 + o),
                    (thigh, pelvis, 1 + o), (shin, thigh, 4 + o), (foot, shin, 7 + o), (toe, foot, 10 + o)]
        entries += [(n.format(side), p.format(side), (a + o, b + o, f)) for n, p, (a, b, f) in helpers]
    return _rig(entries)


@pytest.mark.parametrize("rig", [
    # Source engine's ValveBiped, its head 'Head1', a helper 'L_Wrist' beside the hand (refused: "no 'Head'", then
    # the hand "expected under 'L_Wrist'")
    _named_rig([("ValveBiped.Bip01_Pelvis", 0), ("ValveBiped.Bip01_Spine", 3), ("ValveBiped.Bip01_Spine1", 6),
                ("ValveBiped.Bip01_Spine2", 9), ("ValveBiped.Bip01_Neck1", 12), ("ValveBiped.Bip01_Head1", 15)],
               [f"ValveBiped.Bip01_{{}}_{n}" for n in ("Clavicle", "UpperArm", "Forearm", "Hand", "Thigh", "Calf",
                                                      "Foot", "Toe0")],
               [("ValveBiped.Bip01_{}_Wrist", "ValveBiped.Bip01_{}_Forearm", (18, 20, 0.9))]),
    # Blender Auto-Rig Pro's export: the middle '.x', the deforming limbs '_stretch' (refused: "no left hip")
    _named_rig([("root.x", 0), ("spine_01.x", 3), ("spine_02.x", 6), ("spine_03.x", 9), ("neck.x", 12),
                ("head.x", 15)],
               [f"{n}.{{}}" for n in ("shoulder", "arm_stretch", "forearm_stretch", "hand", "thigh_stretch",
                                     "leg_stretch", "foot", "toes_01")]),
])
def test_rigs_named_as_game_and_blender_tools_name_them_read_as_their_motion(tmp_path, rig):
    poses, trans = _motion(5, seed=23)
    poses[:, 22:] = 0
    m = load_motion(rig_bvh(tmp_path / "rig.bvh", poses, trans, rig), world_checks=False)
    limbs = [1, 2, 4, 5, 7, 8, 13, 14, 16, 17, 18, 19, 20, 21]
    np.testing.assert_allclose(_smpl_world(m.poses)[:, limbs], _smpl_world(poses)[:, limbs], atol=1e-4)
