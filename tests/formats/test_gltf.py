"""Tests of formats/gltf.py: glTF 2.0 files of a skeleton's animation, written here as Blender and three.js write
them (joint nodes with rest rotations, an Armature node scaling them, quaternion channels, a .glb's binary chunk,
a .gltf's base64 or external buffers, several animations), read back as the SMPL motion they move as."""

import base64
import json
import logging
import struct
from urllib.parse import quote

import numpy as np
import pytest
from scipy.interpolate import CubicHermiteSpline
from scipy.spatial.transform import Rotation, Slerp

from core.errors import InputError
from core.rotations import axis_angle_to_matrix
from formats.gltf import VRM_BONES, cubic_rate, key_rate, key_times, sampled_keys
from formats.motion import load_motion, motion_takes
from tests.formats.test_bvh import MIXAMO, _motion, rig_motion
from tests.formats.test_motion import _assert_one_line, assert_each_refused


class _Buffer:
    """The binary buffer of a glTF being written: accessors appended (float32, or normalized int16)."""

    def __init__(self):
        self.data, self.views, self.accessors = bytearray(), [], []

    def add(self, values, kind, int16=False) -> int:
        values = np.asarray(values, np.float64).reshape(len(values), -1)
        raw = (np.round(values * 32767).astype("<i2") if int16 else values.astype("<f4")).tobytes()
        while len(self.data) % 4:
            self.data.append(0)
        self.views.append({"buffer": 0, "byteOffset": len(self.data), "byteLength": len(raw)})
        self.data += raw
        accessor = {"bufferView": len(self.views) - 1, "componentType": 5122 if int16 else 5126,
                    "count": len(values), "type": kind}
        if int16:
            accessor["normalized"] = True
        if kind == "SCALAR":
            accessor.update(min=[float(values.min())], max=[float(values.max())])
        self.accessors.append(accessor)
        return len(self.accessors) - 1


