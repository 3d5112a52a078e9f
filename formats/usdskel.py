"""USD skeletal animation (UsdSkel: a Skeleton prim and a SkelAnimation, as Blender, Houdini's KineFX, Maya,
Omniverse and Apple's tools write them; `.usd`, `.usda`, `.usdc`, `.usdz`), read as the skeleton and motion
`core.retarget` turns into SMPL's, as an FBX or a glTF is (`formats.fbx`, `formats.gltf`).

The skeleton is the stage's Skeleton of the most humanoid joint names (then of the most joints), its joints'
names the last element of their paths, their hierarchy its topology. Each joint's transform is its
SkelAnimation's translation, rotation and scale at the frame (a joint the animation leaves out, or a component
it does not author, keeps its rest's), composed down the hierarchy and placed in the stage by the Skeleton's own
transforms at that time (an Armature's turn from Y-up and centimetre scaling, as Blender writes it). The
animation is the one the Skeleton (or a prim above it) binds as `skel:animationSource`, else the first; a stage of
several holds them as takes (`--take` names one by its prim's name). Frames are the animation's time samples'
spacing (timeCodesPerSecond; snapped to a common rate as glTF keys are), between its first and last samples, USD
interpolating between them. The rest pose is the skin's bind pose (`bindTransforms`: Blender writes
`restTransforms` as the pose of the frame it exported), else `restTransforms` composed. `core.retarget` reads the
rest's world and the legs' unit as for any rig. A stage of no Skeleton named as a motion is refused in one line;
a Skeleton with no animation is one frame of its rest, warned.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
from pxr import Tf, Usd, UsdGeom, UsdSkel

from core.errors import InputError
from core.retarget import role_names
from core.rotations import quat_to_matrix
from formats.bvh import Skeleton
from formats.fbx import chosen_take, skeleton_of
from formats.gltf import DEFAULT_FPS, key_times
from formats.usd import open_stage

log = logging.getLogger(__name__)


def _skeletons(stage: Usd.Stage) -> list:
    return [UsdSkel.Skeleton(p) for p in stage.Traverse() if p.IsA(UsdSkel.Skeleton)]


def holds_skeleton(path: Path) -> bool:
    """Whether the USD file `path` has a UsdSkel Skeleton prim; True where it cannot be opened (named as a motion,
    it is refused with the reason)."""
    try:
        stage = Usd.Stage.Open(str(path))
    except Tf.ErrorException:
        return True
    return stage is None or bool(_skeletons(stage))


def _joint_names(skel) -> list[str]:
    return [str(j).rsplit("/", 1)[-1] for j in (skel.GetJointsAttr().Get() or [])]


def _chosen_skeleton(stage: Usd.Stage, src: str):
    skels = [s for s in _skeletons(stage) if s.GetJointsAttr().Get()]
    if not skels:
        prims = sum(1 for _ in stage.Traverse())
        raise InputError(f"{src}: expected a USD of a skeleton (a UsdSkel Skeleton prim and its joints), found "
                         f"{prims} prim(s) and no Skeleton: export the character's skeleton with its animation")
    return max(skels, key=lambda s: (role_names(_joint_names(s)), len(s.GetJointsAttr().Get())))


def _bound_animation(skel):
    """The path of the SkelAnimation `skel` binds (on itself or a prim above it), else None."""
    prim = skel.GetPrim()
    while prim and prim.IsValid():
        targets = UsdSkel.BindingAPI(prim).GetAnimationSourceRel().GetTargets()
        if targets:
            return targets[0]
        prim = prim.GetParent()
    return None


def _animations(stage: Usd.Stage, skel) -> list:
    """The SkelAnimations of `skel`, the one it binds first: of the others, those no other skeleton binds and most
    of whose joints are its (a cape's or a prop's animation beside it was offered as a take of the human, who
    stood at rest through it)."""
    found = [UsdSkel.Animation(p) for p in stage.Traverse() if p.IsA(UsdSkel.Animation)]
    bound = _bound_animation(skel)
    others = {_bound_animation(s) for s in _skeletons(stage) if s.GetPrim() != skel.GetPrim()} - {None, bound}
    tokens = [str(j) for j in (skel.GetJointsAttr().Get() or [])]
    names = set(tokens) | {t.rsplit("/", 1)[-1] for t in tokens}

    def its(animation) -> bool:
        joints = [str(j) for j in (animation.GetJointsAttr().Get() or [])]
        return 2 * sum(j in names for j in joints) > len(joints)

    kept = [a for a in found if a.GetPath() == bound or (a.GetPath() not in others and its(a))]
    return sorted(kept, key=lambda a: a.GetPath() != bound)


def animation_names(path: Path) -> list[str]:
    """The names of the SkelAnimations of the USD file `path` where it holds several (`--take`; the one its
    skeleton binds first), else []; InputError naming the file where it has no skeleton."""
    src = f"motion '{path}'"
    stage = open_stage(Path(path), src)
    names = [a.GetPrim().GetName() for a in _animations(stage, _chosen_skeleton(stage, src))]
    return names if len(names) > 1 else []


def read_usdskel(path: Path, src: str, take: str | None = None) -> Skeleton:
    """The skeleton and motion of the USD file `path` (module docstring), as `formats.fbx.read_fbx` gives an FBX's;
    of a stage of several animations, the one named `take` (default: the one its skeleton binds). InputError
    naming `src` for a file that is no USD, or one without a skeleton."""
    stage = open_stage(Path(path), src)
    skel = _chosen_skeleton(stage, src)
    tokens = [str(j) for j in skel.GetJointsAttr().Get()]
    J = len(tokens)
    topology = UsdSkel.Topology(skel.GetJointsAttr().Get())
    ok, why = topology.Validate()
    if not ok:
        raise InputError(f"{src}: its skeleton '{skel.GetPath()}' has joints not in a hierarchy USD reads ({why})")
    parents = [int(p) for p in topology.GetParentIndices()]
    rest_local = _matrices(skel.GetRestTransformsAttr().Get(), J)
    bind = _matrices(skel.GetBindTransformsAttr().Get(), J)
    if bind is not None and not _invertible(bind):
        bind = None
        if rest_local is not None:
            log.warning("%s: its skeleton's bindTransforms are not %d invertible 4x4 matrices: its restTransforms "
                        "are taken as its rest", src, J)
    if rest_local is None and bind is None:
        raise InputError(f"{src}: its skeleton '{skel.GetPath()}' has neither invertible bindTransforms nor "
                         f"restTransforms for its {J} joints")
    given_rest = rest_local is not None
    if rest_local is None:  # the bind pose, joint by joint from its parent
        rest_local = np.array([bind[j] if p < 0 else np.linalg.inv(bind[p]) @ bind[j] for j, p in enumerate(parents)])
    animations = _animations(stage, skel)
    chosen = chosen_take([a.GetPrim().GetName() for a in animations], take, src, "animations")
    animation = animations[chosen] if chosen is not None else None
    times, fps = _frame_times(stage, animation, src)
    if times is None:
        log.warning("%s: no animation of its skeleton: its one frame is the skeleton as it stands", src)
    local = np.broadcast_to(rest_local, (1 if times is None else len(times), J, 4, 4)).copy()
    if times is not None:
        _animate(local, animation, tokens, times, rest_local, src)
    else:
        times, fps = np.zeros(1), DEFAULT_FPS
    skel_space = _composed(local, parents)
    imageable = UsdGeom.Imageable(skel.GetPrim())
    place = np.array([np.asarray(imageable.ComputeLocalToWorldTransform(Usd.TimeCode(t))).T for t in times])
    world = {j: place @ skel_space[:, j] for j in range(J)}
    if bind is None:
        resting = place[0] @ _composed(rest_local[None], parents)[0]
    elif _bind_in_world(bind, place[0], _composed(rest_local[None], parents)[0] if given_rest else skel_space[0],
                        parents, exact=given_rest):
        resting = bind  # the spec's world space (maya-usd's), the skeleton's parents' transforms in it
    else:
        resting = place[0] @ bind  # the skeleton's own space (Blender's)
    rest = {j: resting[j] for j in range(J)}
    names = {j: t.rsplit("/", 1)[-1] for j, t in enumerate(tokens)}
    skeleton = skeleton_of(list(range(J)), names, {j: p for j, p in enumerate(parents) if p >= 0}, list(range(J)),
                           world, rest, 1.0 / fps)
    return skeleton._replace(take=animation.GetPrim().GetName()) if len(animations) > 1 else skeleton


def _bind_in_world(bind: np.ndarray, place: np.ndarray, skel_space: np.ndarray, parents: list[int],
                   exact: bool) -> bool:
    """Whether a Skeleton's bindTransforms (J, 4, 4) are in world space, the skeleton's place in the world
    (`place`, (4, 4): its parents' transforms) in them, as USD's schema defines them and maya-usd writes them,
    rather than in the skeleton's own space as Blender writes them (a skeleton under a group scaled 0.01 walked
    100 times too far, under one turned 90 degrees lay on its back). Told by the joints of `skel_space` (J, 4, 4),
    the skeleton's space: where `exact` (its restTransforms composed, the bind pose as maya-usd writes them), the
    bind's joints lie where those do in one space; else (Blender's restTransforms are its first frame's pose, and
    a skeleton without them has its animation's first frame) its bones are as long as they are in one space (a
    place that turns only: the skeleton's space)."""
    if np.allclose(place, np.eye(4), atol=1e-9):
        return False
    world = place @ skel_space
    if exact:
        size = max(float(np.ptp(world[:, :3, 3], axis=0).max()), 1e-12)
        near_world = np.abs(bind[:, :3, 3] - world[:, :3, 3]).max() <= 1e-4 * size
        near_own = np.abs(bind[:, :3, 3] - skel_space[:, :3, 3]).max() <= 1e-4 * size
        if near_world != near_own:
            return near_world
    bones = [j for j, p in enumerate(parents) if p >= 0]
    if not bones:
        return False

    def lengths(m):
        return np.linalg.norm(m[bones, :3, 3] - m[[parents[j] for j in bones], :3, 3], axis=1)

    own = lengths(skel_space)
    kept = own > 1e-9 * max(float(own.max()), 1e-300)
    if not kept.any():
        return False
    ratio = float(np.median(lengths(bind)[kept] / own[kept]))
    scale = float(np.cbrt(abs(np.linalg.det(place[:3, :3]))))
    return abs(np.log(max(ratio, 1e-300) / scale)) < abs(np.log(max(ratio, 1e-300)))


