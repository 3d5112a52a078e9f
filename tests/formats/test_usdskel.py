"""Tests of formats/usdskel.py: USD skeletal animation (a UsdSkel Skeleton and its SkelAnimations), written here as
Blender writes it (joints named 'mixamorig_Hips', an Armature Xform turning a Y-up skeleton in centimetres into a
Z-up stage in metres, bindTransforms the rest, restTransforms the pose of the first frame), read back as the SMPL
motion it moves as; several animations as takes; stages of no skeleton refused in one line."""

import logging

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, UsdSkel, UsdUtils, Vt
from scipy.spatial.transform import Rotation

from core.errors import InputError
from core.rotations import axis_angle_to_matrix
from formats.motion import load_motion, motion_takes
from tests.formats.test_bvh import MIXAMO, _motion, rig_motion
from tests.formats.test_motion import assert_each_refused


def _matrix(M: np.ndarray) -> Gf.Matrix4d:
    """A column-vector (4, 4) as USD's row-vector matrix."""
    return Gf.Matrix4d(np.asarray(M, dtype=np.float64).T.tolist())


def rig_usd(path, takes, rig=MIXAMO, fps=30, seed=1, armature=True, bound=0, drop=None, scales=True,
            bind_world=False, rest_pose="first"):
    """A USD stage of `rig_motion`'s rig (centimetres, an A-pose, 15 % larger): a Skeleton of joints named as
    Blender writes them ('mixamorig_Hips', paths from the root), each with a random rest rotation, its
    bindTransforms the rest and its restTransforms the first frame's pose; a SkelAnimation per take
    {name: (poses, trans)} of every joint's translation, rotation and scale per frame (time codes 1, 2, ... at
    `fps`), the take `bound` bound as the Skeleton's animation source. armature: the Skeleton under an Xform
    turning Y-up to Z-up and scaling centimetres to metres in a Z-up stage in metres (Blender's); else the
    Skeleton at the root of a Y-up stage in centimetres. drop: a joint (index) the animations leave out (its rest
    kept); scales: False leaves the scales unauthored. The animations list their joints in reverse order. No
    takes: the skeleton alone (its bindTransforms). bind_world: the bindTransforms in world space, the Armature's
    transform in them (USD's schema's, maya-usd's: Blender's are in the skeleton's space); rest_pose: the
    restTransforms of "first" the first frame's pose (Blender's), "bind" the bind pose (maya-usd's), None: none."""
    moving = {name: rig_motion(*m, rig, unit=0.01, scale=1.15, a_pose=40.0) for name, m in takes.items()}
    names, parents, offsets, _, root = next(iter(moving.values()), None) or rig_motion(*_motion(1), rig, unit=0.01,
                                                                                      scale=1.15, a_pose=40.0)
    rng = np.random.default_rng(seed)
    J = len(names)
    pre = Rotation.random(J, random_state=rng).as_matrix()
    frame, place, tokens = [None] * J, [None] * J, [None] * J
    bind = np.tile(np.eye(4), (J, 1, 1))
    steps = []
    for j, p in enumerate(parents):
        parent_frame = frame[p] if p >= 0 else np.eye(3)
        frame[j] = parent_frame @ pre[j]
        place[j] = root[0] if p < 0 else place[p] + offsets[j]
        steps.append(root[0] if p < 0 else parent_frame.T @ offsets[j])
        bind[j, :3, :3], bind[j, :3, 3] = frame[j], place[j]
        name = names[j].split(":")[-1]
        tokens[j] = f"mixamorig_{name}" if p < 0 else f"{tokens[p]}/mixamorig_{name}"
    stage = Usd.Stage.CreateNew(str(path))
    stage.SetTimeCodesPerSecond(fps)
    if armature:
        UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
        UsdGeom.SetStageMetersPerUnit(stage, 1.0)
        xform = UsdGeom.Xform.Define(stage, "/root/Armature")
        xform.AddRotateXYZOp().Set(Gf.Vec3f(90, 0, 0))
        xform.AddScaleOp().Set(Gf.Vec3f(0.01, 0.01, 0.01))
        skel_path = "/root/Armature/Armature"
    else:
        UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
        UsdGeom.SetStageMetersPerUnit(stage, 0.01)
        skel_path = "/Skel"
    skel = UsdSkel.Skeleton.Define(stage, skel_path)
    skel.GetJointsAttr().Set(Vt.TokenArray(tokens))
    if bind_world:
        world = np.asarray(UsdGeom.Imageable(skel.GetPrim()).ComputeLocalToWorldTransform(Usd.TimeCode.Default())).T
        skel.GetBindTransformsAttr().Set(Vt.Matrix4dArray([_matrix(world @ b) for b in bind]))
    else:
        skel.GetBindTransformsAttr().Set(Vt.Matrix4dArray([_matrix(b) for b in bind]))
    if rest_pose == "bind":
        rest = np.tile(np.eye(4), (J, 1, 1))
        rest[:, :3, :3], rest[:, :3, 3] = pre, steps
        skel.GetRestTransformsAttr().Set(Vt.Matrix4dArray([_matrix(r) for r in rest]))
    order = [j for j in reversed(range(J)) if j != drop]
    anim_paths = []
    for k, (take, (*_, rotations, take_root)) in enumerate(moving.items()):
        anim = UsdSkel.Animation.Define(stage, f"{skel_path}/{take}")
        anim.GetJointsAttr().Set(Vt.TokenArray([tokens[j] for j in order]))
        for t in range(len(rotations)):
            local = np.empty((J, 3, 3))
            for j, p in enumerate(parents):
                parent_frame = frame[p] if p >= 0 else np.eye(3)
                local[j] = parent_frame.T @ rotations[t, j] @ parent_frame @ pre[j]
            moves = np.array(steps)
            moves[0] = take_root[t]
            if k == 0 and t == 0 and rest_pose == "first":  # the pose of the first frame, as Blender writes them
                rest = np.tile(np.eye(4), (J, 1, 1))
                rest[:, :3, :3], rest[:, :3, 3] = local, moves
                skel.GetRestTransformsAttr().Set(Vt.Matrix4dArray([_matrix(r) for r in rest]))
            quats = Rotation.from_matrix(local[order]).as_quat()  # x y z w
            code = Usd.TimeCode(t + 1)
            anim.GetTranslationsAttr().Set(Vt.Vec3fArray([Gf.Vec3f(*m) for m in moves[order]]), code)
            anim.GetRotationsAttr().Set(Vt.QuatfArray([Gf.Quatf(q[3], q[0], q[1], q[2]) for q in quats]), code)
            if scales:
                anim.GetScalesAttr().Set(Vt.Vec3hArray([Gf.Vec3h(1, 1, 1)] * len(order)), code)
        anim_paths.append(anim.GetPath())
    if anim_paths:
        UsdSkel.BindingAPI.Apply(skel.GetPrim()).CreateAnimationSourceRel().SetTargets([anim_paths[bound]])
    stage.GetRootLayer().Save()
    return path