def rig_gltf(path, takes, rig=MIXAMO, fps=30, seed=1, armature_scale=0.01, buffer="glb", int16=False,
             skin=True, ik_feet=False, controls=0, vrm=False, posed=0.0, bind_space=None, pointer=False):
    """A glTF of `rig_motion`'s rig (centimetres, an A-pose, 15 % larger) under an Armature node scaling it by
    `armature_scale`: every joint node with a random rest rotation (its frame not the world's at rest), its
    rotation channel per animation, the root's translation channel; takes {name: (poses, trans)}, an animation
    each; buffer: 'glb' (a binary chunk), 'base64' (a .gltf data URI) or 'file' (a .bin beside the .gltf);
    int16: rotations as normalized int16 (as KHR_mesh_quantization allows); skin: False leaves the skin out;
    ik_feet: each ankle under a 'FootControl' joint of the Armature (as game rigs with IK controls have them), not
    under its knee, its place and turn animated there; controls: a chain of that many static 'Ctrl' joints under
    the Armature beside the skeleton (a control rig larger than it), in the skin; vrm: the joint nodes named
    'bone<k>', a VRM Animation humanoid map naming their roles. The skin's inverse bind matrices are the rest's;
    posed: each joint node's own rotation but the hips' and the first spine joint's then turned this many degrees
    about a random axis (a file saved with its character posed: the animation is the same); bind_space: (4, 4) the
    space the mesh was bound in, from the world (the matrices as `inv(bind_space @ world)`; default: the world, as
    glTF says); pointer: every channel's target a KHR_animation_pointer ('/nodes/3/rotation'), and one more
    channel animating a material's colour."""
    moving = {name: rig_motion(*m, rig, unit=0.01, scale=1.15, a_pose=40.0) for name, m in takes.items()}
    names, parents, offsets, _, root = next(iter(moving.values()))
    rng = np.random.default_rng(seed)
    J = len(names)
    pre = Rotation.random(J, random_state=rng).as_matrix()
    frame = [None] * J
    nodes = [{"name": "Armature", "children": [1], "scale": [armature_scale] * 3}]
    steps, rest = [], [None] * J  # each joint's translation from its parent; its place in the Armature at rest
    for j, p in enumerate(parents):
        parent_frame = frame[p] if p >= 0 else np.eye(3)
        frame[j] = parent_frame @ pre[j]
        steps.append(root[0] if p < 0 else parent_frame.T @ offsets[j])
        rest[j] = root[0] if p < 0 else rest[p] + offsets[j]
        nodes.append({"name": names[j], "rotation": list(Rotation.from_matrix(pre[j]).as_quat()),
                      "translation": list(steps[j])})
    feet = [j for j, n in enumerate(names) if n.endswith("Foot")] if ik_feet else []
    for j in feet:  # its own transform: its rest in the Armature
        nodes[j + 1].update(rotation=list(Rotation.from_matrix(frame[j]).as_quat()), translation=list(rest[j]))
    for j, p in enumerate(parents):
        if p >= 0 and j not in feet:
            nodes[p + 1].setdefault("children", []).append(j + 1)
    for j in feet:  # a control at the Armature's origin holds the foot
        nodes[0]["children"].append(len(nodes))
        nodes.append({"name": f"FootControl.{'L' if 'Left' in names[j] else 'R'}", "children": [j + 1]})
    if controls:
        nodes[0]["children"].append(len(nodes))
        for k in range(controls):
            nodes.append({"name": "Ctrl_Master" if k == 0 else f"Ctrl_{k}", "translation": [0.0, 1.0, 0.0]})
            if k + 1 < controls:
                nodes[-1]["children"] = [len(nodes)]
    buf = _Buffer()
    worlds = _node_worlds(nodes)  # before any posing: the bind pose
    for node in [n for n in nodes[1:J + 1] if posed and not n["name"].endswith(("Hips", "Spine"))]:
        turn = Rotation.from_rotvec(_unit_vector(rng) * np.radians(posed))
        node["rotation"] = list((Rotation.from_quat(node["rotation"]) * turn).as_quat())
    space = np.eye(4) if bind_space is None else bind_space
    bind = buf.add([np.linalg.inv(space @ worlds[k]).T.ravel() for k in range(1, len(nodes))], "MAT4")
    animations = []
    for take, (*_, rotations, take_root) in moving.items():
        times = buf.add(np.arange(len(rotations)) / fps, "SCALAR")
        channels, samplers = [], []
        place, turn = [None] * J, [None] * J  # each joint node's transform in the Armature, per frame
        for j, p in enumerate(parents):  # its node turns so that its frame turns as the rig's joint does
            parent_frame = frame[p] if p >= 0 else np.eye(3)
            local = parent_frame.T @ rotations[:, j] @ parent_frame @ pre[j]
            at = take_root if p < 0 else place[p] + turn[p] @ steps[j]
            turn[j], place[j] = (local if p < 0 else turn[p] @ local), at
            if j in feet:  # under its control: its turn and place in the Armature, animated
                local = turn[j]
                samplers.append({"input": times, "output": buf.add(place[j], "VEC3")})
                channels.append({"sampler": len(samplers) - 1, "target": {"node": j + 1, "path": "translation"}})
            samplers.append({"input": times, "output": buf.add(Rotation.from_matrix(local).as_quat(), "VEC4", int16)})
            channels.append({"sampler": len(samplers) - 1, "target": {"node": j + 1, "path": "rotation"}})
        samplers.append({"input": times, "output": buf.add(take_root, "VEC3")})
        channels.append({"sampler": len(samplers) - 1, "target": {"node": 1, "path": "translation"}})
        if pointer:
            for channel in channels:
                target = channel["target"]
                channel["target"] = {"path": "pointer", "extensions": {"KHR_animation_pointer": {
                    "pointer": f"/nodes/{target['node']}/{target['path']}"}}}
            samplers.append({"input": times, "output": buf.add(np.ones((len(rotations), 4)), "VEC4")})
            channels.append({"sampler": len(samplers) - 1, "target": {"path": "pointer", "extensions": {
                "KHR_animation_pointer": {"pointer": "/materials/0/pbrMetallicRoughness/baseColorFactor"}}}})
        animations.append({"name": take, "channels": channels, "samplers": samplers})
    doc = {"asset": {"version": "2.0", "generator": "garment tests"}, "scene": 0, "scenes": [{"nodes": [0]}],
           "nodes": nodes, "animations": animations, "accessors": buf.accessors, "bufferViews": buf.views,
           "buffers": [{"byteLength": len(buf.data)}]}
    if skin:
        doc["skins"] = [{"joints": list(range(1, len(nodes))), "skeleton": 1, "inverseBindMatrices": bind}]
    if pointer:
        doc["extensionsUsed"] = ["KHR_animation_pointer"]
    if vrm:
        roles = {name: bone for bone, name in VRM_BONES.items()}
        bones = {roles[n.split(":")[-1]]: {"node": j + 1} for j, n in enumerate(names) if n.split(":")[-1] in roles}
        doc["extensions"] = {"VRMC_vrm_animation": {"specVersion": "1.0", "humanoid": {"humanBones": bones}}}
        for k, node in enumerate(nodes[1:J + 1]):
            node["name"] = f"bone{k}"
    data = bytes(buf.data)
    if buffer == "glb":
        text = json.dumps(doc).encode()
        text += b" " * (-len(text) % 4)
        data += bytes(-len(data) % 4)
        body = struct.pack("<II", len(text), 0x4E4F534A) + text + struct.pack("<II", len(data), 0x004E4942) + data
        path.write_bytes(b"glTF" + struct.pack("<II", 2, 12 + len(body)) + body)
        return path
    if buffer == "base64":
        doc["buffers"][0]["uri"] = "data:application/octet-stream;base64," + base64.b64encode(data).decode()
    else:
        doc["buffers"][0]["uri"] = quote(path.stem + ".bin")  # a URI: a space is '%20'
        path.with_suffix(".bin").write_bytes(data)
    path.write_text(json.dumps(doc))
    return path


