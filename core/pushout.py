"""Two post-processes against body penetration: the exact push-out and the model's contact guard.

Push-out: any method's output can be pushed out (`bake --push-out`, and the `+push-out` rows of `garment
tradeoff`). A vertex inside the posed body (its winding number) or outside closer than `margin` is moved to the
closest body point plus `margin` outward (the vertex's own side for one outside), or, where that point lies
inside another part of a body that passes through itself, to the nearest point of its outer surface
(`push_out`), except where that tears the cloth (neighbours sent to opposite sides of a crease); before that,
one below the ground (the lowest
point the body reaches in the motion, as the simulator's) is lifted straight up to `margin` above it. The
cloth's own shape is not relaxed afterwards: a pushed region can stretch by up to its depth of penetration.
It searches the closest body point and tests the winding number of every vertex in every frame (51-169 ms/frame
on the example garments, measured beside other work: `benchmarks/results/push_out.md`).

Contact guard (`ContactAnchors`, `guard_contact`; on by default for `--method model`): each garment
vertex is tied once, on the rest pose, to where it is nearest the body (a point and a normal blended over the
faces about as near as the nearest); in every frame the vertex is kept on the outer side of that point's
plane, at no less than min(margin, its rest offset), wherever it lies within GUARD_REACH_M of the point
along the plane and no deeper than GUARD_DEPTH_M behind it (beyond GUARD_NEAR_FROM_M along it, where the network
let the cloth lag behind the body, also outside the plane of the body vertices nearest it); over
bands beyond both bounds (GUARD_REACH_FADE_M, GUARD_DEPTH_FADE_M) the lift fades linearly to none, so that
it changes continuously as a vertex crosses a bound (a cut-off made cloth pop by up to 5 cm in one frame).
The lifts are then spread over the garment's surface (over about GUARD_SPREAD_M: passes of
`graph_smoothing`), and the guard run again on the result (GUARD_ROUNDS): a vertex lifted alone, its
neighbours tied to other faces or left where they were, pulls them along instead of standing out of the cloth
as a spike (where the body curves, in an armpit or behind a knee, one face's plane stands for the body badly,
and unspread lifts tore a t-shirt's armpits in every frame of most motions). A last round, spread over a quarter
as much, lifts what the spread left behind its plane (GUARD_TOP_UP). With the strain limit on (`guard_and_limit`), the guard's spread
rounds run, then the limit, then that last round on what the limit pulled back in, then the limit again
(GUARD_LIMIT_ALTERNATIONS).
The faces are posed exactly (they are the body's own), so this undoes what the network adds on top of
skinning (blend shapes pushing cloth into the body, learned weights that drift from the body's) at 3-14
ms/frame on the example garments (0.7-3.0 before the nearest vertices' planes, `benchmarks/results/guard_near.md`);
it cannot see a vertex that slides over to another body part, which the exact push-out does.
"""

from __future__ import annotations

import functools
import time
import warnings
import weakref
from dataclasses import dataclass, replace

import numpy as np
import scipy.sparse as sp
import torch

from core.body import Body
from core.deform import Deformer
from core.garment import Garment, frames_at_once, mesh_edges
from core.geodesic import edge_lengths
from core.geometry import InsideTest, TriangleMesh, face_normals, in_threads, outward_faces, outward_offsets
from core.motion import Motion, poses_for_body
from core.skinning import graph_smoothing, spread_passes_over, surface_blend
from core.strain import (STRAIN_ITERATIONS, garment_strain, limit_strain, still_over, strain_chunk_frames,
                         strain_report)

#: Distance outside the body a pushed vertex ends at (metres): within the 2 mm depth the penetration
#: statistics tolerate, so a pushed vertex never counts as inside.
PUSH_OUT_MARGIN_M = 0.001

#: Distance (metres) outside its rest body face the contact guard keeps a vertex (one authored closer keeps its
#: rest offset): the simulator's (`core.sim.Material.contact_distance_m`, the cloth's half-thickness), where the
#: cloth of the model's training data rests. At 1 mm the body's curve showed through the flat faces between
#: lifted vertices (light specks down the example dress's side on the run, in every renderer); at 4 mm none, and
#: against the simulator's references of the tradeoff scenes the skirt 20.46 mm (20.43 at 1 mm), the dress 20.78
#: (20.77); vertices inside on the example run 0.64 % (0.71), t-shirt 1.94 (2.39), jumpsuit 1.26 (1.53).
GUARD_MARGIN_M = 0.004

#: Distance (metres) along the plane of a vertex's anchor, from the anchor's point, within which the plane
#: stands for the body: further out (a hem swung far away) the guard leaves the vertex alone. On the
#: held-out test sequences 5 cm left twice the penetration of 10 cm; 20 cm and more changed nothing further.
GUARD_REACH_M = 0.1

#: Deepest (metres) a vertex may be behind its face's plane and still be lifted: deeper, the plane no longer
#: stands for the body there (an anchor on an arm that swung away from the torso's cloth), so the vertex stays.
#: The shipped model pushes some vertices 3-5 cm in; on the held-out test sequences a cap of 3 cm left 0.14 %
#: of vertices inside, 5 cm 0.12 %, none 0.11 % but lifted single vertices by up to 14 cm.
GUARD_DEPTH_M = 0.05

#: Widths (metres) of the bands beyond GUARD_REACH_M and GUARD_DEPTH_M over which the lift fades from full to
#: none: along the plane its weight falls linearly; in depth the lift itself falls linearly from GUARD_DEPTH_M to
#: none (`_depth_share`), so it stays at most GUARD_DEPTH_M and what is left behind the plane grows with the depth
#: (the guard keeps the order of vertices along a normal), the output moving 1 + depth / fade times as fast as
#: the network's there. Since 2026-12-07 the depth's band is 5 cm and linear in the lift (before: 3 cm, the weight
#: linear, up to 3.7 times as fast), its share decided on the network's output: on the example crouch the
#: vertex-frames the guard accelerates more than 10 mm/frame^2 beyond the network went 393 -> 255 (dress) and
#: 89 -> 56 (trousers), the largest 53.6 -> 38.5 mm; on the run, the jump and the held-out walk within 2 %; the
#: error against the simulator within 0.01 mm and the share inside within 0.02 points on all
#: (`python benchmarks/contact_guard.py --depth-bands`).
GUARD_REACH_FADE_M = 0.05
GUARD_DEPTH_FADE_M = 0.05

#: Distance (metres) along its anchor's plane beyond which a vertex is also kept outside the plane of the posed
#: body vertices nearest it (their points and normals blended, among the anchors' body vertices: `_near_lift`),
#: the two lifts blended
#: linearly from the anchor's alone at GUARD_NEAR_FROM_M to the nearest vertex's alone at GUARD_NEAR_TO_M (both
#: fading out beyond GUARD_REACH_M as the anchor's did, and with the depth behind their planes). The
#: network lets cloth lag several centimetres behind a fast body along it; there the anchor's plane no longer
#: stands for the body (on the example run the t-shirt's front lagged 4-11 cm at every stride, 6-8 % of its
#: vertices inside the belly and chest, above their anchors' planes: holes in every render).
GUARD_NEAR_FROM_M = 0.01
GUARD_NEAR_TO_M = 0.03

