"""BVH motion capture of an SMPL skeleton (as SMPL motions exported to BVH are: smpl2bvh, SMPL's Blender add-on):
read as the arrays `formats.motion.load_motion` reads.

Joints are matched to SMPL's by name, in its naming variants ('Left_hip', 'L_Hip', 'left_hip', 'm_avg_L_Hip';
'L_Palm' or 'L_Hand' for the hands), and must keep SMPL's hierarchy; their rest pose (the OFFSETs) must be SMPL's
T-pose, since a BVH rotation turns a joint from its rest: a skeleton of another rig (Mixamo's, CMU's) needs
retargeting and is refused naming what differs. Rotation channels compose in the order listed (Zrotation
Yrotation Xrotation: R = Rz Ry Rx); the unit is told by the skeleton's legs (metres, centimetres, inches or
millimetres); the root's position less its OFFSET (the rest pelvis SMPL exporters write there) is the
translation. The world is the BVH's own (SMPL's Y-up as exported: --motion-up y).
"""

from __future__ import annotations

import logging
import re
from pathlib import Path

import numpy as np

from core.body import N_BODY_JOINTS, SMPL_JOINT_NAMES, SMPL_PARENTS
from core.errors import InputError
from core.rotations import axis_angle_to_matrix, matrix_to_axis_angle

log = logging.getLogger(__name__)

#: Prefixes of SMPL joint names in exported rigs (SMPL's Blender/Unity models: m_avg_, f_avg_).
_NAME_PREFIXES = ("m_avg_", "f_avg_", "smpl_", "smplx_")
#: Other names of SMPL's joints after `_canonical` (the hands as palms).
_ALIASES = {"lpalm": "lhand", "rpalm": "rhand"}
#: A rest bone further than this from SMPL's T-pose bone (degrees) is another rest pose: refused.
REST_MAX_DEGREES = 30.0
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
    n = name.lower()
    for prefix in _NAME_PREFIXES:
        if n.startswith(prefix):
            n = n[len(prefix):]
    n = re.sub(r"[^a-z0-9]", "", n)
    n = re.sub(r"^left", "l", n)
    n = re.sub(r"^right", "r", n)
    return _ALIASES.get(n, n)


_SMPL_INDEX = {_canonical(n): k for k, n in enumerate(SMPL_JOINT_NAMES)}


def read_bvh(path: Path, src: str) -> dict:
    """{'poses' (T, 24, 3) axis-angle, 'trans' (T, 3) metres, 'mocap_framerate'} of the BVH `path` (module
    docstring); InputError naming `src` for a file that is no BVH, a damaged one, or a skeleton that is not SMPL's."""
    try:
        text = path.read_text(encoding="latin-1")
    except OSError as exc:
        raise InputError(f"{src}: cannot read it ({exc.strerror or exc})") from None
    head, *rest = re.split(r"^\s*MOTION\s*$", text, maxsplit=1, flags=re.MULTILINE)  # its own line
    motion = rest[0] if rest else ""
    tokens = head.split()
    if not tokens or tokens[0] != "HIERARCHY" or not rest:
        raise InputError(f"{src}: expected a BVH file (HIERARCHY, then MOTION), got "
                         f"{'no MOTION section' if tokens[:1] == ['HIERARCHY'] else 'a file that is not one'}")
    names, parents, offsets, channels = _hierarchy(tokens[1:], src)
    rates = re.search(r"Frames:\s*(\d+)\s+Frame\s+Time:\s*(\S+)", motion)
    if rates is None:
        raise InputError(f"{src}: expected 'Frames: N' and 'Frame Time: S' after MOTION, found neither")
    n_frames, frame_time = int(rates.group(1)), _number(rates.group(2), "Frame Time", src)
    try:
        values = np.array(motion[rates.end():].split(), dtype=np.float64)
    except ValueError:
        raise InputError(f"{src}: expected numbers in its frames, found text among them") from None
    width = sum(len(c) for c in channels)
    if n_frames < 1 or values.size != n_frames * width:
        raise InputError(f"{src}: expected {n_frames} frames of {width} channel values ({n_frames * width}), got "
                         f"{values.size} values")
    if not (np.isfinite(frame_time) and frame_time > 0):
        raise InputError(f"{src}: expected a Frame Time over 0 seconds, got {frame_time}")
    values = values.reshape(n_frames, width)
    smpl = _match_smpl(names, parents, src)
    unit, unit_name = _unit(names, offsets, smpl, src)
    _check_rest(names, offsets, smpl, src)
    poses = np.zeros((n_frames, len(SMPL_JOINT_NAMES), 3))
    trans = np.zeros((n_frames, 3))
    start = 0
    for j, chans in enumerate(channels):
        block = values[:, start:start + len(chans)]
        start += len(chans)
        if j not in smpl:
            continue
        R = np.broadcast_to(np.eye(3), (n_frames, 3, 3))
        for c, name in enumerate(chans):
            if name.endswith("rotation"):  # about the channel's axis, by its degrees
                R = R @ axis_angle_to_matrix(np.radians(block[:, c])[:, None] * np.eye(3)["xyz".index(name[0])])
            elif j == 0 and name.endswith("position"):
                trans[:, "xyz".index(name[0])] = (block[:, c] - offsets[0]["xyz".index(name[0])]) * unit
        poses[:, smpl[j]] = matrix_to_axis_angle(R)
    log.info("%s: an SMPL skeleton of %d joints in %s, %d frames at %.6g fps", src, len(names), unit_name, n_frames,
             1.0 / frame_time)
    return {"poses": poses.astype(np.float32), "trans": trans.astype(np.float32),
            "mocap_framerate": np.float64(1.0 / frame_time)}


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
                names.append(tokens[i + 1])
                parents.append(stack[-1] if stack else -1)
                offsets.append(np.zeros(3))
                channels.append([])
                stack.append(len(names) - 1)
                i += 3  # name, "{"
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