def _node_worlds(nodes) -> np.ndarray:
    """(N, 4, 4) each node's transform in the world, from the nodes' translation, rotation and scale."""
    worlds = np.zeros((len(nodes), 4, 4))
    parent = {c: i for i, node in enumerate(nodes) for c in node.get("children", [])}
    for i in sorted(range(len(nodes)), key=lambda i: len(_chain(parent, i))):
        node = nodes[i]
        local = np.eye(4)
        local[:3, :3] = Rotation.from_quat(node.get("rotation", [0, 0, 0, 1])).as_matrix() * node.get("scale", [1] * 3)
        local[:3, 3] = node.get("translation", [0, 0, 0])
        worlds[i] = local if i not in parent else worlds[parent[i]] @ local
    return worlds


def _chain(parent, i) -> list:
    return [i] + (_chain(parent, parent[i]) if i in parent else [])


def _unit_vector(rng) -> np.ndarray:
    v = rng.normal(size=3)
    return v / np.linalg.norm(v)


@pytest.mark.parametrize("buffer, int16", [("glb", False), ("base64", False), ("file", True)])
def test_a_gltf_of_a_rig_reads_as_the_smpl_motion_it_moves_as(tmp_path, buffer, int16):
    """A Mixamo rig's glTF (joint nodes with rest rotations, an Armature node scaling it, 15 % larger, an A-pose)
    is retargeted to the SMPL motion it moves as, its buffer in a .glb, a base64 URI or a file beside it, its
    rotations float or normalized int16 (the file's name, and so its buffer's URI, with a space); Y-up read from its
    rest."""
    poses, trans = _motion(5, seed=7)
    poses[:, 22:] = 0
    suffix = ".glb" if buffer == "glb" else ".gltf"
    m = load_motion(rig_gltf(tmp_path / f"brisk walk{suffix}", {"Walk": (poses, trans)}, buffer=buffer, int16=int16),
                    world_checks=False)
    assert m.fps == pytest.approx(30) and m.poses.shape == (5, 24, 3) and m.rest_up == "y" and m.take is None
    tolerance = 1e-3 if int16 else 1e-4  # int16 quaternions: 3e-5 a component
    np.testing.assert_allclose(axis_angle_to_matrix(m.poses), axis_angle_to_matrix(poses), atol=tolerance)
    np.testing.assert_allclose(m.trans, trans, atol=tolerance)


