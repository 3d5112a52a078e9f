"""Motion capture of another humanoid rig (Mixamo's, CMU's, 3ds Max Biped's, MotionBuilder's, Xsens', Daz's,
VRoid's, a game engine's) turned into SMPL joint rotations and translation: what `formats.bvh`, `formats.fbx` and
`formats.gltf` read a BVH, an FBX or a glTF of such a rig as.

Joints are matched by name to roles (`_ROLE_NAMES`: 'LeftUpLeg', 'L_Thigh', 'thigh_l', 'Bip01 L Thigh', 'HipLeft'
are all the left hip; a prefix all the joints share dropped, `joint_keys`), the spine by the skeleton's shape (the
joints from the pelvis to the neck; the chest the one the arms hang from). Each matched SMPL joint takes its rig
joint's world rotation, composed with a fixed rotation that turns SMPL's rest bone onto the rig's rest bone
(`_rest_turns`: the bone's direction, and the body's forward, or up for a bone along forward): a rig resting in an
A-pose, or with bones of other lengths, moves SMPL's bones along its own. SMPL joints the rig lacks (a second spine
joint, the collars, the toes) follow their parent; rig joints SMPL lacks (fingers, twist joints, a hip joint between
the pelvis and the thigh) pass their rotation on to the next matched joint. The pelvis's path is scaled by SMPL's
legs over the rig's (its unit too), so the feet keep their stride. Joint positions along the bones agree exactly
where the rig's joints between two matched ones do not turn; the twist about a limb is the rig's.

The bones are turned from the rig's rest pose (all its rotations zero) where it stands (legs down from the hips,
the head above the pelvis). A rig whose zero pose folds the body (LAFAN1's, Bandai Namco's: every bone along its
joint's own X) gives no forward to turn the bones by: each bone is turned from the clip's frame it stands best
in instead (`_turns_by_bone`: a leg, the spine or a foot nearest SMPL's rest, an arm hanging or held out; among
the frames upright in the world most frames stand in), the pelvis from the frame whose legs are straightest
(`_standing_frame`), warned (the twist about a limb then the actor's at its frame, whose hanging arms give SMPL's
palms facing the thighs); where its knees and elbows bend as hinges, the bones either side are twisted onto the
hinges' axes (`_hinged`). A clip whose thighs and shins never come near down is refused.
"""

from __future__ import annotations

import logging
import os
import re
from typing import NamedTuple

import numpy as np

from core.body import SMPL_JOINT_NAMES, SMPL_PARENTS, default_body
from core.errors import InputError
from core.rotations import matrix_to_axis_angle

log = logging.getLogger(__name__)

#: Prefixes of joint names in exported rigs, left out before matching (after any 'namespace:'; Mixamo's namespace
#: written 'mixamorig_' where ':' may not be, as in USD).
_PREFIXES = re.compile(r"^(m_avg_|f_avg_|smplx?_|bip0*1[ _]?|cc_base_|def[_-]|org[_-]|b_|j_bip_(c_)?|mixamorig\d*_)")
#: Suffixes of joint names in exported rigs, left out before matching: what a joint is, not which ('hips_joint',
#: 'left_upLeg_joint' of Apple's ARKit skeleton; 'L_thigh_jnt', 'elbow_bind_jnt' of Maya rigs; '_bone').
_SUFFIXES = re.compile(r"([ _.\-](bind|skin|def))?[ _.\-](joint|jnt|bone)$")
#: Names (after `canonical`: lower case, letters and digits, the side a leading 'l' or 'r') of each role; the
#: side's letter is put before them. 'shoulder', 'foot' and 'hand' are told by the names beside them (`_sides`).
_ROLE_NAMES = {
    "hip": ("upleg", "thigh", "upperleg", "hip", "femur", "thighbend", "uplegroll", "upperleg01"),
    "knee": ("leg", "knee", "shin", "calf", "lowerleg", "lowleg", "tibia", "shinbend", "lowerleg01"),
    "ankle": ("ankle", "footankle"),
    "foot": ("toebase", "toe", "toes", "toe0", "ball", "football"),
    "collar": ("collar", "clavicle", "clav", "scapula"),
    "shoulder": ("arm", "upperarm", "uparm", "humerus", "shldr", "shldrbend", "uarm", "armupper", "upperarm01"),
    "elbow": ("forearm", "lowerarm", "elbow", "lowarm", "radius", "forearmbend", "farm", "armlower", "lowerarm01"),
    "wrist": ("wrist", "handwrist"),
}
#: Names of the head and the neck in rigs that number their spine instead (Blender's Rigify: 'spine.004' the neck,
#: 'spine.006' the head), taken where no joint is named as the head.
_NUMBERED_SPINE = {"spine006": "head", "spine004": "neck"}
PELVIS_NAMES = ("hips", "hip", "pelvis")
#: The roles a rig must have (each side's), and an example name of each for the refusal.
_REQUIRED = {"hip": "LeftUpLeg", "knee": "LeftLeg", "ankle": "LeftFoot", "shoulder": "LeftArm",
             "elbow": "LeftForeArm", "wrist": "LeftHand"}