@pytest.mark.parametrize("suffix, armature, bind_world, rest_pose", [
    (".usda", True, False, "first"), (".usdc", False, False, "first"), (".usdz", True, False, "first"),
    # maya-usd's: the bind in world space, the group's turn and scale in it (read in the skeleton's space, the
    # body lay on its back and walked 100 times too far), restTransforms the bind pose or none
    (".usda", True, True, "bind"), (".usda", True, True, None), (".usda", False, True, "bind")])
def test_a_usd_skeletal_animation_reads_as_the_smpl_motion_it_moves_as(tmp_path, suffix, armature, bind_world,
                                                                        rest_pose):
    """Blender's UsdSkel (an Armature Xform turning a Y-up skeleton in centimetres into a Z-up stage; the bind
    pose the rest, restTransforms posed) and a Y-up stage in centimetres read back the SMPL motion, in each's world;
    as text, crate and a .usdz package; and maya-usd's (bindTransforms in world space) alike."""
    poses, trans = _motion(5, seed=31)
    poses[:, 22:] = 0
    written = rig_usd(tmp_path / ("walk.usda" if suffix == ".usdz" else f"walk{suffix}"), {"Walk": (poses, trans)},
                      armature=armature, bind_world=bind_world, rest_pose=rest_pose)
    if suffix == ".usdz":
        assert UsdUtils.CreateNewUsdzPackage(Sdf.AssetPath(str(written)), str(tmp_path / "walk.usdz"))
        written = tmp_path / "walk.usdz"
    m = load_motion(written, world_checks=False)
    assert m.fps == pytest.approx(30) and m.n_frames == 5 and m.take is None
    assert m.rest_up == ("z" if armature else "y")
    expected = axis_angle_to_matrix(poses)
    if armature:  # the Armature turns the rig's Y-up world to Z-up: the root turns with it, the path too
        turn = Rotation.from_euler("x", 90, degrees=True).as_matrix()
        expected[:, 0] = turn @ expected[:, 0]
        body = default_pelvis()
        trans = (body + trans) @ turn.T - body
    np.testing.assert_allclose(axis_angle_to_matrix(m.poses), expected, atol=1e-4)
    np.testing.assert_allclose(m.trans, trans, atol=1e-4)


