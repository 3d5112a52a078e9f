"""Tests of formats/fbx.py: binary FBX files of a skeleton's animation, written here as Mixamo, Maya and Blender
write them (joints of LimbNode Models with pre-rotations and Euler orders, an Armature Null above them scaling
centimetres to metres, curves per axis, compressed arrays, a BindPose), read back as the SMPL motion they move as."""

import logging
import re
import struct
import zlib

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from core.errors import InputError
from core.rotations import axis_angle_to_matrix
from formats.fbx import TICKS_PER_SECOND, read_nodes
from formats.motion import load_motion
from tests.formats.test_bvh import MIXAMO, _motion, hinge_motion, hinged_limbs_off, rig_motion
from tests.formats.test_motion import _assert_one_line, assert_each_refused

#: FBX's RotationOrder enum, by axes in the order they turn a point.
_ORDER = {"xyz": 0, "xzy": 1, "yzx": 2, "yxz": 3, "zxy": 4, "zyx": 5}


def _prop(value, endian: str = "<") -> bytes:
    """A property record of a (type code, value) pair: 'L', 'I', 'D', 'S', a letter 'C', a byte 'B' or 'Z', or
    arrays 'd',
    'l', 'f', 'c' (bytes; their upper-case code 'Dz', 'Lz', 'Fz': zlib-compressed), in byte order `endian`."""
    code, v = value
    if code == "C":
        return b"C" + v.encode("latin-1")
    if code in ("L", "I", "D", "B", "Z"):
        return code.encode() + struct.pack(endian + {"L": "q", "I": "i", "D": "d", "B": "B", "Z": "B"}[code], v)
    if code == "S":
        raw = v.encode("latin-1")
        return b"S" + struct.pack(endian + "I", len(raw)) + raw
    kind = code[0].lower() if code != "c" else "c"
    raw = np.asarray(v, dtype=endian + {"d": "f8", "l": "i8", "f": "f4", "c": "u1"}[kind]).tobytes()
    packed = zlib.compress(raw) if code.endswith("z") else raw
    return kind.encode() + struct.pack(endian + "III", len(v), int(code.endswith("z")), len(packed)) + packed


def _node(name: str, props=(), children=()) -> tuple:
    """A node: its name, its properties as (type code, value) pairs (`_prop`), its children."""
    return (name, list(props), list(children))


def _encode(node, at: int, endian: str = "<") -> bytes:
    """A node record (FBX 7.4: 32-bit offsets) starting at file offset `at`, in byte order `endian`."""
    name, props, children = node
    head = 13 + len(name)
    body = b"".join(_prop(p, endian) for p in props)
    inner = b""
    for child in children:
        inner += _encode(child, at + head + len(body) + len(inner), endian)
    if children:
        inner += bytes(13)
    end = at + head + len(body) + len(inner)
    return (struct.pack(endian + "III", end, len(props), len(body)) + bytes([len(name)]) + name.encode() + body
            + inner)


def _ascii(node, depth: int = 0) -> str:
    """A node as an ASCII FBX writes it: `Name: value, ...` (strings quoted, an object's 'Name\\x00\\x01Class'
    as "Class::Name", arrays `*N {` then `a: ...` wrapped every 8 values `}`), its children in braces, a
    comment line above each object as Maya writes them."""
    name, props, children = node
    tab = "\t" * depth

    def value(code, v):
        if code == "C":  # a letter, bare
            return v
        if code == "S":
            text, _, cls = v.partition("\x00\x01")
            return f'"{cls}::{text}"' if cls else f'"{text}"'
        if code in ("L", "I"):
            return str(int(v))
        if code == "D":
            return repr(float(v))
        items = [str(int(x)) if code[0] in "lL" else repr(float(x)) for x in np.asarray(v).reshape(-1)]
        rows = ",\n".join(",".join(items[k:k + 8]) for k in range(0, len(items), 8))
        return f"*{len(items)} {{\n{tab}\ta: {rows}\n{tab}}}"

    head = f"{tab}; {name} of {len(children)} children\n" if children and depth == 1 else ""
    line = f"{head}{tab}{name}: {', '.join(value(*p) for p in props)}"
    if not children:
        return line + "\n"
    return line + " {\n" + "".join(_ascii(c, depth + 1) for c in children) + f"{tab}}}\n"