def _match_smpl(names: list[str], parents: list[int], src: str) -> dict[int, int]:
    """{BVH joint: SMPL joint} by name; InputError where SMPL's 22 body joints are not all there, or are not
    in SMPL's hierarchy. Joints SMPL lacks (fingers, a jaw) are left out, with a warning."""
    smpl = {}
    for j, name in enumerate(names):
        k = _SMPL_INDEX.get(_canonical(name))
        if k is not None and k not in smpl.values():
            smpl[j] = k
    missing = [SMPL_JOINT_NAMES[k] for k in range(N_BODY_JOINTS) if k not in smpl.values()]
    if missing:
        raise InputError(f"{src}: expected the joints of an SMPL skeleton (pelvis, left_hip, ... by name), lacks "
                         f"{len(missing)} of its 22 body joints ({', '.join(missing[:4])}"
                         f"{', ...' if len(missing) > 4 else ''}; it has {', '.join(names[:4])}, ...): a capture of "
                         f"another rig needs retargeting to SMPL first")
    back = {k: j for j, k in smpl.items()}
    if back[0] != 0:
        raise InputError(f"{src}: expected the pelvis as the ROOT, got '{names[0]}'")
    for j, k in smpl.items():
        if k and parents[j] != back.get(SMPL_PARENTS[k]):
            found = names[parents[j]] if parents[j] >= 0 else "none"
            raise InputError(f"{src}: expected SMPL's hierarchy, got joint '{names[j]}' under '{found}' (SMPL: under "
                             f"'{SMPL_JOINT_NAMES[SMPL_PARENTS[k]]}')")
    others = [n for j, n in enumerate(names) if j not in smpl]
    if others:
        log.warning("%s: %d joint(s) SMPL's body lacks left at rest (%s%s)", src, len(others),
                    ", ".join(others[:5]), ", ..." if len(others) > 5 else "")
    return smpl


def _unit(names, offsets, smpl, src) -> tuple[float, str]:
    """(metres per unit, its name) told by the legs' length (`_UNITS`)."""
    back = {k: j for j, k in smpl.items()}
    legs = np.mean([sum(np.linalg.norm(offsets[back[SMPL_JOINT_NAMES.index(f"{side}_{part}")]])
                        for part in ("knee", "ankle")) for side in ("left", "right")])
    if not (np.isfinite(legs) and legs > 0):
        raise InputError(f"{src}: expected legs of some length in its OFFSETs, got {legs}")
    unit, name = next((unit, name) for limit, unit, name in _UNITS if legs < limit)
    return unit, name


def _check_rest(names, offsets, smpl, src) -> None:
    """InputError where a limb's or the spine's rest bone is over REST_MAX_DEGREES from SMPL's T-pose."""
    back = {k: j for j, k in smpl.items()}
    worst = (0.0, "")
    for joint, direction in _SMPL_BONES.items():
        bone = offsets[back[SMPL_JOINT_NAMES.index(joint)]]
        norm = np.linalg.norm(bone)
        if norm == 0:
            continue
        angle = float(np.degrees(np.arccos(np.clip(bone @ np.array(direction) / norm, -1, 1))))
        worst = max(worst, (angle, joint))
    if worst[0] > REST_MAX_DEGREES:
        raise InputError(f"{src}: expected the rest pose of SMPL (a T-pose, Y up), got its {worst[1]} bone "
                         f"{worst[0]:.0f} degrees from it (an A-pose, or another up axis?): its rotations would "
                         f"turn SMPL's joints from another rest; retarget it to SMPL first")