def test_a_gltf_animated_through_khr_animation_pointer_reads_as_through_its_nodes(tmp_path):
    """KHR_animation_pointer (Blender 4.2's export can write them so): each channel's target a JSON pointer to a
    node's rotation or translation, one more to a material's colour: the same motion as the nodes' own targets
    give (it read as no animation, its rest's one frame)."""
    poses, trans = _motion(5, seed=3)
    poses[:, 22:] = 0
    m = load_motion(rig_gltf(tmp_path / "pointer.glb", {"Walk": (poses, trans)}, pointer=True), world_checks=False)
    assert m.n_frames == 5
    np.testing.assert_allclose(axis_angle_to_matrix(m.poses), axis_angle_to_matrix(poses), atol=1e-4)
    np.testing.assert_allclose(m.trans, trans, atol=1e-4)


@pytest.mark.parametrize("ik_feet, controls", [(True, 0), (False, 40), (True, 40)])
def test_a_rig_of_feet_under_ik_controls_or_beside_a_larger_control_rig_reads_as_its_motion(tmp_path, ik_feet,
                                                                                          controls):
    """Game rigs keep joints apart from the body's tree: the ankles under IK controls at the Armature (their place
    and turn animated there), the skeleton beside a larger chain of control joints: the other trees hang from the
    largest one's root, their places followed per frame, and the motion reads back as without them."""
    poses, trans = _motion(5, seed=9)
    poses[:, 22:] = 0
    path = rig_gltf(tmp_path / "game.glb", {"idle": (poses, trans)}, ik_feet=ik_feet, controls=controls)
    m = load_motion(path, world_checks=False)
    np.testing.assert_allclose(axis_angle_to_matrix(m.poses), axis_angle_to_matrix(poses), atol=1e-4)
    np.testing.assert_allclose(m.trans, trans, atol=1e-4)


def test_a_vrm_animation_is_matched_by_its_humanoid_map_whatever_its_nodes_are_called(tmp_path):
    """A VRM Animation (.vrma: glTF, its nodes 'bone0', 'bone1', ..., the VRMC_vrm_animation extension mapping
    VRM's humanoid bones to them) reads as its motion; without the map its nodes name no humanoid: refused."""
    poses, trans = _motion(4, seed=15)
    poses[:, 22:] = 0
    path = rig_gltf(tmp_path / "dance.vrma", {"dance": (poses, trans)}, vrm=True)
    m = load_motion(path, world_checks=False)
    np.testing.assert_allclose(axis_angle_to_matrix(m.poses), axis_angle_to_matrix(poses), atol=1e-4)
    np.testing.assert_allclose(m.trans, trans, atol=1e-4)
    data = path.read_bytes().replace(b"VRMC_vrm_animation", b"VRMC_vrm_animatioX")
    assert_each_refused(tmp_path / "plain.vrma", [(data, "expected a humanoid skeleton")])


@pytest.mark.parametrize("bind_space", [False, True])
def test_a_gltf_saved_posed_reads_from_its_skins_bind_pose(tmp_path, caplog, bind_space):
    """A glTF saved with its character posed (its limbs' nodes turned 70 degrees from the pose its mesh was bound
    in, as real game characters' stand holding a weapon) reads as the motion it moves as: the rest is the skin's
    bind pose (its inverse bind matrices), also where they were written in a mesh's space (turned and shifted from
    the world). Without them the posed nodes are the rest: the motion reads otherwise. Matrices that cannot be
    inverted are warned about and the nodes taken."""
    poses, trans = _motion(5, seed=21)
    poses[:, 22:] = 0
    space = None
    if bind_space:
        space = np.eye(4)
        space[:3, :3] = Rotation.from_euler("xyz", [20, -35, 50], degrees=True).as_matrix()
        space[:3, 3] = [0.3, -1.2, 0.5]
    path = rig_gltf(tmp_path / "posed.gltf", {"Idle": (poses, trans)}, buffer="base64", posed=70.0, bind_space=space)
    with caplog.at_level(logging.INFO):
        m = load_motion(path, world_checks=False)
    assert "its joints stand posed, 'mixamorig7:" in caplog.text and "that bind pose is its rest" in caplog.text
    assert m.rest_up == "y"
    np.testing.assert_allclose(axis_angle_to_matrix(m.poses), axis_angle_to_matrix(poses), atol=1e-4)
    np.testing.assert_allclose(m.trans, trans, atol=1e-4)
    doc = json.loads(path.read_text())
    del doc["skins"][0]["inverseBindMatrices"]
    (tmp_path / "nodes.gltf").write_text(json.dumps(doc))
    unbound = load_motion(tmp_path / "nodes.gltf", world_checks=False)
    assert np.abs(axis_angle_to_matrix(unbound.poses) - axis_angle_to_matrix(poses)).max() > 0.5
    doc["skins"][0]["inverseBindMatrices"] = 1  # the key times, not 4x4 matrices
    (tmp_path / "broken.gltf").write_text(json.dumps(doc))
    with caplog.at_level(logging.WARNING):
        broken = load_motion(tmp_path / "broken.gltf", world_checks=False)
    assert "its skin's inverse bind matrices are not 27 invertible 4x4 matrices" in caplog.text
    np.testing.assert_array_equal(broken.poses, unbound.poses)