#: How far (metres, the spread's standard deviation over the surface) the guard spreads its lifts, and its
#: rounds (each lifts what the spread left behind its plane). A garment's lifts are spread by passes of
#: `core.skinning.graph_smoothing` (strength 0.5, each spreading over about an edge: `spread_passes`), as
#: many as its median edge length needs for this distance. Measured on 78 simulated sequences (48 of real
#: motion capture on four garments, 30 synthetic dress motions; benchmarks/results/contact_guard_simulated.md):
#: unspread, the guard tore (an edge over twice its rest length and 2 cm longer) a t-shirt in 386 of 427 real
#: frames and trousers in 200, where the network alone tore 44 and 97; spread over less than 1.5 cm the t-shirt
#: still tore in most frames; a second round leaves fewer vertices inside the body than unspread lifts did.
GUARD_SPREAD_M = 0.03
GUARD_ROUNDS = 2

#: Least distance (metres) a vertex moved by the guard counts as moved in its report: the spread's tails move
#: many more by less.
GUARD_MOVED_M = 1e-4

#: Most passes of the spread (a garment of 3 mm edges; finer ones spread over less than GUARD_SPREAD_M).
GUARD_MAX_SPREAD_PASSES = 200


def spread_passes(edge_m: float, spread_m: float = GUARD_SPREAD_M, strength: float = 0.5) -> int:
    """`core.skinning.spread_passes_over`, at most GUARD_MAX_SPREAD_PASSES."""
    return spread_passes_over(edge_m, spread_m, GUARD_MAX_SPREAD_PASSES, strength)


def _fade(x: torch.Tensor, bound: float, width: float) -> torch.Tensor:
    """1 up to `bound`, falling linearly to 0 at `bound + width` (a step at `bound` when width is 0)."""
    if width <= 0:
        return (x <= bound).to(x.dtype)
    return ((bound + width - x) / width).clamp(0.0, 1.0)


def _depth_share(behind: torch.Tensor, depth: float, fade: float) -> torch.Tensor:
    """The share of its depth `behind` (metres behind its plane) the guard lifts a vertex by: all of it up to
    `depth`; beyond, the lift falls linearly from `depth` to none at `depth + fade` (a cut-off at `depth` when fade
    is 0). The lift changes at most depth / fade times as fast as the depth (the vertex's output 1 + depth / fade
    times), never above `depth`, and what is left behind the plane grows with the depth."""
    if fade <= 0:
        return (behind <= depth).to(behind.dtype)
    beyond = depth * (depth + fade - behind) / (fade * behind.clamp(min=1e-12))
    return torch.where(behind <= depth, torch.ones_like(behind), beyond.clamp(min=0.0))


#: A move to the body's outer surface is taken back (the vertex goes to its closest body point, as one not inside
#: another part does) where it makes an edge of the garment longer than this many times its length before the
#: push-out, plus PUSH_OUT_TEAR_SLACK_M: in a crease where two parts overlap (an armpit, between the thighs)
#: neighbours went to the outer surface on opposite sides (the arm's, the torso's), 2-3 cm apart, and the
#: example t-shirt tore in every frame of the held-out walk (edges 10x their length, `benchmarks/push_out.py`).
PUSH_OUT_TEAR_RATIO = 1.5
PUSH_OUT_TEAR_SLACK_M = 0.002