def write_fbx(path, nodes, version=7400, ascii=False, big_endian=False):
    """A binary FBX of `nodes` (FBX `version`); ascii: an ASCII one, its header naming the version; big_endian:
    its numbers big-endian, as Maya on PowerPC Macs wrote them (the header's byte 22 set)."""
    if ascii:
        header = _node("FBXHeaderExtension", [], [_node("FBXHeaderVersion", [("I", 1003)]),
                                                  _node("FBXVersion", [("I", version)])])
        text = f"; FBX {version // 1000}.{version % 1000 // 100}.0 project file\n; ----\n\n"
        path.write_text(text + "".join(_ascii(n) + "\n" for n in [header, *nodes]))
        return path
    endian = ">" if big_endian else "<"
    data = b"Kaydara FBX Binary  \x00\x1a" + bytes([big_endian]) + struct.pack(endian + "I", version)
    for node in nodes:
        data += _encode(node, len(data), endian)
    path.write_bytes(data + bytes(13) + bytes(160))  # the null record, then a footer the reader leaves
    return path


def _p70(*entries):
    """Properties70 of (name, type code, values...) entries."""
    return _node("Properties70", (), [_node("P", [("S", name), ("S", ""), ("S", ""), ("S", "")]
                                            + [(code, v) for v in values]) for name, code, *values in entries])


