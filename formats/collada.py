"""COLLADA (`.dae`) skeletal animation (Mixamo's Collada download, Blender's, 3ds Max's and Maya's exports; XML),
read as the skeleton and motion `core.retarget` turns into SMPL's, as an FBX or a glTF is (`formats.fbx`,
`formats.gltf`).

The joints are the visual scene's nodes of type JOINT, their hierarchy the nodes' nesting, each named by its name
(else its sid or id); a node's transform is its elements in order (matrix, translate, rotate, scale), animated by
the channels that target them: a whole matrix ('<node>/transform', as Blender and Mixamo write a key per frame),
or an element or one of its components ('<node>/rotateX.ANGLE', '<node>/translate.X', as Maya and 3ds Max do).
Keys are interpolated as their sampler says (LINEAR; STEP; BEZIER and HERMITE curves taken as straight lines
between keys), a matrix's rotation slerped; frames are spaced as the keys are (`formats.gltf.key_times`), from the
first key to the last. All the file's channels are one take. The rest pose is the skin's bind pose (its
INV_BIND_MATRIX, placed as glTF's inverse bind matrices are: `formats.gltf.bind_from_inverse`), else the nodes'
own transforms. `core.retarget` reads the rest's world and the legs' unit as for any rig. A file of no JOINT node
is refused in one line; one of no animation is one frame of its rest, warned.
"""

from __future__ import annotations

import logging
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from core.errors import InputError, read_input
from core.rotations import axis_angle_to_matrix, matrix_to_quat, quat_to_matrix
from formats.bvh import Skeleton
from formats.fbx import skeleton_of
from formats.gltf import DEFAULT_FPS, bind_from_inverse, key_times, sampled_keys

log = logging.getLogger(__name__)

#: A node's transform elements and how many values each holds.
_ELEMENTS = {"matrix": 16, "translate": 3, "rotate": 4, "scale": 3}
_AXES = {"X": 0, "Y": 1, "Z": 2, "ANGLE": 3}


def read_collada(path: Path, src: str) -> Skeleton:
    """The skeleton and motion of the COLLADA file `path` (module docstring), as `formats.fbx.read_fbx` gives an
    FBX's. InputError naming `src` for a file that is no COLLADA, a damaged one, or one without joints."""
    data = read_input(Path(path), src)
    try:
        root = ET.fromstring(data)
    except ET.ParseError as exc:
        raise InputError(f"{src}: expected a COLLADA file (XML), got XML that does not parse ({exc})") from None
    if not root.tag.endswith("COLLADA"):
        raise InputError(f"{src}: expected a COLLADA document (a <COLLADA> root), got <{root.tag.split('}')[-1]}>")
    try:
        return _read(root, src)
    except InputError:
        raise
    except (IndexError, KeyError, TypeError, ValueError, AttributeError) as exc:
        raise InputError(f"{src}: its COLLADA elements are not as COLLADA writes them ({type(exc).__name__}: "
                         f"{str(exc)[:80]})") from None


def _read(root: ET.Element, src: str) -> Skeleton:
    ns = root.tag[:root.tag.index("}") + 1] if root.tag.startswith("{") else ""
    by_id = {e.get("id"): e for e in root.iter() if e.get("id")}
    scene = _visual_scene(root, ns, by_id)
    nodes, parent = [], {}  # each node's element; its parent's index

    def walk(element: ET.Element, up: int | None) -> None:
        for child in element.findall(f"{ns}node"):
            nodes.append(child)
            if up is not None:
                parent[len(nodes) - 1] = up
            walk(child, len(nodes) - 1)

    walk(scene, None)
    joints = [i for i, n in enumerate(nodes) if n.get("type") == "JOINT"]
    if not joints:  # some exporters leave joints of type NODE: the ones a skin names
        named = {name for skin in _skins(root, ns) for name in _source(by_id, ns, skin[0])[0]}
        joints = [i for i, n in enumerate(nodes) if named & {n.get("sid"), n.get("id"), n.get("name")}]
    if not joints:
        raise InputError(f"{src}: expected a COLLADA skeleton (nodes of type JOINT), found {len(nodes)} node(s) and no "
                         f"joint: export the character's armature with its animation")
    elements = [[(e.tag[len(ns):], e.get("sid"), _floats(e.text)) for e in n if e.tag[len(ns):] in _ELEMENTS]
                for n in nodes]
    index = {n.get("id"): i for i, n in enumerate(nodes) if n.get("id")}
    channels = _channels(root, ns, by_id, index, elements, src)
    if not channels:
        log.warning("%s: no animation of its joints: its one frame is the skeleton as it stands", src)
        t, fps = np.zeros(1), DEFAULT_FPS
    else:
        t, fps = key_times([c[0] for c in channels.values()], src)
    needed = set()
    for j in joints:
        while j is not None and j not in needed:
            needed.add(j)
            j = parent.get(j)
    world, rest = {}, {}
    for i in range(len(nodes)):  # parents come first in document order
        if i not in needed:
            continue
        local = _local(elements[i], {k[1]: v for k, v in channels.items() if k[0] == i}, t)
        resting = _local(elements[i], {}, t[:1])[0]
        p = parent.get(i)
        world[i] = local if p is None else world[p] @ local
        rest[i] = resting if p is None else rest[p] @ resting
    names = {j: nodes[j].get("name") or nodes[j].get("sid") or nodes[j].get("id") or f"joint{j}" for j in joints}
    rest.update(_bind_pose(root, ns, by_id, nodes, joints, rest, src, names))
    return skeleton_of(joints, names, parent, list(range(len(nodes))), world, rest, 1.0 / fps)