def test_a_gltf_of_joint_nodes_without_a_skin_reads_from_its_hips(tmp_path):
    """An animation without its mesh (Blender's armature exported alone; a VRM Animation, which holds no mesh)
    has no skin: its joints are the nodes from the one named as hips (or mapped to VRM's hips) down, and its rest
    the nodes' own (VRM's T-pose)."""
    poses, trans = _motion(4, seed=23)
    poses[:, 22:] = 0
    for name, vrm in (("armature.glb", False), ("dance.vrma", True)):
        m = load_motion(rig_gltf(tmp_path / name, {"a": (poses, trans)}, skin=False, vrm=vrm), world_checks=False)
        np.testing.assert_allclose(axis_angle_to_matrix(m.poses), axis_angle_to_matrix(poses), atol=1e-4)
        np.testing.assert_allclose(m.trans, trans, atol=1e-4)


def test_a_gltf_of_several_animations_reads_the_first_warned_or_the_one_named(tmp_path, caplog):
    (walk, walk_trans), (run, run_trans) = _motion(5, seed=3), _motion(3, seed=4)
    walk[:, 22:] = run[:, 22:] = 0
    path = rig_gltf(tmp_path / "moves.glb", {"Walk": (walk, walk_trans), "Run": (run, run_trans)})
    with caplog.at_level(logging.WARNING):
        m = load_motion(path, world_checks=False)
    assert "holds 2 animations ('Walk', 'Run'): reading 'Walk', the first (--take NAME reads another)" in caplog.text
    assert m.take == "Walk" and m.n_frames == 5
    m = load_motion(path, world_checks=False, take="run")
    assert m.take == "Run" and m.n_frames == 3
    np.testing.assert_allclose(axis_angle_to_matrix(m.poses), axis_angle_to_matrix(run), atol=1e-4)
    assert motion_takes(path) == ["Walk", "Run"]
    with pytest.raises(InputError) as info:
        load_motion(path, take="Jump")
    _assert_one_line(info, "moves.glb", "expected --take one of its 2 animations ('Walk', 'Run'), got 'Jump'")