def rig_fbx(path, poses, trans, rig=MIXAMO, fps=30, seed=1, bind_pose=False, extra_links=(), time_mode=None,
            takes=None, ascii=False, floor_joint=False, creator=None, big_endian=False, version=7400,
            unbound=()):
    """An FBX of `rig_motion`'s rig (centimetres, an A-pose, 15 % larger) under an Armature Null scaling it to
    metres: every joint with a random pre-rotation (its frame not the world's at rest, as Maya's joint orients)
    and Euler order, its rotation curves per axis, the root's translation curves. bind_pose: its static
    rotations are the first frame's (not the rest) and a BindPose holds the rest (but of the joints named in
    `unbound`, as a skin leaves out joints it does not weight). extra_links: connections
    added (kind, child, parent); time_mode: (TimeMode, CustomFrameRate) written instead of `fps`'s. takes:
    {stack name: (poses, trans)}, one animation stack (and layer) each, instead of 'Take 001' of `poses`;
    ascii: an ASCII FBX of the same nodes (big_endian: a big-endian binary one); version 6100: FBX 6's layout
    of the same (`_as_fbx6`); floor_joint: the hips (their translation curves the path) under a
    static 'root' joint at the Armature's origin, as game engines' rigs are; creator: the file's Creator
    ('Blender (stable FBX IO) ...')."""
    takes = takes or {"Take 001": (poses, trans)}
    moving = {name: rig_motion(*motion, rig, unit=0.01, scale=1.15, a_pose=40.0) for name, motion in takes.items()}
    names, parents, offsets, _, root = next(iter(moving.values()))
    rng = np.random.default_rng(seed)
    J = len(names)
    pre = Rotation.random(J, random_state=rng)
    orders = [list(_ORDER)[k] for k in rng.integers(0, 6, J)]
    frame = [None] * J  # each joint's world frame at rest: its parent's, then its pre-rotation
    translation, place = [], []
    for j, p in enumerate(parents):
        parent_frame = frame[p] if p >= 0 else np.eye(3)
        frame[j] = parent_frame @ pre[j].as_matrix()
        translation.append(parent_frame.T @ offsets[j])
        place.append(root[0] if p < 0 else place[p] + offsets[j])

    def curves(rotations):
        """Each joint's Euler angles (T, 3), degrees, about x, y, z: its frame turns as the rig's joint does from
        its rest: F_p(t) Pre R(t) = W(t) F, so R = F^T L F."""
        out = []
        for j in range(J):
            R = frame[j].T @ rotations[:, j] @ frame[j]
            angles = Rotation.from_matrix(R).as_euler(orders[j])  # extrinsic, about the axes in that order
            out.append(np.degrees(angles[:, [orders[j].index(a) for a in "xyz"]]))
        return out

    ids = {j: 1000 + j for j in range(J)}
    armature = 900
    objects = [_node("Model", [("L", armature), ("S", "Armature\x00\x01Model"), ("S", "Null")],
                     [_p70(("Lcl Scaling", "D", 0.01, 0.01, 0.01))])]
    links = [("OO", armature, 0)]
    first = curves(next(iter(moving.values()))[3])
    for k, (take, (*_, rotations, take_root)) in enumerate(moving.items()):
        stack, layer = 800 + 2 * k, 801 + 2 * k
        euler = curves(rotations)
        t = np.arange(len(rotations)) * (TICKS_PER_SECOND // fps)
        objects += [_node("AnimationStack", [("L", stack), ("S", f"{take}\x00\x01AnimStack"), ("S", "")],
                          [_p70(("LocalStart", "L", 0), ("LocalStop", "L", int(t[-1])))]),
                    _node("AnimationLayer", [("L", layer), ("S", "BaseLayer\x00\x01AnimLayer"), ("S", "")])]
        links.append(("OO", layer, stack))
        for j in range(J):
            channels = [("R", "Lcl Rotation", euler[j])] + ([("T", "Lcl Translation", take_root)]
                                                            if parents[j] < 0 else [])
            for c, (key, prop, values) in enumerate(channels):
                node_id = 200000 * (k + 1) + 10 * j + c
                objects.append(_node("AnimationCurveNode", [("L", node_id), ("S", f"{key}\x00\x01AnimCurveNode"),
                                                            ("S", "")]))
                links += [("OO", node_id, layer), ("OP", node_id, ids[j], prop)]
                for a in range(3):
                    curve_id = 10_000_000 * (k + 1) + 100 * j + 10 * c + a
                    code = "Fz" if (j + a) % 2 else "f"
                    objects.append(_node("AnimationCurve", [("L", curve_id), ("S", "\x00\x01AnimCurve"), ("S", "")],
                                         [_node("KeyTime", [("Lz" if a else "l", t)]),
                                          _node("KeyValueFloat", [(code, values[:, a])])]))
                    links.append(("OP", curve_id, node_id, "d|" + "XYZ"[a]))
    poses_nodes = []
    for j in range(J):
        static = first[j][0] if bind_pose else np.zeros(3)
        objects.append(_node("Model", [("L", ids[j]), ("S", f"{names[j]}\x00\x01Model"), ("S", "LimbNode")],
                             [_p70(("PreRotation", "D", *pre[j].as_euler("xyz", degrees=True)),
                                   ("RotationOrder", "I", _ORDER[orders[j]]),
                                   ("Lcl Translation", "D", *(root[0] if parents[j] < 0 else translation[j])),
                                   ("Lcl Rotation", "D", *static))]))
        links.append(("OO", ids[j], ids[parents[j]] if parents[j] >= 0 else 950 if floor_joint else armature))
        if bind_pose and names[j] not in unbound:  # the world at rest: the Armature's scaling, the joint's frame
            # and place
            M = np.eye(4)
            M[:3, :3] = 0.01 * frame[j]
            M[:3, 3] = 0.01 * place[j]
            poses_nodes.append(_node("PoseNode", [], [_node("Node", [("L", ids[j])]),
                                                     _node("Matrix", [("d", M.T.reshape(-1))])]))
    if floor_joint:
        objects.append(_node("Model", [("L", 950), ("S", "root\x00\x01Model"), ("S", "LimbNode")]))
        links.append(("OO", 950, armature))
    if bind_pose:
        objects.append(_node("Pose", [("L", 700), ("S", "BindPose\x00\x01Pose"), ("S", "BindPose")], poses_nodes))
    mode = [("TimeMode", "I", {30: 6, 60: 3}[fps])] if time_mode is None else [
        ("TimeMode", "I", time_mode[0]), ("CustomFrameRate", "D", time_mode[1])]
    settings = _node("GlobalSettings", [], [_p70(("UpAxis", "I", 1), *mode)])
    links += list(extra_links)
    connections = _node("Connections", [], [_node("C", [("S", kind), ("L", a), ("L", b)]
                                                   + ([("S", rest[0])] if rest else []))
                                            for kind, a, b, *rest in links])
    top = [settings, _node("Objects", [], objects), connections]
    if creator:
        top.insert(0, _node("Creator", [("S", creator)]))
    if version < 7000:
        top = _as_fbx6(top)
    return write_fbx(path, top, ascii=ascii, big_endian=big_endian, version=version)


def _as_fbx6(top: list) -> list:
    """`rig_fbx`'s FBX 7 nodes laid out as FBX 6 writes the same: objects named, not numbered ('Model' of the
    name and type, Properties60's 'Property' of name, type, flags and values), Connections' 'Connect' of names,
    the BindPose's matrices as 16 values, the frame rate in GlobalSettings' Properties60, and each animation
    stack a Take whose Models hold Channel 'Transform' / 'T', 'R' / 'X', 'Y', 'Z', each a 'Key' of time, value and
    'L' (linear) per key, as the FBX SDK 2009 writes them."""
    nodes = {n[0]: n for n in top}
    objects = nodes["Objects"][2]
    by_id = {o[1][0][1]: o for o in objects}
    named = {i: o[1][1][1] for i, o in by_id.items() if o[0] == "Model"}
    named[0] = "Scene\x00\x01Model"

    def props60(node):
        block = next((c for c in node[2] if c[0] == "Properties70"), None)
        return _node("Properties60", [], [_node("Property", [p[1][0], ("S", ""), p[1][3], *p[1][4:]])
                                          for p in (block[2] if block else [])])

    links = [tuple(v for _, v in c[1]) for c in nodes["Connections"][2]]
    out = []
    for o in objects:
        if o[0] == "Model":
            out.append(_node("Model", [("S", named[o[1][0][1]]), o[1][2]], [props60(o)]))
        elif o[0] == "Pose":
            out.append(_node("Pose", [("S", "BIND_POSES\x00\x01Pose"), ("S", "BindPose")],
                             [_node("PoseNode", [], [_node("Node", [("S", named[pn[2][0][1][0][1]])]),
                                                     _node("Matrix", [("D", float(x)) for x in pn[2][1][1][0][1]])])
                              for pn in o[2]]))
    settings = next(c for c in nodes["GlobalSettings"][2] if c[0] == "Properties70")
    out.append(_node("GlobalSettings", [], [props60(("GlobalSettings", [], [settings]))]))
    connect = [_node("Connect", [("S", kind), ("S", named[a]), ("S", named[b])]) for kind, a, b, *_ in links
               if kind == "OO" and a in named and b in named]
    takes = []
    for stack in (o for o in objects if o[0] == "AnimationStack"):
        layer = next(a for kind, a, b, *_ in links if b == stack[1][0][1])
        span = [p[1][4][1] for p in stack[2][0][2]]
        models: dict = {}
        for kind, curve_node, model, *prop in links:
            if kind != "OP" or model not in named or (curve_node, layer) not in {(a, b) for _, a, b, *_ in links}:
                continue
            axes = []
            for a, (k2, curve, parent, *axis) in enumerate(lk for lk in links if lk[2] == curve_node):
                times, values = (by_id[curve][2][j][1][0][1] for j in (0, 1))
                keys = [x for t, v in zip(times, values) for x in (("L", int(t)), ("D", float(v)), ("C", "L"))]
                axes.append(_node("Channel", [("S", axis[0][2])], [_node("Default", [("D", float(values[0]))]),
                                                                  _node("KeyVer", [("I", 4005)]),
                                                                  _node("KeyCount", [("I", len(times))]),
                                                                  _node("Key", keys)]))
            letter = {"Lcl Translation": "T", "Lcl Rotation": "R", "Lcl Scaling": "S"}[prop[0]]
            models.setdefault(model, []).append(_node("Channel", [("S", letter)], axes))
        takes.append(_node("Take", [("S", by_id[stack[1][0][1]][1][1][1].split("\x00")[0])],
                           [_node("LocalTime", [("L", span[0]), ("L", span[1])])]
                           + [_node("Model", [("S", named[m])], [_node("Channel", [("S", "Transform")], channels)])
                              for m, channels in models.items()]))
    kept = [n for n in top if n[0] not in ("Objects", "Connections", "GlobalSettings")]
    return kept + [_node("Objects", [], out), _node("Connections", [], connect), _node("Takes", [], takes)]


@pytest.mark.parametrize("bind_pose, ascii, big_endian, version", [
    (False, False, False, 7400), (True, False, False, 7400), (True, True, False, 7400), (True, False, True, 7400),
    (True, False, False, 6100), (True, True, False, 6100), (False, True, False, 6100)])
def test_a_mixamo_fbx_reads_as_the_smpl_motion_it_moves_as(tmp_path, bind_pose, ascii, big_endian, version):
    """A Mixamo rig's FBX (pre-rotated joint frames, six Euler orders, an Armature scaling centimetres, an A-pose
    15 % larger, 30 fps) is retarget to the SMPL motion it moves as: every body joint's rotation, the
    translation; with its static rotations another pose than the rest, its BindPose gives the rest; the same
    FBX written as ASCII (Maya's comments, 'Model::Name' names, arrays wrapped over lines), big-endian (as Maya
    on PowerPC Macs wrote binary FBX), or as FBX 6.1 (Mixamo's and the 2006-2010 tools' "FBX 6.1 (2009)": named
    objects, Properties60, Takes of letter-coded keys), binary or ASCII, reads as well."""
    poses, trans = _motion(5, seed=7)
    poses[:, 22:] = 0
    path = rig_fbx(tmp_path / "walk.fbx", poses, trans, bind_pose=bind_pose, ascii=ascii, big_endian=big_endian,
                   version=version)
    assert read_nodes(path.read_bytes(), "walk.fbx")[0] == version
    assert path.read_bytes().startswith(b"; FBX ") == ascii
    m = load_motion(path, world_checks=False)
    assert m.fps == pytest.approx(30) and m.poses.shape == (5, 24, 3) and m.rest_up == "y"
    np.testing.assert_allclose(axis_angle_to_matrix(m.poses), axis_angle_to_matrix(poses), atol=1e-4)
    np.testing.assert_allclose(m.trans, trans, atol=1e-4)


def test_joints_a_bind_pose_leaves_out_keep_their_places_along_their_bound_parents(tmp_path):
    """Joints a BindPose leaves out (end joints, controls: a skin weights none of their vertices) rest where their
    own transforms put them below their parents' bind poses, not where the file's posed values put the whole
    chain: the head's end joint and a finger rest as with a full BindPose, the motion the same."""
    from formats.fbx import read_fbx

    poses, trans = _motion(3, seed=11)
    poses[:, 22:] = 0
    full = read_fbx(rig_fbx(tmp_path / "full.fbx", poses, trans, bind_pose=True), "full")
    left_out = ("mixamorig7:HeadTop_End", "mixamorig7:LeftHandIndex1")
    partial = read_fbx(rig_fbx(tmp_path / "partial.fbx", poses, trans, bind_pose=True, unbound=left_out), "partial")
    ends = [full.names.index(name) for name in left_out]
    np.testing.assert_allclose(partial.offsets[ends], full.offsets[ends], atol=1e-9)
    assert np.abs(full.offsets[ends]).max() > 0.01
    m = load_motion(tmp_path / "partial.fbx", world_checks=False)
    np.testing.assert_allclose(axis_angle_to_matrix(m.poses), axis_angle_to_matrix(poses), atol=1e-4)


def test_a_blender_fbx_of_an_armature_without_its_mesh_is_warned_about(tmp_path, caplog):
    """Blender writes an armature without a mesh with no BindPose, its joints' values the pose of the frame it
    exported at: warned (not for another tool's file, nor for one with a BindPose), and its bones are turned as a
    folded rig's, each from the frame it stands best in, its knees and elbows onto their hinges: a clip that
    hinges, exported at a frame whose upper arms are turned about themselves, reads its limbs as the actor's,
    where the same file of another tool (that frame taken as the rest) puts them 60 degrees off. (On Gangnam
    Style exported so from Blender 4.2, SMPL's joints turn within 27 degrees of the BVH's reading at the 95th
    percentile, 46 with the exported frame as the rest.)"""
    poses, trans = _motion(3, seed=5)
    blender = "Blender (stable FBX IO) - 4.2.0 - 5.12.4"
    for creator, bind_pose, warned in ((blender, False, True), (blender, True, False), ("FBX SDK", False, False)):
        caplog.clear()
        path = rig_fbx(tmp_path / "arm.fbx", poses, trans, creator=creator, bind_pose=bind_pose)
        with caplog.at_level(logging.WARNING):
            load_motion(path, world_checks=False)
        assert ("an armature Blender wrote without its mesh holds no rest pose" in caplog.text) == warned, caplog.text

    poses, trans = hinge_motion()
    poses[0, 1:] = 0  # the exported frame stands, its arms hanging, each upper arm turned about itself
    for k, side in ((16, -1), (17, 1)):
        poses[0, k] = (Rotation.from_rotvec([0, 0, side * 1.3]) * Rotation.from_rotvec([side, 0, 0])).as_rotvec()
    names = rig_motion(poses[:1], trans[:1], MIXAMO)[0]  # none in the BindPose: the values the exported frame's
    for creator, off in ((blender, lambda d: d < 1e-3), ("FBX SDK", lambda d: d > 30.0)):
        path = rig_fbx(tmp_path / "hinges.fbx", poses, trans, creator=creator, bind_pose=True, unbound=names)
        caplog.clear()
        with caplog.at_level(logging.WARNING):
            m = load_motion(path, world_checks=False)
        assert off(hinged_limbs_off(m.poses, poses)), creator
        assert ("its rest a pose the file held: each bone is turned from the frame" in caplog.text) == (
            creator == blender)


def test_hips_animated_under_a_root_joint_at_the_floor_carry_the_path(tmp_path):
    """An FBX whose hips move (their translation curves) under a static 'root' joint at the floor, as game
    engines' rigs export them: the path is the hips', the motion the same."""
    poses, trans = _motion(5, seed=12)
    poses[:, 22:] = 0
    m = load_motion(rig_fbx(tmp_path / "game.fbx", poses, trans, floor_joint=True), world_checks=False)
    np.testing.assert_allclose(axis_angle_to_matrix(m.poses), axis_angle_to_matrix(poses), atol=1e-4)
    np.testing.assert_allclose(m.trans, trans, atol=1e-4)


def test_an_ascii_broken_or_skeleton_less_fbx_is_one_line(tmp_path):
    poses, trans = _motion(2)
    good = rig_fbx(tmp_path / "good.fbx", poses, trans).read_bytes()
    cases = [(b"; FBX 7.4.0 project file\nFBXHeaderExtension:  {\n", "its ASCII FBX is cut short (1 block(s) "
                                                                      "left open)"),
             (b"; FBX 7.4.0 project file\nObjects:  {\n} }\n", "its ASCII FBX is damaged at line 3 (a '}' "
                                                                "closing nothing)"),
             (b"; FBX 7.4.0 project file\nKeyTime: *3 {\n a: 1,2\n}\n", "has an array of 2 values where it says 3"),
             (b"; FBX 7.4.0 project file\nObjects: 1 2\n", "damaged at line 2 (a value '2' out of place)"),
             (b"not an fbx at all", "expected an FBX file (binary 'Kaydara FBX Binary', or ASCII), got a file that "
                                    "is not one"),
             (good[:len(good) // 2], "its FBX records are damaged or cut short"),
             (good.replace(b"LimbNode", b"MeshNode"), "expected an FBX of a skeleton (Models of type LimbNode), "
                                                      "found 28 Model(s) and no joint"),
             (good[:23] + struct.pack("<I", 5800) + good[27:], "expected FBX 6 or 7 (2006 and later), got FBX 5.8: "
                                                               "export it again")]
    assert_each_refused(tmp_path / "bad.fbx", cases)
    assert read_nodes(good, "good.fbx")[0] == 7400


def test_what_real_exporters_write_beside_the_usual_parses():
    """What real files hold beside the usual nodes parses (found reading the ufbx project's test files, every
    real one of which Maya and MotionBuilder once refused): ASCII node names with a dash (Maya's and
    MotionBuilder's 'Pre-Extrapolation' of a curve that cycles), comments between an array's values, Microsoft's
    '1.#INF' and '-1.#IND' of the SDK on Windows; binary byte properties 'B' and 'Z' and byte arrays 'c' (Maya's
    audio, MotionBuilder's thumbnail)."""
    text = (b"; FBX 7.7.0 project file\nAnimationCurve: 7, \"AnimCurve::\", \"\" {\n\tDefault: 1.#INF\n"
            b"\tKeyValueFloat: *3 {\n\t\ta: 1.5, ; the first\n\t\t-1.#IND, 2\n\t}\n"
            b"\tPre-Extrapolation:  {\n\t\tType: \"R\"\n\t\tRepetition: 2\n\t}\n}\n")
    _, nodes = read_nodes(text, "x.fbx")
    curve = nodes[0]
    assert curve.child("Default").props == [np.inf]
    values = curve.child("KeyValueFloat").props[0]
    assert values[0] == 1.5 and np.isnan(values[1]) and values[2] == 2.0
    assert curve.child("Pre-Extrapolation").child("Type").props == ["R"]
    data = b"Kaydara FBX Binary  \x00\x1a\x00" + struct.pack("<I", 7400)
    data += _encode(_node("Thumbnail", [("B", 7), ("Z", 200), ("c", [1, 2, 255])]), len(data)) + bytes(13)
    _, nodes = read_nodes(data, "x.fbx")
    assert nodes[0].props[:2] == [7, 200] and nodes[0].props[2].tolist() == [1, 2, 255]


def test_curves_that_repeat_past_their_keys_read_over_the_takes_whole_span(tmp_path):
    """A take whose curves repeat after their keys (Maya's cycle, Post-Extrapolation 'R') reads over its whole
    span (LocalStop, here three times the keys'), each frame past the keys the pose and place of the frame a
    whole number of cycles before; curves that hold their last value read to their last key only, as before."""
    poses, trans = _motion(4, seed=9)
    poses[:, 22:] = 0
    path = rig_fbx(tmp_path / "cycle.fbx", poses, trans, ascii=True)
    text = path.read_text()
    stop = 3 * 3 * (TICKS_PER_SECOND // 30)
    held = text.replace('"LocalStop", "", "", "", ' + str(3 * (TICKS_PER_SECOND // 30)),
                        '"LocalStop", "", "", "", ' + str(stop))
    assert held != text
    cycling = re.sub(r"(\tKeyValueFloat: \*4 \{[^}]*\}\n)",
                     r"\1\t\tPost-Extrapolation: {\n\t\t\tType: R\n\t\t\tRepetition: -1\n\t\t}\n", held)
    assert cycling.count("Post-Extrapolation") > 10
    path.write_text(held)
    assert load_motion(path, world_checks=False).n_frames == 4
    path.write_text(cycling)
    m = load_motion(path, world_checks=False)
    cycle = [0, 1, 2, 3, 1, 2, 0, 1, 2, 0]  # frame 3 + k is k's, the seam at the first key
    assert m.n_frames == 10
    np.testing.assert_allclose(axis_angle_to_matrix(m.poses), axis_angle_to_matrix(poses[cycle]), atol=1e-4)
    np.testing.assert_allclose(m.trans, trans[cycle], atol=1e-4)


def test_an_fbx_read_take_after_take_is_parsed_once_and_again_when_it_changes(tmp_path):
    """Reading a file's takes one after another (`garment info`, `bake --take all`) parses it once; the same path
    rewritten with other bytes of the same size (another frame rate) is parsed again, not read stale."""
    from formats import fbx

    poses, trans = _motion(4, seed=2)
    path = rig_fbx(tmp_path / "rate.fbx", poses, trans, time_mode=(14, 30.0))
    first = fbx.parsed_file(path, "x")
    assert fbx.parsed_file(path, "x") is first
    size = path.stat().st_size
    rig_fbx(path, poses, trans, time_mode=(14, 60.0))
    assert path.stat().st_size == size and fbx.parsed_file(path, "x") is not first
    assert load_motion(path, world_checks=False).fps == pytest.approx(60.0)


def test_a_damaged_fbxs_cycle_reads_and_its_time_span_is_one_line(tmp_path):
    """Connections that make a cycle (the Armature under the hips it holds) are cut, not followed for ever: the
    motion reads as its own; a custom frame rate of a billion frames per second is refused before any frame is
    sampled, as is one of 0."""
    poses, trans = _motion(4, seed=2)
    poses[:, 22:] = 0
    m = load_motion(rig_fbx(tmp_path / "cycle.fbx", poses, trans, extra_links=[("OO", 900, 1000)]),
                    world_checks=False)
    np.testing.assert_allclose(axis_angle_to_matrix(m.poses), axis_angle_to_matrix(poses), atol=1e-4)
    for rate, expected in ((1e9, "expected an animation of at most 3,600,000 frames, got 100,000,001 at 1e+09 fps"),
                           (0.0, "expected a frame rate over 0 in its CustomFrameRate, got 0")):
        with pytest.raises(InputError) as info:
            load_motion(rig_fbx(tmp_path / "span.fbx", poses, trans, time_mode=(14, rate)))
        _assert_one_line(info, "span.fbx", expected)


def test_an_fbx_without_curves_is_its_skeleton_standing_one_frame(tmp_path, caplog):
    """A character's FBX of no animation (a skinned download without motion) is one frame of its rest pose, told:
    SMPL at rest but for its shoulders, lowered as the rig's A-pose (40 degrees)."""
    import logging

    from formats.fbx import read_nodes as parse

    poses, trans = _motion(3)
    path = rig_fbx(tmp_path / "character.fbx", poses * 0, trans)
    data = path.read_bytes()
    for name in (b"AnimationCurveNode", b"AnimationCurve"):  # renamed out of sight, sizes kept
        data = data.replace(name, name.upper().replace(b"CURVE", b"CURVX"))
    path.write_bytes(data)
    assert parse(data, "x")[0] == 7400
    with caplog.at_level(logging.WARNING):
        m = load_motion(path, world_checks=False)
    assert m.n_frames == 1 and "no animation curves" in caplog.text
    others = [k for k in range(24) if k not in (16, 17)]
    np.testing.assert_allclose(m.poses[0, others], 0, atol=1e-6)
    np.testing.assert_allclose(np.degrees(np.linalg.norm(m.poses[0, [16, 17]], axis=-1)), 40, atol=1e-3)


@pytest.mark.parametrize("version", [7400, 6100])
def test_an_fbx_of_several_takes_reads_the_first_warned_or_the_one_named(tmp_path, caplog, version):
    """An FBX of two animation stacks ('Walk', 5 frames; 'Run', 3 frames, another motion): the first read, the
    other named in a warning; take='run' reads the other (its case aside); a name it lacks is one line naming
    those it has; `animation_takes` lists them; a file of one stack reads as it is, a take of another name
    warned about. FBX 6's Takes are its stacks."""
    import logging

    from formats.fbx import animation_takes

    (walk, walk_trans), (run, run_trans) = _motion(5, seed=3), _motion(3, seed=4)
    walk[:, 22:] = run[:, 22:] = 0
    path = rig_fbx(tmp_path / "moves.fbx", None, None, takes={"Walk": (walk, walk_trans), "Run": (run, run_trans)},
                   version=version)
    with caplog.at_level(logging.WARNING):
        m = load_motion(path, world_checks=False)
    assert "holds 2 animation stacks ('Walk', 'Run'): reading 'Walk', the first (--take NAME reads another)" \
        in caplog.text
    assert m.take == "Walk" and m.n_frames == 5
    np.testing.assert_allclose(axis_angle_to_matrix(m.poses), axis_angle_to_matrix(walk), atol=1e-4)
    caplog.clear()
    with caplog.at_level(logging.WARNING):
        m = load_motion(path, world_checks=False, take="run")
    assert m.take == "Run" and m.n_frames == 3 and "animation stacks" not in caplog.text
    np.testing.assert_allclose(axis_angle_to_matrix(m.poses), axis_angle_to_matrix(run), atol=1e-4)
    np.testing.assert_allclose(m.trans, run_trans, atol=1e-4)
    with pytest.raises(InputError) as info:
        load_motion(path, take="Jump")
    _assert_one_line(info, "moves.fbx", "expected --take one of its 2 animation stacks ('Walk', 'Run'), got 'Jump'")
    assert animation_takes(path) == ["Walk", "Run"]

    one = rig_fbx(tmp_path / "one.fbx", walk, walk_trans, version=version)
    assert animation_takes(one) == []
    with caplog.at_level(logging.WARNING):
        m = load_motion(one, world_checks=False, take="Run")
    assert "holds only 'Take 001': --take Run left aside" in caplog.text and m.take is None
    np.testing.assert_allclose(axis_angle_to_matrix(m.poses), axis_angle_to_matrix(walk), atol=1e-4)


def test_a_file_of_two_characters_reads_the_first_skeletons_motion_not_a_mix():
    """Two characters of one rig (a duet's file; the second's joints in another namespace, so that their names
    match the first's): the skeleton is the first's, every SMPL joint matched in it, the motion its own."""
    from core.retarget import rig_pose
    from formats.bvh import skeleton_arrays
    from formats.fbx import skeleton_of

    def transforms(poses, trans):
        names, parents, offsets, rotations, root = rig_motion(poses, trans, MIXAMO)
        world, position = rig_pose(parents, offsets, rotations, root)
        M = np.broadcast_to(np.eye(4), world.shape[:2] + (4, 4)).copy()
        M[..., :3, :3], M[..., :3, 3] = world, position
        rest = np.broadcast_to(np.eye(4), (len(names), 4, 4)).copy()
        rest[:, :3, 3] = rig_pose(parents, offsets, np.broadcast_to(np.eye(3), (1,) + rotations.shape[1:]),
                                  offsets[:1])[1][0]
        return names, parents, M, rest

    (a, a_trans), (b, b_trans) = _motion(4, seed=18), _motion(4, seed=19)
    a[:, 22:] = b[:, 22:] = 0
    names, parents, world_a, rest = transforms(a, a_trans)
    _, _, world_b, _ = transforms(b, b_trans + [2.0, 0.0, 0.0])
    J = len(names)
    ids = list(range(J)) + [100 + j for j in range(J)]  # B's joints after A's: B's names would win a mix
    name_of = {j: n for j, n in enumerate(names)} | {100 + j: "mixamorig8:" + n.split(":")[-1]
                                                      for j, n in enumerate(names)}
    parent = {j: p for j, p in enumerate(parents) if p >= 0} | {100 + j: 100 + p for j, p in enumerate(parents)
                                                                if p >= 0}
    world = {j: world_a[:, j] for j in range(J)} | {100 + j: world_b[:, j] for j in range(J)}
    rests = {j: rest[j] for j in range(J)} | {100 + j: rest[j] for j in range(J)}
    order = sorted(ids, key=lambda i: (i % 100, -i))  # parents first, each of B's joints before A's of its name
    skeleton = skeleton_of(ids, name_of, parent, order, world, rests, 1 / 30)
    arrays = skeleton_arrays(skeleton, "duet")
    np.testing.assert_allclose(axis_angle_to_matrix(arrays["poses"]), axis_angle_to_matrix(a), atol=1e-4)
    np.testing.assert_allclose(arrays["trans"], a_trans, atol=1e-4)