#: SMPL's joint down each chain from a joint (spine to neck to head, down the limbs): the bone that turns it.
CHAIN_CHILD = {3: 6, 6: 9, 9: 12, 12: 15, 1: 4, 4: 7, 7: 10, 2: 5, 5: 8, 8: 11, 13: 16, 16: 18, 18: 20, 20: 22,
                14: 17, 17: 19, 19: 21, 21: 23}
#: SMPL's pelvis, spine, neck and head.
_TRUNK = (0, 3, 6, 9, 12, 15)
#: The world axes a rest skeleton may stand along (`Retargeted.up`), and how close (cosine, 30 degrees).
_UP_AXES = {"z": (0.0, 0.0, 1.0), "y": (0.0, 1.0, 0.0), "-y": (0.0, -1.0, 0.0)}
_UP_COSINE = np.cos(np.radians(30.0))
#: Frames retargeted at a time: the rig's and SMPL's poses in the world are held for these only (about 6 KB a
#: frame for a 27-joint rig).
CHUNK_FRAMES = 4096
#: A thigh or shin further than this from the body's down (degrees; up: from the pelvis to the head) does not stand.
LEG_MAX_DEGREES = 45.0
#: A body leaning further from the world's up than this (degrees, its median frame) gives no up axis.
LEAN_MAX_DEGREES = 60.0
#: Frames looked through, evenly spread, for each bone's best view where the rig's zero pose does not stand.
BONE_FRAMES = 512


def role_names(names: list[str]) -> int:
    """How many of `names` name a humanoid's joint (a role of `_ROLE_NAMES` with its side, a pelvis, spine, neck
    or head; `joint_keys`): of a file's trees of joints, the body's names the most (a control rig's and a prop's
    the fewest)."""
    return _roles(joint_keys(names))


def _roles(keys: list[str]) -> int:
    groups = (*_ROLE_NAMES.values(), ("foot", "hand", "shoulder"))
    roles = {side + n for side in "lr" for group in groups for n in group}
    roles |= {*PELVIS_NAMES, "head", "neck", "spine"}
    return sum(k in roles for k in keys)


def joint_keys(names: list[str]) -> list[str]:
    """Each of `names` as matched (`canonical`), without a prefix they all share up to a separator where that names
    more of a humanoid's joints ('Character1_' of MotionBuilder's HumanIK, 'Skeleton1_' of OptiTrack's Motive,
    'FullBody_' of Meta's body tracking)."""
    keys = [canonical(n) for n in names]
    prefix = os.path.commonprefix(list(names)) if len(names) > 1 else ""
    cut = max(prefix.rfind(c) for c in "_:- .")
    if cut > 0:
        bare = [canonical(n[cut + 1:]) for n in names]
        if _roles(bare) > _roles(keys):
            return bare
    return keys


def canonical(name: str) -> str:
    """A joint's name as matched: no 'namespace:', no rig prefix or suffix, lower case letters and digits, the side
    ('Left', 'L', a '_l' or '.L' suffix, a 'Left' ending the name) a leading 'l' or 'r' ('_M', the middle,
    dropped)."""
    n = re.sub(r"^m(?=[A-Z])", "", name.rsplit(":", 1)[-1].strip()).lower()  # Second Life's 'mHipLeft
    n = _SUFFIXES.sub("", _PREFIXES.sub("", n))
    # a side, or the middle (AdvancedSkeleton's 'Head_M', Auto-Rig Pro's 'head.x')
    side = re.search(r"[ _.\-](l|r|left|right|m|c|x)$", n)
    if side:
        n = side.group(1)[0].replace("m", "").replace("c", "").replace("x", "") + n[:side.start()]
    elif not re.match(r"(left|right)", n):  # the side a word at its end (Kinect's 'KneeLeft')
        side = re.search(r"(?<=[a-z0-9])(left|right)$", n)
        if side:
            n = side.group(1) + n[:side.start()]
    n = re.sub(r"(?<=[a-z0-9])[ _.\-]stretch$", "", n)  # Auto-Rig Pro's deforming 'arm_stretch.l'
    n = re.sub(r"[^a-z0-9]", "", n)
    return re.sub(r"^(left|right)", lambda m: m.group(1)[0], n)


class Retargeted(NamedTuple):
    """poses: (T, 24, 3) SMPL axis-angle. trans: (T, 3) metres. up: the world axis ("z", "y", "-y") the rig's rest
    skeleton stands along (within 30 degrees), else None. said: what was matched, in words."""

    poses: np.ndarray
    trans: np.ndarray
    up: str | None
    said: str