def _floats(text: str | None) -> np.ndarray:
    return np.array((text or "").split(), dtype=np.float64)


def _visual_scene(root: ET.Element, ns: str, by_id: dict) -> ET.Element:
    """The visual scene the document's <scene> instances, else its first."""
    instance = root.find(f"{ns}scene/{ns}instance_visual_scene")
    if instance is not None and instance.get("url", "").lstrip("#") in by_id:
        return by_id[instance.get("url").lstrip("#")]
    scene = root.find(f"{ns}library_visual_scenes/{ns}visual_scene")
    return scene if scene is not None else ET.Element("visual_scene")


def _source(by_id: dict, ns: str, ref: str) -> tuple[np.ndarray | list[str], int]:
    """(values, stride) of the <source> `ref` ('#id'): a float_array's numbers, or a Name_array's names."""
    source = by_id[ref.lstrip("#")]
    stride = int(source.find(f"{ns}technique_common/{ns}accessor").get("stride", 1))
    floats = source.find(f"{ns}float_array")
    if floats is not None:
        return _floats(floats.text), stride
    names = source.find(f"{ns}Name_array")
    if names is None:
        names = source.find(f"{ns}IDREF_array")
    return (names.text or "").split(), stride


def _channels(root: ET.Element, ns: str, by_id: dict, index: dict, elements: list, src: str = "") -> dict:
    """{(node, (element, member)): (times (K,), values (K, width), interpolation)} of every channel that animates
    a node's transform element; member: None (the whole element), a component (0-3) or a matrix entry (r, c)."""
    out = {}
    for channel in root.iter(f"{ns}channel"):
        target = channel.get("target", "")
        node_id, _, rest = target.partition("/")
        if node_id not in index:
            continue
        sid, member = re.match(r"([^.(]*)(.*)", rest).groups()
        node = index[node_id]
        k = next((k for k, (_, s, _) in enumerate(elements[node]) if s == sid), None)
        if k is None:
            continue
        if member.startswith("."):
            part = _AXES.get(member[1:].upper())
        elif member.startswith("("):
            part = tuple(int(x) for x in re.findall(r"\((\d+)\)", member))
        else:
            part = None
        if member and part is None:
            continue  # a component this reader does not know
        sampler = by_id[channel.get("source", "").lstrip("#")]
        inputs = {i.get("semantic"): i.get("source") for i in sampler.findall(f"{ns}input")}
        times, _ = _source(by_id, ns, inputs["INPUT"])
        values, stride = _source(by_id, ns, inputs["OUTPUT"])
        kinds = _source(by_id, ns, inputs["INTERPOLATION"])[0] if "INTERPOLATION" in inputs else ["LINEAR"]
        values = np.asarray(values, dtype=np.float64)
        if len(times) and values.size != len(times) * stride:  # its element was read at rest, silently
            raise InputError(f"{src}: expected animation source '{inputs['OUTPUT'].lstrip('#')}' to hold "
                             f"{len(times) * stride} values ({stride} per key time), got {values.size}")
        values = values.reshape(len(times), -1)
        if len(times):
            interpolation = "STEP" if kinds and all(k == "STEP" for k in kinds) else "LINEAR"
            out[(node, (k, part))] = (np.asarray(times, dtype=np.float64), values, interpolation)
    return out


