"""BVH motion capture, read as the arrays `formats.motion.load_motion` reads: of an SMPL skeleton as it is (as SMPL
motions exported to BVH are: smpl2bvh, SMPL's Blender add-on), of any other humanoid rig retargeted onto SMPL's
(`core.retarget`: Mixamo's, CMU's, Biped's, ... skeletons).

An SMPL skeleton's joints are matched by name, in its naming variants ('Left_hip', 'L_Hip', 'left_hip',
'm_avg_L_Hip'; 'L_Palm' or 'L_Hand' for the hands), in SMPL's hierarchy and resting in SMPL's T-pose (within
REST_MAX_DEGREES, the arms and legs within LIMB_REST_MAX_DEGREES): their rotations are SMPL's, the unit is told by
the legs (metres, centimetres, inches or millimetres) and the root's position less its OFFSET (the rest pelvis
SMPL exporters write there) is the translation. A skeleton that is not (other names, joints, bone lengths or rest
pose) is retargeted. Rotation channels compose in the order listed (Zrotation Yrotation Xrotation: R = Rz Ry Rx);
the root's position channels are its position. Its world is the one its rest skeleton stands in (REST_UP_KEY: Y-up as most tools write it),
which `garmentcli.common.resolved_up` takes where --motion-up is left out.
"""

from __future__ import annotations

import logging
import re
from pathlib import Path
from typing import NamedTuple

import numpy as np

from core.body import N_BODY_JOINTS, SMPL_JOINT_NAMES, SMPL_PARENTS
from core.errors import InputError
from core.motion import common_rate
from core.retarget import canonical, retarget
from core.rotations import axis_angle_to_matrix, matrix_to_axis_angle

log = logging.getLogger(__name__)

#: The key of `skeleton_arrays`' arrays holding the world axis its rest skeleton stands along ("z", "y", "-y"; none
#: where it stands along none), which `--motion-up auto` takes.
REST_UP_KEY = "rest_up"
#: The key of `skeleton_arrays`' arrays naming the animation read (of an FBX or glTF of several).
TAKE_KEY = "garment_take"
#: Other names of SMPL's joints after `core.retarget.canonical` (the hands as palms).
_ALIASES = {"lpalm": "lhand", "rpalm": "rhand"}
#: A rest bone further than this from SMPL's T-pose bone (degrees) is another rest pose: the skeleton is retargeted
#: (`core.retarget`), not read as SMPL's. The spine's, neck's, head's and collars' bones: SMPL's own lie up to 20
#: degrees off the axes of `_SMPL_BONES` (the embedded body's with betas of +-3 up to 22).
REST_MAX_DEGREES = 30.0
#: The same for the arms' and legs' bones, where a rig's rest pose shows (an A-pose lowers the arms 25-45 degrees):
#: SMPL's arms rest within a few degrees of the horizontal and its legs within 12 degrees of the vertical (the
#: embedded body's with betas of +-3: arms 0, knees to 11.4), while an SMPL-named rig resting 25 degrees lower
#: (an avatar's A-pose) was read as if in the T-pose: every frame's arms 25 degrees too high.
LIMB_REST_MAX_DEGREES = {"elbow": 10.0, "wrist": 10.0, "knee": 15.0, "ankle": 15.0}
#: SMPL's T-pose bone directions (Y-up, +X the body's left), joint -> unit vector from its parent; limbs and spine.
_SMPL_BONES = {
    "left_knee": (0, -1, 0), "right_knee": (0, -1, 0), "left_ankle": (0, -1, 0), "right_ankle": (0, -1, 0),
    "spine2": (0, 1, 0), "spine3": (0, 1, 0), "neck": (0, 1, 0), "head": (0, 1, 0),
    "left_shoulder": (1, 0, 0), "right_shoulder": (-1, 0, 0), "left_elbow": (1, 0, 0), "right_elbow": (-1, 0, 0),
    "left_wrist": (1, 0, 0), "right_wrist": (-1, 0, 0),
}
#: The skeleton's leg length (hips to ankles, both legs' mean) in each unit tells it: (under this many, metres per
#: unit). An adult's legs are 0.7-1 m: inches 28-40, centimetres 70-100 (a child's 40 and more).
_UNITS = ((3.0, 1.0, "metres"), (38.0, 0.0254, "inches"), (300.0, 0.01, "centimetres"), (np.inf, 0.001, "millimetres"))


def _canonical(name: str) -> str:
    """A joint's name as `core.retarget.canonical` matches it ('m_avg_L_Hip', 'Left_hip': 'lhip'), palms as hands."""
    n = canonical(name)
    return _ALIASES.get(n, n)