def retarget(names: list[str], parents: list[int], offsets: np.ndarray, rotations: np.ndarray,
             root_positions: np.ndarray, src: str, moving: np.ndarray | None = None, trees: tuple = (),
             rest_posed: bool = False) -> Retargeted:
    """SMPL's motion of a rig's (module docstring).

    names, parents (-1 for the root; parents before children): the rig's joints. offsets (J, 3): each joint's
    rest position from its parent (the root's: its rest position), in the rig's unit. rotations (T, J, 3, 3):
    each joint's rotation from its rest, in its parent's frame. root_positions (T, 3): the root's position.
    moving (T, J, 3): each joint's position from its parent's per frame, where they move (`rig_pose`); trees:
    the tree the file keeps each joint in, where it keeps several (`match_joints`); rest_posed: whether the rest
    is a pose the file happened to hold, its bones then turned as a folded rig's are. InputError naming `src` where
    the rig lacks a role, its matched joints are not in a body's order, or neither its rest nor a frame stands.
    """
    rest = rest_positions(parents, offsets)
    match = match_joints(names, parents, src, trees)
    smpl_rest = default_body().shaped(None)[1][:24].astype(np.float64)
    itself = {k: k for k in range(24)}  # SMPL's rest joints as a rig matched to itself
    chunks = [slice(s, s + CHUNK_FRAMES) for s in range(0, len(rotations), CHUNK_FRAMES)]

    carriers = _segment_carriers(match, parents)

    def posed(c: slice) -> tuple[np.ndarray, np.ndarray]:
        world, position = rig_pose(parents, offsets, rotations[c], root_positions[c],
                                   None if moving is None else moving[c])
        for j, t in carriers.items():  # a limb split into segments turns as its last one
            world[:, j] = world[:, t]
        return world, position

    by_bone = leaning_up = None
    body_m = _body_frame(smpl_rest, itself)
    bent, leg = _bent(rest, match)
    if bent > LEG_MAX_DEGREES or rest_posed:  # each bone turned from the frame it is seen best in (`_turns_by_bone`)
        keys = (0, 15, 1, 2, 4, 5, 7, 8)  # the pelvis, head and legs: what a frame's standing is told by
        trunk = np.concatenate([posed(c)[1][:, [match[k] for k in keys]] for c in chunks])
        t, frame_bent = _standing_frame(trunk, {k: i for i, k in enumerate(keys)})
        rest = posed(slice(t, t + 1))[1][0]
        frames = np.union1d(np.linspace(0, len(rotations) - 1, min(len(rotations), BONE_FRAMES)).astype(int), [t])
        world_n, position_n = posed(frames)
        by_bone, worst, leaning_up = _turns_by_bone(match, world_n, position_n, smpl_rest, body_m,
                                                    int(np.searchsorted(frames, t)))
        if worst > LEG_MAX_DEGREES:
            raise InputError(f"{src}: expected a rest pose (all rotations zero) or a frame that stands, got its "
                             f"'{names[match[leg]]}' leg {bent:.0f} degrees from down at rest and, in its straightest "
                             f"frame ({t}), a leg {frame_bent:.0f} degrees from down (each thigh and shin at best "
                             f"{worst:.0f}; the head above the pelvis is up): a rig that never stands needs "
                             f"retargeting to one first")
        why = ("its rest a pose the file held" if bent <= LEG_MAX_DEGREES else
               f"the rig's zero pose does not stand (its '{names[match[leg]]}' leg {bent:.0f} degrees from down)")
        log.warning("%s: %s: each bone is turned from the frame it stands best in (its legs nearest SMPL's, within "
                    "%.0f degrees of down, an arm hanging or held out, the body upright; frame %d the straightest, "
                    "legs within %.0f degrees; knees and elbows that hinge twisted onto their axes); the twist about "
                    "each limb is the actor's there", src, why, worst, t, frame_bent)
    body_s = _body_frame(rest, match)
    if by_bone is None:
        turns = _rest_turns(match, rest, smpl_rest, body_m, body_s)
    else:  # the turns are from those frames' joint rotations, not from zero ones
        turns = {**by_bone, **_hinged(match, by_bone, world_n, position_n, smpl_rest)}
    legs_m, legs_s = _legs(smpl_rest, itself), _legs(rest, match)
    if not (np.isfinite(legs_s) and legs_s > 0):
        raise InputError(f"{src}: expected legs of some length in its OFFSETs, got {legs_s}")

    poses = np.empty((len(rotations), 24, 3))
    trans = np.empty((len(rotations), 3))
    for c in chunks:  # a chunk of frames at a time: the rig's pose in the world is its size in joints
        world, position = posed(c)
        smpl_world = np.empty((len(world), 24, 3, 3))
        local = np.empty_like(smpl_world)
        for k in range(24):
            if k in match:
                smpl_world[:, k] = world[:, match[k]] @ turns[k]
            else:
                smpl_world[:, k] = smpl_world[:, SMPL_PARENTS[k]]
            parent = SMPL_PARENTS[k]
            local[:, k] = (smpl_world[:, k] if parent < 0
                           else np.swapaxes(smpl_world[:, parent], 1, 2) @ smpl_world[:, k])
        poses[c] = matrix_to_axis_angle(local)
        trans[c] = position[:, match[0]] * (legs_m / legs_s) - smpl_rest[0]
    up = next((axis for axis, v in _UP_AXES.items() if body_s[:, 1] @ v > _UP_COSINE), None)
    if up is None and by_bone is not None:  # a body leaning throughout (a sad walk): the axis it leans nearest to
        up = leaning_up
    roles = (("pelvis", (0,)), ("hips", (1, 2)), ("knees", (4, 5)), ("ankles", (7, 8)), ("spine", (3, 6, 9)),
             ("shoulders", (16, 17)), ("elbows", (18, 19)), ("wrists", (20, 21)))

    def named(k: int) -> str:  # (a wrong elbow, or a twist joint passed over, is seen)
        if k not in match:
            return "-"
        j = match[k]
        return names[j] + (f" (turning as {names[carriers[j]]})" if j in carriers else "")

    listed = "; ".join(f"{role} " + ", ".join(named(k) for k in ks) for role, ks in roles)
    said = (f"{len(match)} of SMPL's 24 joints matched ({listed}); "
            f"legs of {legs_s:.4g} units, SMPL's {legs_m:.2f} m, its path scaled by {legs_m / legs_s:.4g}")
    return Retargeted(poses, trans, up, said)


