"""Tests of formats/mvnx.py: Xsens MVNX files (MVN's XML: per frame, each segment's orientation quaternion, w
first, and position, Z-up metres; identity and T-pose frames before the motion), written here from an SMPL motion
on Xsens' body model, read back as that motion."""

import logging

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from core.body import default_body
from core.motion import Y_UP_TO_Z_UP_MATRIX
from core.retarget import rig_pose
from core.rotations import axis_angle_to_matrix
from formats.motion import load_motion
from formats.mvnx import XSENS_PARENTS
from tests.formats.test_bvh import _motion, _rig, rig_motion
from tests.formats.test_motion import assert_each_refused

#: Xsens' 23 segments as rig_motion's rig: each on its SMPL joint (L3 SMPL's middle spine joint, as the spine's
#: shape matches it), T12 between SMPL's upper two.
XSENS = _rig([("Pelvis", None, 0), ("L5", "Pelvis", 3), ("L3", "L5", 6), ("T12", "L3", (6, 9, 0.5)),
              ("T8", "T12", 9), ("Neck", "T8", 12), ("Head", "Neck", 15)]
             + [e for side, s in (("Left", 0), ("Right", 1)) for e in (
                 (f"{side}Shoulder", "T8", 13 + s), (f"{side}UpperArm", f"{side}Shoulder", 16 + s),
                 (f"{side}ForeArm", f"{side}UpperArm", 18 + s), (f"{side}Hand", f"{side}ForeArm", 20 + s),
                 (f"{side}UpperLeg", "Pelvis", 1 + s), (f"{side}LowerLeg", f"{side}UpperLeg", 4 + s),
                 (f"{side}Foot", f"{side}LowerLeg", 7 + s), (f"{side}Toe", f"{side}Foot", 10 + s))])


def write_mvnx(path, poses, trans, fps=60, jitter=0.0, namespace=True):
    """An MVNX of Xsens' body model moving as the SMPL motion (`poses`, `trans`), in MVN's Z-up world, its
    segments in MVN's order (not rig_motion's), an identity and a T-pose frame before the motion's; jitter: metres
    of noise on every segment's position (the soft joints of MVN's fusion)."""
    names, parents, offsets, rotations, root = rig_motion(poses, trans, XSENS, unit=1.0)
    world, position = rig_pose(parents, offsets, rotations, root)
    turn = Y_UP_TO_Z_UP_MATRIX
    world, position = turn @ world, position @ turn.T
    position = position + np.random.default_rng(0).normal(scale=jitter, size=position.shape)
    rest_world = np.broadcast_to(turn, (len(names), 3, 3))
    rest_position = rig_pose(parents, offsets, np.broadcast_to(np.eye(3), (1, len(names), 3, 3)),
                             offsets[:1])[1][0] @ turn.T
    order = [names.index(s) for s in XSENS_PARENTS]

    def frame(kind, R, p, index=None):
        q = Rotation.from_matrix(R[order]).as_quat()[:, [3, 0, 1, 2]]  # w first
        at = "" if index is None else f' index="{index}" time="{index * 1000 / fps:.0f}"'
        return (f'<frame type="{kind}"{at}><orientation>{" ".join(f"{v:.9f}" for v in q.ravel())}</orientation>'
                f'<position>{" ".join(f"{v:.9f}" for v in p[order].ravel())}</position></frame>')

    ns = ' xmlns="http://www.xsens.com/mvn/mvnx"' if namespace else ""
    segments = "".join(f'<segment label="{s}" id="{k + 1}"><points/></segment>' for k, s in enumerate(XSENS_PARENTS))
    frames = [frame("identity", np.broadcast_to(np.eye(3), rest_world.shape), rest_position),
              frame("tpose", rest_world, rest_position)]
    frames += [frame("normal", world[t], position[t], t) for t in range(len(poses))]
    path.write_text(f'<?xml version="1.0" encoding="UTF-8"?>\n<mvnx version="4"{ns}><mvn version="2022.0.0"/>'
                    f'<subject label="s1" frameRate="{fps}" segmentCount="23"><segments>{segments}</segments>'
                    f'<frames segmentCount="23">{"".join(frames)}</frames></subject></mvnx>')
    return path


