"""Tests of formats/gltf.py: glTF 2.0 files of a skeleton's animation, written here as Blender and three.js write
them (joint nodes with rest rotations, an Armature node scaling them, quaternion channels, a .glb's binary chunk,
a .gltf's base64 or external buffers, several animations), read back as the SMPL motion they move as."""

import base64
import json
import logging
import struct

import numpy as np
import pytest
from scipy.interpolate import CubicHermiteSpline
from scipy.spatial.transform import Rotation, Slerp

from core.errors import InputError
from core.rotations import axis_angle_to_matrix
from formats.gltf import _frame_rate, _sampled
from formats.motion import load_motion, motion_takes
from tests.formats.test_bvh import MIXAMO, _motion, rig_motion
from tests.formats.test_motion import _assert_one_line


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
             skin=True):
    """A glTF of `rig_motion`'s rig (centimetres, an A-pose, 15 % larger) under an Armature node scaling it by
    `armature_scale`: every joint node with a random rest rotation (its frame not the world's at rest), its
    rotation channel per animation, the root's translation channel; takes {name: (poses, trans)}, an animation
    each; buffer: 'glb' (a binary chunk), 'base64' (a .gltf data URI) or 'file' (a .bin beside the .gltf);
    int16: rotations as normalized int16 (as KHR_mesh_quantization allows); skin: False leaves the skin out."""
    moving = {name: rig_motion(*m, rig, unit=0.01, scale=1.15, a_pose=40.0) for name, m in takes.items()}
    names, parents, offsets, _, root = next(iter(moving.values()))
    rng = np.random.default_rng(seed)
    J = len(names)
    pre = Rotation.random(J, random_state=rng).as_matrix()
    frame = [None] * J
    nodes = [{"name": "Armature", "children": [1], "scale": [armature_scale] * 3}]
    for j, p in enumerate(parents):
        parent_frame = frame[p] if p >= 0 else np.eye(3)
        frame[j] = parent_frame @ pre[j]
        nodes.append({"name": names[j], "rotation": list(Rotation.from_matrix(pre[j]).as_quat()),
                      "translation": list(root[0] if p < 0 else parent_frame.T @ offsets[j])})
    for j, p in enumerate(parents):
        if p >= 0:
            nodes[p + 1].setdefault("children", []).append(j + 1)
    buf = _Buffer()
    animations = []
    for take, (*_, rotations, take_root) in moving.items():
        times = buf.add(np.arange(len(rotations)) / fps, "SCALAR")
        channels, samplers = [], []
        for j, p in enumerate(parents):  # its node turns so that its frame turns as the rig's joint does
            parent_frame = frame[p] if p >= 0 else np.eye(3)
            local = parent_frame.T @ rotations[:, j] @ parent_frame @ pre[j]
            samplers.append({"input": times, "output": buf.add(Rotation.from_matrix(local).as_quat(), "VEC4", int16)})
            channels.append({"sampler": len(samplers) - 1, "target": {"node": j + 1, "path": "rotation"}})
        samplers.append({"input": times, "output": buf.add(take_root, "VEC3")})
        channels.append({"sampler": len(samplers) - 1, "target": {"node": 1, "path": "translation"}})
        animations.append({"name": take, "channels": channels, "samplers": samplers})
    doc = {"asset": {"version": "2.0", "generator": "garment tests"}, "scene": 0, "scenes": [{"nodes": [0]}],
           "nodes": nodes, "animations": animations, "accessors": buf.accessors, "bufferViews": buf.views,
           "buffers": [{"byteLength": len(buf.data)}]}
    if skin:
        doc["skins"] = [{"joints": list(range(1, J + 1)), "skeleton": 1}]
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
        doc["buffers"][0]["uri"] = path.stem + ".bin"
        path.with_suffix(".bin").write_bytes(data)
    path.write_text(json.dumps(doc))
    return path


