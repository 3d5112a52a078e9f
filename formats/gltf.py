"""glTF 2.0 animation of a humanoid skeleton (`.glb`, `.gltf`: Blender's, three.js', Ready Player Me's, VRoid's
exports), read as the skeleton and motion `core.retarget` turns into SMPL's, as an FBX is (`formats.fbx`).

The file's JSON (a .glb's first chunk, its second the binary buffer; a .gltf's buffers embedded as base64 data
URIs or in files beside it) is read here, with no library: the skeleton's joints are its largest skin's (a file
of no skin, a VRM Animation's or an armature exported without its mesh: the nodes from its hips down), their
hierarchy the nodes' children; each node's transform its matrix or its translation, rotation (a unit quaternion,
x y z w) and scale, animated by one animation's channels (a take: the first, or the one `--take` names; a
channel's target its node and path, or a KHR_animation_pointer to them),
sampled at the rate its keys are spaced by (30 fps where that is unclear) with their interpolation (LINEAR: a
quaternion's slerp, STEP, CUBICSPLINE's Hermite curves); the rest pose is the skin's bind pose (its inverse
bind matrices: a file saved with its character posed, as game characters are, holding a weapon, stands in that
pose in its nodes), else the nodes' own transforms (a VRM Animation's T-pose). glTF is Y-up in metres;
`core.retarget` reads the rest's world and the legs' unit as for any rig. A file of neither a skin nor hips is
refused in one line; one of no animation is one frame of its rest, warned.
"""

from __future__ import annotations

import base64
import json
import logging
import re
import struct
from pathlib import Path
from urllib.parse import unquote

import numpy as np

from core.errors import InputError, read_input
from core.motion import COMMON_RATES, common_rate
from core.retarget import PELVIS_NAMES, canonical, role_names
from core.rotations import quat_slerp, quat_to_matrix
from formats.bvh import Skeleton
from formats.fbx import MAX_FRAMES, chosen_take, node_depths, skeleton_of

log = logging.getLogger(__name__)

#: glTF files: VRM avatars (.vrm) and VRM Animation (.vrma) are glTF binaries too.
GLTF_SUFFIXES = (".glb", ".gltf", ".vrm", ".vrma")
#: VRM's humanoid bones (VRMC_vrm_animation, VRMC_vrm, VRM 0.x) by the names `core.retarget` matches (Mixamo's):
#: a file that maps its nodes to them is matched by that map, whatever its nodes are called.
VRM_BONES = {"hips": "Hips", "neck": "Neck", "head": "Head",
             **{f"{side}{bone}": f"{side.title()}{name}" for side in ("left", "right")
                for bone, name in (("UpperLeg", "UpLeg"), ("LowerLeg", "Leg"), ("Foot", "Foot"), ("Toes", "ToeBase"),
                                   ("Shoulder", "Shoulder"), ("UpperArm", "Arm"), ("LowerArm", "ForeArm"),
                                   ("Hand", "Hand"))}}
_GLB_MAGIC = b"glTF"
_JSON_CHUNK, _BIN_CHUNK = 0x4E4F534A, 0x004E4942
_COMPONENTS = {5120: "<i1", 5121: "<u1", 5122: "<i2", 5123: "<u2", 5125: "<u4", 5126: "<f4"}
_WIDTHS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
#: The frame rate of a file whose keys tell none (one key, or keys at uneven times).
DEFAULT_FPS = 30.0
#: A sample time within this share of a key spacing of a key is the key's (float32 key times 300 s into a clip
#: are 3e-5 s apart from their frames' times: 1e-3 of a 30 fps spacing).
_SNAP = 2e-3
#: Keys more sparse (fps) are sampled between them (`cubic_rate`): a cubic curve's shape, a linear or step
#: channel's keys seconds apart or at uneven times.
MIN_CUBIC_FPS = 24.0


