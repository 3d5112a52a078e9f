"""Xsens MVN motion capture (`.mvnx`: MVN Analyze's and MVN Animate's XML export; the Nymeria dataset's body
motion), read as the skeleton and motion `core.retarget` turns into SMPL's, as an FBX is (`formats.fbx`).

An MVNX holds, per frame, every segment's orientation (a unit quaternion, w first, from the segment's frame to the
world's) and position (metres, the world Z-up) of Xsens' body model: 23 segments (Pelvis, L5, L3, T12, T8, Neck,
Head, each side's Shoulder, UpperArm, ForeArm, Hand, UpperLeg, LowerLeg, Foot, Toe) whose hierarchy is the
model's own (`XSENS_PARENTS`, by label; a glove's finger segments, listed apart, are left out). Its frames of
type "normal" are the motion, at the subject's frameRate; its "tpose" frame (else its "identity" frame, else its
first) is the rest. The file is read as a stream
(`xml.etree.ElementTree.iterparse`), its frames' text parsed in bulk.
"""

from __future__ import annotations

import logging
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from core.errors import InputError
from core.rotations import quat_to_matrix
from formats.bvh import Skeleton
from formats.fbx import MAX_FRAMES, skeleton_of

log = logging.getLogger(__name__)

#: Each segment of Xsens' body model by label, and the segment it hangs from (None: the root).
XSENS_PARENTS = {"Pelvis": None, "L5": "Pelvis", "L3": "L5", "T12": "L3", "T8": "T12", "Neck": "T8", "Head": "Neck",
                 **{f"{side}{seg}": f"{side}{up}" if up else parent
                    for side in ("Right", "Left")
                    for seg, up, parent in (("Shoulder", None, "T8"), ("UpperArm", "Shoulder", None),
                                            ("ForeArm", "UpperArm", None), ("Hand", "ForeArm", None),
                                            ("UpperLeg", None, "Pelvis"), ("LowerLeg", "UpperLeg", None),
                                            ("Foot", "LowerLeg", None), ("Toe", "Foot", None))}}


#: The element listing a glove's finger segments (MVN's finger tracking: fingerTrackingSegmentsLeft, ...Right),
#: whose data each frame holds apart from the body's (orientationFingersLeft, ...).
FINGER_SEGMENTS = "fingerTrackingSegments"


def _tag(element) -> str:
    return element.tag.rsplit("}", 1)[-1]  # the namespace ('{http://www.xsens.com/mvn/mvnx}frame') left out


def read_mvnx(path: Path, src: str) -> Skeleton:
    """The skeleton and motion of the MVNX `path` (module docstring); InputError naming `src` for a file that is
    no MVNX, a damaged one, or one whose segments are not Xsens' body model's."""
    labels: list[str] = []
    pending: list[str] = []  # the segments of the list being read
    fingers = 0
    rate = None
    rest: dict[str, tuple[str, str]] = {}
    orientations: list[str] = []
    positions: list[str] = []
    try:
        for _, element in ET.iterparse(path, events=("end",)):
            tag = _tag(element)
            if tag == "segment" and element.get("label"):
                pending.append(element.get("label"))
            elif tag == "segments":  # the body's; a glove's fingers are listed apart (`FINGER_SEGMENTS`)
                labels += pending
                pending = []
            elif tag.startswith(FINGER_SEGMENTS):
                fingers += len(pending)
                pending = []
            elif tag == "subject":
                rate = element.get("frameRate")
            elif tag == "frame":
                parts = {_tag(child): child.text or "" for child in element}
                kind = element.get("type", "normal")
                if kind == "normal":
                    orientations.append(parts.get("orientation", ""))
                    positions.append(parts.get("position", ""))
                    if len(orientations) > MAX_FRAMES:
                        raise InputError(f"{src}: expected at most {MAX_FRAMES:,} frames, got more")
                elif "orientation" in parts and "position" in parts:
                    rest.setdefault(kind, (parts["orientation"], parts["position"]))
                element.clear()
    except InputError:
        raise
    except (ET.ParseError, LookupError, ValueError) as exc:  # LookupError: an encoding the XML names is unknown
        raise InputError(f"{src}: its MVNX (XML) is damaged ({exc})") from None
    except OSError as exc:
        raise InputError(f"{src}: cannot read it ({exc.strerror or exc})") from None
    labels = labels or pending  # segments outside a <segments> list
    if not labels:
        raise InputError(f"{src}: expected an Xsens MVNX (segments and frames), found no segments")
    if fingers:
        log.warning("%s: its %d finger segments (finger tracking) left out: the body's hands are read, its fingers "
                    "rest", src, fingers)
    missing = [s for s in XSENS_PARENTS if s not in labels]
    if missing:
        raise InputError(f"{src}: expected the segments of Xsens' body model, found none named "
                         f"{', '.join(missing[:4])}{', ...' if len(missing) > 4 else ''} (it has "
                         f"{', '.join(labels[:4])}{', ...' if len(labels) > 4 else ''})")
    try:
        fps = float(rate)
    except (TypeError, ValueError):
        raise InputError(f"{src}: expected a frameRate on its subject, got {rate!r}") from None
    if not (np.isfinite(fps) and fps > 0):
        raise InputError(f"{src}: expected a frameRate over 0, got {fps:g}")
    if not orientations:
        raise InputError(f"{src}: expected frames of type 'normal' (the motion), found none")
    S = len(labels)
    quats = _values(orientations, S, 4, "orientation", src)
    places = _values(positions, S, 3, "position", src)
    kind = next((k for k in ("tpose", "identity") if k in rest), None)
    rest_q, rest_p = ((_values([rest[kind][0]], S, 4, "orientation", src)[0],
                       _values([rest[kind][1]], S, 3, "position", src)[0]) if kind else (quats[0], places[0]))
    index = {label: k for k, label in enumerate(labels)}
    world, rest_m = {}, {}
    for label, k in index.items():
        world[k] = _transforms(quats[:, k], places[:, k])
        rest_m[k] = _transforms(rest_q[None, k], rest_p[None, k])[0]
    joints = [index[s] for s in XSENS_PARENTS]
    parent = {index[s]: index[p] for s, p in XSENS_PARENTS.items() if p is not None}
    order = joints  # XSENS_PARENTS lists parents first
    return skeleton_of(joints, {k: labels[k] for k in joints}, parent, order, world, rest_m, 1.0 / fps)


def _values(texts: list[str], segments: int, width: int, what: str, src: str) -> np.ndarray:
    """(T, segments, width) float64 of the frames' `what` texts (whitespace-separated numbers)."""
    try:
        flat = np.array(" ".join(texts).split(), dtype=np.float64)
    except ValueError:
        raise InputError(f"{src}: expected numbers in its frames' {what}, found text among them") from None
    if flat.size != len(texts) * segments * width:
        raise InputError(f"{src}: expected {segments * width} {what} values in each of its {len(texts)} frames, "
                         f"got {flat.size} in all")
    if not np.isfinite(flat).all():
        raise InputError(f"{src}: expected finite {what} values, found NaN or infinity")
    return flat.reshape(len(texts), segments, width)


def _transforms(q: np.ndarray, p: np.ndarray) -> np.ndarray:
    """(T, 4, 4) transforms of (T, 4) quaternions w x y z and (T, 3) positions."""
    out = np.broadcast_to(np.eye(4), (len(q), 4, 4)).copy()
    out[:, :3, :3] = quat_to_matrix(q)
    out[:, :3, 3] = p
    return out
