"""Tests of formats/collada.py: COLLADA files of a skeleton's animation, written here as Blender and Mixamo write
them (a matrix per joint node, keyed every frame, a skin's inverse bind matrices) and as Maya and 3ds Max do
(translate and rotate elements, one channel per angle), read back as the SMPL motion they move as."""

import logging
import re

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from core.rotations import axis_angle_to_matrix
from formats.motion import load_motion
from tests.formats.test_bvh import MIXAMO, _bone_directions, _motion, rig_motion
from tests.formats.test_motion import assert_each_refused

NS = "http://www.collada.org/2005/11/COLLADASchema"


def _numbers(values) -> str:
    return " ".join(f"{v:.9g}" for v in np.asarray(values, dtype=np.float64).ravel())


def _source(sid: str, values, stride: int, names: bool = False) -> str:
    values = list(values)
    count = len(values) if names else int(np.asarray(values).size)
    array = (f'<Name_array id="{sid}-array" count="{count}">{" ".join(values)}</Name_array>' if names
             else f'<float_array id="{sid}-array" count="{count}">{_numbers(values)}</float_array>')
    return (f'<source id="{sid}">{array}<technique_common><accessor source="#{sid}-array" '
            f'count="{count // stride}" stride="{stride}"/></technique_common></source>')


def rig_dae(path, poses, trans, fps=30, seed=1, elements="matrix", posed=0.0, skin=True):
    """A COLLADA file of `rig_motion`'s rig (centimetres, an A-pose, 15 % larger, Y-up): each joint a node of type
    JOINT with a random rest rotation; elements 'matrix': its transform one <matrix> and a channel of a matrix per
    frame (Blender's, Mixamo's); 'components': translate, rotateZ, rotateY, rotateX elements and a channel per
    angle, the root's translate keyed whole (Maya's). skin: a controller's inverse bind matrices of the rest;
    posed: each limb node's own rotation then turned this many degrees (a file saved posed: the animation is the
    same)."""
    names, parents, offsets, rotations, root = rig_motion(poses, trans, MIXAMO, unit=0.01, scale=1.15, a_pose=40.0)
    rng = np.random.default_rng(seed)
    J, T = len(names), len(poses)
    pre = Rotation.random(J, random_state=rng).as_matrix()
    frame, steps, world = [None] * J, [None] * J, [None] * J
    local = np.empty((T, J, 4, 4))
    for j, p in enumerate(parents):
        parent_frame = frame[p] if p >= 0 else np.eye(3)
        frame[j] = parent_frame @ pre[j]
        steps[j] = root[0] if p < 0 else parent_frame.T @ offsets[j]
        rest = np.eye(4)
        rest[:3, :3], rest[:3, 3] = pre[j], steps[j]
        world[j] = rest if p < 0 else world[p] @ rest
        local[:, j] = np.eye(4)
        local[:, j, :3, :3] = parent_frame.T @ rotations[:, j] @ parent_frame @ pre[j]
        local[:, j, :3, 3] = root if p < 0 else steps[j]
    times = np.arange(T) / fps
    sid = [n.split(":")[-1] for n in names]
    animations, nodes = [], {}
    for j in range(J):
        static = local[0, j].copy() if posed == 0 else np.eye(4)
        static[:3, :3] = pre[j] @ (Rotation.from_rotvec(rng.normal(size=3) / np.sqrt(3) * np.radians(posed))
                                   .as_matrix() if posed and not sid[j].endswith(("Hips", "Spine")) else np.eye(3))
        static[:3, 3] = steps[j]
        if elements == "matrix":
            body = f'<matrix sid="transform">{_numbers(static)}</matrix>'
            keyed = [("transform", local[:, j].reshape(T, 16), 16)]
        else:
            zyx = Rotation.from_matrix(local[:, j, :3, :3]).as_euler("ZYX", degrees=True)
            zyx = np.degrees(np.unwrap(np.radians(zyx), axis=0))
            rest_zyx = Rotation.from_matrix(static[:3, :3]).as_euler("ZYX", degrees=True)
            body = (f'<translate sid="location">{_numbers(static[:3, 3])}</translate>'
                    + "".join(f'<rotate sid="rotation{a}">{_numbers(axis)} {rest_zyx[k]:.9g}</rotate>'
                              for k, (a, axis) in enumerate(zip("ZYX", np.eye(3)[::-1]))))
            keyed = [(f"rotation{a}.ANGLE", zyx[:, k:k + 1], 1) for k, a in enumerate("ZYX")]
            if parents[j] < 0:
                keyed.append(("location", local[:, j, :3, 3], 3))
        nodes[j] = (f'<node id="n{j}" name="{names[j]}" sid="{sid[j]}" type="JOINT">{body}', parents[j])
        for target, values, stride in keyed:
            a = f"a{j}_{target.replace('.', '_')}"
            animations.append(f'<animation id="{a}">{_source(a + "-in", times, 1)}{_source(a + "-out", values, stride)}'
                              f'{_source(a + "-interp", ["LINEAR"] * T, 1, names=True)}<sampler id="{a}-s">'
                              f'<input semantic="INPUT" source="#{a}-in"/><input semantic="OUTPUT" source="#{a}-out"/>'
                              f'<input semantic="INTERPOLATION" source="#{a}-interp"/></sampler>'
                              f'<channel source="#{a}-s" target="n{j}/{target}"/></animation>')

    def tree(j: int) -> str:
        return nodes[j][0] + "".join(tree(c) for c, (_, p) in nodes.items() if p == j) + "</node>"

    scale = np.diag([0.01, 0.01, 0.01, 1.0])  # an Armature node scaling centimetres
    controller = ""
    if skin:
        ibm = [np.linalg.inv(scale @ world[j]) for j in range(J)]
        controller = (f'<library_controllers><controller id="skin"><skin source="#mesh"><bind_shape_matrix>'
                      f'{_numbers(np.eye(4))}</bind_shape_matrix>{_source("joints", sid, 1, names=True)}'
                      f'{_source("binds", np.array(ibm), 16)}<joints><input semantic="JOINT" source="#joints"/>'
                      f'<input semantic="INV_BIND_MATRIX" source="#binds"/></joints></skin></controller>'
                      f'</library_controllers>')
    text = (f'<?xml version="1.0" encoding="utf-8"?><COLLADA xmlns="{NS}" version="1.4.1"><asset><unit meter="1"/>'
            f'<up_axis>Y_UP</up_axis></asset><library_animations>{"".join(animations)}</library_animations>'
            f'{controller}<library_visual_scenes><visual_scene id="scene"><node id="Armature" name="Armature" '
            f'type="NODE"><matrix sid="transform">{_numbers(scale)}</matrix>{tree(0)}</node></visual_scene>'
            f'</library_visual_scenes><scene><instance_visual_scene url="#scene"/></scene></COLLADA>')
    path.write_text(text)
    return path