def _local(elements: list, animated: dict, t: np.ndarray) -> np.ndarray:
    """(T, 4, 4) a node's transform at times `t`: its elements composed in order, each replaced (whole, or in a
    component) by its channels' values where animated ({(element, member): (times, values, interpolation)})."""
    out = np.broadcast_to(np.eye(4), (len(t), 4, 4)).copy()
    for k, (kind, _, static) in enumerate(elements):
        whole = animated.get((k, None))
        if kind == "matrix" and whole is not None:
            M = _sampled_matrices(*whole, t)
        else:
            values = np.broadcast_to(static, (len(t), len(static))).copy()
            if whole is not None:
                values = sampled_keys(*whole, t, False)
            for (element, part), channel in animated.items():
                if element == k and part is not None:
                    sampled = sampled_keys(*channel, t, False)[:, 0]
                    if isinstance(part, tuple):
                        values[:, part[0] * 4 + part[1]] = sampled
                    else:
                        values[:, part] = sampled
            M = _element_matrices(kind, values)
        out = out @ M
    return out


def _element_matrices(kind: str, values: np.ndarray) -> np.ndarray:
    """(T, 4, 4) of an element's values per frame (T, width)."""
    M = np.broadcast_to(np.eye(4), (len(values), 4, 4)).copy()
    if kind == "matrix":
        M[:] = values.reshape(-1, 4, 4)  # row-major, column vectors
    elif kind == "translate":
        M[:, :3, 3] = values
    elif kind == "scale":
        M[:, [0, 1, 2], [0, 1, 2]] = values
    else:  # rotate: axis, degrees
        axis = values[:, :3] / np.maximum(np.linalg.norm(values[:, :3], axis=1, keepdims=True), 1e-12)
        M[:, :3, :3] = axis_angle_to_matrix(axis * np.radians(values[:, 3:4]))
    return M


def _sampled_matrices(times: np.ndarray, values: np.ndarray, interpolation: str, t: np.ndarray) -> np.ndarray:
    """(T, 4, 4) keyed matrices (K, 16) at times `t`: their translations and scales interpolated, their rotations
    slerped."""
    M = values.reshape(-1, 4, 4)
    scale = np.linalg.norm(M[:, :3, :3], axis=1)  # (K, 3) column norms
    R = M[:, :3, :3] / np.maximum(scale[:, None, :], 1e-12)
    q = matrix_to_quat(R)  # w x y z; slerped along the shorter arc between keys
    out = np.broadcast_to(np.eye(4), (len(t), 4, 4)).copy()
    out[:, :3, :3] = quat_to_matrix(sampled_keys(times, q, interpolation, t, True)) \
        * sampled_keys(times, scale, interpolation, t, False)[:, None, :]
    out[:, :3, 3] = sampled_keys(times, M[:, :3, 3], interpolation, t, False)
    return out


def _skins(root: ET.Element, ns: str) -> list[tuple[str, str]]:
    """(JOINT source, INV_BIND_MATRIX source) of each skin of the file's controllers."""
    out = []
    for joints in root.iter(f"{ns}joints"):
        inputs = {i.get("semantic"): i.get("source") for i in joints.findall(f"{ns}input")}
        if "JOINT" in inputs and "INV_BIND_MATRIX" in inputs:
            out.append((inputs["JOINT"], inputs["INV_BIND_MATRIX"]))
    return out


def _bind_pose(root: ET.Element, ns: str, by_id: dict, nodes: list, joints: list, rest: dict, src: str,
               names: dict) -> dict:
    """The joints' bind pose (`formats.gltf.bind_from_inverse`) of the file's skin of the most joints, its joints
    named by sid (else id or name); {} where it has none."""
    bound: dict = {}
    for joint_source, matrix_source in _skins(root, ns):
        listed, _ = _source(by_id, ns, joint_source)
        matrices, _ = _source(by_id, ns, matrix_source)
        lookup = {}
        for j in joints:
            for key in (nodes[j].get("sid"), nodes[j].get("id"), nodes[j].get("name")):
                if key:
                    lookup.setdefault(key, j)
        found = [lookup.get(n) for n in listed]
        if len(matrices) == 16 * len(listed) and len([f for f in found if f is not None]) > len(bound):
            ibm = np.asarray(matrices, dtype=np.float64).reshape(-1, 4, 4)
            bound = {f: m for f, m in zip(found, ibm) if f is not None}
    if not bound:
        return {}
    ids = list(bound)
    return bind_from_inverse(ids, rest, np.array([bound[j] for j in ids]), src, names)