_SMPL_INDEX = {_canonical(n): k for k, n in enumerate(SMPL_JOINT_NAMES)}


class Skeleton(NamedTuple):
    """A skeleton and its motion (a BVH's; an FBX's, a glTF's, an MVNX's: `formats.motion.read_rig`): joint
    `names`, `parents` (-1 for the root; parents first), `offsets` (J, 3) in its unit, `rotations` (T, J, 3, 3)
    each joint's from its rest (its channels composed), `root` (T, 3) the root's position, `frame_time` in
    seconds; `take`: the name of the animation read of an FBX or glTF of several, else None; `moving` (T, J, 3):
    each joint's offset per frame where joints' places move (a tree of joints a file keeps apart from the body's,
    attached to the root; hips animated under a floor joint; a BVH's position channels below its root), else
    None; `trees`: where a file keeps its joints in several trees, each joint's (the index of its tree's root),
    else () (`core.retarget.match_joints`); `rest_posed`: whether its rest is a pose the file happened to hold (a
    Blender FBX of an armature without its mesh), its bones then turned as a folded rig's are (`core.retarget`)."""

    names: list[str]
    parents: list[int]
    offsets: np.ndarray
    rotations: np.ndarray
    root: np.ndarray
    frame_time: float
    take: str | None = None
    moving: np.ndarray | None = None
    trees: tuple = ()
    rest_posed: bool = False


def read_skeleton(path: Path, src: str) -> Skeleton:
    """The skeleton and motion of the BVH `path`; InputError naming `src` for a file that is no BVH or a damaged
    one."""
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise InputError(f"{src}: cannot read it ({exc.strerror or exc})") from None
    text = raw.removeprefix(b"\xef\xbb\xbf").decode("latin-1")  # a UTF-8 byte-order mark some tools write
    head, *rest = re.split(r"^\s*MOTION\s*$", text, maxsplit=1, flags=re.MULTILINE)  # its own line
    motion = rest[0] if rest else ""
    tokens = head.split()
    if not tokens or tokens[0] != "HIERARCHY" or not rest:
        raise InputError(f"{src}: expected a BVH file (HIERARCHY, then MOTION), got "
                         f"{'no MOTION section' if tokens[:1] == ['HIERARCHY'] else 'a file that is not one'}")
    names, parents, offsets, channels = _hierarchy(tokens[1:], src)
    frames = re.search(r"^\s*Frames\s*:[ \t]*(\S*)", motion, flags=re.MULTILINE)
    timing = re.search(r"^\s*Frame\s+Time\s*:[ \t]*(\S*)", motion, flags=re.MULTILINE)
    if frames is None or timing is None:
        found = "neither" if frames is None and timing is None else "only 'Frames'" if timing is None else \
            "only 'Frame Time'"
        raise InputError(f"{src}: expected 'Frames: N' and 'Frame Time: S' (seconds per frame) after MOTION, found "
                         f"{found}")
    frames_text = frames.group(1)
    if not frames_text.isdigit():
        raise InputError(f"{src}: expected a whole number of frames after 'Frames:', got '{frames_text[:20]}'")
    n_frames, frame_time = int(frames_text), _number(timing.group(1), "Frame Time", src)
    if n_frames < 1:
        raise InputError(f"{src}: expected at least 1 frame after MOTION, got 'Frames: 0' (a skeleton exported "
                         f"without its animation?)")
    if not (np.isfinite(frame_time) and frame_time > 0):
        raise InputError(f"{src}: expected a Frame Time over 0 seconds, got {frame_time}")
    try:
        values = np.array(motion[max(frames.end(), timing.end()):].split(), dtype=np.float64)
    except ValueError:
        raise InputError(f"{src}: expected numbers in its frames, found text among them") from None
    width = sum(len(c) for c in channels)
    if values.size != n_frames * width:
        raise InputError(f"{src}: expected {n_frames} frames of {width} channel values ({n_frames * width}), got "
                         f"{values.size} values")
    rotations, root, moving = _channels(channels, offsets, values.reshape(n_frames, width))
    rate = _written_rate(frame_time, timing.group(1))
    return Skeleton(names, parents, offsets, rotations, root, frame_time if rate is None else 1.0 / rate,
                    moving=moving)