def push_out(points: np.ndarray, body_points: np.ndarray, body_faces: np.ndarray,
             margin: float = PUSH_OUT_MARGIN_M, ground_z: float | None = None,
             report: dict | None = None, edges: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Lift vertices under `ground_z` + `margin` (the ground, world Z metres; None: no ground) straight up to that
    height, then move those inside the body, or outside it closer than `margin` to its surface, to `margin`
    outside (the body wins where both cannot hold: cloth pinched under a foot on the ground stays just below it).

    Inside is the body's winding number (`core.geometry.points_inside_mesh`), as the penetration statistics count
    it: a posed body passes through itself where it touches itself (an arm pressed to the torso, the thighs of a
    crouch), and there the nearest face can lie inside another part. A vertex inside goes to its closest body
    point, `margin` out along that face's outward side, where that lands outside; where it does not (the point
    lies inside another part, e.g. a sleeve's vertex between the arm and the torso, whose nearest face is the
    arm's), to the nearest point of the body's outer surface from which `margin` out along its face's normal is
    outside (`_to_outer_surface`). A vertex outside within `margin` of the surface is moved out along its own side
    (never through the face nearest it into another part; to the outer surface where that lands inside one).
    With the garment's `edges`, a move to the outer surface that tears an edge (`PUSH_OUT_TEAR_RATIO`) is taken
    back to the closest point's target: that vertex stays inside the other part, within `margin` of a surface
    (never counted more than 2 mm inside), in the crease where the two parts meet.

    points: (T, V, 3) garment; body_points: (T, Vb, 3) posed body (closed, outward-oriented faces);
    body_faces: (Fb, 3); edges: (E, 2) the garment's, or None. Returns (pushed points (T, V, 3) float32, moved
    (T,) vertex counts); `report`, where given, gets how many were moved to the outer surface, how many were taken
    back from it not to tear the cloth and how many it left inside (summed over frames).
    """
    out = np.array(points, dtype=np.float32, copy=True)
    moved = np.zeros(len(out), dtype=np.int64)
    body_faces = np.asarray(body_faces, dtype=np.int64)
    to_outer = left_inside = kept = 0
    for t in range(len(out)):
        low = np.zeros(out.shape[1], dtype=bool)
        if ground_z is not None:
            low = out[t, :, 2] < ground_z + margin
            out[t, low, 2] = ground_z + margin
        p = out[t].astype(np.float64)
        test = InsideTest(body_points[t], body_faces)  # one per frame: every query below is in this pose
        signed, closest, direction = outward_offsets(p, None, None, mesh=test.mesh)
        inside = test(p)
        # `direction` is the nearest face's outward side where it calls the point inside, else the point's own
        # side; a point outside that the nearest face calls inside (in a crease between two parts) keeps its own.
        near = ~inside & (np.abs(signed) < margin)
        own_side = np.where((signed < 0)[:, None], -direction, direction)
        target = np.where(inside[:, None], direction, own_side)
        sel = inside | near
        new = closest + margin * target
        still = np.flatnonzero(sel)  # those that land inside (another part within the margin too)
        if len(still):
            still = still[test(new[still])]
        if len(still):
            fallback = np.where(sel[:, None], new, p)  # every vertex where it goes without the outer surface
            new[still], left = _to_outer_surface(new[still], p[still], test, margin)
            went = still[np.any(new[still] != fallback[still], axis=1)]  # not those it left at `new`
            back = _tearing(np.where(sel[:, None], new, p), fallback, p, went, edges) if edges is not None \
                else went[:0]
            new[back] = fallback[back]
            to_outer += len(still) - left - len(back)
            left_inside += left
            kept += len(back)
        out[t, sel] = new[sel].astype(np.float32)
        moved[t] = int((sel | low).sum())
    if report is not None:
        report.update(vertices_to_outer_surface=int(to_outer), vertices_kept_off_outer_surface=int(kept),
                      vertices_left_inside=int(left_inside))
    return out, moved


def _tearing(new: np.ndarray, fallback: np.ndarray, before: np.ndarray, outer: np.ndarray,
             edges: np.ndarray) -> np.ndarray:
    """Of the vertices `outer` (sorted ids) moved to the outer surface in `new` (V, 3), those to take back to
    `fallback` (V, 3: their closest point's target), sorted: the ends among them of an edge (E, 2) longer than
    PUSH_OUT_TEAR_RATIO times its length `before` (V, 3) plus PUSH_OUT_TEAR_SLACK_M, round after round until none
    is (one taken back can tear an edge to a neighbour left out: a patch torn apart goes back whole)."""
    longest = PUSH_OUT_TEAR_RATIO * np.linalg.norm(before[edges[:, 0]] - before[edges[:, 1]], axis=1) \
        + PUSH_OUT_TEAR_SLACK_M
    out_now = np.zeros(len(new), dtype=bool)
    out_now[outer] = True
    at = new.copy()
    while True:  # each round takes back one vertex at least
        torn = np.linalg.norm(at[edges[:, 0]] - at[edges[:, 1]], axis=1) > longest
        ends = np.unique(edges[torn].reshape(-1))
        ends = ends[out_now[ends]]
        if not len(ends):
            break
        out_now[ends] = False
        at[ends] = fallback[ends]
    return np.setdiff1d(outer, np.flatnonzero(out_now))


#: How far outside a face (metres, along its normal) its centroid and corners are probed to tell whether it is
#: on the body's outer surface.
OUTER_PROBE_M = 1e-4
#: The first radius (metres) searched for outer faces about a vertex left inside another part; doubled until
#: one is found, the last OUTER_SEARCH_MAX_M (no body part is thicker).
OUTER_SEARCH_M = 0.01
OUTER_SEARCH_MAX_M = 1.0
#: Outer faces tried per vertex, the nearest first, while the point out of them is inside.
OUTER_TRIES = 8


def _to_outer_surface(new: np.ndarray, points: np.ndarray, test: InsideTest, margin: float) -> tuple[np.ndarray, int]:
    """`points` (inside the body, whose closest point's face pushed them into another part: `new`) moved to the
    nearest point of the body's outer surface from which `margin` out along that face's normal is outside;
    returns (those targets, how many are still inside: left at `new`, also where no outer face lies within
    OUTER_SEARCH_MAX_M).

    A face is outer where its centroid or a corner, OUTER_PROBE_M out along its normal, is outside (a face that
    the line where two parts meet crosses is outer in part); only the faces within a growing radius of the points
    are probed (about 1 % of a body's faces). The nearest face's point is taken where `margin` out of it is
    outside, else that face is set aside and the next nearest tried (OUTER_TRIES): the target lies within about a
    face's width of the nearest outer point (on three overlapping spheres of 3-5 cm faces, 2 mm further, the
    margin, at the median, 14 mm at the 99th percentile and 22 mm at most, beside the line where two meet)."""
    normals = face_normals(test.mesh.verts, test.mesh.faces)
    outer = np.zeros(len(normals), dtype=np.int8)  # 0 unknown, 2 outer, 1 outer in part, -1 not
    target, chosen = new.copy(), np.full(len(points), -1)
    reach = np.full(len(points), OUTER_SEARCH_M)  # where each point's search starts: its last face's distance
    todo = np.arange(len(points))
    for attempt in range(OUTER_TRIES + 1):
        # the last try takes wholly outer faces only (their points out of them lie outside but at sharp creases)
        least = 2 if attempt == OUTER_TRIES else 1
        target[todo], chosen[todo], reach[todo] = _nearest_outer(test, normals, outer, points[todo], new[todo],
                                                                 margin, least, reach[todo])
        # a target still inside (1 mm out of a face beside a crease, the other part within 1 mm): that face is
        # taken as not outer and the next nearest looked for
        todo = todo[(chosen[todo] >= 0) & test(target[todo])]
        if not len(todo):
            break
        outer[chosen[todo]] = -1
    left = np.flatnonzero(chosen < 0)
    if len(todo):
        left = np.union1d(left, todo)
    target[left] = new[left]
    return target, len(left)


def _nearest_outer(test: InsideTest, normals: np.ndarray, outer: np.ndarray, points: np.ndarray, new: np.ndarray,
                   margin: float, least: int, start: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(`margin` out of the nearest outer face of each point, that face (-1: none within OUTER_SEARCH_MAX_M; the
    point's `new` kept), its distance (where the next search may start)); `outer` (per face: 0 unknown, 2 outer,
    1 outer in part, -1 not) filled in as faces are probed, those of at least `least` taken; each point's search
    starts at its radius in `start` (no nearer face is left to take) and doubles."""
    mesh = test.mesh
    verts, faces = mesh.verts, mesh.faces
    target, chosen = new.copy(), np.full(len(points), -1)
    distance = np.array(start, dtype=np.float64)
    found = np.zeros(len(points), dtype=bool)
    radius = np.clip(np.asarray(start, dtype=np.float64) * 1.0001, OUTER_SEARCH_M, OUTER_SEARCH_MAX_M)
    while not found.all():
        todo = np.flatnonzero(~found)
        pairs = [(todo[pi], fi, bary, dist) for pi, fi, bary, dist in mesh.faces_within(points[todo], radius[todo])]
        if pairs:
            pi, fi, bary, dist = (np.concatenate(a) for a in zip(*pairs))
            unknown = np.unique(fi[outer[fi] == 0])
            if len(unknown):
                corners = verts[faces[unknown]]  # (U, 3, 3)
                probes = np.concatenate([corners, corners.mean(axis=1, keepdims=True)], axis=1) \
                    + OUTER_PROBE_M * normals[unknown, None]
                inside = test(probes.reshape(-1, 3)).reshape(len(unknown), 4)
                outer[unknown] = np.where(inside.all(axis=1), -1, np.where(inside.any(axis=1), 1, 2))
            ok = outer[fi] >= least
            pi, fi, bary, dist = pi[ok], fi[ok], bary[ok], dist[ok]
            order = np.lexsort((dist, pi))  # each point's nearest outer face first
            pi, fi, bary, dist = pi[order], fi[order], bary[order], dist[order]
            _, first = np.unique(pi, return_index=True)
            pi, fi, bary, dist = pi[first], fi[first], bary[first], dist[first]
            target[pi] = np.einsum("pk,pkd->pd", bary, verts[faces[fi]]) + margin * normals[fi]
            chosen[pi], distance[pi], found[pi] = fi, dist, True
        if (radius[~found] >= OUTER_SEARCH_MAX_M).all():
            break
        radius = np.where(found, radius, np.minimum(2.0 * radius, OUTER_SEARCH_MAX_M))
    return target, chosen, distance


@dataclass(frozen=True)
class ContactAnchors:
    """Where each garment vertex (V of them) is tied to the body, as found on the rest pose: its point, a blend
    of the body's vertices (V, Vb) sparse, rows summing to 1 (`core.skinning.surface_blend`: the closest points
    of every face about as near as the nearest); its normal, a blend (V, Fr) sparse of the cross products of
    the body faces `ring` (Fr, 3) int64 (wound outward: those around the point's vertices, the area-weighted
    vertex normals blended as the point is), normalised; the least offset along the normal the guard keeps
    (V,), metres; one pass of the garment's `graph_smoothing` (V, V), which spreads the lifts (None: each vertex
    lifted alone), and how many passes it takes. Point and normal change continuously with the garment and
    the body: a vertex over an edge or equally near two faces, tied to whichever face rounding picked, was lifted
    against that face's plane (a 1e-7 m nudge of the example dress moved its bake by 10.8 mm)."""

    point: sp.csr_matrix
    ring: np.ndarray
    normal: sp.csr_matrix
    floor: np.ndarray
    spread: sp.csr_matrix | None = None
    passes: int = 0


def contact_anchors(rest: np.ndarray, body_verts: np.ndarray, body_faces: np.ndarray,
                    margin: float = GUARD_MARGIN_M, garment_faces: np.ndarray | None = None) -> ContactAnchors:
    """Tie each rest garment vertex (V, 3) to where it is nearest the rest body (Vb, 3), faces (Fb, 3) outward;
    the garment's faces (F, 3), where given, spread the lifts over its surface.

    The garment and the body must share a shape (both shaped by the same betas), in metres.
    """
    rest = np.asarray(rest, dtype=np.float64)
    verts = np.asarray(body_verts, dtype=np.float64)
    body_faces = np.asarray(body_faces, dtype=np.int64)
    point = surface_blend(TriangleMesh(verts, body_faces), rest)
    used = np.zeros(len(verts), dtype=bool)
    used[point.indices] = True
    ring = body_faces[used[body_faces].any(axis=1)]
    incidence = sp.csr_matrix((np.ones(ring.size), (ring.reshape(-1), np.repeat(np.arange(len(ring)), 3))),
                              shape=(len(verts), len(ring)))
    anchors = ContactAnchors(point, ring, (point @ incidence).tocsr(), np.zeros(len(rest)))
    at, normal = (x[0].numpy() for x in _planes(torch.from_numpy(verts)[None], anchors))
    offset = np.einsum("vc,vc->v", rest - at, normal)
    spread, passes = None, 0
    if garment_faces is not None:
        spread = graph_smoothing(garment_faces, len(rest))
        edges = mesh_edges(garment_faces)
        passes = spread_passes(float(np.median(edge_lengths(rest, edges)))) if len(edges) else 0
    return replace(anchors, floor=np.minimum(margin, offset), spread=spread, passes=passes)


def _as_tensors(points, body_points) -> tuple[torch.Tensor, torch.Tensor, bool]:
    """(points, body_points) as tensors in body_points' device and dtype (arrays: float64 on the CPU), and
    whether they came as arrays."""
    if isinstance(body_points, torch.Tensor):
        return points.to(body_points.dtype), body_points, False
    # contiguous: the strain limit's output is a transposed view, whose norms along the last axis ran 10x slower
    as64 = lambda a: torch.from_numpy(np.ascontiguousarray(a, dtype=np.float64))  # noqa: E731
    return as64(points), as64(body_points), True


def _times(op: sp.csr_matrix, x: torch.Tensor) -> torch.Tensor:
    """The sparse operator `op` (M, N) applied to per-item vectors `x` (T, N, C): (T, M, C), in x's dtype and on
    its device (see `spread_over`)."""
    T, N, C = x.shape
    y = x.permute(1, 0, 2).reshape(N, T * C)
    if x.device.type == "cpu":
        y = torch.from_numpy(op.astype(y.numpy().dtype, copy=False) @ y.numpy())
    else:
        y = _torch_operator(op, x.dtype, x.device) @ y
    return y.reshape(op.shape[0], T, C).permute(1, 0, 2)


def _ring_cross(bp: torch.Tensor, ring: torch.Tensor) -> torch.Tensor:
    """(T, Fr, 3) cross products of the anchors' `ring` faces (Fr, 3) on the posed body `bp` (T, Vb, 3): along
    each face's normal, twice its area (`core.geometry.face_cross` of tensors)."""
    c0, c1, c2 = (torch.index_select(bp, 1, ring[:, k]) for k in range(3))
    return torch.linalg.cross(c1 - c0, c2 - c0, dim=-1)


def _planes(bp: torch.Tensor, anchors: ContactAnchors,
            cross: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor]:
    """Each vertex's anchor point (T, V, 3) and unit normal (T, V, 3; zero where its faces have no area) on the
    posed body `bp` (T, Vb, 3); `cross`: the ring's `_ring_cross` where made already."""
    if cross is None:
        cross = _ring_cross(bp, torch.as_tensor(anchors.ring, device=bp.device))
    normal = torch.nn.functional.normalize(_times(anchors.normal, cross), dim=-1, eps=1e-30)
    return _times(anchors.point, bp), normal


def _offsets(p: torch.Tensor, bp: torch.Tensor, anchors: ContactAnchors, planes=None):
    """`anchor_offsets` of tensors, and each vertex's distance (T, V) from its anchor's point; `planes`: `_planes`
    of `bp` where made already (the body stands still while the guard's rounds move the cloth)."""
    point, normal = _planes(bp, anchors) if planes is None else planes
    rel = p - point
    along = torch.einsum("tvc,tvc->tv", rel, normal)
    lateral = torch.linalg.norm(rel - along[..., None] * normal, dim=-1)
    floor = torch.as_tensor(anchors.floor, dtype=bp.dtype, device=bp.device)
    return (floor[None] - along).clamp(min=0.0), lateral, normal, torch.linalg.norm(rel, dim=-1)


def _nearest_body_vertices(p: torch.Tensor, bp: torch.Tensor, k: int,
                           trees: dict | None = None) -> tuple[torch.Tensor, torch.Tensor]:
    """(indices (S, k), distances (S, k)) of the `k` body vertices of `bp` (T, N, 3) nearest each of the points `p`
    (S, 4): (frame, x, y, z), nearest first (on the CPU by a k-d tree per frame, frames on threads: the query
    releases the GIL, and on two cores the dress of benchmarks/throughput.py searched in 1.9 ms/frame, 3.5 on one).
    `trees`: the k-d trees by frame of `bp` made by earlier searches of the same body, kept for later ones."""
    frames = p[:, 0].long()
    k = min(k, bp.shape[1])
    index = torch.empty((len(p), k), dtype=torch.long, device=p.device)
    distance = torch.empty((len(p), k), dtype=p.dtype, device=p.device)
    if p.device.type != "cpu":
        for t in torch.unique(frames).tolist():
            at = torch.nonzero(frames == t).reshape(-1)
            distance[at], index[at] = _nearest_by_distances(p[at, 1:], bp[t], k)
        return index, distance
    from scipy.spatial import cKDTree

    order = torch.argsort(frames, stable=True)
    bounds = torch.searchsorted(frames[order], torch.arange(bp.shape[0] + 1, device=p.device)).tolist()
    x, d_out, i_out = p[order, 1:].numpy(), np.empty((len(p), k)), np.empty((len(p), k), dtype=np.int64)

    trees = {} if trees is None else trees

    def one(t: int) -> None:
        a, b = bounds[t], bounds[t + 1]
        if t not in trees:
            trees[t] = cKDTree(bp[t].numpy())
        d, i = trees[t].query(x[a:b], k=k)
        d_out[a:b], i_out[a:b] = d.reshape(b - a, k), i.reshape(b - a, k)

    in_threads(one, [t for t in range(bp.shape[0]) if bounds[t + 1] > bounds[t]])
    index[order] = torch.from_numpy(i_out)
    distance[order] = torch.from_numpy(d_out).to(p.dtype)
    return index, distance


def _nearest_by_distances(x: torch.Tensor, verts: torch.Tensor, k: int) -> tuple[torch.Tensor, torch.Tensor]:
    """(distances (S, k), indices (S, k)) of the `k` of `verts` (N, 3) nearest each of `x` (S, 3), from all their
    distances (a GPU's search)."""
    return torch.cdist(x, verts).topk(k, dim=1, largest=False)


#: Body vertices whose planes the guard blends for a vertex slid far along its anchor's (`_near_lift`): each
#: weighted 1 - its distance over the next nearest's, so that the blend changes continuously as the cloth moves
#: (the nearest vertex's plane alone jumped by up to 3.8 mm where the nearest switched).
GUARD_NEAR_VERTICES = 4
#: The guard's rounds (of GUARD_ROUNDS) that look for the nearest body vertices: the first only. Its search is the
#: guard's cost (a k-d tree per frame on the CPU); in both rounds the t-shirt's share inside on the example run fell
#: from 1.82 % (the anchors alone) to 0.53 % (0.78 in the first only) at 22 ms/frame (about 12; the anchors alone
#: 4).
GUARD_NEAR_ROUNDS = 1
#: After its spread rounds the guard lifts once more, unspread, each vertex still behind its plane (its anchor's,
#: or for those round 0 lifted by their nearest body vertices' planes, those blended as in round 0: a search of
#: those vertices only): the spread left the edges of a lifted patch behind it (the example jumpsuit's seat
#: through the cloth at each stride of the run). Its lifts are spread less (GUARD_TOP_UP_SPREAD) (with the strain
#: limit on, `alternate_guard_limit` runs this round after the limit, and the limit again).
GUARD_TOP_UP = True
#: The top-up's lifts are spread over this share of the garment's passes (at least one): unspread, a vertex lifted in
#: one frame and not the next flicked (on the example jumpsuit's run 34 vertex-frames accelerated 2 cm a frame
#: more than without the top-up; spread over a quarter 16, the share inside 0.30 -> 0.32 %; the t-shirt's 13 -> 0).
GUARD_TOP_UP_SPREAD = 0.25


def _near_lift(p: torch.Tensor, bp: torch.Tensor, anchors: ContactAnchors, where: torch.Tensor,
               anchor_distance: torch.Tensor, depth: float, depth_fade: float,
               body: dict) -> tuple[torch.Tensor, torch.Tensor]:
    """(S, 3) lifts of the vertices `where` (S, 2: frame, vertex) of `p` (T, V, 3) out of the plane of the posed
    body vertices nearest each (GUARD_NEAR_VERTICES of the anchors' `ring` faces' vertices, their points and
    area-weighted normals over those faces blended): to the vertex's floor in front of it, fading out with the
    depth as the anchor's lift does; and (S,) how far those planes stand for the body there: 1 where the nearest
    body vertex is at most half as far as the anchor's point (`anchor_distance`), falling linearly to 0 where it
    is as far (a body coarser than the slide, whose vertices are no nearer than the anchor). `body`: what is
    known of the posed body (`guard_contact`'s, with the ring's cross products "cross"); its vertices' normals
    and k-d trees are added to it for the guard's later searches."""
    ring = torch.as_tensor(anchors.ring, device=bp.device)
    if "normals" not in body:
        normals = torch.zeros_like(bp)
        for k in range(3):
            normals.index_add_(1, ring[:, k], body["cross"])
        body["normals"] = torch.nn.functional.normalize(normals, dim=-1, eps=1e-30)
    normals = body["normals"]
    t, v = where[:, 0], where[:, 1]
    x = p[t, v]
    ids = torch.unique(ring)  # the anchors' body vertices (all of `bp` where `anchored_body` made it)
    near, distance = _nearest_body_vertices(torch.cat([t[:, None].to(x.dtype), x], dim=1), bp[:, ids],
                                            GUARD_NEAR_VERTICES + 1, body.setdefault("trees", {}))
    weight = (1.0 - distance / distance[:, -1:].clamp(min=1e-12)).clamp(min=0.0)[:, :-1]
    weight = weight / weight.sum(dim=1, keepdim=True).clamp(min=1e-12)
    near = ids[near[:, :-1]]
    point = torch.einsum("sk,skc->sc", weight, bp[t[:, None], near])
    normal = torch.nn.functional.normalize(torch.einsum("sk,skc->sc", weight, normals[t[:, None], near]), dim=-1,
                                           eps=1e-30)
    along = torch.einsum("sc,sc->s", x - point, normal)
    floor = torch.as_tensor(anchors.floor, dtype=bp.dtype, device=bp.device)[v]
    behind = (floor - along).clamp(min=0.0)
    trust = (2.0 - 2.0 * distance[:, 0] / anchor_distance.clamp(min=1e-12)).clamp(0.0, 1.0)
    return (behind * _depth_share(behind, depth, depth_fade))[:, None] * normal, trust


def anchor_offsets(points, body_points, anchors: ContactAnchors):
    """Where each vertex lies against its posed anchor: (behind (T, V), its depth below the guard's floor,
    0 where it is above; lateral (T, V), its distance from the anchor's point along the plane; the anchor's unit
    normal (T, V, 3)), metres. points: (T, V, 3); body_points: (T, Vb, 3). Arrays in, float64 arrays out;
    tensors in, tensors of `body_points`' device and dtype out (a GPU's bake keeps its frames there)."""
    p, bp, arrays = _as_tensors(points, body_points)
    out = _offsets(p, bp, anchors)[:3]
    return tuple(x.numpy() for x in out) if arrays else out


def _torch_operator(op: sp.csr_matrix, dtype: torch.dtype, device: torch.device) -> torch.Tensor:
    """The sparse operator `op` (V, V) as a torch CSR tensor of `dtype` on `device`, made once per operator, dtype
    and device while `op` lives (a GPU's bake guards every batch with the same anchors: the copy to the device
    was made per batch)."""
    key = (id(op), dtype, str(torch.device(device)))
    held = _TORCH_OPERATORS.get(key)
    if held is not None and held[0]() is op:
        return held[1]
    index = lambda a: torch.from_numpy(a.astype(np.int64))  # noqa: E731
    with warnings.catch_warnings():  # torch calls its CSR tensors beta (a product with a dense matrix is all used)
        warnings.filterwarnings("ignore", message="Sparse CSR tensor support is in beta")
        out = torch.sparse_csr_tensor(index(op.indptr), index(op.indices), torch.from_numpy(op.data),
                                      size=op.shape, dtype=dtype, check_invariants=False).to(device)
    _TORCH_OPERATORS[key] = (weakref.ref(op, lambda _: _TORCH_OPERATORS.pop(key, None)), out)
    return out


#: `_torch_operator`'s tensors by (id of the scipy operator, dtype, device): (a weak reference to the operator,
#: the tensor); an entry goes with its operator.
_TORCH_OPERATORS: dict = {}


#: A spread of many passes (a fine garment's) is computed as a Chebyshev polynomial of the pass's operator P
#: (`spread_polynomial`) within this of P^passes on P's eigenvalues (in [0, 1]): a lift of 5 cm is then spread
#: within 0.5 um of the passes' result, in fewer products (200 passes: 45; 80: 28; 40: 20).
SPREAD_TOLERANCE = 1e-5


@functools.lru_cache(maxsize=None)
def spread_polynomial(passes: int) -> tuple[float, ...] | None:
    """Chebyshev coefficients (of T_k(2x - 1)) of the least degree interpolant within SPREAD_TOLERANCE of x^passes
    on [0, 1]; None where its degree would be more than half of `passes` (a few passes: plain passes are as
    cheap, and the example garments' guard stays exactly as measured)."""
    from numpy.polynomial import chebyshev

    y = np.cos(np.linspace(0.0, np.pi, 4001))
    power = lambda y: ((y + 1.0) / 2.0) ** passes  # noqa: E731
    for degree in range(1, passes // 2 + 1):
        c = chebyshev.chebinterpolate(power, degree)
        if np.abs(chebyshev.chebval(y, c) - power(y)).max() < SPREAD_TOLERANCE:
            return tuple(float(v) for v in c)
    return None


def spread_over(shift: torch.Tensor, op, passes: int) -> torch.Tensor:
    """`passes` passes of the sparse operator `op` (V, V) over per-vertex vectors `shift` (T, V, C): on the CPU
    `op` as scipy's CSR matrix (a float64 product 3.4x faster than torch's CSR one, float32 as fast), elsewhere as
    `_torch_operator`'s, in shift's dtype and on its device. Many passes are a polynomial of fewer products
    (`spread_polynomial`; its three-term recurrence)."""
    T, V, C = shift.shape
    x = shift.permute(1, 0, 2).reshape(V, T * C)
    if isinstance(op, sp.spmatrix):
        x = x.numpy()
        op = op.astype(x.dtype, copy=False)
    coefficients = spread_polynomial(passes)
    if coefficients is None:
        for _ in range(passes):  # CSR times dense: 3-4 x faster than a gather and index_add on a CPU
            x = op @ x
    else:  # sum c_k T_k(2P - I) x, T_{k+1} = 2 (2P - I) T_k - T_{k-1}
        before, now = x, 2.0 * (op @ x) - x
        out = coefficients[0] * before + coefficients[1] * now
        for c in coefficients[2:]:
            before, now = now, 2.0 * (2.0 * (op @ now) - now) - before
            out = out + c * now
        x = out
    if isinstance(x, np.ndarray):
        x = torch.from_numpy(x)
    return x.reshape(V, T, C).permute(1, 0, 2)


def guard_contact(points, body_points, anchors: ContactAnchors, reach: float = GUARD_REACH_M,
                  depth: float = GUARD_DEPTH_M, reach_fade: float = GUARD_REACH_FADE_M,
                  depth_fade: float = GUARD_DEPTH_FADE_M, passes: int | None = None, rounds: int = GUARD_ROUNDS,
                  state: dict | None = None, top_up: bool | None = None):
    """Keep each vertex outside its posed anchor's plane (see the module's docstring).

    points: (T, V, 3) garment; body_points: (T, Vb, 3) the posed body, both arrays (float64 arithmetic) or both
    tensors (on their device, in body_points' dtype). Fades of 0 cut the lift off at the bounds. Where `anchors`
    has the garment's surface and `passes` (None: the anchors' own) is not 0, the lifts are spread over it in
    that many passes and the guard runs `rounds` times (each lifting what the spread left behind); else once,
    each vertex lifted alone. `state`: a dict carried between guards of the same frames (`guard_and_limit`):
    empty, it is filled with round 0's blend weights of the nearest body vertices' planes ("held", (T, V)) and
    the vertices those planes lifted ("lifted"); filled, the guard searches those vertices only, as its top-up
    round does, the others keeping their share of the anchor's lift; what the guards know of the posed body
    (its planes, normals and k-d trees: "body") is kept there too, and the share of its depth behind its anchor's
    plane each vertex is lifted by ("depth_share", `_depth_share`), decided on the first guard's input, the
    network's output: a round that moved a vertex too deep to lift into the depth's fade band lifted it there (the
    dress's hem at the knee on the example crouch jumped 28 mm in one frame, the network's output 9 mm).
    Returns (points (T, V, 3) float32, moved (T,) counts of vertices moved more than GUARD_MOVED_M), arrays or
    tensors as given.
    """
    p0, bp, arrays = _as_tensors(points, body_points)
    p = p0
    passes = anchors.passes if passes is None else passes
    spreading = anchors.spread is not None and passes > 0
    op = None if not spreading else anchors.spread if p.device.type == "cpu" else _torch_operator(anchors.spread,
                                                                                                   p.dtype, p.device)
    body = {} if state is None else state.setdefault("body", {})
    if "planes" not in body:
        body["cross"] = _ring_cross(bp, torch.as_tensor(anchors.ring, device=bp.device))
        body["planes"] = _planes(bp, anchors, body["cross"])
    spread_rounds = rounds if spreading else 1
    decided = {} if state is None else state
    top_up = spreading and (GUARD_TOP_UP if top_up is None else top_up)
    prior = state is not None and "held" in state
    # round 0's (or an earlier guard's): the nearest body vertices' planes' weights, the vertices they lifted
    held, lifted = (state["held"], state["lifted"]) if prior else (None, None)
    for round_ in range(spread_rounds + top_up):
        final = round_ == spread_rounds
        subset = final or prior
        behind, lateral, normal, distance = _offsets(p, bp, anchors, body["planes"])
        within = _fade(lateral, reach, reach_fade)
        if "depth_share" not in decided:  # on the first guard's input: the network's output
            decided["depth_share"] = _depth_share(behind, depth, depth_fade)
        shift = anchor_shift = (behind * decided["depth_share"] * within)[..., None] * normal
        if round_ < GUARD_NEAR_ROUNDS or final:  # slid far along its anchor: the nearest body's plane too
            near = ((lateral - GUARD_NEAR_FROM_M) / (GUARD_NEAR_TO_M - GUARD_NEAR_FROM_M)).clamp(0.0, 1.0) * within
            if subset:  # those round 0 left to the anchor's plane alone keep its share of the lift
                if held is None:  # round 0 searched none
                    held, lifted = torch.zeros_like(near), torch.zeros_like(near, dtype=torch.bool)
                shift = anchor_shift * (1.0 - held)[..., None]
            where = torch.nonzero(lifted if subset else near > 0)
            if len(where):
                t, v = where[:, 0], where[:, 1]
                lift, trust = _near_lift(p, bp, anchors, where, distance[t, v], depth, depth_fade, body)
                w = near[t, v] * trust
                if round_ == 0 and not prior:
                    held = torch.zeros_like(near).index_put((t, v), w)
                    lifted = torch.zeros_like(near, dtype=torch.bool).index_put((t, v), (w > 0) & (lift != 0).any(1))
                shift = shift.index_put((t, v), (1.0 - w)[:, None] * anchor_shift[t, v] + w[:, None] * lift)
        if spreading and not final:
            shift = spread_over(shift, op, passes)
        elif spreading and GUARD_TOP_UP_SPREAD > 0:
            shift = spread_over(shift, op, max(1, int(round(passes * GUARD_TOP_UP_SPREAD))))
        p = p + shift
    if state is not None and not prior and held is not None:
        state.update(held=held, lifted=lifted)
    out, moved = p.float(), (torch.linalg.norm(p - p0, dim=-1) > GUARD_MOVED_M).sum(dim=1)
    return (out.numpy(), moved.numpy()) if arrays else (out, moved)


#: Frames the contact guard works on at once over a sequence: at most GUARD_CHUNK_FRAMES, fewer for a large garment
#: (`guard_chunk_frames`: about GUARD_CHUNK_VERTEX_FRAMES vertex-frames, GUARD_MIN_CHUNK_FRAMES at least). LBS on the
#: example dress subdivided 0-3 times, 64 frames of the run, one thread: 3,240 vertices 1.2 ms/frame at 16 (1.9 at
#: 4); 12,816: 8.0 at 4 (16.3 at 32, 8.1 at 16); 50,976: 49.5 at 4 (121.6 at 16, peak memory 330 MB more); 203,328:
#: 537 at 4 (819 at 16, peak +700 MB). (Before the body was posed at the anchors only: 2 at a time 2.3 ms/frame,
#: 16 at a time 1.3, on the dress.) A small garment's chunks are longer, the work of a chunk being mostly fixed: the
#: extremes suite's 384-vertex tube, 2,000 frames of the model with the guard and strain limit, 16.5 s at 16 and
#: 11.0 at 128, the same output (its 10,000-frame test took 92 s).
GUARD_CHUNK_FRAMES = 128
GUARD_CHUNK_VERTEX_FRAMES = 64_000
GUARD_MIN_CHUNK_FRAMES = 4


def guard_chunk_frames(n_vertices: int) -> int:
    """Frames `guard_sequence` guards at once for a garment of `n_vertices` (`frames_at_once`)."""
    return frames_at_once(n_vertices, GUARD_CHUNK_VERTEX_FRAMES, GUARD_MIN_CHUNK_FRAMES, GUARD_CHUNK_FRAMES)


def anchored_body(anchors: ContactAnchors) -> tuple[np.ndarray, ContactAnchors]:
    """The body vertices the anchors use (ids (N,), for `Body.pose_at`: the guard need not pose the rest of the
    body) and the anchors with their body vertices as indices into them."""
    ids, local = np.unique(anchors.ring, return_inverse=True)  # every vertex of the points is one of the ring's
    return ids, replace(anchors, point=anchors.point[:, ids].tocsr(), ring=local.reshape(anchors.ring.shape))


def body_anchors(rest: np.ndarray, faces: np.ndarray, body: Body, betas: np.ndarray | None) -> ContactAnchors:
    """`contact_anchors` of a garment at rest (V, 3), faces (F, 3), on `body` shaped by `betas` (its faces wound
    outward)."""
    shaped_body, _ = body.shaped(betas)
    return contact_anchors(np.asarray(rest), shaped_body, outward_faces(shaped_body, body.faces),
                           garment_faces=faces)


def guard_report(moved: list, seconds: float | None, frames: int) -> dict:
    """The deformer report's entries of a guarded sequence: "contact_guard" (its bounds and how many vertices it
    moved per frame: `moved`, (T,) counts in pieces) and "seconds_per_frame_guard" (None: not timed apart)."""
    moved = np.concatenate([np.asarray(m) for m in moved]) if moved else np.zeros(1, dtype=np.int64)
    guard = {"margin_m": GUARD_MARGIN_M, "reach_m": GUARD_REACH_M, "depth_m": GUARD_DEPTH_M,
             "reach_fade_m": GUARD_REACH_FADE_M, "depth_fade_m": GUARD_DEPTH_FADE_M,
             "spread_m": GUARD_SPREAD_M, "rounds": GUARD_ROUNDS,
             "vertices_moved_per_frame_mean": float(moved.mean()), "vertices_moved_per_frame_max": int(moved.max())}
    report = {"contact_guard": guard}
    if seconds is not None:
        report["seconds_per_frame_guard"] = seconds / max(frames, 1)
    return report


def guard_sequence(points: np.ndarray, rest: np.ndarray, faces: np.ndarray, body: Body, poses: np.ndarray,
                   trans: np.ndarray, betas: np.ndarray | None,
                   anchors: ContactAnchors | None = None, on_frames=None, strain=None) -> tuple[np.ndarray, dict]:
    """The contact guard over a deformed sequence (the model's and psd's): each vertex tied to its closest face
    of the body at rest (`body_anchors`), then kept outside it in every frame (`guard_contact`), the body posed
    `guard_chunk_frames` frames at a time.

    points: (T, V, 3) the sequence (written in place); rest: (V, 3) the garment at rest on the shaped body, faces
    (F, 3); poses: (T, J, 3) in the body's layout; anchors: `body_anchors(rest, faces, body, betas)` where made;
    on_frames(n): called after each chunk of n frames (a progress bar); strain: a `core.strain.StrainLimit` the
    guard alternates with, chunk by chunk (`alternate_guard_limit`; chunks no larger than `strain_chunk_frames`).
    Returns (points, `guard_report`'s entries; with `strain`, the limit's "strain_limit" entry among them, its
    time not the guard's).
    """
    t0 = time.perf_counter()
    if anchors is None:
        anchors = body_anchors(rest, faces, body, betas)
    ids, anchors = anchored_body(anchors)
    moved, over, left, passes, limit_s = [], [], [], 0, 0.0
    chunk = guard_chunk_frames(points.shape[1])
    if strain is not None:
        chunk = min(chunk, strain_chunk_frames(points.shape[1]))
    for s in range(0, len(points), chunk):
        fr = slice(s, min(s + chunk, len(points)))
        posed = body.pose_at(ids, poses[fr], trans[fr], betas)
        if strain is None:
            points[fr], n = guard_contact(points[fr], posed, anchors)
        else:
            points[fr], out = alternate_guard_limit(points[fr], posed, anchors, strain)
            n = out["moved"]
            over.append(out["over"])
            left.append(out["left"])
            passes, limit_s = max(passes, out["passes"]), limit_s + out["limit_seconds"]
        moved.append(n)
        if on_frames is not None:
            on_frames(fr.stop - fr.start)
    report = guard_report(moved, time.perf_counter() - t0 - limit_s, len(points))
    report["contact_guard"]["alternations_with_strain_limit"] = 1 if strain is None else GUARD_LIMIT_ALTERNATIONS
    if strain is not None:
        report["strain_limit"] = strain_report(strain, STRAIN_ITERATIONS, over, passes, limit_s, len(points), left)
    return points, report


#: Times the contact guard and then the strain limit run over a sequence where both are on (`guard_and_limit`,
#: `alternate_guard_limit`): the limit sees no body, and pulling a stretched edge short it pulled cloth the guard
#: had lifted back in (the example jumpsuit's seat showed through at each stride of the run: 154 vertices inside
#: at frame 5 where the guard alone left 22); the guard's top-up round lifts those out again, the second limit
#: undoes the stretch that makes. On the example garments' run, jump and held-out walk (`python
#: benchmarks/guard_limit.py`): the jumpsuit 0.65 -> 0.32 % of vertices inside on the run (worst frame 2.90 ->
#: 1.71), 0.93 -> 0.63 on the walk; the t-shirt 0.78 -> 0.51 on the run, 2.08 -> 1.55 on the jump; the dress
#: 0.48 -> 0.40 on the run; the skirt's jump 0.05 -> 0.06 and the trousers' worst frame there 2.22 -> 2.31; no
#: torn frame, the error against the simulator within 0.05 mm; the guard and limit 1-5 ms/frame more on one
#: thread (the 4k dress of benchmarks/throughput.py about 2 of 18).
GUARD_LIMIT_ALTERNATIONS = 2


def guard_and_limit(deformer: Deformer, points: np.ndarray, garment: Garment, rest: np.ndarray, body: Body,
                    poses: np.ndarray, trans: np.ndarray, betas: np.ndarray | None, anchors: ContactAnchors | None,
                    limit: float | None, on_frames=None) -> tuple[np.ndarray, dict]:
    """The contact guard (`guard_sequence` with `anchors`; None: off) and then the strain limit
    (`deformer.limit_strain_of`; `limit` None: off) over a deformed sequence (T, V, 3) written in place; where
    both are on, GUARD_LIMIT_ALTERNATIONS times over each chunk of frames (`guard_sequence` with the strain limit;
    `on_frames(n)` once per chunk). Returns (points, the guard's `guard_report` entries, {} without one); the
    limit's entry goes to the deformer's report."""
    if anchors is None or limit is None:
        guard = {}
        if anchors is not None:
            points, guard = guard_sequence(points, rest, garment.faces, body, poses, trans, betas, anchors, on_frames)
        return deformer.limit_strain_of(points, garment, rest, limit, on_frames), guard
    strain = garment_strain(garment, rest, limit, deformer._strain)
    points, guard = guard_sequence(points, rest, garment.faces, body, poses, trans, betas, anchors, on_frames, strain)
    deformer.report["strain_limit"] = guard.pop("strain_limit")
    return points, guard


def alternate_guard_limit(points, posed, anchors: ContactAnchors, strain, synchronize=lambda: None):
    """`guard_contact` and then `core.strain.limit_strain` of frames `points` (T, V, 3) on the posed body's
    anchored vertices `posed` (`anchored_body`), GUARD_LIMIT_ALTERNATIONS times: the first guard its spread rounds
    (no top-up round), each later one its top-up round alone, searching only the vertices the first lifted by
    their nearest body vertices' planes (its `state`). Returns (points, {"moved": the first guard's counts (T,),
    "over": the first limit's edges over (T,), "left": `still_over` after the last, "passes": the most a limit
    took, "limit_seconds": the limits' time, "alternations"}), arrays or tensors as given. `synchronize`: waits
    for the device before a limit is timed."""
    state, out, limit_s, passes = {}, {}, 0.0, 0
    for k in range(GUARD_LIMIT_ALTERNATIONS):
        points, moved = guard_contact(points, posed, anchors, rounds=0 if k else GUARD_ROUNDS, state=state,
                                      top_up=k > 0)
        synchronize()
        t = time.perf_counter()
        points, over, done = limit_strain(points, strain)
        synchronize()
        limit_s, passes = limit_s + time.perf_counter() - t, max(passes, done)
        if k == 0:
            out = {"moved": moved, "over": over}
    return points, {**out, "left": still_over(points, strain), "passes": passes, "limit_seconds": limit_s,
                    "alternations": GUARD_LIMIT_ALTERNATIONS}


class PushOutDeformer(Deformer):
    """Another deformer's output with `push_out` applied to every frame."""

    def __init__(self, inner: Deformer, margin: float = PUSH_OUT_MARGIN_M):
        super().__init__()
        self.inner, self.margin = inner, margin
        self.name = inner.name  # the method; the report says it was pushed out

    def prepare(self, garment: Garment, body: Body, source: str | None = None) -> None:
        self.inner.prepare(garment, body, source)

    def deform(self, garment: Garment, body: Body, motion: Motion) -> np.ndarray:
        self.inner.on_frames, self.inner.skips = self.on_frames, self.skips
        points = self.inner.deform(garment, body, motion)
        self.scene = self.inner.scene
        body_points, _ = body.pose(poses_for_body(motion, body.n_joints), motion.trans, motion.betas)
        # The ground, as the simulator's: the lowest point the body reaches (never above a body point).
        ground = float(body_points[..., 2].min())
        outer: dict = {}
        pushed, moved = push_out(points, body_points, body.faces, self.margin, ground, report=outer,
                                 edges=mesh_edges(garment.faces))
        self.report = {**self.inner.report, "push_out": {"margin_m": self.margin, "ground_z_m": ground,
                                                         "vertices_moved_per_frame_mean": float(moved.mean()),
                                                         "vertices_moved_per_frame_max": int(moved.max(initial=0)),
                                                         **outer}}
        return pushed