@pytest.mark.parametrize("buffer, int16", [("glb", False), ("base64", False), ("file", True)])
def test_a_gltf_of_a_rig_reads_as_the_smpl_motion_it_moves_as(tmp_path, buffer, int16):
    """A Mixamo rig's glTF (joint nodes with rest rotations, an Armature node scaling it, 15 % larger, an A-pose)
    is retargeted to the SMPL motion it moves as, its buffer in a .glb, a base64 URI or a file beside it, its
    rotations float or normalized int16; Y-up read from its rest."""
    poses, trans = _motion(5, seed=7)
    poses[:, 22:] = 0
    suffix = ".glb" if buffer == "glb" else ".gltf"
    m = load_motion(rig_gltf(tmp_path / f"walk{suffix}", {"Walk": (poses, trans)}, buffer=buffer, int16=int16),
                    world_checks=False)
    assert m.fps == pytest.approx(30) and m.poses.shape == (5, 24, 3) and m.rest_up == "y" and m.take is None
    tolerance = 1e-3 if int16 else 1e-4  # int16 quaternions: 3e-5 a component
    np.testing.assert_allclose(axis_angle_to_matrix(m.poses), axis_angle_to_matrix(poses), atol=tolerance)
    np.testing.assert_allclose(m.trans, trans, atol=tolerance)


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
    external = rig_gltf(tmp_path / "lost.gltf", {"a": (poses, trans)}, buffer="file")
    external.with_suffix(".bin").unlink()
    cases = [(good[:len(good) // 2], "bad.glb", "its glTF is damaged or cut short"),
             (no_skin, "bad.glb", "expected a glTF of a skinned skeleton (a skin's joints), found 28 node(s) and no "
                                  "skin"),
             (good[:4] + struct.pack("<I", 1) + good[8:], "bad.glb", "expected glTF 2.0, got a glTF 1 binary"),
             (b"not a gltf", "bad.glb", "expected a glTF file (.glb binary or .gltf JSON), got a file that is not"),
             (external.read_bytes(), "lost.gltf", "cannot read its buffer 'lost.bin' beside it")]
    for data, name, expected in cases:
        (tmp_path / name).write_bytes(data)
        with pytest.raises(InputError) as info:
            load_motion(tmp_path / name)
        _assert_one_line(info, name, expected)


def test_channels_are_sampled_as_gltf_interpolates_them():
    """LINEAR rotations: scipy's slerp; LINEAR vectors: straight lines; STEP: the key before; CUBICSPLINE (equal
    in- and out-tangents): scipy's cubic Hermite spline; held beyond the keys. Key spacings snap to common rates."""
    rng = np.random.default_rng(0)
    times = np.array([0.0, 0.4, 0.5, 1.2])
    t = np.linspace(-0.1, 1.3, 57)
    quats = Rotation.random(4, random_state=rng)
    got = Rotation.from_quat(_sampled(times, quats.as_quat(), "LINEAR", t, rotation=True))
    want = Slerp(times, quats)(np.clip(t, 0, 1.2))
    assert np.max((got.inv() * want).magnitude()) < 1e-6
    values = rng.normal(size=(4, 3))
    np.testing.assert_allclose(_sampled(times, values, "LINEAR", t, False),
                               np.stack([np.interp(t, times, v) for v in values.T], 1), atol=1e-12)
    steps = _sampled(times, values, "STEP", t, False)
    np.testing.assert_allclose(steps, values[np.clip(np.searchsorted(times, t, side="right") - 1, 0, 3)])
    tangents = rng.normal(size=(4, 3))
    cubic = _sampled(times, np.stack([tangents, values, tangents], 1).reshape(12, 3), "CUBICSPLINE", t, False)
    inside = (t >= 0) & (t <= 1.2)
    np.testing.assert_allclose(cubic[inside], CubicHermiteSpline(times, values, tangents)(t[inside]), atol=1e-12)
    assert _frame_rate([np.arange(10) / 60.0]) == 60.0 and _frame_rate([np.arange(5) / 24.0]) == 24.0
    assert _frame_rate([np.array([0.0])]) == 30.0 and _frame_rate([np.arange(4) / 7.0]) == 7.0
