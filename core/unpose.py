"""Bring a garment authored on a posed body (an A-pose, a scan's pose) back to the body's rest pose.

Every other command expects the garment on the rest pose (T-pose). Many garments are modelled on an
avatar standing in an A-pose instead: baked as they are, their sleeves cut through the torso. Here each
garment vertex takes the skinning weights of where it is nearest the body posed like the garment
(`core.skinning.surface_blend`, smoothed over the garment as `bind_garment` smooths them), and is moved by the
inverse of its blended skinning transform: the inverse of the linear blend skinning that `lbs` applies, so that
skinning the result with the same weights and pose gives the input back.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from core.body import Body
from core.errors import InputError
from core.garment import Garment, mesh_edges
from core.geometry import TriangleMesh, vertex_normals
from core.skinning import (REST_INSIDE_DEPTH_M, surface_blend, transfer_shapedirs, transfer_weights,
                           wound_outward)

#: The A-pose's default: each upper arm lowered this far from the T-pose (degrees, about the body's forward axis).
A_POSE_ARM_DEGREES = 45.0
#: Weight smoothing of the transfer (passes over the garment graph), as the model's prior binding smooths.
UNPOSE_SMOOTH_ITERATIONS = 10
#: Passes that re-take the weights from the rest body at the unposed points and solve again, so that skinning
#: the result as `bake` does (weights from the rest body) gives the input back: on the example t-shirt in an
#: A-pose, the 99th percentile of the round trip's error falls from 9.0 mm (none) to 2.6 mm (3).
UNPOSE_REFINE_PASSES = 3
#: A blended transform whose smallest singular value is below this cannot be inverted: weights blend joints
#: turned nearly opposite ways.
MIN_SINGULAR_VALUE = 0.05
#: How far beyond its nearest posed body face (metres) a garment vertex looks for a face facing its own way, whose
#: weights it takes (`surface_blend`'s normals): the underside of a sleeve on an arm hanging by the torso is
#: nearest the torso, whose weights tore the sleeve from the arm on unposing (the example t-shirt skinned to arms
#: lowered 75 degrees: back to its rest shape within 179 mm, 8.7 mm mean).
UNPOSE_FACING_REACH_M = 0.05
#: An edge of the unposed garment longer than this many times its length as authored, plus UNPOSE_TEAR_SLACK_M,
#: and than UNPOSE_TEAR_MEDIANS times the unposed garment's median edge, is torn (`unpose_garment`'s report, warned
#: of by `garment unpose`): unposing undoes the pose's stretch and squash (armpit edges squashed 13-16x by the
#: A-pose come back whole, as long as the garment's other edges: the jumpsuit's 1 mm to 16.5 at 60 degrees), a
#: part that took another body part's weights stretches by centimetres (to 8-11x before UNPOSE_FACING_REACH_M).
UNPOSE_TEAR_RATIO = 3.0
UNPOSE_TEAR_SLACK_M = 0.01
UNPOSE_TEAR_MEDIANS = 4.0


def a_pose(body: Body, arm_degrees: float = A_POSE_ARM_DEGREES) -> np.ndarray:
    """(J, 3) axis-angle pose of `body`: the rest pose with both shoulders lowered by `arm_degrees`.

    The shoulders are SMPL joints 16 (left, arm along +X) and 17 (right), turned about the body's forward
    axis (+Z in the Y-up rest frame). Raises InputError for a body of another joint layout.
    """
    if body.layout is None:  # SMPL, SMPL+H and SMPL-X share the body joints 0-21
        raise InputError(f"--pose apose: expected an SMPL, SMPL+H or SMPL-X body (24, 52 or 55 joints; joints 16 and "
                         f"17 the shoulders), got body '{body.name}' with {body.n_joints} joints")
    if not (np.isfinite(arm_degrees) and -90.0 <= arm_degrees <= 90.0):
        raise InputError(f"--arm-angle: expected degrees in [-90, 90], got {arm_degrees}")
    pose = np.zeros((body.n_joints, 3), dtype=np.float32)
    angle = np.radians(arm_degrees)
    pose[16, 2] = -angle  # left arm: +X towards -Y
    pose[17, 2] = angle  # right arm: -X towards -Y
    return pose


def unpose_garment(garment: Garment, body: Body, pose: np.ndarray, betas: np.ndarray | None = None,
                   smooth_iterations: int = UNPOSE_SMOOTH_ITERATIONS, source: str | None = None) -> tuple[Garment, dict]:
    """The garment moved from `body` in `pose` (shaped by `betas`) to the body's rest pose, mean shape.

    garment: vertices in the body's frame (Y-up, metres) on the posed body; pose: (J, 3) axis-angle radians
    (the root's rotation is ignored: the garment is in the body's frame); betas: (S',) or None.
    Returns (the garment on the rest pose, same faces and UVs; a report: the posed body's fit, the largest
    vertex move, the largest distance between the input and the result skinned back into `pose`, the edges torn:
    longer than UNPOSE_TEAR_RATIO times their authored length plus UNPOSE_TEAR_SLACK_M and than
    UNPOSE_TEAR_MEDIANS times the median edge, the worst's ratio and a vertex of it, None where none is). Raises
    InputError naming `source` when a vertex's blended transform cannot be inverted.
    """
    name = source or garment.name
    pose = np.asarray(pose, dtype=np.float32).reshape(body.n_joints, 3).copy()
    pose[0] = 0.0
    if betas is not None:  # fitted to the body once: a count it does not have is warned about once, not per use
        betas = body.fit_betas(betas)
    posed, _, A = body.pose_with_transforms(pose[None], None, betas)
    A = A[0, :, :3, :].astype(np.float64)  # (J, 3, 4)
    target = garment.vertices.astype(np.float64)
    shaped, _ = body.shaped(betas)
    posed_mesh = TriangleMesh(posed[0], body.faces)
    hit, signed = posed_mesh.signed_closest(target)
    # the garment's normals facing away from the posed body, as the bind turns them from the rest body
    normals = vertex_normals(target, wound_outward(target, garment.faces, posed_mesh)[0])
    blend = surface_blend(posed_mesh, target, hit, normals=normals, reach=UNPOSE_FACING_REACH_M)
    rest_mesh = TriangleMesh(shaped, body.faces)

    def blended(at) -> np.ndarray:  # (V, 3, 4): each vertex's blend of the joints' transforms, weights from `at`
        return np.einsum("vj,jrc->vrc", transfer_weights(at, body, garment.faces, smooth_iterations), A)

    rest = None
    for _ in range(UNPOSE_REFINE_PASSES + 1):
        if rest is not None:  # the weights `bake` will use: from the (shaped) rest body, at the unposed points
            blend = surface_blend(rest_mesh, rest)
        M = blended(blend)
        bad = np.linalg.svd(M[:, :, :3], compute_uv=False)[:, -1] < MIN_SINGULAR_VALUE
        if bad.any():
            raise InputError(f"garment mesh '{name}': cannot unpose {int(bad.sum())} vertices (e.g. vertex "
                             f"{int(np.argmax(bad))}): their closest body parts turn nearly opposite ways in this pose")
        rest = np.linalg.solve(M[:, :, :3], (target - M[:, :, 3])[..., None])[..., 0]
    # The round trip as `bake` makes it: weights taken once more at the result, skinned into `pose`.
    M = blended(surface_blend(rest_mesh, rest))
    reposed = np.einsum("vrc,vc->vr", M[:, :, :3], rest) + M[:, :, 3]
    if betas is not None:  # back to the mean shape the rest body has
        rest = rest - np.einsum("vcs,s->vc", transfer_shapedirs(blend, body), betas.astype(np.float64))
    moved = np.linalg.norm(rest - target, axis=1)
    edges = mesh_edges(garment.faces)
    now = np.linalg.norm(rest[edges[:, 0]] - rest[edges[:, 1]], axis=1)
    authored = np.linalg.norm(target[edges[:, 0]] - target[edges[:, 1]], axis=1)
    excess = now - UNPOSE_TEAR_RATIO * authored
    torn = (excess > UNPOSE_TEAR_SLACK_M) & (now > UNPOSE_TEAR_MEDIANS * np.median(now) if len(now) else False)
    worst = int(np.argmax(np.where(torn, excess, -np.inf))) if torn.any() else 0
    report = {"edges_torn": int(torn.sum()),
              "max_edge_stretch": float(now[worst] / max(authored[worst], 1e-9)) if torn.any() else None,
              "torn_at_vertex": int(edges[worst, 0]) if torn.any() else None,
              "posed_median_distance_m": float(np.median(np.abs(signed))),
              "posed_inside_share": float(np.mean(signed < -REST_INSIDE_DEPTH_M)),
              "max_move_m": float(moved.max(initial=0.0)), "moved_over_1cm": int(np.sum(moved > 0.01)),
              "reposed_max_error_m": float(np.linalg.norm(reposed - target, axis=1).max(initial=0.0))}
    return replace(garment, vertices=rest.astype(np.float32)), report


def baked_back_error(rest: Garment, body: Body, pose: np.ndarray, betas: np.ndarray | None,
                     target: np.ndarray) -> float:
    """The largest distance (metres) between `target` (V, 3), the garment as authored in `pose` on the body shaped by
    `betas`, and `rest` (the unposed garment as `bake` reads it from the file written: its polygons split at the
    rest positions, which the in-memory garment's split at the posed ones differs from) baked back into `pose` by
    `lbs` with the weights unposing inverts (UNPOSE_SMOOTH_ITERATIONS passes, no legs' spread: the model's prior's;
    `core.deform.LBSDeformer`)."""
    from core.deform import LBSDeformer, LBSOptions
    from core.motion import Motion

    pose = np.asarray(pose, dtype=np.float32).reshape(1, body.n_joints, 3).copy()
    pose[0, 0] = 0.0
    lbs = LBSDeformer(LBSOptions(smooth_iterations=UNPOSE_SMOOTH_ITERATIONS, leg_spread_m=None))
    posed = lbs.deform(rest, body, Motion(poses=pose, trans=np.zeros((1, 3), np.float32), fps=30.0, betas=betas))[0]
    return float(np.linalg.norm(posed - np.asarray(target, dtype=np.float64), axis=1).max(initial=0.0))