def gltf_document(path: Path, src: str) -> tuple[dict, list[bytes]]:
    """(the JSON document, its buffers' bytes) of the .glb or .gltf `path`; InputError naming `src` for a file
    that is no glTF 2.0, a damaged one, or a buffer that cannot be read."""
    data = read_input(path, src)
    binary = None
    try:
        if data[:4] == _GLB_MAGIC:
            version, _ = struct.unpack_from("<II", data, 4)
            if version != 2:
                raise InputError(f"{src}: expected glTF 2.0, got a glTF {version} binary: export it again as glTF 2")
            at, chunks = 12, {}
            while at + 8 <= len(data):
                size, kind = struct.unpack_from("<II", data, at)
                chunks.setdefault(kind, data[at + 8:at + 8 + size])
                at += 8 + size
            doc = json.loads(chunks[_JSON_CHUNK].decode("utf-8"))
            binary = chunks.get(_BIN_CHUNK)
        elif data.lstrip()[:1] == b"{":
            doc = json.loads(data.decode("utf-8"))
        else:
            raise InputError(f"{src}: expected a glTF file (.glb binary or .gltf JSON), got a file that is not one")
    except InputError:
        raise
    except (KeyError, ValueError, UnicodeDecodeError, struct.error) as exc:
        raise InputError(f"{src}: its glTF is damaged or cut short ({type(exc).__name__})") from None
    if not isinstance(doc, dict):
        raise InputError(f"{src}: expected a glTF document (a JSON object), got a JSON {type(doc).__name__}")
    version = str(doc.get("asset", {}).get("version", "2"))
    if not version.startswith("2"):
        raise InputError(f"{src}: expected glTF 2.0, got asset version {version!r}")
    buffers = []
    for k, buffer in enumerate(doc.get("buffers", [])):
        uri = buffer.get("uri")
        if uri is None:
            if binary is None:
                raise InputError(f"{src}: its buffer {k} has no data (no .glb binary chunk)")
            buffers.append(binary)
        elif uri.startswith("data:"):
            try:
                buffers.append(base64.b64decode(uri.split(",", 1)[1]))
            except (ValueError, IndexError):
                raise InputError(f"{src}: its buffer {k}'s data URI is damaged (no base64 after 'data:...,')") \
                    from None
        else:
            beside = Path(path).parent / unquote(uri)  # a URI: 'my%20take.bin' names 'my take.bin'
            try:
                buffers.append(beside.read_bytes())
            except OSError as exc:
                raise InputError(f"{src}: cannot read its buffer '{uri}' beside it ({exc.strerror or exc})") \
                    from None
    return doc, buffers


def _accessor(doc: dict, buffers: list[bytes], index: int) -> np.ndarray:
    """(count, width) float64 values of accessor `index` (normalized integers as glTF maps them to [-1, 1] or
    [0, 1]; a sparse accessor's substitutions applied)."""
    acc = doc["accessors"][index]
    dtype = np.dtype(_COMPONENTS[acc["componentType"]])
    width, count = _WIDTHS[acc["type"]], int(acc["count"])

    def view(view_index: int, offset: int, n: int, dt: np.dtype, w: int) -> np.ndarray:
        bv = doc["bufferViews"][view_index]
        raw = buffers[bv.get("buffer", 0)]
        start = bv.get("byteOffset", 0) + offset
        stride = bv.get("byteStride") or dt.itemsize * w
        if n and start + stride * (n - 1) + dt.itemsize * w > len(raw):
            raise ValueError("accessor beyond its buffer")
        return np.ndarray((n, w), dtype=dt, buffer=raw, offset=start, strides=(stride, dt.itemsize)).copy()

    values = (view(acc["bufferView"], acc.get("byteOffset", 0), count, dtype, width) if "bufferView" in acc
              else np.zeros((count, width), dtype))
    sparse = acc.get("sparse")
    if sparse:
        idx = sparse["indices"]
        at = view(idx["bufferView"], idx.get("byteOffset", 0), int(sparse["count"]),
                  np.dtype(_COMPONENTS[idx["componentType"]]), 1)[:, 0]
        val = sparse["values"]
        values[at.astype(np.int64)] = view(val["bufferView"], val.get("byteOffset", 0), int(sparse["count"]),
                                           dtype, width)
    out = values.astype(np.float64)
    if acc.get("normalized") and dtype.kind in "iu":
        top = float(np.iinfo(dtype).max)
        out = np.maximum(out / top, -1.0)
    return out