def _written_rate(frame_time: float, text: str) -> float | None:
    """The common rate (`core.motion.common_rate`) a Frame Time of a few digits stands for, or None: Blender's
    0.033333 and CMU's 0.0083333 are 30 and 120 fps (as read, 30.0003 fps lost the last frame of every bake at 30
    and moved every frame a little), where the rate's frame time rounds to the digits written, within 1.5 units of
    the last (0.03353438, 8 digits, is 29.82 fps, not 29.97: snapped, a minute's last frame moved by 0.3 s)."""
    rate = common_rate(1.0 / frame_time) if frame_time < 1.0 else None
    written = re.fullmatch(r"\+?\d*\.(\d+)", text)
    if rate is not None and written and abs(1.0 / rate - frame_time) > 1.5 * 10.0 ** -len(written.group(1)):
        return None
    return rate


def skeleton_arrays(skeleton: Skeleton, src: str) -> dict:
    """{'poses' (T, 24, 3) axis-angle, 'trans' (T, 3) metres, 'mocap_framerate', REST_UP_KEY where its rest
    skeleton stands along a world axis, TAKE_KEY} of a skeleton's motion (a BVH's, `read_skeleton`; an FBX's, a
    glTF's, an MVNX's): an SMPL skeleton's rotations as they are, any other humanoid's retargeted
    (`core.retarget`; InputError naming `src` for a skeleton that is no humanoid's)."""
    names, parents, offsets, rotations, root, frame_time = skeleton[:6]
    n_frames = len(rotations)
    smpl = _smpl_skeleton(names, parents, offsets, src)
    if smpl is None:
        poses, trans, up, said = retarget(names, parents, offsets, rotations, root, src, skeleton.moving,
                                          skeleton.trees, skeleton.rest_posed)
        log.info("%s: a rig of %d joints retargeted onto SMPL's skeleton (%s), %d frames at %.6g fps", src,
                 len(names), said, n_frames, 1.0 / frame_time)
    else:
        up = "y"  # SMPL's T-pose, Y up (`_smpl_skeleton`)
        unit, unit_name = _unit(offsets, smpl, src)
        poses = np.zeros((n_frames, len(SMPL_JOINT_NAMES), 3))
        for j, k in smpl.items():
            poses[:, k] = matrix_to_axis_angle(rotations[:, j])
        trans = (root - offsets[0]) * unit
        log.info("%s: an SMPL skeleton of %d joints in %s, %d frames at %.6g fps", src, len(names), unit_name,
                 n_frames, 1.0 / frame_time)
    arrays = {"poses": poses.astype(np.float32), "trans": trans.astype(np.float32),
              "mocap_framerate": np.float64(1.0 / frame_time)}
    if up is not None:
        arrays[REST_UP_KEY] = np.str_(up)
    if skeleton.take is not None:
        arrays[TAKE_KEY] = np.str_(skeleton.take)
    return arrays