def default_pelvis() -> np.ndarray:
    from core.body import default_body

    return default_body().shaped(None)[1][0].astype(np.float64)


def test_joints_an_animation_leaves_out_or_components_it_does_not_author_keep_the_rest(tmp_path):
    """An animation listing its joints in another order than the skeleton's, without one of them (a finger's end,
    left at rest) and without scales, reads as the motion it moves as."""
    poses, trans = _motion(4, seed=33)
    poses[:, 22:] = 0
    drop = next(j for j, (name, *_) in enumerate(MIXAMO) if name.endswith("HeadTop_End"))
    m = load_motion(rig_usd(tmp_path / "walk.usda", {"Walk": (poses, trans)}, armature=False, drop=drop,
                            scales=False), world_checks=False)
    np.testing.assert_allclose(axis_angle_to_matrix(m.poses), axis_angle_to_matrix(poses), atol=1e-4)
    np.testing.assert_allclose(m.trans, trans, atol=1e-4)


def test_an_animation_naming_joints_by_their_last_part_or_with_a_nan_on_its_first_reads_or_is_refused(tmp_path,
                                                                                                       caplog):
    """An animation whose joints are the joints' names, not the skeleton's paths (`mixamorig_Spine`, not
    `.../mixamorig_Hips/mixamorig_Spine`), was read with every joint but the root at rest, without a word: each
    name is its joint where one joint only has it; a name no joint has is warned about. A NaN rotation of the
    animation's first joint (a toe) put every joint of its frame at rest: it is refused as NaNs elsewhere are."""
    poses, trans = _motion(4, seed=31)
    poses[:, 22:] = 0
    path = rig_usd(tmp_path / "names.usda", {"Walk": (poses, trans)}, armature=False)
    stage = Usd.Stage.Open(str(path))
    animation = UsdSkel.Animation(stage.GetPrimAtPath("/Skel/Walk"))
    tokens = [str(t).rsplit("/", 1)[-1] for t in animation.GetJointsAttr().Get()]
    end = next(k for k, t in enumerate(tokens) if t.endswith("HeadTop_End"))  # a leaf no SMPL joint reads
    animation.GetJointsAttr().Set(Vt.TokenArray(tokens[:end] + ["NoSuchJoint"] + tokens[end + 1:]))
    stage.Save()
    with caplog.at_level(logging.WARNING, logger="formats.usdskel"):
        m = load_motion(path, world_checks=False)
    np.testing.assert_allclose(axis_angle_to_matrix(m.poses[:, :22]), axis_angle_to_matrix(poses[:, :22]), atol=1e-4)
    assert "1 of its animation's" in caplog.text and "NoSuchJoint): left at rest" in caplog.text
    path = rig_usd(tmp_path / "nan.usda", {"Walk": (poses, trans)}, armature=False)
    stage = Usd.Stage.Open(str(path))
    rotations = UsdSkel.Animation(stage.GetPrimAtPath("/Skel/Walk")).GetRotationsAttr()
    code = rotations.GetTimeSamples()[2]
    values = list(rotations.Get(code))
    values[0] = Gf.Quatf(*[float("nan")] * 4)
    rotations.Set(Vt.QuatfArray(values), code)
    stage.Save()
    assert_each_refused(path, [(path.read_bytes(), "contains NaN or Inf (first at frame 2)")])
    rotations.Set(Vt.QuatfArray(values[1:]), code)  # a sample short of a joint: its frame was the rest, silently
    stage.Save()
    assert_each_refused(path, [(path.read_bytes(), "its animation '/Skel/Walk' has 26 rotations at time 3 for its 27 "
                                                   "joints")])


def test_another_skeletons_animation_is_no_take_of_the_human(tmp_path, caplog):
    """A cape's skeleton bound to its own animation beside the human's: its animation was offered as a take of the
    human ("holds 2 animations ('Walk', 'CapeFlap')"), who stood at rest through it under --take CapeFlap."""
    poses, trans = _motion(4, seed=32)
    poses[:, 22:] = 0
    path = rig_usd(tmp_path / "cape.usda", {"Walk": (poses, trans)}, armature=False)
    stage = Usd.Stage.Open(str(path))
    cape = UsdSkel.Skeleton.Define(stage, "/Cape")
    cape.GetJointsAttr().Set(Vt.TokenArray(["cape", "cape/cape1"]))
    cape.GetBindTransformsAttr().Set(Vt.Matrix4dArray([Gf.Matrix4d(1.0)] * 2))
    flap = UsdSkel.Animation.Define(stage, "/Cape/CapeFlap")
    flap.GetJointsAttr().Set(Vt.TokenArray(["cape", "cape/cape1"]))
    for t in range(30):
        flap.GetRotationsAttr().Set(Vt.QuatfArray([Gf.Quatf(1, 0, 0, 0)] * 2), Usd.TimeCode(t + 1))
    UsdSkel.BindingAPI.Apply(cape.GetPrim()).CreateAnimationSourceRel().SetTargets([flap.GetPath()])
    stage.Save()
    assert motion_takes(path) == []
    with caplog.at_level(logging.WARNING):
        m = load_motion(path, world_checks=False)
    assert m.n_frames == 4 and m.take is None and "animations" not in caplog.text
    np.testing.assert_allclose(axis_angle_to_matrix(m.poses), axis_angle_to_matrix(poses), atol=1e-4)


