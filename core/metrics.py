"""Quality metrics between a predicted and a ground-truth garment sequence (paper Sec. 5.2).

The five measures of the paper's Eqs. 11-15 (vertex distance, vertex- and
face-normal angle, relative edge-length error, Gaussian-curvature error), each
a pure numpy function `(pred (T,V,3), gt (T,V,3), faces (F,3)) -> (T,)`
vectorised over frames, plus the mesh quantities they need (`face_normals`,
`vertex_normals`, `gaussian_curvature`). `compute_metrics` checks the inputs,
evaluates all of them (and, given an inside-the-body test, the share of
garment vertices inside the body) and returns a `MetricsResult` that
`formats.report` writes as JSON, CSV or Markdown.

Degenerate geometry never gives NaN: zero-area faces have zero normals (see
`e_vnorm` for how they are scored), angles are taken with atan2 (no arccos of a
cosine rounded past 1), and
zero-length ground-truth edges are left out of the relative edge error.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from core.errors import InputError, check_finite_points, frames_text
from core.garment import boundary_edges, mesh_edges
from core.geometry import (as_float, face_cross, face_normals, normalise, scatter_corners, vertex_areas,  # noqa: F401
                           vertex_normals)

log = logging.getLogger(__name__)

#: Metric names in report order -> (label as in the paper's tables, unit).
METRICS: dict[str, tuple[str, str]] = {
    "e_verts": ("E_verts", "mm"),
    "e_vnorm": ("E_vnorm", "deg"),
    "e_fnorm": ("E_fnorm", "deg"),
    "e_edge": ("E_edge", "%"),
    "e_curv": ("E_curv", "1/m^2"),
    "penetration_pct": ("penetration", "%"),
    "gt_penetration_pct": ("GT penetration", "%"),
}

# Below this a length, area or cross-product norm (in metres or m^2) counts as zero.
_EPS = 1e-12

InsideFn = Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]


# ---------------------------------------------------------------------------
# Mesh quantities
# ---------------------------------------------------------------------------

def boundary_vertex_mask(faces: np.ndarray, n_vertices: int) -> np.ndarray:
    """Vertices on the mesh boundary: those on an edge used by exactly one face.

    faces: (F, 3) int -> (V,) bool.
    """
    mask = np.zeros(n_vertices, dtype=bool)
    mask[boundary_edges(faces).reshape(-1)] = True
    return mask


_TOPOLOGY_CACHE: dict = {}


def _topology(faces: np.ndarray, n_vertices: int) -> tuple[np.ndarray, np.ndarray]:
    """(`mesh_edges(faces)` (E, 2), `boundary_vertex_mask(faces, n_vertices)` (V,)), cached by the faces' bytes:
    `compute_metrics` takes a long sequence a few frames at a time (`_by_frames`), and sorting a 200k-vertex
    garment's edges for every part and side took about a second each."""
    faces = np.ascontiguousarray(faces, dtype=np.int64)
    key = (faces.shape, hash(faces.tobytes()), n_vertices)
    if key not in _TOPOLOGY_CACHE:
        if len(_TOPOLOGY_CACHE) > 8:
            _TOPOLOGY_CACHE.clear()
        _TOPOLOGY_CACHE[key] = (mesh_edges(faces), boundary_vertex_mask(faces, n_vertices))
    return _TOPOLOGY_CACHE[key]