def _composed(local: np.ndarray, parents: list[int]) -> np.ndarray:
    """(T, J, 4, 4) each joint's transform in the skeleton's space of local ones (T, J, 4, 4), parents first."""
    out = np.empty_like(local)
    for j, p in enumerate(parents):
        out[:, j] = local[:, j] if p < 0 else out[:, p] @ local[:, j]
    return out


def _matrices(value, J: int) -> np.ndarray | None:
    """(J, 4, 4) column-vector matrices of a USD matrix4d[] (row vectors) of J joints, else None."""
    if value is None or len(value) != J:
        return None
    out = np.asarray(value, dtype=np.float64).transpose(0, 2, 1)
    return out if np.isfinite(out).all() else None


def _invertible(m: np.ndarray) -> bool:
    s = np.linalg.svd(m[:, :3, :3], compute_uv=False)
    return bool((s[:, -1] > 1e-9 * s[:, 0]).all())


def _authored(animation) -> bool:
    return any(a.HasAuthoredValue() for a in (animation.GetTranslationsAttr(), animation.GetRotationsAttr(),
                                             animation.GetScalesAttr()))


def _frame_times(stage: Usd.Stage, animation, src: str) -> tuple[np.ndarray | None, float]:
    """(the time codes of the frames, frames per second) of `animation`'s samples: spaced as its most sampled
    attribute's (`formats.gltf.key_times`), from its first sample to its last; one frame where it holds static
    values only; (None, 0) where it holds none (or there is none)."""
    if animation is None:
        return None, 0.0
    per_second = stage.GetTimeCodesPerSecond() or DEFAULT_FPS
    samples = [np.asarray(a.GetTimeSamples(), dtype=np.float64) for a in
               (animation.GetTranslationsAttr(), animation.GetRotationsAttr(), animation.GetScalesAttr())]
    samples = [s for s in samples if len(s)]
    if not samples:
        return (np.zeros(1), DEFAULT_FPS) if _authored(animation) else (None, 0.0)
    return key_times(samples, src, per_second, "samples")