def test_a_usd_of_several_animations_reads_the_bound_one_or_the_one_named(tmp_path, caplog):
    (walk, walk_trans), (run, run_trans) = _motion(5, seed=3), _motion(3, seed=4)
    walk[:, 22:] = run[:, 22:] = 0
    path = rig_usd(tmp_path / "moves.usda", {"Walk": (walk, walk_trans), "Run": (run, run_trans)}, bound=1,
                   armature=False)
    assert motion_takes(path) == ["Run", "Walk"]  # the bound one first
    with caplog.at_level(logging.WARNING):
        m = load_motion(path, world_checks=False)
    assert "holds 2 animations ('Run', 'Walk'): reading 'Run', the first" in caplog.text
    assert m.take == "Run" and m.n_frames == 3
    np.testing.assert_allclose(axis_angle_to_matrix(m.poses), axis_angle_to_matrix(run), atol=1e-4)
    m = load_motion(path, world_checks=False, take="walk")
    assert m.take == "Walk" and m.n_frames == 5
    np.testing.assert_allclose(m.trans, walk_trans, atol=1e-4)


def write_usd_mesh(path):
    """A USD stage of one (empty) mesh, '/garment': no skeleton."""
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.Mesh.Define(stage, "/garment")
    stage.GetRootLayer().Save()
    return path


def test_a_usd_of_no_skeleton_damaged_or_without_animation(tmp_path, caplog):
    """A stage of a mesh alone, or text that is no USD, is one line naming the file; a skeleton without an
    animation is one frame of its rest, warned; bindTransforms that cannot be inverted give way to restTransforms,
    warned, and without either the skeleton is one line."""
    cloth = write_usd_mesh(tmp_path / "cloth.usda").read_bytes()
    cases = [(cloth, "expected a USD of a skeleton (a UsdSkel Skeleton prim and its joints), found 1 prim(s) and no "
                     "Skeleton"),
             (b"#usda 1.0\ndef Skeleton \"S\" {\n  broken", "cannot be opened as USD"),
             (cloth.replace(b'"garment"', b'"garm\x81ent"'), "cannot be opened as USD (its text is not UTF-8)")]
    assert_each_refused(tmp_path / "bad.usda", cases)
    still = rig_usd(tmp_path / "still.usda", {}, armature=False)
    with caplog.at_level(logging.WARNING):
        m = load_motion(still, world_checks=False)
    assert "no animation of its skeleton: its one frame is the skeleton as it stands" in caplog.text
    assert m.n_frames == 1
    standing = (np.zeros((3, 24, 3), np.float32), _motion(3)[1])  # its first frame, restTransforms, stands
    stage = Usd.Stage.Open(str(rig_usd(tmp_path / "flat.usda", {"Walk": standing}, armature=False)))
    skel = UsdSkel.Skeleton(stage.GetPrimAtPath("/Skel"))
    skel.GetBindTransformsAttr().Set(Vt.Matrix4dArray([Gf.Matrix4d(0.0)] * len(MIXAMO)))  # not invertible
    stage.GetRootLayer().Save()
    caplog.clear()
    with caplog.at_level(logging.WARNING):
        assert load_motion(tmp_path / "flat.usda", world_checks=False).n_frames == 3
    assert "its skeleton's bindTransforms are not 27 invertible 4x4 matrices: its restTransforms are taken" in \
        caplog.text
    skel.GetRestTransformsAttr().Block()
    stage.GetRootLayer().Save()
    assert_each_refused(tmp_path / "none.usda", [((tmp_path / "flat.usda").read_bytes(), "has neither invertible "
                                                  "bindTransforms nor restTransforms for its 27 joints")])
    with pytest.raises(InputError, match="expected --take one of"):
        load_motion(rig_usd(tmp_path / "two.usda", {"a": _motion(2), "b": _motion(2)}), take="c")