def corner_angles(verts: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Interior angle of each face at each of its corners.

    verts: (..., V, 3) float, metres. faces: (F, 3) int.
    Returns (..., F, 3) float64 radians; angle k is at vertex faces[:, k].
    Computed as atan2(|a x b|, a . b), so degenerate faces give finite angles.
    """
    verts = np.asarray(verts, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    p = [verts[..., faces[:, k], :] for k in range(3)]
    out = []
    for k in range(3):
        a = p[(k + 1) % 3] - p[k]
        b = p[(k + 2) % 3] - p[k]
        out.append(np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.einsum("...i,...i->...", a, b)))
    return np.stack(out, axis=-1)


def gaussian_curvature(verts: np.ndarray, faces: np.ndarray, area_normalised: bool = True) -> np.ndarray:
    """Discrete Gaussian curvature per vertex by angle deficit.

    The deficit is 2*pi - (sum of incident corner angles) at an interior vertex
    and pi - (sum) at a boundary vertex (one on an edge used by a single face),
    so a flat sheet has zero curvature at interior vertices and along straight
    stretches of its rim; at a rim corner the boundary formula gives the rim's
    turning angle (its geodesic curvature), e.g. pi/2 at a square's corner. With
    `area_normalised` (the default, and what `e_curv` uses) the deficit is
    divided by the vertex's barycentric area (a third of the incident face
    areas): the result is a curvature density in 1/m^2 that does not depend on
    the mesh resolution (about 1/r^2 on a sphere of radius r). Without it the
    raw deficit in radians is returned (it sums to 2*pi*chi, Gauss-Bonnet).
    Vertices with no incident face, or only zero-area ones, get 0.

    verts: (..., V, 3) float, metres. faces: (F, 3) int.
    Returns (..., V) float64: 1/m^2 (area_normalised) or radians.
    """
    verts = np.asarray(verts, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    V = verts.shape[-2]
    angle_sum = scatter_corners(corner_angles(verts, faces)[..., None], faces, V)[..., 0]
    used = np.zeros(V, dtype=bool)
    used[faces.reshape(-1)] = True
    full = np.where(_topology(faces, V)[1], np.pi, 2.0 * np.pi)
    deficit = np.where(used, full - angle_sum, 0.0)
    if not area_normalised:
        return deficit
    vertex_area = vertex_areas(verts, faces)
    ok = vertex_area > _EPS
    return np.where(ok, deficit / np.where(ok, vertex_area, 1.0), 0.0)


# ---------------------------------------------------------------------------
# Per-frame metrics (Eqs. 11-15)
# ---------------------------------------------------------------------------

def _angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle in degrees between unit-or-zero vectors (..., 3); see `e_vnorm` for zero vectors.

    atan2(|a x b|, a . b) equals the paper's arccos(a . b) for unit vectors but is
    exact (0) for identical ones and accurate for small angles, where arccos of a
    rounded cosine is not; it needs no clipping and a zero vector gives 90 deg.
    """
    cross = np.linalg.norm(np.cross(a, b), axis=-1)
    dot = np.einsum("...i,...i->...", a, b)
    angle = np.degrees(np.arctan2(cross, dot))
    angle = np.where((cross == 0) & (dot == 0), 90.0, angle)  # one normal is zero: no agreement
    both_zero = ~np.any(a != 0, axis=-1) & ~np.any(b != 0, axis=-1)
    return np.where(both_zero, 0.0, angle)


def vertex_distance_mm(pred: np.ndarray, gt: np.ndarray) -> np.ndarray:
    """Per-vertex Euclidean distance. pred, gt: (T, V, 3) metres -> (T, V) float64 millimetres."""
    d = np.asarray(pred, dtype=np.float64) - np.asarray(gt, dtype=np.float64)
    return 1000.0 * np.linalg.norm(d, axis=-1)