#: SMPL's joints whose bone a rig may split into twist segments: the hips, knees, shoulders and elbows (not the
#: ankles: a foot's metatarsal joint bends the forefoot, which the heel does not follow).
_TWISTING = (1, 2, 4, 5, 16, 17, 18, 19)


def _segment_carriers(match: dict[int, int], parents: list[int]) -> dict[int, int]:
    """{matched rig joint: the joint its limb's next matched joint hangs from}, where that is another below it: a
    limb split into segments in its chain (Daz's lShldrBend > lShldrTwist > lForearmBend, Rigify's DEF-upper_arm.L >
    DEF-upper_arm.L.001, Meta's WristTwist), whose last segment turns as the whole bone with its twist. SMPL's joint
    took the first segment's rotation: the twist the others hold went to the next joint (a Daz shoulder 17 degrees
    off on a walk, an elbow 84 on a bent, rolled arm). Only the limbs of `_TWISTING`: the spine's own extra joints
    are matched otherwise."""
    carriers = {}
    for k, j in match.items():
        c = chain_end(k, match)
        if k not in _TWISTING or c is None:
            continue
        t = parents[match[c]]
        if t != j and _descends(parents, t, j):
            carriers[j] = t
    return carriers


def rig_pose(parents: list[int], offsets: np.ndarray, rotations: np.ndarray, root_positions: np.ndarray,
             moving: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(T, J, 3, 3) each rig joint's rotation in the world and (T, J, 3) its position (`retarget`'s arguments;
    moving: the offsets per frame, where the joints' places move)."""
    world = np.empty_like(rotations)
    position = np.empty(rotations.shape[:2] + (3,))
    for j, p in enumerate(parents):
        if p < 0:
            world[:, j], position[:, j] = rotations[:, j], root_positions
        else:
            world[:, j] = world[:, p] @ rotations[:, j]
            offset = offsets[j] if moving is None else moving[:, j, :, None]
            position[:, j] = position[:, p] + (world[:, p] @ offset).reshape(-1, 3)
    return world, position


def rest_positions(parents: list[int], offsets: np.ndarray) -> np.ndarray:
    """(J, 3) each rig joint's position in its rest pose (all rotations zero)."""
    identity = np.broadcast_to(np.eye(3), (1, len(parents), 3, 3))
    return rig_pose(parents, offsets, identity, offsets[:1])[1][0]


def _descends(parents: list[int], child: int, ancestor: int) -> bool:
    while child >= 0:
        if child == ancestor:
            return True
        child = parents[child]
    return False


def _path(parents: list[int], j: int) -> list[int]:
    """The joints from the root down to `j`."""
    out = []
    while j >= 0:
        out.append(j)
        j = parents[j]
    return out[::-1]


def _sides(by_name: dict[str, int], side: str) -> dict[str, int]:
    """{role: rig joint} of one side ('l' or 'r'). 'Shoulder' is the upper arm beside a collar (SMPL's, BVH
    exporters' 'LeftCollar', 'LeftShoulder') or where no other joint is the arm, else the collar (Mixamo's
    'LeftShoulder', 'LeftArm'); 'foot' is the ankle unless an 'ankle' is there (SMPL's 'left_foot' is its toes),
    'hand' the wrist unless a 'wrist' is (SMPL's 'left_hand' its knuckles)."""
    out = {role: next((by_name[side + n] for n in names if side + n in by_name), None)
           for role, names in _ROLE_NAMES.items()}
    shoulder = by_name.get(side + "shoulder")
    if shoulder is not None:
        if out["shoulder"] is None:
            out["shoulder"] = shoulder
        elif out["collar"] is None:
            out["collar"] = shoulder
    if out["ankle"] is None:
        out["ankle"] = by_name.get(side + "foot")
    elif out["foot"] is None:
        out["foot"] = by_name.get(side + "foot")
    hand = by_name.get(side + "hand", by_name.get(side + "palm"))
    if out["wrist"] is None:
        out["wrist"], out["hand"] = hand, None
    else:
        out["hand"] = hand
    return out


def match_joints(names: list[str], parents: list[int], src: str, trees: tuple = ()) -> dict[int, int]:
    """{SMPL joint: rig joint} (module docstring); InputError naming the first role the rig lacks, or a limb's
    joints that are not each under the one before (but for two joints the file keeps in different trees, `trees`
    giving each joint's: a foot an IK control holds)."""
    keys = joint_keys(names)
    by_name: dict[str, int] = {}
    for j, key in enumerate(keys):
        by_name.setdefault(key, j)
    if "head" not in by_name:
        for key, role in _NUMBERED_SPINE.items():
            if key in by_name:
                by_name.setdefault(role, by_name[key])
    if "head" not in by_name:  # ValveBiped's 'Bip01_Head1'
        numbered = next((j for j, key in enumerate(keys) if re.fullmatch(r"head\d+", key)), None)
        if numbered is not None:
            by_name["head"] = numbered
    sides = {side: _sides(by_name, side) for side in ("l", "r")}
    for roles in sides.values():  # a 'wrist' the hand does not hang from is a helper (ValveBiped's L_Wrist)
        if roles["wrist"] is not None and roles["hand"] is not None and not _descends(parents, roles["hand"],
                                                                                      roles["wrist"]):
            roles["wrist"], roles["hand"] = roles["hand"], None
    for role, example in _REQUIRED.items():
        for side, word in (("l", "left"), ("r", "right")):
            if sides[side][role] is None:
                raise InputError(f"{src}: expected a humanoid skeleton (hips, legs, spine, head and arms by the names "
                                 f"of SMPL's, Mixamo's, CMU's, Biped's or a like rig), found no {word} {role} (a "
                                 f"joint named such as {example.replace('Left', word.title())}; it has "
                                 f"{', '.join(names[:4])}{', ...' if len(names) > 4 else ''}): retarget it to one first")
    head = by_name.get("head")
    if head is None:
        raise InputError(f"{src}: expected a humanoid skeleton with a joint named 'Head', found none among its "
                         f"{len(names)} joints ({', '.join(names[:4])}{', ...' if len(names) > 4 else ''})")
    hips = (sides["l"]["hip"], sides["r"]["hip"])
    common = [a for a, b in zip(_path(parents, hips[0]), _path(parents, hips[1])) if a == b]
    if not common:
        raise InputError(f"{src}: expected its legs under one pelvis, got '{names[hips[0]]}' and '{names[hips[1]]}' "
                         f"in two trees")
    pelvis = next((j for j in reversed(common) if keys[j] in PELVIS_NAMES), common[-1])
    match = {0: pelvis}
    for side, first in (("l", 1), ("r", 2)):
        roles = sides[side]
        for role, k in (("hip", first), ("knee", first + 3), ("ankle", first + 6), ("foot", first + 9),
                        ("collar", first + 12), ("shoulder", first + 15), ("elbow", first + 17),
                        ("wrist", first + 19), ("hand", first + 21)):
            if roles[role] is not None:
                match[k] = roles[role]
    # the spine: the joints on the way to the head below the pelvis, up to a neck; the chest, the one the arms
    # hang from (their lowest common joint with the head).
    way = [j for j in _path(parents, head) if not _descends(parents, pelvis, j)]
    neck_key = by_name.get("neck")
    neck = next((i for i, j in enumerate(way) if "neck" in keys[j] or j == neck_key), len(way) - 1)
    spine = way[:neck]
    if neck < len(way) - 1:
        match[12] = way[neck]
    match[15] = head
    arm = _path(parents, match.get(16))
    chest = max((i for i, j in enumerate(spine) if j in arm), default=len(spine) - 1)
    if spine:
        match[3] = spine[0]
        if chest > 0:
            match[9] = spine[chest]
            if chest > 1:
                match[6] = spine[chest // 2]
    for k, j in match.items():  # each limb's joints under the one before
        parent = next(p for p in _ancestors(k) if p in match) if k else 0
        apart = bool(trees) and trees[j] != trees[match[parent]]
        if parent not in _TRUNK and not apart and not _descends(parents, j, match[parent]):
            raise InputError(f"{src}: expected '{names[j]}' (SMPL's {SMPL_JOINT_NAMES[k]}) under "
                             f"'{names[match[parent]]}' (its {SMPL_JOINT_NAMES[parent]}), got it elsewhere")
    return match


def _ancestors(k: int) -> list[int]:
    out = []
    while SMPL_PARENTS[k] >= 0:
        k = SMPL_PARENTS[k]
        out.append(k)
    return out


def _body_frame(rest: np.ndarray, joint: dict[int, int]) -> np.ndarray:
    """(..., 3, 3) columns left, up, forward of a skeleton's joint positions (..., J, 3) (`joint`: its joint of
    each SMPL joint): up from the pelvis to the head, left from the right hip to the left."""
    up = _units(rest[..., joint[15], :] - rest[..., joint[0], :])
    left = rest[..., joint[1], :] - rest[..., joint[2], :]
    left = _units(left - np.sum(left * up, axis=-1, keepdims=True) * up)
    return np.stack([left, up, np.cross(left, up)], axis=-1)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / max(float(np.linalg.norm(v)), 1e-12)


def _leg_angles(position: np.ndarray, match: dict[int, int]) -> np.ndarray:
    """(..., 4) the angles in degrees of the left thigh, right thigh, left shin and right shin from the body's down
    (up: from the pelvis to the head) of rig joint positions (..., J, 3)."""
    up = position[..., match[15], :] - position[..., match[0], :]
    up = up / np.maximum(np.linalg.norm(up, axis=-1, keepdims=True), 1e-12)
    bones = np.stack([position[..., match[k + 3], :] - position[..., match[k], :] for k in (1, 2, 4, 5)], axis=-2)
    bones = bones / np.maximum(np.linalg.norm(bones, axis=-1, keepdims=True), 1e-12)
    return np.degrees(np.arccos(np.clip(-np.einsum("...bi,...i->...b", bones, up), -1.0, 1.0)))


#: SMPL's shoulders, elbows and wrists: the arm bones, which hang down where an actor stands.
_ARM_JOINTS = (16, 17, 18, 19, 20, 21)


def _turns_by_bone(match: dict[int, int], world: np.ndarray, position: np.ndarray, smpl_rest: np.ndarray,
                   body_m: np.ndarray, straightest: int) -> tuple[dict[int, np.ndarray], float, str | None]:
    """({SMPL joint: its turn (`_rest_turns`) from its rig joint's frame}, the largest angle in degrees any thigh or
    shin keeps from down at best (the body's down, or the world's where the body leans), the world axis the body
    stands along (`_UP_AXES`; the one it leans nearest to where it stands along none, within LEAN_MAX_DEGREES
    in the median frame; else None)) of a rig whose zero pose does not stand, each joint's turn taken in the frame (of
    `world` (N, J, 3, 3) and `position` (N, J, 3)) its bone is seen nearest as it stands: an arm bone hanging or
    held out sideways (as in a T-pose), another (a leg's, the spine's, a foot's) as SMPL's at rest, in the body's
    frame (its twist then told by the body's forward, square to it); the pelvis and joints without a bone
    of their own in the `straightest` frame. Where the body is upright in most frames, only those are looked at
    (an actor lying straight on the floor is no rest)."""
    angles = _leg_angles(position, match)  # (N, 4): thighs and shins from down
    body_s = _body_frame(position, match)  # (N, 3, 3)
    up = body_s[:, :, 1]
    along = up @ np.array(list(_UP_AXES.values())).T > _UP_COSINE  # (N, axes)
    upright = along[:, int(np.argmax(along.sum(axis=0)))]
    looked = upright if upright.sum() * 2 >= len(upright) else np.ones(len(upright), dtype=bool)
    looked[straightest] = True
    # the straightest frame's turns, for the pelvis and the joints without a bone of their own
    turns = _rest_turns(match, position[straightest], smpl_rest, body_m, body_s[straightest])
    out = {k: world[straightest, match[k]].T @ turn for k, turn in turns.items()}
    size = np.linalg.norm(position[:, match[1]] - position[:, match[2]], axis=1)
    for k in turns:
        c = chain_end(k, match)
        if k == 0 or c is None:
            continue
        bone_m = smpl_rest[c] - smpl_rest[k]
        axis = _twist_axis(bone_m, body_m)
        bone = position[:, match[c]] - position[:, match[k]]
        if k in _ARM_JOINTS:  # hanging, or held out to its side
            toward = _units(np.einsum("nji,nj->ni", body_s, bone))
            cosine = np.maximum(-toward[:, 1], toward[:, 0] * (1.0 if k % 2 == 0 else -1.0))
        else:
            cosine = np.einsum("nji,nj,i->n", body_s, _units(bone), body_m.T @ _unit(bone_m))
        cosine = np.where(looked & (np.linalg.norm(bone, axis=1) >= 1e-9 * size) & np.isfinite(cosine), cosine,
                          -np.inf)  # a frame of NaNs (a damaged file's) is no view
        n = int(np.argmax(cosine))
        if np.isfinite(cosine[n]):
            turn = _frame(bone[n], body_s[n][:, axis]) @ _frame(bone_m, body_m[:, axis]).T
            out[k] = world[n, match[k]].T @ turn
    # the legs from down: the body's (pelvis to head), or the world's where the body leans over them (a sad walk):
    # the axis it is upright along most, else the one it leans nearest to on average
    axes = np.array(list(_UP_AXES.values()))
    nearest = int(np.argmax(along.sum(axis=0))) if along.any() else int(np.argmax((up @ axes.T).mean(axis=0)))
    vertical = axes[nearest]
    bones = _units(np.stack([position[:, match[k + 3]] - position[:, match[k]] for k in (1, 2, 4, 5)], axis=1))
    world_angles = np.degrees(np.arccos(np.clip(-bones @ vertical, -1.0, 1.0)))
    worst = float(np.where(looked[:, None], np.minimum(angles, world_angles), np.inf).min(axis=0).max())
    leaning = float(np.degrees(np.arccos(np.clip(np.median(up @ vertical), -1.0, 1.0))))
    return out, worst, (list(_UP_AXES)[nearest] if leaning < LEAN_MAX_DEGREES else None)


#: SMPL's hinge joints (the knees and elbows): {joint: its axis of flexion in its rest frame}, a positive turn about
#: it bending the bone below as a body bends (the shins back, the forearms forward).
_HINGES = {4: (1.0, 0.0, 0.0), 5: (1.0, 0.0, 0.0), 18: (0.0, -1.0, 0.0), 19: (0.0, 1.0, 0.0)}
#: A hinge whose bends sweep less than this (the spread of the bone below across the plane it bends in, as seen
#: from the bone above: about a tenth of a radian) tells its axis too little.
HINGE_SWEEP = 0.02
#: A clip of fewer frames than this does not tell a hinge from chance.
HINGE_FRAMES = 30
#: A limb whose bends leave the plane of a hinge by more than this (degrees, their spread) is no hinge.
HINGE_SPREAD = 8.0


def _hinged(match: dict[int, int], turns: dict[int, np.ndarray], world: np.ndarray, position: np.ndarray,
            smpl_rest: np.ndarray) -> dict[int, np.ndarray]:
    """{SMPL joint: its turn twisted about its bone} for the bones on either side of a knee or elbow (`_HINGES`)
    whose rig limb bends as a hinge (frames of `world` (N, J, 3, 3) and `position` (N, J, 3)), whatever frame
    their twists were first taken from (`_turns_by_bone`): seen from the bone above, the bone below sweeps a cone
    about the hinge's axis, so the bone above is twisted to put that cone's axis (its circle's plane, fitted to
    the frames, turned the way the limb bends: a knee or elbow flexes one way) on SMPL's hinge; the bone below is
    then twisted to share that axis in the world, on average over the frames (its own turning about its length,
    a forearm's, left to it). A limb whose bends leave one plane (by more than HINGE_SPREAD degrees), lie along
    the plane's axis rather than across it (a patch of bends every way), or span too little of it, or a clip of
    fewer than HINGE_FRAMES frames, keeps its turns."""
    out = {}
    for k, hinge in _HINGES.items():
        c, parent = chain_end(k, match), next((p for p in _ancestors(k) if p in match), None)
        if k not in match or c is None or parent is None or k not in turns or parent not in turns:
            continue
        h = np.asarray(hinge)
        frame = world[:, match[parent]] @ turns[parent]  # (N, 3, 3): SMPL's thigh or upper arm in the world
        below = _units(position[:, match[c]] - position[:, match[k]])
        points = np.einsum("nji,nj->ni", frame, below)  # the bone below, in the frame of the one above
        points = points[np.isfinite(points).all(axis=1)]  # frames of NaNs (a damaged file's) left out
        if len(points) < HINGE_FRAMES:
            continue  # too short a clip to tell
        centred = points - points.mean(axis=0)
        _, spread, axes = np.linalg.svd(centred, full_matrices=False)
        bone = _unit(smpl_rest[k] - smpl_rest[parent])
        bending = np.cross(bone, points).sum(axis=0)  # the way the bone below bends from the one above: flexion
        normal = axes[2] if axes[2] @ bending >= 0 else -axes[2]
        if spread[1] / np.sqrt(len(points)) < HINGE_SWEEP or np.std(centred @ normal) > np.sin(
                np.radians(HINGE_SPREAD)) or normal @ _unit(bending) < np.cos(np.radians(HINGE_SPREAD * 4)):
            continue  # bent too little, not about one axis (the plane of a patch of bends, square to the way it
            # bends, is no hinge's)
        out[parent] = turns[parent] @ _turn_about(bone, float(_angle_about(h, normal, bone)))
        axis_world = (world[:, match[parent]] @ out[parent]) @ h  # the hinge's axis in the world per frame
        bone = _unit(smpl_rest[c] - smpl_rest[k])
        frame = world[:, match[k]] @ turns[k]
        angles = _angle_about(frame @ h, axis_world, frame @ bone)
        angles = angles[np.isfinite(angles)]
        mean = np.array([np.cos(angles).mean(), np.sin(angles).mean()]) if len(angles) else np.zeros(2)
        if np.hypot(*mean) >= np.cos(np.radians(HINGE_SPREAD * 4)):
            out[k] = turns[k] @ _turn_about(bone, float(np.arctan2(mean[1], mean[0])))
    return out


def _angle_about(start: np.ndarray, end: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """The angles (radians) turning vectors `start` onto `end` about the unit `axis` (each (..., 3)), both seen
    square to it."""
    a, b = (v - np.sum(v * axis, axis=-1, keepdims=True) * axis for v in (start, end))
    return np.arctan2(np.sum(np.cross(a, b) * axis, axis=-1), np.sum(a * b, axis=-1))


def _turn_about(axis: np.ndarray, angle: float) -> np.ndarray:
    """(3, 3) the rotation by `angle` (radians) about the unit `axis`."""
    K = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    return np.eye(3) + np.sin(angle) * K + (1.0 - np.cos(angle)) * (K @ K)


def _units(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-12)


def _bent(rest: np.ndarray, match: dict[int, int]) -> tuple[float, int]:
    """How far (degrees) a rest skeleton's most bent thigh or shin is from down, and the SMPL hip of its leg."""
    angles = _leg_angles(rest, match)
    return float(angles.max()), (1, 2, 1, 2)[int(angles.argmax())]


def _standing_frame(position: np.ndarray, match: dict[int, int]) -> tuple[int, float]:
    """The frame of rig joint positions (T, J, 3) whose thighs and shins are all nearest down, and how far
    (degrees) its most bent one is; where the body stands along one world axis (`_UP_AXES`) in at least half the
    frames, among those frames only (an actor lying straight on the floor is no rest: its world would be read
    turned)."""
    worst = _leg_angles(position, match).max(axis=-1)
    up = position[:, match[15]] - position[:, match[0]]
    up = up / np.maximum(np.linalg.norm(up, axis=-1, keepdims=True), 1e-12)
    along = up @ np.array(list(_UP_AXES.values())).T > _UP_COSINE  # (T, axes)
    upright = along[:, int(np.argmax(along.sum(axis=0)))]
    if upright.sum() * 2 >= len(worst):
        worst = np.where(upright, worst, np.inf)
    t = int(np.argmin(worst))
    return t, float(worst[t])


def _rest_turns(match, rest, smpl_rest, body_m, body_s) -> dict[int, np.ndarray]:
    """{SMPL joint: the rotation taking SMPL's rest frame of its bone to the rig's} (module docstring); a joint
    with no matched joint down its chain (the head, a hand) takes its matched parent's."""
    turns = {0: body_s @ body_m.T}
    for k in range(1, 24):
        if k not in match:
            continue
        c = chain_end(k, match)
        bone_s = rest[match[c]] - rest[match[k]] if c is not None else np.zeros(3)
        if c is None or np.linalg.norm(bone_s) < 1e-9 * np.linalg.norm(rest[match[1]] - rest[match[2]]):
            turns[k] = turns[next(p for p in _ancestors(k) if p in turns)]
            continue
        bone_m = smpl_rest[c] - smpl_rest[k]
        axis = _twist_axis(bone_m, body_m)
        turns[k] = _frame(bone_s, body_s[:, axis]) @ _frame(bone_m, body_m[:, axis]).T
    return turns


def _twist_axis(bone_m: np.ndarray, body_m: np.ndarray) -> int:
    """The column of the body's frame (left, up, forward) a bone's twist is told by: forward, or up for a bone
    along forward (a foot)."""
    return 1 if abs(_unit(bone_m) @ body_m[:, 2]) > 0.7 else 2


def chain_end(k: int, match: dict[int, int]) -> int | None:
    """The SMPL joint at the other end of joint `k`'s bone on a rig (`match`): the first matched one down its chain
    (CHAIN_CHILD), or None."""
    c = CHAIN_CHILD.get(k)
    while c is not None and c not in match:
        c = CHAIN_CHILD.get(c)
    return c


def _frame(primary: np.ndarray, secondary: np.ndarray) -> np.ndarray:
    a = _unit(primary)
    b = _unit(secondary - (secondary @ a) * a)
    return np.stack([a, b, np.cross(a, b)], axis=1)


def _legs(rest: np.ndarray, match: dict[int, int]) -> float:
    """The mean length of both legs, hips to knees to ankles."""
    return float(np.mean([np.linalg.norm(rest[match[k + 3]] - rest[match[k]])
                          + np.linalg.norm(rest[match[k + 6]] - rest[match[k + 3]]) for k in (1, 2)]))