def _channels(channels: list[list[str]], offsets: np.ndarray, values: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """(T, J, 3, 3) each joint's rotation from its rest (its rotation channels composed in their order), (T, 3)
    the root's position (its position channels; its OFFSET where it has none), and (T, J, 3) each joint's
    position from its parent where another joint's position channels move it from its OFFSET (exporters that
    write positions on every joint; a stretching limb), else None."""
    n_frames = len(values)
    rotations = np.empty((n_frames, len(channels), 3, 3))
    root = np.broadcast_to(offsets[0], (n_frames, 3)).copy()
    moving = None
    start = 0
    for j, chans in enumerate(channels):
        block = values[:, start:start + len(chans)]
        start += len(chans)
        R = np.broadcast_to(np.eye(3), (n_frames, 3, 3))
        for c, name in enumerate(chans):
            if name.endswith("rotation"):  # about the channel's axis, by its degrees
                R = R @ axis_angle_to_matrix(np.radians(block[:, c])[:, None] * np.eye(3)["xyz".index(name[0])])
            elif j == 0:
                root[:, "xyz".index(name[0])] = block[:, c]
            elif not np.allclose(block[:, c], offsets[j, "xyz".index(name[0])], rtol=1e-6, atol=1e-6):
                if moving is None:
                    moving = np.broadcast_to(offsets, (n_frames,) + offsets.shape).copy()
                moving[:, j, "xyz".index(name[0])] = block[:, c]
        rotations[:, j] = R
    return rotations, root, moving


def _number(text: str, what: str, src: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise InputError(f"{src}: expected a number for {what}, got '{text[:20]}'") from None


def _hierarchy(tokens: list[str], src: str):
    """(names, parents, offsets (J, 3), channel names per joint) of the HIERARCHY's tokens."""
    names, parents, offsets, channels = [], [], [], []
    stack: list[int] = []  # open joints (-1: an End Site)
    i = 0
    try:
        while i < len(tokens):
            tok = tokens[i]
            if tok in ("ROOT", "JOINT"):
                if (tok == "ROOT") == bool(names):  # a second ROOT, or a JOINT before one
                    raise InputError(f"{src}: expected one ROOT, then JOINTs, got {tok} '{tokens[i + 1]}' "
                                     f"{'after' if names else 'before'} the ROOT")
                brace = tokens.index("{", i + 1)  # a name may hold spaces ('Bip01 L Thigh')
                names.append(" ".join(tokens[i + 1:brace]))
                parents.append(stack[-1] if stack else -1)
                offsets.append(np.zeros(3))
                channels.append([])
                stack.append(len(names) - 1)
                i = brace + 1
            elif tok == "End":
                stack.append(-1)
                i += 3  # "Site", "{"
            elif tok == "OFFSET":
                if stack[-1] >= 0:
                    offsets[stack[-1]] = np.array([_number(t, "OFFSET", src) for t in tokens[i + 1:i + 4]])
                i += 4
            elif tok == "CHANNELS":
                n = int(tokens[i + 1])
                chans = [t.lower() for t in tokens[i + 2:i + 2 + n]]
                bad = [t for t in chans if t not in {a + k for a in "xyz" for k in ("position", "rotation")}]
                if bad:
                    raise InputError(f"{src}: expected channels such as Xposition or Zrotation, got '{bad[0]}'")
                channels[stack[-1]] = chans
                i += 2 + n
            elif tok == "}":
                stack.pop()
                i += 1
            else:
                raise InputError(f"{src}: expected ROOT, JOINT, End Site, OFFSET, CHANNELS or a brace in its "
                                 f"HIERARCHY, got '{tok[:30]}'")
    except InputError:
        raise
    except (IndexError, ValueError):
        raise InputError(f"{src}: its HIERARCHY ends early or is malformed (near joint "
                         f"'{names[-1] if names else '?'}')") from None
    if not names or stack:
        raise InputError(f"{src}: expected a HIERARCHY of joints with balanced braces, got "
                         f"{'no joint' if not names else f'{len(stack)} unclosed'}")
    return names, parents, np.array(offsets), channels


def _smpl_skeleton(names: list[str], parents: list[int], offsets: np.ndarray, src: str) -> dict[int, int] | None:
    """{BVH joint: SMPL joint} where the skeleton is SMPL's: its 22 body joints by SMPL's names, in SMPL's hierarchy,
    resting in SMPL's T-pose (the spine within REST_MAX_DEGREES, arms and legs LIMB_REST_MAX_DEGREES); None for any
    other (retargeted). Joints SMPL lacks (fingers, a jaw) are left out, with a warning."""
    smpl = {}
    for j, name in enumerate(names):
        k = _SMPL_INDEX.get(_canonical(name))
        if k is not None and k not in smpl.values():
            smpl[j] = k
    back = {k: j for j, k in smpl.items()}
    if any(k not in back for k in range(N_BODY_JOINTS)) or back[0] != 0:
        return None
    if any(k and parents[j] != back.get(SMPL_PARENTS[k]) for j, k in smpl.items()):
        return None
    for joint, direction in _SMPL_BONES.items():
        bone = offsets[back[SMPL_JOINT_NAMES.index(joint)]]
        norm = np.linalg.norm(bone)
        limit = LIMB_REST_MAX_DEGREES.get(joint.split("_")[-1], REST_MAX_DEGREES)
        if norm and np.degrees(np.arccos(np.clip(bone @ np.array(direction) / norm, -1, 1))) > limit:
            return None
    others = [n for j, n in enumerate(names) if j not in smpl]
    if others:
        log.warning("%s: %d joint(s) SMPL's body lacks left at rest (%s%s)", src, len(others),
                    ", ".join(others[:5]), ", ..." if len(others) > 5 else "")
    return smpl


def _unit(offsets, smpl, src) -> tuple[float, str]:
    """(metres per unit, its name) told by the legs' length (`_UNITS`)."""
    back = {k: j for j, k in smpl.items()}
    legs = np.mean([sum(np.linalg.norm(offsets[back[SMPL_JOINT_NAMES.index(f"{side}_{part}")]])
                        for part in ("knee", "ankle")) for side in ("left", "right")])
    if not (np.isfinite(legs) and legs > 0):
        raise InputError(f"{src}: expected legs of some length in its OFFSETs, got {legs}")
    unit, name = next((unit, name) for limit, unit, name in _UNITS if legs < limit)
    return unit, name