def vertex_normal_angle_deg(pred: np.ndarray, gt: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Per-vertex angle between vertex normals. pred, gt: (T, V, 3); faces: (F, 3) -> (T, V) degrees."""
    pred = np.asarray(pred, dtype=np.float64)
    gt = np.asarray(gt, dtype=np.float64)
    return _angle_deg(vertex_normals(pred, faces), vertex_normals(gt, faces))


def edge_relative_error(pred: np.ndarray, gt: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-edge |l - l_gt| / l_gt over unique edges.

    pred, gt: (T, V, 3) metres; faces: (F, 3). Returns (rel (T, E) fraction, valid (T, E) bool):
    edges of zero ground-truth length are not valid (their relative error is undefined, stored as 0).
    """
    pred = np.asarray(pred, dtype=np.float64)
    gt = np.asarray(gt, dtype=np.float64)
    edges = _topology(faces, pred.shape[-2])[0]
    l_pred = np.linalg.norm(pred[:, edges[:, 0]] - pred[:, edges[:, 1]], axis=-1)
    l_gt = np.linalg.norm(gt[:, edges[:, 0]] - gt[:, edges[:, 1]], axis=-1)
    ok = l_gt > _EPS
    return np.where(ok, np.abs(l_pred - l_gt) / np.where(ok, l_gt, 1.0), 0.0), ok


def e_verts(pred: np.ndarray, gt: np.ndarray, faces: np.ndarray | None = None) -> np.ndarray:
    """Eq. 11: mean Euclidean vertex distance per frame.

    pred, gt: (T, V, 3) float, metres. faces: unused (same signature as the others).
    Returns (T,) float64, millimetres.
    """
    return vertex_distance_mm(pred, gt).mean(axis=-1)


def e_vnorm(pred: np.ndarray, gt: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Eq. 12: mean angle between predicted and ground-truth vertex normals per frame.

    pred, gt: (T, V, 3) float, metres. faces: (F, 3) int. Returns (T,) float64, degrees.
    A vertex whose normal is zero in both (no incident area) scores 0; zero in
    one only scores 90 (the cosine is taken as 0: no agreement).
    """
    return vertex_normal_angle_deg(pred, gt, faces).mean(axis=-1)


def e_fnorm(pred: np.ndarray, gt: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Eq. 13: mean angle between predicted and ground-truth face normals per frame.

    pred, gt: (T, V, 3) float, metres. faces: (F, 3) int. Returns (T,) float64, degrees.
    Zero-area faces are scored as in `e_vnorm` (0 if degenerate in both, 90 if in one).
    """
    pred = np.asarray(pred, dtype=np.float64)
    gt = np.asarray(gt, dtype=np.float64)
    return _angle_deg(face_normals(pred, faces), face_normals(gt, faces)).mean(axis=-1)


def e_edge(pred: np.ndarray, gt: np.ndarray, faces: np.ndarray, zero_edges: list | None = None) -> np.ndarray:
    """Eq. 14: mean relative edge-length error |l - l_gt| / l_gt over unique edges, per frame.

    pred, gt: (T, V, 3) float, metres. faces: (F, 3) int. Returns (T,) float64, percent.
    Edges of zero ground-truth length (relative error undefined) are left out
    of the mean (with a warning, or their count appended to `zero_edges`); a frame with no usable edge scores 0.
    """
    rel, ok = edge_relative_error(pred, gt, faces)
    if zero_edges is not None:
        zero_edges.append(int((~ok).sum()))
    else:
        _warn_zero_edges(int((~ok).sum()))
    n = ok.sum(axis=-1)
    return 100.0 * rel.sum(axis=-1) / np.maximum(n, 1)


def _warn_zero_edges(count: int) -> None:
    if count:
        log.warning("%d ground-truth edges of zero length left out of E_edge", count)


#: A vertex of the prediction with less than this share of the ground truth's area around it (its faces
#: collapsed) is counted in `e_curv`'s warning: its curvature density, the angle deficit over that area, grows
#: without bound (a push-out that collapsed a few faces put the t-shirt's E_curv at 7.7e6 against 657).
COLLAPSED_AREA_SHARE = 0.01


def e_curv(pred: np.ndarray, gt: np.ndarray, faces: np.ndarray, collapsed: list | None = None) -> np.ndarray:
    """Eq. 15: mean absolute difference of area-normalised Gaussian curvature per frame.

    pred, gt: (T, V, 3) float, metres. faces: (F, 3) int. Returns (T,) float64, 1/m^2
    (see `gaussian_curvature` for the definition). Vertices of `pred` whose faces collapsed
    (COLLAPSED_AREA_SHARE) are warned about, or their count appended to `collapsed`.
    """
    pred = np.asarray(pred, dtype=np.float64)
    gt = np.asarray(gt, dtype=np.float64)
    gt_area = vertex_areas(gt, faces)
    count = int(((vertex_areas(pred, faces) < COLLAPSED_AREA_SHARE * gt_area) & (gt_area > _EPS)).sum())
    if collapsed is not None:
        collapsed.append(count)
    else:
        _warn_collapsed(count)
    return np.abs(gaussian_curvature(pred, faces) - gaussian_curvature(gt, faces)).mean(axis=-1)


def _warn_collapsed(count: int) -> None:
    if count:
        log.warning("%d vertex-frames of the prediction have under %g %% of the ground truth's area around them "
                    "(collapsed faces): their curvature density dominates E_curv", count, 100 * COLLAPSED_AREA_SHARE)


PER_FRAME_METRICS: dict[str, Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]] = {
    "e_verts": e_verts,
    "e_vnorm": e_vnorm,
    "e_fnorm": e_fnorm,
    "e_edge": e_edge,
    "e_curv": e_curv,
}


# ---------------------------------------------------------------------------
# Checks and the whole evaluation
# ---------------------------------------------------------------------------

@dataclass
class MetricsResult:
    """Metrics of one prediction against its ground truth.

    per_frame: name -> (T,) float64 (names and units in `METRICS`).
    overall: name -> float, the mean over frames.
    """

    per_frame: dict[str, np.ndarray]
    overall: dict[str, float]
    n_frames: int
    n_vertices: int
    n_faces: int = 0
    metadata: dict = field(default_factory=dict)


def check_comparable(pred_points: np.ndarray, pred_faces: np.ndarray, gt_points: np.ndarray,
                     gt_faces: np.ndarray, pred_name: str = "pred", gt_name: str = "gt") -> None:
    """Raise InputError unless two sequences share a topology and a frame count.

    pred_points, gt_points: (T, V, 3). pred_faces, gt_faces: (F, 3) int.
    Nothing is trimmed or resampled: mismatches are the user's to resolve. Faces that differ only in order,
    winding or the diagonals that split quads (`same_surface`: a quad mesh triangulated by two tools) are one
    topology; the metrics use the prediction's faces for both.
    """
    for name, pts in ((pred_name, pred_points), (gt_name, gt_points)):
        if np.ndim(pts) != 3 or np.shape(pts)[-1] != 3:
            raise InputError(f"'{name}': expected points of shape (T, V, 3), got {tuple(np.shape(pts))}")
    Vp, Vg = np.shape(pred_points)[1], np.shape(gt_points)[1]
    if Vp != Vg:
        name, more = (pred_name, pred_points) if Vp > Vg else (gt_name, gt_points)
        first = np.asarray(more[0], dtype=np.float64) if len(more) else np.zeros((0, 3))
        shared = len(first) - len(np.unique(np.round(first, 6), axis=0))  # vertices at another's position (1 um)
        hint = (f": {shared} of '{name}''s vertices lie where others do (the mesh split at its UV or panel seams, as "
                "some exporters write it?): export it welded, or as the other side is" if shared >= abs(Vp - Vg)
                else "")
        raise InputError(f"'{pred_name}' has {Vp} vertices, '{gt_name}' has {Vg}: "
                         f"expected the same garment mesh (same vertices and faces){hint}")
    pf, gf = np.asarray(pred_faces), np.asarray(gt_faces)
    if pf.shape != gf.shape or not (np.array_equal(pf, gf) or same_surface(pf, gf, Vp)):
        detail = (f"{pf.shape[0]} vs {gf.shape[0]} faces" if pf.shape != gf.shape
                  else f"first difference at face {int(np.argmax(np.any(pf != gf, axis=-1)))}")
        hint = ("" if pf.shape != gf.shape else ": the same garment exported with its vertices in another order? "
                "export both keeping the vertex order of one mesh")
        raise InputError(f"'{pred_name}' and '{gt_name}' have different faces ({detail}): "
                         f"expected the same garment mesh (same vertices and faces){hint}")
    Tp, Tg = np.shape(pred_points)[0], np.shape(gt_points)[0]
    if Tp != Tg:
        raise InputError(f"'{pred_name}' has {frames_text(Tp)}, '{gt_name}' has {Tg}: expected the same "
                         "frame count (trim or resample one of them to match)")


def _edge_keys(faces: np.ndarray, n_vertices: int) -> np.ndarray:
    """Sorted unique undirected edges of triangles (F, 3) (`mesh_edges`), each as a * V + b with a < b."""
    e = mesh_edges(faces)
    return e[:, 0] * n_vertices + e[:, 1]


def _flipped_edges(faces: np.ndarray, n_vertices: int) -> np.ndarray:
    """The other diagonal of every quad two triangles of `faces` form across an edge they share: (b, d) for
    the edge (a, c) of triangles (a, b, c) and (a, c, d); as keys like `_edge_keys`."""
    f = np.asarray(faces, dtype=np.int64)
    corner = np.concatenate([f[:, [0, 1, 2]], f[:, [1, 2, 0]], f[:, [2, 0, 1]]])  # edge (u, v), opposite w
    key = np.minimum(corner[:, 0], corner[:, 1]) * n_vertices + np.maximum(corner[:, 0], corner[:, 1])
    order = np.argsort(key, kind="stable")
    key, opposite = key[order], corner[order, 2]
    pair = np.flatnonzero(key[1:] == key[:-1])  # consecutive equal keys: two triangles on one edge
    b, d = opposite[pair], opposite[pair + 1]
    return np.unique(np.minimum(b, d) * n_vertices + np.maximum(b, d))


def same_surface(faces_a: np.ndarray, faces_b: np.ndarray, n_vertices: int) -> bool:
    """Whether two triangulations of one vertex set are one surface: the same number of triangles and of edges,
    and every edge of one either an edge of the other or the other diagonal of a quad it forms (two tools
    splitting a quad mesh along different diagonals, in any order and winding)."""
    a, b = np.asarray(faces_a, dtype=np.int64), np.asarray(faces_b, dtype=np.int64)
    if a.shape != b.shape:
        return False
    ea, eb = _edge_keys(a, n_vertices), _edge_keys(b, n_vertices)
    if len(ea) != len(eb):
        return False
    only_a, only_b = np.setdiff1d(ea, eb), np.setdiff1d(eb, ea)
    return bool(np.isin(only_a, _flipped_edges(b, n_vertices)).all()
                and np.isin(only_b, _flipped_edges(a, n_vertices)).all())


def _check_points(points: np.ndarray, name: str) -> np.ndarray:
    points = np.asarray(points)
    if points.ndim != 3 or points.shape[-1] != 3:
        raise InputError(f"'{name}': expected points of shape (T, V, 3), got {tuple(points.shape)}")
    if points.shape[0] == 0 or points.shape[1] == 0:
        raise InputError(f"'{name}': expected at least one frame and one vertex, got shape {tuple(points.shape)}")
    if not np.issubdtype(points.dtype, np.number):
        raise InputError(f"'{name}': expected numeric points, got dtype {points.dtype}")
    check_finite_points(points, f"'{name}'")
    return points


def _check_faces(faces: np.ndarray, n_vertices: int, name: str) -> np.ndarray:
    faces = np.asarray(faces)
    if faces.ndim != 2 or faces.shape[1] != 3 or faces.shape[0] == 0:
        raise InputError(f"'{name}': expected triangle faces of shape (F, 3), got {tuple(faces.shape)}")
    if not np.issubdtype(faces.dtype, np.integer):
        raise InputError(f"'{name}': expected integer face indices, got dtype {faces.dtype}")
    if faces.min() < 0 or faces.max() >= n_vertices:
        raise InputError(f"'{name}': expected face indices in [0, {n_vertices - 1}], "
                         f"got {int(faces.min())}..{int(faces.max())}")
    return faces.astype(np.int64)


def _unique_faces(faces: np.ndarray, name: str) -> np.ndarray:
    """`faces` without those on the same three vertices as an earlier one, warned of: a duplicate counted twice in
    the normals and the angle sums and made its border edges inner ones (E_curv 27.5 -> 28.0 for one of 50)."""
    _, first = np.unique(np.sort(faces, axis=1), axis=0, return_index=True)
    if len(first) == len(faces):
        return faces
    log.warning(f"'{name}': {len(faces) - len(first)} duplicate faces (on the same vertices as an earlier face) "
                "left out of the metrics")
    return faces[np.sort(first)]


def frames_inside(points_inside_mesh: Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]) -> InsideFn:
    """Lift a one-frame inside test to the (T, ...) `inside_fn` that `compute_metrics` takes.

    points_inside_mesh(points (N,3), mesh_verts (Vb,3), mesh_faces (Fb,3)) -> (N,) bool.
    Returns inside_fn(points (T,V,3), body_points (T,Vb,3), body_faces) -> (T,V) bool.
    """

    def inside_fn(points: np.ndarray, body_points: np.ndarray, body_faces: np.ndarray) -> np.ndarray:
        return np.stack([np.asarray(points_inside_mesh(points[t], body_points[t], body_faces), dtype=bool)
                         for t in range(points.shape[0])])

    return inside_fn