def test_a_gltf_without_skin_damaged_or_of_another_version_is_one_line(tmp_path):
    poses, trans = _motion(2)
    good = rig_gltf(tmp_path / "good.glb", {"a": (poses, trans)}).read_bytes()
    no_skin = rig_gltf(tmp_path / "prop.glb", {"a": (poses, trans)}, skin=False).read_bytes()
    no_skin = no_skin.replace(b':Hips"', b':Base"')  # a prop's nodes: no hips
    external = rig_gltf(tmp_path / "lost.gltf", {"a": (poses, trans)}, buffer="file")
    external.with_suffix(".bin").unlink()
    cases = [(good[:len(good) // 2], "bad.glb", "its glTF is damaged or cut short"),
             (no_skin, "bad.glb", "expected a glTF of a skinned skeleton (a skin's joints) or of a humanoid's joint "
                                  "nodes (a node named as its hips), found 28 node(s), no skin and no hips"),
             (good[:4] + struct.pack("<I", 1) + good[8:], "bad.glb", "expected glTF 2.0, got a glTF 1 binary"),
             (b"not a gltf", "bad.glb", "expected a glTF file (.glb binary or .gltf JSON), got a file that is not"),
             (external.read_bytes(), "lost.gltf", "cannot read its buffer 'lost.bin' beside it")]
    for data, name, expected in cases:
        assert_each_refused(tmp_path / name, [(data, expected)])


def test_channels_are_sampled_as_gltf_interpolates_them():
    """LINEAR rotations: scipy's slerp; LINEAR vectors: straight lines; STEP: the key before; CUBICSPLINE (equal
    in- and out-tangents): scipy's cubic Hermite spline; held beyond the keys. Key spacings snap to common rates."""
    rng = np.random.default_rng(0)
    times = np.array([0.0, 0.4, 0.5, 1.2])
    t = np.linspace(-0.1, 1.3, 57)
    quats = Rotation.random(4, random_state=rng)
    got = Rotation.from_quat(sampled_keys(times, quats.as_quat(), "LINEAR", t, rotation=True))
    want = Slerp(times, quats)(np.clip(t, 0, 1.2))
    assert np.max((got.inv() * want).magnitude()) < 1e-6
    values = rng.normal(size=(4, 3))
    np.testing.assert_allclose(sampled_keys(times, values, "LINEAR", t, False),
                               np.stack([np.interp(t, times, v) for v in values.T], 1), atol=1e-12)
    steps = sampled_keys(times, values, "STEP", t, False)
    np.testing.assert_allclose(steps, values[np.clip(np.searchsorted(times, t, side="right") - 1, 0, 3)])
    tangents = rng.normal(size=(4, 3))
    cubic = sampled_keys(times, np.stack([tangents, values, tangents], 1).reshape(12, 3), "CUBICSPLINE", t, False)
    inside = (t >= 0) & (t <= 1.2)
    np.testing.assert_allclose(cubic[inside], CubicHermiteSpline(times, values, tangents)(t[inside]), atol=1e-12)
    assert key_rate([np.arange(10) / 60.0]) == 60.0 and key_rate([np.arange(5) / 24.0]) == 24.0
    assert key_rate([np.array([0.0])]) == 30.0 and key_rate([np.arange(4) / 7.0]) == 7.0


def test_sparse_cubic_keys_are_sampled_between_them_and_a_flipped_quaternion_span_is_slerped():
    """Cubic curves keyed every 10 frames of 30 (a hand-keyed walk as Blender exports it unsampled: CUBICSPLINE
    keys at 3 fps) are sampled at 30 fps, their curves between the keys kept (sampled at the keys' 3 fps, a bake's
    slerps between them left Blender's own curves by up to 8 degrees), and so are linear ones (read at 3 fps,
    the same motion once resampled; keys 2 s apart were refused); keys closer than MIN_CUBIC_FPS keep their
    rate. A rotation span whose key quaternions lie in opposite hemispheres is slerped
    (its cubic, as Blender writes such tangents, swung the hips 169 degrees in one frame)."""
    keys = np.arange(0.0, 2.01, 1 / 3)
    t, fps = key_times([keys], "x", cubic=True)
    assert fps == 30.0 and len(t) == 61 and np.allclose(t, np.arange(61) / 30)
    assert key_times([keys], "x")[1] == 30.0 and key_times([np.arange(5) / 60.0], "x", cubic=True)[1] == 60.0
    assert cubic_rate(12.0) == 24.0 and cubic_rate(2.5) == 30.0 and cubic_rate(7.0) == 30.0
    rng = np.random.default_rng(3)
    times = np.array([0.0, 1 / 3, 2 / 3])
    q = Rotation.random(3, random_state=rng).as_quat()
    q[1] *= np.sign(q[0] @ q[1])  # keys 0 and 1 in one hemisphere ...
    q[2] *= -np.sign(q[1] @ q[2])  # ... key 2 in the other
    tangents = 0.2 * rng.normal(size=(3, 4))
    values = np.stack([tangents, q, tangents], 1).reshape(9, 4)
    got = sampled_keys(times, values, "CUBICSPLINE", t[:21], rotation=True)
    first = t[:21] <= 1 / 3
    np.testing.assert_allclose(got[first], CubicHermiteSpline(times[:2], q[:2], tangents[:2])(t[:21][first]),
                               atol=1e-12)
    slerped = Slerp(times[1:], Rotation.from_quat(q[1:]))(t[:21][~first])
    assert np.max((Rotation.from_quat(got[~first]).inv() * slerped).magnitude()) < 1e-6


def _retimed(path, times, dest):
    """The base64 .gltf `path` with every sampler keyed at `times` (seconds) instead (one accessor appended)."""
    doc = json.loads(path.read_text())
    data = bytearray(base64.b64decode(doc["buffers"][0]["uri"].split(",", 1)[1]))
    raw = np.asarray(times, dtype="<f4").tobytes()
    data += b"\0" * (-len(data) % 4)
    doc["bufferViews"].append({"buffer": 0, "byteOffset": len(data), "byteLength": len(raw)})
    data += raw
    doc["accessors"].append({"bufferView": len(doc["bufferViews"]) - 1, "componentType": 5126,
                             "count": len(times), "type": "SCALAR"})
    for sampler in doc["animations"][0]["samplers"]:
        sampler["input"] = len(doc["accessors"]) - 1
    doc["buffers"][0].update(uri="data:application/octet-stream;base64," + base64.b64encode(bytes(data)).decode(),
                             byteLength=len(data))
    dest.write_text(json.dumps(doc))
    return dest


def test_keys_seconds_apart_or_at_uneven_times_are_sampled_at_a_common_rate(tmp_path):
    """Linear keys 2 s apart (hand-keyed poses) were refused as a frame rate of 0.5 Hz, and keys at 0, 0.2, 1 and
    2 s read at their median spacing (1.25 fps: the pose at 0.2 s lost, the last key dropped); both are sampled at
    30 fps, every key on a frame; keys 5000 s apart read (they divided by a rate rounded to 0)."""
    poses, trans = _motion(4, seed=7)
    poses[:, 22:] = 0
    source = rig_gltf(tmp_path / "keys.gltf", {"Walk": (poses, trans)}, buffer="base64")
    for times, frames in (([0.0, 2.0], [0, 60]), ([0.0, 0.2, 1.0, 2.0], [0, 6, 30, 60])):
        keyed = len(times)
        rig = rig_gltf(tmp_path / f"k{keyed}.gltf", {"Walk": (poses[:keyed], trans[:keyed])}, buffer="base64")
        m = load_motion(_retimed(rig, times, tmp_path / f"retimed{keyed}.gltf"), world_checks=False)
        assert m.fps == 30 and m.n_frames == 61, (m.fps, m.n_frames)
        np.testing.assert_allclose(axis_angle_to_matrix(m.poses[frames]), axis_angle_to_matrix(poses[:keyed]),
                                   atol=1e-4)
    assert source.is_file()
    from formats.gltf import key_times

    t, fps = key_times([np.array([0.0, 5000.0])], "far.gltf")
    assert fps == 30 and len(t) == 150_001 and t[-1] == 5000.0


def test_a_sampler_of_too_few_values_or_times_out_of_order_is_one_line(tmp_path):
    """A sampler whose output holds one value fewer than its key times (its joint was read at rest without a word)
    and key times that go back (numpy's 'zero-size array' was the reason given): one line each."""
    poses, trans = _motion(3, seed=7)
    rig = rig_gltf(tmp_path / "rig.gltf", {"Walk": (poses, trans)}, buffer="base64")
    short = _retimed(rig, [0.0, 1 / 30, 2 / 30, 3 / 30], tmp_path / "short.gltf")
    back = _retimed(rig, [0.0, 2 / 30, 1 / 30], tmp_path / "back.gltf")
    for path, expected in ((short, "output to hold 4 values (1 per key time, LINEAR), got 3"),
                           (back, "key times to increase, got them out of order (at key 2)")):
        with pytest.raises(InputError) as info:
            load_motion(path)
        assert path.name in str(info.value) and expected in str(info.value) and "\n" not in str(info.value)