@pytest.mark.parametrize("namespace, jitter", [(True, 0.0), (False, 0.003)])
def test_an_mvnx_reads_as_the_smpl_motion_its_segments_move_as(tmp_path, namespace, jitter):
    """Every body joint's rotation (in MVN's Z-up world: the root turned from SMPL's Y-up one), the pelvis's path
    (its place in that world), the frame rate, Z up read from its T-pose; with the segments' places jittered by
    3 mm (MVN's soft joints), the rotations the same and the path within the jitter."""
    poses, trans = _motion(6, seed=13)
    poses[:, 22:] = 0
    poses[:, [10, 11]] = 0  # the toes: Xsens' Toe segments end the feet, SMPL's toe joints have no bone beyond
    m = load_motion(write_mvnx(tmp_path / "walk.mvnx", poses, trans, jitter=jitter, namespace=namespace),
                    world_checks=False)
    assert m.fps == 60 and m.n_frames == 6 and m.rest_up == "z"
    want = axis_angle_to_matrix(poses.astype(np.float64))
    want[:, 0] = Y_UP_TO_Z_UP_MATRIX @ want[:, 0]
    np.testing.assert_allclose(axis_angle_to_matrix(m.poses), want, atol=1e-4)
    pelvis = default_body().shaped(None)[1][0]
    np.testing.assert_allclose(m.trans, (pelvis + trans) @ Y_UP_TO_Z_UP_MATRIX.T - pelvis, atol=1e-4 + 5 * jitter)


def test_an_mvnx_with_finger_tracking_reads_its_body_and_leaves_the_fingers_out(tmp_path, caplog):
    """MVN's export with gloves lists 20 finger segments a hand after the body's (fingerTrackingSegmentsLeft/Right)
    and their data apart in each frame: it was refused ("expected 252 orientation values in each of its 6 frames,
    got 552 in all")."""
    poses, trans = _motion(6, seed=13)
    plain = load_motion(write_mvnx(tmp_path / "plain.mvnx", poses, trans), world_checks=False)
    text = (tmp_path / "plain.mvnx").read_text()
    lists = "".join(f"<fingerTrackingSegments{side}>"
                    + "".join(f'<segment label="{side}Finger{k}" id="{k + 1}"><points/></segment>' for k in range(20))
                    + f"</fingerTrackingSegments{side}>" for side in ("Left", "Right"))
    data = "".join(f"<orientationFingers{side}>{' '.join(['1 0 0 0'] * 20)}</orientationFingers{side}>"
                   f"<positionFingers{side}>{' '.join(['0 0 0'] * 20)}</positionFingers{side}>"
                   for side in ("Left", "Right"))
    text = text.replace("</segments>", "</segments>" + lists).replace("</position></frame>", "</position>" + data
                                                                      + "</frame>")
    (tmp_path / "gloves.mvnx").write_text(text)
    with caplog.at_level(logging.WARNING):
        gloves = load_motion(tmp_path / "gloves.mvnx", world_checks=False)
    np.testing.assert_array_equal(gloves.poses, plain.poses)
    np.testing.assert_array_equal(gloves.trans, plain.trans)
    assert "its 40 finger segments (finger tracking) left out" in caplog.text


def test_an_mvnx_of_other_segments_damaged_or_without_motion_is_one_line(tmp_path):
    poses, trans = _motion(2)
    good = write_mvnx(tmp_path / "good.mvnx", poses, trans).read_text()
    cases = [(good[:len(good) // 2], "its MVNX (XML) is damaged"),
             (good.replace('label="LeftToe"', 'label="LeftToes"'),
              "expected the segments of Xsens' body model, found none named LeftToe (it has Pelvis, L5, L3, T12, ...)"),
             (good.replace('frameRate="60"', 'frameRate="fast"'), "expected a frameRate on its subject, got 'fast'"),
             (good.replace('type="normal"', 'type="calibration"'), "expected frames of type 'normal' (the motion)"),
             (good.replace("<orientation>1.0", "<orientation>x", 1).replace("<orientation>0.", "<orientation>x", 1),
              "expected numbers in its frames' orientation")]
    assert_each_refused(tmp_path / "bad.mvnx", cases)