def _inside(points: np.ndarray, body_points: np.ndarray, body_faces: np.ndarray, inside_fn: InsideFn) -> np.ndarray:
    """(T, V) bool: `inside_fn` of (T, V, 3) points, its shape checked."""
    inside = np.asarray(inside_fn(points, body_points, body_faces), dtype=bool)
    if inside.shape != points.shape[:2]:
        raise ValueError(f"inside_fn returned shape {inside.shape}, expected {points.shape[:2]}")
    return inside


def penetration_pct(points: np.ndarray, body_points: np.ndarray, body_faces: np.ndarray,
                    inside_fn: InsideFn) -> np.ndarray:
    """Share of garment vertices inside the body per frame.

    points: (T, V, 3) metres; body_points: (T, Vb, 3) metres; body_faces: (Fb, 3) int.
    Returns (T,) float64, percent.
    """
    return 100.0 * _inside(points, body_points, body_faces, inside_fn).mean(axis=-1)


def penetration_pct_pair(first: np.ndarray, second: np.ndarray, body_points: np.ndarray, body_faces: np.ndarray,
                         inside_fn: InsideFn) -> np.ndarray:
    """`penetration_pct` of two garments (T, V, 3) on one body, in one inside test a frame (the body's
    structures built once). Returns (T, 2) percent."""
    inside = _inside(np.concatenate([first, second], axis=1), body_points, body_faces, inside_fn)
    n = first.shape[1]
    return 100.0 * np.stack([inside[:, :n].mean(axis=-1), inside[:, n:].mean(axis=-1)], axis=-1)