def sampled_keys(times: np.ndarray, values: np.ndarray, interpolation: str, t: np.ndarray, rotation: bool
             ) -> np.ndarray:
    """(T, width) a channel's values at times `t` (held beyond its first and last keys)."""
    if interpolation == "CUBICSPLINE":  # per key: in-tangent, value, out-tangent
        tangents_in, keys, tangents_out = values[0::3], values[1::3], values[2::3]
    else:
        keys = values
    if len(times) == 1:
        return np.broadcast_to(keys[0], (len(t), keys.shape[1])).copy()
    k = np.clip(np.searchsorted(times, t, side="right") - 1, 0, len(times) - 2)
    span = times[k + 1] - times[k]
    s = np.clip((t - times[k]) / np.where(span > 0, span, 1.0), 0.0, 1.0)[:, None]
    s = np.where(s < _SNAP, 0.0, np.where(s > 1.0 - _SNAP, 1.0, s))  # a frame on a key its float32 time missed
    a, b = keys[k], keys[k + 1]
    if interpolation == "STEP":
        return np.where(s >= 1.0, b, a)
    if interpolation == "CUBICSPLINE":
        s2, s3, dt = s * s, s * s * s, span[:, None]
        out = ((2 * s3 - 3 * s2 + 1) * a + (s3 - 2 * s2 + s) * dt * tangents_out[k]
               + (-2 * s3 + 3 * s2) * b + (s3 - s2) * dt * tangents_in[k + 1])
        if not rotation:
            return out
        # A span whose keys' quaternions lie in opposite hemispheres (Blender 4.2's export writes some, its
        # tangents across them tens of units long) is slerped: its curve swings through other turns.
        flipped = np.sum(a * b, axis=1) < 0
        if not flipped.any():
            return out
    if rotation:  # slerp along the shorter arc (of the keys made unit: quantized ones are near it)
        a = a / np.maximum(np.linalg.norm(a, axis=1, keepdims=True), 1e-12)
        b = b / np.maximum(np.linalg.norm(b, axis=1, keepdims=True), 1e-12)
        slerped = quat_slerp(a, b, s[:, 0])
        return slerped if interpolation != "CUBICSPLINE" else np.where(flipped[:, None], slerped, out)
    return (1 - s) * a + s * b


def _channel_target(target: dict) -> tuple[int | None, str | None]:
    """(node, 'translation' | 'rotation' | 'scale') a channel animates, else (None, None): its target's node and
    path, or a KHR_animation_pointer's JSON pointer ('/nodes/3/rotation', as Blender 4.2's exporter writes them
    with "Convert TRS/weights to Animation Pointer")."""
    path, node = target.get("path"), target.get("node")
    if path == "pointer":
        pointer = ((target.get("extensions") or {}).get("KHR_animation_pointer") or {}).get("pointer")
        found = re.fullmatch(r"/nodes/(\d+)/(translation|rotation|scale)", pointer if isinstance(pointer, str) else "")
        node, path = (int(found[1]), found[2]) if found else (None, None)
    if path not in ("translation", "rotation", "scale") or node is None:
        return None, None
    return int(node), path


def _vrm_roles(doc: dict) -> dict[int, str]:
    """{node: the name `core.retarget` knows its role by} of a VRM file's humanoid map (VRM Animation's, VRM 1's
    {bone: {"node": i}}, VRM 0's [{"bone", "node"}]), else {}."""
    extensions = doc.get("extensions") or {}
    for key in ("VRMC_vrm_animation", "VRMC_vrm", "VRM"):
        bones = ((extensions.get(key) or {}).get("humanoid") or {}).get("humanBones")
        if isinstance(bones, dict):
            pairs = [(bone, entry.get("node")) for bone, entry in bones.items() if isinstance(entry, dict)]
        elif isinstance(bones, list):
            pairs = [(entry.get("bone"), entry.get("node")) for entry in bones if isinstance(entry, dict)]
        else:
            continue
        return {int(node): VRM_BONES[bone] for bone, node in pairs if bone in VRM_BONES and isinstance(node, int)}
    return {}