@pytest.mark.parametrize("elements, posed, skin", [("matrix", 0.0, False), ("matrix", 70.0, True),
                                                   ("components", 0.0, True)])
def test_a_collada_rig_reads_as_the_smpl_motion_it_moves_as(tmp_path, elements, posed, skin):
    """A rig's COLLADA (joint nodes with rest rotations under an Armature node scaling centimetres, an A-pose, 15 %
    larger), its joints keyed as Blender writes them (a matrix per frame; no skin: its nodes' own transforms the
    rest), also saved with its limbs posed 70 degrees (the skin's bind pose its rest), or as Maya does (translate
    and Euler angle channels), reads back the SMPL motion it moves as; Y-up read from its rest. Posed and saved
    without its skin, its bones still move SMPL's along them."""
    poses, trans = _motion(5, seed=41)
    poses[:, 22:] = 0
    m = load_motion(rig_dae(tmp_path / "walk.dae", poses, trans, elements=elements, posed=posed, skin=skin),
                    world_checks=False)
    assert m.fps == pytest.approx(30) and m.n_frames == 5 and m.rest_up == "y"
    np.testing.assert_allclose(axis_angle_to_matrix(m.poses), axis_angle_to_matrix(poses), atol=1e-4)
    np.testing.assert_allclose(m.trans, trans, atol=1e-4)
    if posed:  # without the skin the posed nodes are the rest, which does not stand: each bone is turned from the
        # frame it stands best in, SMPL's bones along the rig's in every frame (the twist about each the actor's there)
        bare = load_motion(rig_dae(tmp_path / "bare.dae", poses, trans, posed=posed, skin=False), world_checks=False)
        np.testing.assert_allclose(_bone_directions(bare.poses), _bone_directions(poses), atol=1e-4)


def test_a_collada_without_joints_damaged_or_still_is_one_line_or_one_frame(tmp_path, caplog):
    """No JOINT node and no skin naming any, XML cut short, another document: one line; no animation: one frame of
    its rest, warned; joints written as type NODE are the ones its skin names."""
    poses, trans = _motion(2, seed=43)
    good = rig_dae(tmp_path / "good.dae", poses, trans).read_text()
    start, stop = good.index("<library_controllers>"), good.index("</library_controllers>")
    no_skin = good[:start] + good[stop + len("</library_controllers>"):]
    cases = [(no_skin.replace('type="JOINT"', 'type="NODE"').encode(),
              "expected a COLLADA skeleton (nodes of type JOINT), found 28 node(s) and no joint"),
             (good[:len(good) // 2].encode(), "expected a COLLADA file (XML), got XML that does not parse"),
             (b'<?xml version="1.0"?><scene/>', "expected a COLLADA document (a <COLLADA> root), got <scene>")]
    out = re.search(r'<float_array id="([^"]*-out-array)"[^>]*>([^<]*)<', good)  # an output one value short
    short = good[:out.start(2)] + " ".join(out.group(2).split()[:-1]) + good[out.end(2):]
    cases.append((short.encode(), "to hold 32 values (16 per key time), got 31"))  # its joint was read at rest
    assert_each_refused(tmp_path / "bad.dae", cases)
    start, stop = good.index("<library_animations>"), good.index("</library_animations>")
    (tmp_path / "still.dae").write_text(good[:start] + good[stop + len("</library_animations>"):])
    # joints of type NODE, as some exporters write them: the ones the skin names
    (tmp_path / "nodes.dae").write_text(good.replace('type="JOINT"', 'type="NODE"'))
    np.testing.assert_allclose(load_motion(tmp_path / "nodes.dae", world_checks=False).poses,
                               load_motion(tmp_path / "good.dae", world_checks=False).poses, atol=1e-12)
    with caplog.at_level(logging.WARNING):
        m = load_motion(tmp_path / "still.dae", world_checks=False)
    assert "no animation of its joints: its one frame is the skeleton as it stands" in caplog.text
    assert m.n_frames == 1