def self_intersection_pct(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Share of garment faces that intersect another face of the garment, per frame.

    points: (T, V, 3) metres; faces: (F, 3) int. Returns (T,) float64, percent
    (`core.geometry.self_intersecting_faces` on each frame).
    """
    from core.geometry import self_intersecting_faces

    return np.array([100.0 * self_intersecting_faces(x, faces).mean() for x in np.asarray(points)])


#: Vertex-frames the per-frame metrics take at a time (`_by_frames`): their float64 temporaries then stay within
#: a few hundred MB for any garment and sequence (all frames at once took 10 GB for 91 frames of 213k vertices).
METRIC_VERTEX_FRAMES = 1_000_000


def _by_frames(fn: Callable[..., np.ndarray], a: np.ndarray, *others: np.ndarray) -> np.ndarray:
    """(T, ...) per-frame values of `fn(a, *others)` over (T, ...) arrays, taken METRIC_VERTEX_FRAMES vertex-frames
    of `a` at a time, each part in float64."""
    step = max(1, METRIC_VERTEX_FRAMES // max(1, a.shape[1]))
    return np.concatenate([fn(*(x[s:s + step].astype(np.float64) for x in (a, *others)))
                           for s in range(0, a.shape[0], step)])


def compute_metrics(pred: np.ndarray, gt: np.ndarray, faces: np.ndarray,
                    body_points: np.ndarray | None = None, body_faces: np.ndarray | None = None,
                    inside_fn: InsideFn | None = None, pred_name: str = "pred",
                    gt_name: str = "gt", body_name: str | None = None, gt_body_points: np.ndarray | None = None,
                    gt_body_faces: np.ndarray | None = None, gt_body_name: str | None = None) -> MetricsResult:
    """The paper's five metrics (Eqs. 11-15) per frame and overall, plus optional penetration.

    pred, gt: (T, V, 3) float, metres, same topology and frame count.
    faces: (F, 3) int, shared by both.
    body_points: (T, Vb, 3) metres, body_faces: (Fb, 3) int, and
    inside_fn(points (T,V,3), body_points (T,Vb,3), body_faces) -> (T,V) bool:
    when all three are given, `penetration_pct` (pred) and `gt_penetration_pct`
    (gt against gt_body_points/gt_body_faces when given, GT's own body; else the same body) are added, in percent
    of garment vertices.
    pred_name, gt_name, body_name: how error messages name the inputs (e.g.
    file paths; the body defaults to "<pred_name> body").
    Raises InputError on mismatched shapes, bad faces or non-finite values.
    """
    check_comparable(pred, faces, gt, faces, pred_name, gt_name)
    p = _check_points(pred, pred_name)
    g = _check_points(gt, gt_name)
    T, V = p.shape[:2]
    f = _unique_faces(_check_faces(faces, V, f"{pred_name} faces"), pred_name)

    counts: dict[Callable, list[int]] = {e_edge: [], e_curv: []}  # their warnings once for all parts
    keyword = {e_edge: "zero_edges", e_curv: "collapsed"}
    per_frame = {name: _by_frames(lambda a, b: fn(a, b, f, **({keyword[fn]: counts[fn]} if fn in counts else {})),
                                  p, g)
                 for name, fn in PER_FRAME_METRICS.items()}
    _warn_zero_edges(sum(counts[e_edge]))
    _warn_collapsed(sum(counts[e_curv]))

    if body_points is not None and body_faces is not None and inside_fn is not None:
        def checked_body(points, faces, name):  # (points, faces), one pose per garment frame
            b = _check_points(points, name)
            if b.shape[0] != T:
                raise InputError(f"'{name}': has {frames_text(b.shape[0])}, the garment has {T}: "
                                 "expected one body pose per frame")
            return b, _check_faces(faces, b.shape[1], f"{name} faces")

        b, bf = checked_body(body_points, body_faces, body_name or f"{pred_name} body")
        gb, gbf = b, bf
        if gt_body_points is not None and gt_body_faces is not None:
            gb, gbf = checked_body(gt_body_points, gt_body_faces, gt_body_name or f"{gt_name} body")
        if gbf.shape == bf.shape and np.array_equal(gbf, bf) and gb.shape == b.shape and np.array_equal(gb, b):
            # One body for both: PRED's and GT's vertices in one inside test a frame, the body's structures
            # (KD-tree, normals) built once (a 3,240-vertex garment: 40 % of the penetrations' time).
            both = _by_frames(lambda x, y, z: penetration_pct_pair(x, y, z, bf, inside_fn), p, g, b)
            per_frame["penetration_pct"], per_frame["gt_penetration_pct"] = both[:, 0], both[:, 1]
        else:
            per_frame["penetration_pct"] = _by_frames(lambda x, y: penetration_pct(x, y, bf, inside_fn), p, b)
            per_frame["gt_penetration_pct"] = _by_frames(lambda x, y: penetration_pct(x, y, gbf, inside_fn), g, gb)

    overall = {name: float(np.mean(v)) for name, v in per_frame.items()}
    return MetricsResult(per_frame=per_frame, overall=overall, n_frames=int(T), n_vertices=int(V),
                         n_faces=int(f.shape[0]))