def key_rate(inputs: list[np.ndarray]) -> float:
    """The rate the animation's keys are spaced by: the median spacing of its most keyed channel, snapped to a
    common rate within 0.5 % (else its own, to the millisecond); DEFAULT_FPS where no channel has two keys."""
    dense = max(inputs, key=len, default=np.zeros(1))
    steps = np.diff(dense)
    steps = steps[steps > 1e-9]
    if not len(steps):
        return DEFAULT_FPS
    fps = 1.0 / float(np.median(steps))
    near = common_rate(fps)
    return near if near is not None else round(fps, 3) if fps >= 1.0 else fps  # keys seconds apart: not 0


#: The highest common rate `cubic_rate` samples sparse cubic curves at (capture systems' rates beyond it are
#: no keyframe animation's).
CUBIC_MAX_FPS = 120.0


def cubic_rate(fps: float) -> float:
    """The rate to sample cubic curves keyed at `fps` at: their own from MIN_CUBIC_FPS up, else the first of
    DEFAULT_FPS and the common rates over it of which their keys' rate divides a whole number (a hand-keyed
    curve's key every 10 frames of 30: 30), else DEFAULT_FPS. Sampled at their keys, the curves between them
    were lost to the slerps a bake resamples with (Blender's glTF export of a walk keyed every 10 frames: 8
    degrees off its own curves)."""
    if fps >= MIN_CUBIC_FPS:
        return fps
    for rate in (DEFAULT_FPS, *sorted(r for r in COMMON_RATES if r <= CUBIC_MAX_FPS)):
        ratio = rate / fps
        if rate >= MIN_CUBIC_FPS and abs(ratio - round(ratio)) < 1e-3 * ratio:
            return rate
    return DEFAULT_FPS


def key_times(inputs: list[np.ndarray], src: str, per_second: float = 1.0, what: str = "keys", cubic: bool = False
              ) -> tuple[np.ndarray, float]:
    """(the times of the frames, frames per second) of an animation's channels' key times `inputs` (in units
    `per_second` a second: seconds, or USD's time codes): spaced at `key_rate`, from the first key to the last
    (the last frame at or past it: keys at uneven times lost the last); keys sparser than MIN_CUBIC_FPS (hand-keyed
    poses seconds apart, refused as a rate under 1 Hz; keys at uneven times, read at their median spacing) sampled
    at `cubic_rate` whatever their interpolation (cubic: glTF's CUBICSPLINE, its curves between the keys).
    InputError naming `src` for more than MAX_FRAMES frames."""
    fps = key_rate([i / per_second for i in inputs])
    if cubic or fps < MIN_CUBIC_FPS:
        fps = cubic_rate(fps)
    start, stop = min(float(i[0]) for i in inputs), max(float(i[-1]) for i in inputs)
    n = int(np.ceil((stop - start) / per_second * fps - 1e-3)) + 1
    if n > MAX_FRAMES:
        raise InputError(f"{src}: expected an animation of at most {MAX_FRAMES:,} frames, got {n:,} at {fps:g} fps "
                         f"(its {what} span {(stop - start) / per_second:,.0f} s)")
    return start + np.arange(n) / (fps / per_second), fps


