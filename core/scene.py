"""Scene analysis: which work a (garment, body, motion) scene needs, so that methods leave the rest out.

Each decision is cheap next to the work it saves, conservative (it keeps work whenever it cannot
show the work is useless), reported in `summary.json` under "scene", and can be overridden
(`bake --no-skip NAME`, or `all`):

- ``joints``: joints that carry no skinning weight anywhere on the garment are left out of its
  skinning sums (LBS: weights below `JOINT_WEIGHT_EPS` on every vertex, renormalised; the model:
  joints without transferred prior weight, whose learned weights are exactly zero by construction).
- ``body-faces``: the simulator's body collider keeps only the body faces that come within
  `BODY_REACH_M` of the garment's LBS preview in some frame, widened at each garment point by how far
  the cloth there can hang or swing away from its LBS position (`swing_reach`: twice its distance along
  the garment from the part that rests on the body); the rest of the body (the head, the far arm...)
  is never queried. Only where that leaves out at least half the body (`BODY_FACES_MAX_SHARE`: a sleeve,
  a cap, a belt).
- ``self-contact``: cloth-cloth contact, when asked for, is switched off where no two garment points
  more than 10 cm apart along the rest surface (paper Eq. 6) come within `SELF_REACH_M` of each
  other in any frame of the LBS preview.
- ``floor``: the simulator's ground (a plane at the lowest point the body reaches over the motion) is left
  out where the garment's LBS preview, lowered at each point by its swing, stays more than `FLOOR_REACH_M`
  above it in every frame.
- ``levels``: the pooling levels a garment's size and looseness call for (`suggested_levels`);
  reported next to the levels of the model in use (a checkpoint's levels are fixed by its training:
  pass `--model` with a checkpoint of the suggested levels, see `garment tradeoff`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
import torch
from scipy.spatial import cKDTree

from core.body import Body, skin_points
from core.garment import Garment

#: Overridable skips (`bake --no-skip NAME`).
SKIPS = ("joints", "body-faces", "self-contact", "floor")
#: The methods whose work each skip saves (README "Work a scene does not need"): `bake --no-skip` of a skip for
#: another method would change nothing, and is refused as --pin is.
SKIP_METHODS = {"joints": ("lbs", "model"), "body-faces": ("sim",), "self-contact": ("sim",), "floor": ("sim",)}
#: A joint whose LBS weight stays below this on every garment vertex is left out of its skinning.
JOINT_WEIGHT_EPS = 1e-4
#: Body faces further than this from the garment's LBS preview in every frame (plus its swing, `swing_reach`)
#: are left out of the collider.
BODY_REACH_M = 0.15
#: A garment vertex within this of the body (its nearest vertex) in the preview's first frame rests on the body:
#: the simulated cloth there moves with it (`swing_reach`).
ANCHOR_M = 0.03
#: The cloth at a point can lie up to this many times its distance along the garment from the nearest resting
#: vertex (`ANCHOR_M`) away from its LBS position: the simulated point within that distance of the anchor (the
#: cloth hardly stretches), the LBS point within it again. BODY_REACH_M alone assumed far less: the audit of
#: 2026-12-07 measured the simulated dress 18.8 cm from its LBS preview on the crouch (the collider had left out
#: faces of the inner knee 4.9 mm from the cloth) and 38 cm on a high kick, a long skirt 72 cm on a deep bend.
SWING_FACTOR = 2.0
#: The collider is cut only where it keeps at most this share of the body's faces: a cut collider is open, which
#: changes how Newton tells inside from outside for every contact (the audit's skirt walk moved 0.99 mm with
#: the skip, 0.000 without it run twice), and keeping 40-60 % of the faces saved no time measured (0.82-1.02x,
#: `benchmarks/results/scene_skips.md`): a sleeve, a cap or a belt keeps a fifth to a third.
BODY_FACES_MAX_SHARE = 0.5
#: Self-contact is needed when geodesically distant garment points come this close in the LBS preview.
SELF_REACH_M = 0.05
#: The ground is simulated where the garment's LBS preview comes within this of it in some frame (plus how far
#: the garment moves between examined frames): the cloth hangs and swings below its LBS position by less, and
#: its contact reaches 2.4 cm (the material's contact distance and gap).
FLOOR_REACH_M = 0.10
#: Frames of the LBS preview examined (evenly spaced; the gap between them widens the reach).
PREVIEW_FRAMES = 200


@dataclass
class SceneAnalysis:
    """What one scene needs. `report` is JSON-ready (summary.json "scene")."""

    skips: frozenset = frozenset(SKIPS)
    report: dict = field(default_factory=dict)

    def enabled(self, name: str) -> bool:
        return name in self.skips

    def record(self, name: str, applied: bool, **details) -> None:
        self.report[name] = {"skipped_work": bool(applied and self.enabled(name)),
                             "overridden": not self.enabled(name), **details}


def parse_no_skip(names) -> frozenset:
    """The skips left on after `--no-skip NAME ...` (`all` turns every skip off)."""
    names = set(names or ())
    if "all" in names:
        return frozenset()
    return frozenset(SKIPS) - names


def active_joints(weights: np.ndarray, eps: float = JOINT_WEIGHT_EPS) -> np.ndarray:
    """(J,) bool: joints whose weight exceeds `eps` on some vertex of (V, J) `weights`."""
    return np.asarray(weights).max(axis=0) > eps


def restrict_weights(weights: np.ndarray, active: np.ndarray) -> np.ndarray:
    """(V, J_active) weights of the active joints, each row renormalised to sum 1."""
    w = np.asarray(weights)[:, active].astype(np.float64)
    w /= np.maximum(w.sum(axis=1, keepdims=True), 1e-12)
    return w.astype(np.float32)


def preview_frames(n_frames: int, limit: int = PREVIEW_FRAMES) -> np.ndarray:
    """Evenly spaced frame indices (at most `limit`, always the first and last)."""
    return np.unique(np.linspace(0, n_frames - 1, min(n_frames, limit)).round().astype(np.int64))


def lbs_preview(rest: np.ndarray, weights: np.ndarray, transforms: np.ndarray) -> np.ndarray:
    """The garment by plain LBS: rest (V, 3) shaped rest positions; weights (V, J); transforms (T, J, 4, 4).

    Returns (T, V, 3) float32.
    """
    with torch.no_grad():
        return skin_points(torch.from_numpy(np.asarray(rest, np.float32)), torch.from_numpy(np.asarray(weights, np.float32)),
                           torch.from_numpy(np.asarray(transforms, np.float32))).numpy()


def interpolation_slack_per_point(points: np.ndarray, frames: np.ndarray) -> np.ndarray:
    """(len(frames), N) metres: how far each point of (T, N, 3) `points` can be from its position at each
    examined frame while on its way to a neighbouring examined frame (half its longest path over the gap
    on either side; covers skipped frames and the simulator's interpolation within a frame)."""
    N = points.shape[1]
    gaps = np.zeros((len(frames) + 1, N), dtype=np.float32)  # path length over each gap, zero beyond the ends
    for i, (a, b) in enumerate(zip(frames[:-1], frames[1:])):  # gap by gap: memory of one gap's frames only
        gaps[i + 1] = np.linalg.norm(np.diff(points[a:b + 1], axis=0), axis=2).sum(axis=0)
    return 0.5 * np.maximum(gaps[:-1], gaps[1:])


#: Groups of garment points queried apart by `faces_in_reach` (each at its group's largest reach).
REACH_GROUPS = 8


def faces_in_reach(body_points: np.ndarray, body_faces: np.ndarray, garment_points: np.ndarray,
                   reach=BODY_REACH_M, point_reach: np.ndarray | None = None) -> np.ndarray:
    """Indices of the body faces within `reach` of the garment in some frame.

    body_points: (T, Vb, 3); body_faces: (Fb, 3); garment_points: (T, V, 3), same frames, metres;
    reach: metres, one for all, (T,) per frame or (T, Fb) per frame and face; point_reach: (V,) metres more at
    each garment point (finite), or None. A face counts when its centroid lies within reach + its extent (the
    largest corner-to-centroid distance) of a garment point (+ that point's own reach): conservative for every
    point of the face. The points are queried in up to REACH_GROUPS groups of similar reach, each at its largest.
    """
    keep = np.zeros(len(body_faces), dtype=bool)
    reach = np.asarray(reach, dtype=np.float64)
    reach = np.broadcast_to(reach[:, None] if reach.ndim == 1 else reach, (len(body_points), len(body_faces)))
    if point_reach is None:
        groups = [(np.arange(garment_points.shape[1]), 0.0)]
    else:
        edges = np.unique(np.quantile(point_reach, np.linspace(0.0, 1.0, REACH_GROUPS + 1)[1:]))
        group = np.searchsorted(edges, point_reach)  # the first edge at or above each point's reach
        groups = [(np.flatnonzero(group == k), float(edge)) for k, edge in enumerate(edges) if np.any(group == k)]
    for b, g, r in zip(body_points, garment_points, reach):
        for points, more in groups:
            todo = np.flatnonzero(~keep)
            if len(todo) == 0:
                return np.flatnonzero(keep)
            corners = b[body_faces[todo]]  # (F, 3, 3)
            centroid = corners.mean(axis=1)
            bound = r[todo] + more + np.linalg.norm(corners - centroid[:, None], axis=2).max(axis=1)
            d, _ = cKDTree(g[points]).query(centroid, distance_upper_bound=float(bound.max()))
            keep[todo] = d <= bound
    return np.flatnonzero(keep)


def swing_reach(garment: Garment, garment_points: np.ndarray, body_points: np.ndarray) -> np.ndarray:
    """(V,) metres: how far the simulated cloth at each garment vertex can lie from its LBS position, taken as
    SWING_FACTOR times its distance along the garment (`core.geodesic.geodesic_graph`) from the nearest vertex
    that rests on the body (within ANCHOR_M of a body vertex in `garment_points` (V, 3) against `body_points`
    (Vb, 3), one frame); inf where no part of the garment rests on the body (it can fall anywhere)."""
    from scipy.sparse import csgraph

    from core.geodesic import geodesic_graph

    resting = np.flatnonzero(cKDTree(body_points).query(garment_points)[0] <= ANCHOR_M)
    if len(resting) == 0:
        return np.full(garment.n_vertices, np.inf)
    along = csgraph.dijkstra(geodesic_graph(garment.vertices, garment.faces), indices=resting, min_only=True)
    return SWING_FACTOR * np.asarray(along, dtype=np.float64)


def distant_parts_meet(garment: Garment, garment_points: np.ndarray, reach=SELF_REACH_M) -> dict:
    """Whether two garment points > 10 cm apart along the rest surface come within `reach` in some frame.

    garment_points: (T, V, 3) metres; reach: metres, one or (T,) per frame. Returns {"meet": bool,
    "frame": the first such frame (index into garment_points) or None, "pairs": such pairs in it}.
    """
    from core.geodesic import SELF_COLLISION_GEODESIC_M, far_by_neighbourhood, geodesic_graph, geodesic_neighbourhood

    near = None
    reach = np.broadcast_to(np.asarray(reach, dtype=np.float64), len(garment_points))
    for t, pts in enumerate(garment_points):
        pairs = cKDTree(pts).query_pairs(float(reach[t]), output_type="ndarray")
        if len(pairs) == 0:
            continue
        # Geodesic distance is at least the Euclidean one: pairs over 10 cm apart at rest are far for certain.
        far = np.linalg.norm(garment.vertices[pairs[:, 0]] - garment.vertices[pairs[:, 1]], axis=1) \
            > SELF_COLLISION_GEODESIC_M
        if not far.any():
            if near is None:  # built once, on the first frame that needs it
                graph = geodesic_graph(garment.vertices, garment.faces)
                near = geodesic_neighbourhood(garment.vertices, graph, SELF_COLLISION_GEODESIC_M, distances=False)
            far = far_by_neighbourhood(near, pairs)
        if far.any():
            return {"meet": True, "frame": t, "pairs": int(far.sum())}
    return {"meet": False, "frame": None, "pairs": 0}


def suggested_levels(n_vertices: int, looseness_m: float) -> int:
    """Pooling levels of the U-Net a garment calls for (paper: no gain beyond 2).

    Coarse levels carry deformation over distances a tight garment (within 1 cm of the skin, where
    skinning explains nearly all) or a small mesh does not have: under 300 vertices 0 levels, under
    1,500 vertices or tight 1 level, else 2.
    """
    if n_vertices < 300:
        return 0
    if n_vertices < 1500 or looseness_m < 0.01:
        return 1
    return 2


class Collisions(NamedTuple):
    """What the simulator collides: `analyse_collisions`'s answer."""

    #: Indices of the body faces kept in the collider, or None for all.
    body_faces: np.ndarray | None
    #: Whether cloth-cloth contact is on.
    self_contact: bool
    #: (T,) world height (Z, metres) of the ground plane in each body frame, or None for no ground.
    floor_z: np.ndarray | None


def analyse_collisions(analysis: SceneAnalysis, garment: Garment, body_points: np.ndarray, body_faces: np.ndarray,
                       rest: np.ndarray, weights: np.ndarray, transforms: np.ndarray, self_contact: bool,
                       floor: bool = True, motion_from: int = 0) -> Collisions:
    """The simulator's part (body faces, self-contact, ground), recorded in `analysis`.

    body_points: (T, Vb, 3) every simulated body frame, the Z-up world; transforms: (T, J, 4, 4) the same
    frames; rest: (V, 3) shaped garment; weights: (V, J) its LBS weights; self_contact: asked for; floor:
    False leaves the ground out whatever the scene (`SimOptions.floor` "none"); motion_from: body_points
    [motion_from:] are the motion's own frames, those before it the simulator's lead-in (rest pose, blend).

    The ground is the horizontal plane through the lowest point the body reaches in the motion's frames: where
    its feet touch the floor (a walk, a run) that is the floor, without trusting the file's own origin (AMASS
    datasets put the floor at various heights). In a lead-in frame whose body reaches lower (the rest pose's
    straight legs under a clip that starts crouching or seated) it is lowered to that frame's lowest point:
    it is never above a body point.
    """
    frames = preview_frames(len(body_points))
    preview = lbs_preview(rest, weights, transforms[frames])
    # Between examined frames (and within a frame, where the simulator interpolates the body) body and garment
    # move on: widen each face's reach by its own slack and the garment's.
    slack_v = interpolation_slack_per_point(body_points, frames)  # (F, Vb)
    slack_g = interpolation_slack_per_point(preview, np.arange(len(frames))).max(axis=1)  # (F,)
    faces = None
    swing = swing_reach(garment, preview[0], body_points[frames[0]])  # (V,) inf where nothing rests on the body
    if np.all(np.isfinite(swing)):
        kept = faces_in_reach(body_points[frames], body_faces, preview,
                              BODY_REACH_M + slack_g[:, None] + slack_v[:, body_faces].max(axis=2), swing)
        applied = len(kept) <= BODY_FACES_MAX_SHARE * len(body_faces)
        more = {} if applied else {"reason": f"keeps over {BODY_FACES_MAX_SHARE:.0%} of the body's faces: the "
                                             "collider whole (a cut one saved no time there)"}
        analysis.record("body-faces", applied, reach_m=BODY_REACH_M, swing_max_m=round(float(swing.max()), 4),
                        kept_faces=len(kept), body_faces=len(body_faces), frames_examined=len(frames), **more)
    else:
        applied = False
        analysis.record("body-faces", False, reason=f"no part of the garment rests within {ANCHOR_M * 100:g} cm of "
                        "the body: its cloth can fall anywhere")
    if applied and analysis.enabled("body-faces"):
        faces = kept
    contact = self_contact
    if self_contact:
        # Cloth-cloth distances: every frame of the preview up to PREVIEW_FRAMES; with frames skipped, the reach
        # widens by the garment's slack.
        reach = SELF_REACH_M + (slack_g if len(frames) < len(body_points) else 0.0)
        meet = distant_parts_meet(garment, preview, reach)
        # where they first meet, counted as the motion's frames (a negative one: in the simulator's lead-in)
        analysis.record("self-contact", not meet["meet"], reach_m=SELF_REACH_M,
                        first_frame=None if meet["frame"] is None else int(frames[meet["frame"]]) - motion_from,
                        pairs=meet["pairs"])
        if not meet["meet"] and analysis.enabled("self-contact"):
            contact = False
    else:
        analysis.record("self-contact", False, reason="self-contact not requested")
    lowest_body = body_points[..., 2].min(axis=1)  # (T,)
    ground = float(lowest_body[motion_from:].min())
    floor_z = np.minimum(lowest_body, ground)
    if floor:  # the preview lowered by each point's swing (inf: the ground kept)
        lowest = float(((preview[..., 2] - swing).min(axis=1) - slack_g - floor_z[frames]).min())
        not_reached = lowest > FLOOR_REACH_M
        analysis.record("floor", not_reached, reach_m=FLOOR_REACH_M, ground_z_m=ground,
                        lowered_in_lead_in_m=float(ground - floor_z.min()), garment_lowest_above_ground_m=lowest)
        floor = not (not_reached and analysis.enabled("floor"))
    else:
        analysis.record("floor", False, reason="floor none")
    return Collisions(faces, contact, floor_z if floor else None)


def scene_levels(garment: Garment, body: Body, betas) -> dict:
    """The `levels` report: suggested levels and the looseness they follow (on the body shaped by `betas`, a
    motion's)."""
    from core.quality import looseness

    loose = looseness(garment, body, betas)
    return {"suggested": suggested_levels(garment.n_vertices, loose), "vertices": int(garment.n_vertices),
            "looseness_m": loose}