def _animate(local: np.ndarray, animation, tokens: list[str], times: np.ndarray, rest_local: np.ndarray,
             src: str = "") -> None:
    """Write `animation`'s joints' local transforms at `times` into local (T, J, 4, 4) (the skeleton's joint
    order); a component it does not author (at a frame) keeps the rest's. A joint of the animation's named by its
    last part only (`Spine` for the skeleton's `Hips/Spine`, as some exporters write them) is the skeleton's joint
    of that name where one only has it; those that name none are warned about (left at rest: it was silent)."""
    order = {t: j for j, t in enumerate(tokens)}
    leaves = {}
    for j, t in enumerate(tokens):
        leaves.setdefault(t.rsplit("/", 1)[-1], []).append(j)
    anim_joints = [str(t) for t in (animation.GetJointsAttr().Get() or [])]
    into = np.array([order[t] if t in order else leaves[t][0] if len(leaves.get(t, ())) == 1 else -1
                     for t in anim_joints], dtype=np.int64)
    keep = into >= 0
    if not keep.all():
        unknown = [t for t, k in zip(anim_joints, keep) if not k]
        log.warning("%s: %d of its animation's %d joints name none of its skeleton's (%s): left at rest", src,
                    len(unknown), len(anim_joints), ", ".join(unknown[:4]) + (", ..." if len(unknown) > 4 else ""))
    into = into[keep]
    rest_scale = np.linalg.norm(rest_local[into, :3, :3], axis=1)  # (K, 3) column norms
    rest_turn = rest_local[into, :3, :3] / rest_scale[:, None, :]
    attrs = (animation.GetTranslationsAttr(), animation.GetRotationsAttr(), animation.GetScalesAttr())
    authored = [a.HasAuthoredValue() for a in attrs]
    moves, quats, scales, unturned = [], [], [], []
    for t in times:  # USD's values at each frame (interpolated between its samples), then all frames at once
        code = Usd.TimeCode(float(t))
        move, turn, scale = (a.Get(code) if on else None for a, on in zip(attrs, authored))
        for what, v in zip(("translations", "rotations", "scales"), (move, turn, scale)):
            if v is not None and len(v) != len(anim_joints):  # a damaged sample: not the rest (it was, silently)
                raise InputError(f"{src}: its animation '{animation.GetPath()}' has {len(v)} {what} at time "
                                 f"{float(t):g} for its {len(anim_joints)} joints")
        ok = [v is not None for v in (move, turn, scale)]
        moves.append(np.asarray(move, float)[keep] if ok[0] else rest_local[into, :3, 3])
        quats.append(np.asarray(turn, float)[keep] if ok[1] else np.broadcast_to([0.0, 0.0, 0.0, 1.0], (len(into), 4)))
        unturned.append(not ok[1])  # a frame without rotations: its rest's, below (a NaN in one stays one)
        scales.append(np.asarray(scale, float)[keep] if ok[2] else rest_scale)
    q = np.array(quats)  # (T, K, 4) x y z w
    q /= np.maximum(np.linalg.norm(q, axis=-1, keepdims=True), 1e-12)
    R = quat_to_matrix(q[..., [3, 0, 1, 2]])
    missing = np.array(unturned, dtype=bool)
    R[missing] = rest_turn
    block = local[:, into]  # (T, K, 4, 4): a copy (the joints' index apart from the matrices' slices)
    block[..., :3, :3] = R * np.array(scales)[:, :, None, :]
    block[..., :3, 3] = np.array(moves)
    local[:, into] = block