def _local(node: dict, T=None, R=None, S=None, n: int = 1) -> np.ndarray:
    """(n, 4, 4) a node's local transforms: its matrix, or its translation, rotation and scale (each the
    animated values (n, width) where given, else the node's own)."""
    out = np.broadcast_to(np.eye(4), (n, 4, 4)).copy()
    if "matrix" in node and T is None and R is None and S is None:
        out[:] = np.asarray(node["matrix"], dtype=np.float64).reshape(4, 4).T  # column-major
        return out
    T = np.broadcast_to(np.asarray(node.get("translation", (0, 0, 0)), float), (n, 3)) if T is None else T
    R = np.broadcast_to(np.asarray(node.get("rotation", (0, 0, 0, 1)), float), (n, 4)) if R is None else R
    S = np.broadcast_to(np.asarray(node.get("scale", (1, 1, 1)), float), (n, 3)) if S is None else S
    out[:, :3, :3] = quat_to_matrix(R[:, [3, 0, 1, 2]]) * S[:, None, :]  # glTF's x y z w
    out[:, :3, 3] = T
    return out


def holds_skeleton(path: Path) -> bool:
    """Whether the glTF `path` has a skeleton (a skin, a VRM humanoid map's hips or a node named as hips), from its
    JSON alone (a .glb's buffer left unread); True where it cannot be read as one (named as a motion, it is refused
    with the reason)."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(20)
            if head[:4] == _GLB_MAGIC:
                size, kind = struct.unpack_from("<II", head, 12)
                doc = json.loads(fh.read(size).decode("utf-8")) if kind == _JSON_CHUNK else {"skins": [1]}
            else:
                doc = json.loads((head + fh.read()).decode("utf-8"))
        if not isinstance(doc, dict) or doc.get("skins") or "Hips" in _vrm_roles(doc).values():
            return True
        return any(canonical(str(node.get("name") or "")) in PELVIS_NAMES for node in doc.get("nodes", []))
    except (OSError, ValueError, UnicodeDecodeError, struct.error, AttributeError, TypeError):
        return True


def animation_names(path: Path) -> list[str]:
    """The names of the animations of the glTF `path` where it holds several (`--take`), else []; InputError
    naming the file where it is no glTF `read_gltf` reads."""
    src = f"motion '{path}'"
    names = _guarded(lambda: [str(a.get("name") or f"animation {k}")
                              for k, a in enumerate(gltf_document(path, src)[0].get("animations", []))], src)
    return names if len(names) > 1 else []


def read_gltf(path: Path, src: str, take: str | None = None) -> Skeleton:
    """The skeleton and motion of the glTF `path` (module docstring), as `formats.fbx.read_fbx` gives an FBX's;
    of a file of several animations, the one named `take` (default: the first). InputError naming `src` for a
    file that is no glTF 2.0, a damaged one, or one without a skin."""
    return _guarded(lambda: _read(*gltf_document(path, src), src, take), src)


def _humanoid_nodes(nodes: list, parent: dict, roles: dict[int, str], src: str) -> list[int]:
    """The joints of a glTF without a skin (a VRM Animation's, an armature exported without its mesh): the node
    its humanoid map calls hips, else the node named as a pelvis with the most humanoid joint names below it, and
    the nodes below it (but those of a mesh or a camera); InputError naming `src` where no node is either."""
    children = {}
    for c, p in parent.items():
        children.setdefault(p, []).append(c)

    def tree(i: int) -> list[int]:
        out, stack = [], [i]
        while stack:
            j = stack.pop()
            if j == i or not ({"mesh", "camera"} & set(nodes[j])):
                out.append(j)
                stack.extend(sorted(children.get(j, []), reverse=True))
        return out

    def name(i: int) -> str:
        return roles.get(i) or str(nodes[i].get("name") or "")

    hips = [i for i, role in roles.items() if role == "Hips" and i < len(nodes)]
    hips = hips or [i for i in range(len(nodes)) if canonical(name(i)) in PELVIS_NAMES]
    if not hips:
        raise InputError(f"{src}: expected a glTF of a skinned skeleton (a skin's joints) or of a humanoid's joint "
                         f"nodes (a node named as its hips), found {len(nodes)} node(s), no skin and no hips: export "
                         f"the character's armature with its animation")
    return tree(max(hips, key=lambda i: role_names([name(j) for j in tree(i)])))


def _bind_pose(doc: dict, buffers: list[bytes], skin: dict, joints: list[int], rest: dict, src: str,
               names: dict) -> dict:
    """{joint: (4, 4) its transform in the world in the skin's bind pose} (`bind_from_inverse` of the skin's
    inverse bind matrices), where it differs from the nodes' own; {} where the skin has no matrices."""
    if "inverseBindMatrices" not in skin:
        return {}
    ibm = _accessor(doc, buffers, skin["inverseBindMatrices"])
    ibm = ibm.reshape(-1, 4, 4).transpose(0, 2, 1) if ibm.shape == (len(joints), 16) else np.zeros((0, 4, 4))
    return bind_from_inverse(joints, rest, ibm, src, names)


def bind_from_inverse(joints: list, rest: dict, ibm: np.ndarray, src: str, names: dict | None = None) -> dict:
    """{joint: (4, 4) its transform in the world in a skin's bind pose}, where that differs from the joints' own
    rest transforms `rest` {joint: (4, 4) in the world} (a file saved with its character posed: the rest is the
    pose its mesh was bound in). The inverse bind matrices `ibm` (J, 4, 4) give each joint's transform in the bind
    pose in the space the mesh was bound in: the world, as glTF says, unless more of the joints stand in the bind
    pose of another space (a mesh's, as some exporters write them) than in the world's. {} where the bind pose is
    the joints' own (within 1e-5 of the skeleton's size), or where the matrices are not J invertible ones
    (warned). Where it differs, says so at INFO naming the joint turned furthest from it (`names`: {joint: name})."""
    singular = np.linalg.svd(ibm[:, :3, :3], compute_uv=False) if len(ibm) and np.isfinite(ibm).all() else None
    if singular is None or len(ibm) != len(joints) or (singular[:, -1] <= 1e-9 * singular[:, 0]).any():
        log.warning("%s: its skin's inverse bind matrices are not %d invertible 4x4 matrices: its nodes' own "
                    "transforms are taken as its rest", src, len(joints))
        return {}
    size = max(float(np.ptp([rest[j][:3, 3] for j in joints], axis=0).max()), 1e-12)

    def relative(M: np.ndarray) -> np.ndarray:  # translations in the skeleton's size, rotations as they are
        return np.concatenate([M[..., :3, :3], M[..., :3, 3:] / size], axis=-1)

    # each joint's node at rest, in the space its bind pose is given in: the same for every node that stands there
    space = relative(np.array([rest[j] @ m for j, m in zip(joints, ibm)]))
    agree = (np.abs(space[:, None] - space[None]).max(axis=(2, 3)) <= 1e-5).sum(axis=1)
    at_world = int((np.abs(space - np.eye(4)[:3]).max(axis=(1, 2)) <= 1e-5).sum())
    k = int(np.argmax(agree))
    place = rest[joints[k]] @ ibm[k] if agree[k] > max(at_world, 1) else np.eye(4)
    bind = place @ np.linalg.inv(ibm)
    if max(float(np.abs(relative(b - rest[j])).max()) for b, j in zip(bind, joints)) <= 1e-5:
        return {}
    names = names or {}
    body = [role_names([str(names.get(j, ""))]) > 0 for j in joints]  # a body joint's turn told, not a finger's
    turns = [_angle(rest[j][:3, :3], b[:3, :3]) * (1.0 if on or not any(body) else 0.0)
             for j, b, on in zip(joints, bind, body)]
    worst = int(np.argmax(turns))
    log.info("%s: its joints stand posed, '%s' %.0f degrees from the pose its mesh was bound in: that bind pose is its "
             "rest", src, names.get(joints[worst], joints[worst]), turns[worst])
    return dict(zip(joints, bind))


def _angle(a: np.ndarray, b: np.ndarray) -> float:
    """The angle (degrees) between the rotations of two 3 x 3 transforms (their scalings taken out)."""
    a, b = a / np.linalg.norm(a, axis=0), b / np.linalg.norm(b, axis=0)
    return float(np.degrees(np.arccos(np.clip((np.trace(a.T @ b) - 1) / 2, -1.0, 1.0))))


def _guarded(read, src: str):
    """read(), any error of a document not as glTF 2.0 writes it (a list where an object belongs, an index
    beyond its arrays) an InputError naming `src`."""
    try:
        return read()
    except InputError:
        raise
    except (IndexError, KeyError, TypeError, ValueError, AttributeError) as exc:
        raise InputError(f"{src}: its glTF objects are not as glTF 2.0 writes them ({type(exc).__name__}: "
                         f"{str(exc)[:80]})") from None


def _read(doc: dict, buffers: list[bytes], src: str, take: str | None) -> Skeleton:
    nodes = doc.get("nodes", [])
    parent = {int(c): i for i, node in enumerate(nodes) for c in node.get("children", [])}
    depth = node_depths(list(range(len(nodes))), parent)
    parent = {c: p for c, p in parent.items() if depth[p] < depth[c]}  # a damaged file's cycle cut
    order = sorted(range(len(nodes)), key=lambda i: depth[i])
    roles = _vrm_roles(doc)
    skins = [s for s in doc.get("skins", []) if s.get("joints")]
    skin = max(skins, key=lambda s: len(s["joints"])) if skins else None
    joints = [int(j) for j in skin["joints"]] if skin else _humanoid_nodes(nodes, parent, roles, src)
    animations = doc.get("animations", [])
    titles = [str(a.get("name") or f"animation {k}") for k, a in enumerate(animations)]
    chosen = chosen_take(titles, take, src, "animations")
    channels = {}
    if chosen is not None:
        animation = animations[chosen]
        for channel in animation.get("channels", []):
            node, path = _channel_target(channel.get("target", {}))
            if node is None:
                continue  # morph target weights, a material's colour: no skeleton's
            sampler = animation["samplers"][channel["sampler"]]
            times = _accessor(doc, buffers, sampler["input"])[:, 0]
            values = _accessor(doc, buffers, sampler["output"])
            interpolation = sampler.get("interpolation", "LINEAR")
            per_key = 3 if interpolation == "CUBICSPLINE" else 1
            if len(values) != len(times) * per_key:  # the joint was read at rest without a word
                raise InputError(f"{src}: expected animation sampler {channel['sampler']}'s output to hold "
                                 f"{len(times) * per_key} values ({per_key} per key time, {interpolation}), got "
                                 f"{len(values)}")
            if np.any(np.diff(times) < 0):
                raise InputError(f"{src}: expected animation sampler {channel['sampler']}'s key times to increase, "
                                 f"got them out of order (at key {int(np.argmax(np.diff(times) < 0)) + 1})")
            if len(times):
                channels[(node, path)] = (times, values, interpolation)
    if not channels:
        log.warning("%s: no animation of its nodes: its one frame is the skeleton as it stands", src)
        t, fps = np.zeros(1), DEFAULT_FPS
    else:
        t, fps = key_times([c[0] for c in channels.values()], src,
                           cubic=any(c[2] == "CUBICSPLINE" for c in channels.values()))
    needed = set()  # the joints and the nodes above them: the others' transforms are not computed
    for j in joints:
        while j is not None and j not in needed:
            needed.add(j)
            j = parent.get(j)
    world, rest = {}, {}
    for i in (i for i in order if i in needed):
        node = nodes[i]
        animated = {path: sampled_keys(*channels[(i, path)], t, path == "rotation")
                    for path in ("translation", "rotation", "scale") if (i, path) in channels}
        local = _local(node, animated.get("translation"), animated.get("rotation"), animated.get("scale"), len(t))
        resting = _local(node)[0]
        p = parent.get(i)
        world[i] = local if p is None else world[p] @ local
        rest[i] = resting if p is None else rest[p] @ resting
    names = {i: str(nodes[i].get("name") or f"node{i}") for i in joints}
    if skin is not None:
        rest.update(_bind_pose(doc, buffers, skin, joints, rest, src, names))
    names.update({i: name for i, name in roles.items() if i in names})
    skeleton = skeleton_of(joints, names, parent, order, world, rest, 1.0 / fps)
    return skeleton._replace(take=titles[chosen]) if len(animations) > 1 else skeleton
