"""Mesh geometry: normals, exact closest points on a triangle mesh, signed distance, inside tests.

Used by weight transfer (nearest body face), penetration statistics and
validation. Closest points are exact: a KD-tree over points covering each face proposes
candidates and a distance bound proves that no other face can be closer
(points where it cannot are re-queried with more candidates). Signs come from
angle-weighted pseudo-normals (Baerentzen and Aanaes 2005), exact for closed,
consistently oriented meshes.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

_EPS = 1e-12

#: The turn from the body's Y-up rest frame to the motions' Z-up world (+90 degrees about X,
#: `core.motion.Y_UP_TO_Z_UP`) as a matrix on column vectors: (x, y, z) -> (x, -z, y). Points stored as rows
#: turn with `points @ Y_UP_TO_Z_UP_MATRIX.T`, and back with `points @ Y_UP_TO_Z_UP_MATRIX`.
Y_UP_TO_Z_UP_MATRIX = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


def as_float(verts: np.ndarray) -> np.ndarray:
    verts = np.asarray(verts)
    return verts if np.issubdtype(verts.dtype, np.floating) else verts.astype(np.float64)


def face_cross(verts: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(v1 - v0) x (v2 - v0) per face: (..., F, 3), norm = twice the face area."""
    faces = np.asarray(faces, dtype=np.int64)
    # np.take along the vertex axis: several times faster than fancy indexing with an ellipsis
    v0, v1, v2 = (np.take(verts, faces[:, k], axis=-2) for k in range(3))
    return np.cross(v1 - v0, v2 - v0)


def normalise(vectors: np.ndarray) -> np.ndarray:
    """Unit vectors along the last axis; vectors with norm below _EPS become zero vectors."""
    norm = np.linalg.norm(vectors, axis=-1, keepdims=True)
    return np.where(norm > _EPS, vectors / np.where(norm > _EPS, norm, 1.0), 0.0).astype(vectors.dtype)


def _dot3_soa(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Dot product of (3, ...) arrays (coordinates first)."""
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]


def _incidence(faces: np.ndarray, n_vertices: int) -> sp.csr_matrix:
    """Sparse (V, 3F) matrix summing per-corner values (corner order: all corner 0, then 1, then 2) into vertices."""
    faces = np.asarray(faces, dtype=np.int64)
    F = faces.shape[0]
    rows = faces.T.reshape(-1)  # corner k of face f sits at column k*F + f
    cols = np.arange(3 * F)
    return sp.csr_matrix((np.ones(3 * F), (rows, cols)), shape=(n_vertices, 3 * F))


def scatter_corners(corner_values: np.ndarray, faces: np.ndarray, n_vertices: int) -> np.ndarray:
    """Sum per-corner values into vertices.

    corner_values: (..., F, 3, C) (value of corner k of face f) -> (..., V, C) float64.
    """
    lead = corner_values.shape[:-3]
    F, C = corner_values.shape[-3], corner_values.shape[-1]
    B = int(np.prod(lead, dtype=np.int64))
    # (B, F, 3, C) -> (3, F, B, C) -> (3F, B*C), matching the incidence's corner order.
    x = np.asarray(corner_values, dtype=np.float64).reshape(B, F, 3, C).transpose(2, 1, 0, 3).reshape(3 * F, B * C)
    out = _incidence(faces, n_vertices) @ x  # (V, B*C)
    return out.reshape(n_vertices, B, C).transpose(1, 0, 2).reshape(*lead, n_vertices, C)


def vertex_areas(verts: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Barycentric vertex areas, a third of each incident face's area: verts (..., V, 3) metres, faces (F, 3) ->
    (..., V) float64 m^2."""
    verts = np.asarray(verts, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    V, lead = verts.shape[-2], verts.shape[:-2]
    area = 0.5 * np.linalg.norm(face_cross(verts, faces), axis=-1).reshape(-1, len(faces))  # (B, F)
    at = (faces.reshape(1, -1) + V * np.arange(len(area))[:, None]).reshape(-1)  # each frame's own V slots
    return np.bincount(at, weights=np.repeat(area.reshape(-1) / 3.0, 3), minlength=len(area) * V).reshape(*lead, V)


def face_normals(verts: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Unit face normals, right-handed in the face's vertex order.

    verts: (..., V, 3) float, metres. faces: (F, 3) int.
    Returns (..., F, 3), the dtype of `verts` (float64 for integer input);
    zero-area faces get zero vectors.
    """
    verts = as_float(verts)
    return normalise(face_cross(verts, faces))


def vertex_normals(verts: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Unit vertex normals: the area-weighted sum of incident face normals, normalised.

    verts: (..., V, 3) float, metres. faces: (F, 3) int.
    Returns (..., V, 3), the dtype of `verts` (float64 for integer input);
    vertices with no incident face of non-zero area (or whose normals cancel)
    get zero vectors.
    """
    verts = as_float(verts)
    cross = face_cross(verts, faces)  # norm = 2 * area: weighting by area is summing the raw cross products
    corners = np.broadcast_to(cross[..., :, None, :], cross.shape[:-1] + (3, 3))
    summed = scatter_corners(corners, faces, verts.shape[-2])
    return normalise(summed).astype(verts.dtype)


def closest_point_on_triangles(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray):
    """Closest point of each triangle to each point (Ericson, Real-Time Collision Detection 5.1.5).

    p, a, b, c: (..., 3) broadcastable float64. Returns (closest (..., 3), barycentric (..., 3)).
    """
    closest, bary = _closest_on_triangles_soa(*(np.moveaxis(np.asarray(x, dtype=np.float64), -1, 0)
                                                for x in (p, a, b, c)))
    return np.moveaxis(closest, 0, -1), np.moveaxis(bary, 0, -1)


def _closest_on_triangles_soa(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray,
                              flat_tol: np.ndarray | None = None):
    """`closest_point_on_triangles` with the coordinate axis first: p, a, b, c (3, ...) broadcastable ->
    (closest (3, ...), barycentric (3, ...)). Coordinates first, every operation runs over long rows (with
    them last, numpy steps through rows of three: several times slower).

    flat_tol: (...) the triangles' `1e-9 * |ab|^2 * |ac|^2` where the caller has it per face (`TriangleMesh`
    gathers it instead of recomputing it per point); the same numbers either way.
    Every value comes from the same float operations in the same order as Ericson's formulas written out one
    array at a time (the same bits); results go into reused arrays to spare the allocation and memory traffic
    of ~100 temporaries (816k pairs in cache-sized chunks on the 2-core Zen 4: 66 ms, 74 written out).
    """
    p, a, b, c = np.broadcast_arrays(p, a, b, c)  # views: every array below has the full shape
    if p.ndim == 1:  # one point and one triangle: as a row of one (the in-place writes need arrays)
        closest, bary = _closest_on_triangles_soa(p[:, None], a[:, None], b[:, None], c[:, None],
                                                  None if flat_tol is None else np.reshape(flat_tol, 1))
        return closest[:, 0], bary[:, 0]
    ab, ac = b - a, c - a
    t = np.empty(ab.shape[1:])  # scratch for products and quotients
    d = []  # d1..d6: ab.ap, ac.ap, ab.bp, ac.bp, ab.cp, ac.cp
    for corner in (a, b, c):
        off = p - corner
        d += [_dot3_into(ab, off, t), _dot3_into(ac, off, t)]
    del off
    d1, d2, d3, d4, d5, d6 = d
    va = d3 * d6
    va -= np.multiply(d5, d4, out=t)
    vb = d5 * d2
    vb -= np.multiply(d1, d6, out=t)
    vc = d1 * d4
    vc -= np.multiply(d3, d2, out=t)
    area2 = va + vb
    area2 += vc  # |ab x ac|^2 up to rounding

    # Each region's barycentric coordinates, written from the lowest priority (interior) to the highest
    # (vertex a): where several region tests hold (degenerate triangles), Ericson's first test wins.
    with np.errstate(divide="ignore", invalid="ignore"):
        denom = np.where(np.abs(area2) < _EPS, _EPS, area2)
        w0, w1, w2 = va / denom, vb / denom, vc / denom  # interior
        del denom
        e43, e56 = d4 - d3, d5 - d6
        mask = (va <= 0) & (e43 >= 0) & (e56 >= 0)  # edge bc
        _set_region(mask, np.divide(e43, np.add(e43, e56, out=t), out=t), w0, w2, w1)
        del e43, e56
        mask = (vb <= 0) & (d2 >= 0) & (d6 <= 0)  # edge ac
        _set_region(mask, np.divide(d2, np.subtract(d2, d6, out=t), out=t), w1, w2, w0)
        mask = (vc <= 0) & (d1 >= 0) & (d3 <= 0)  # edge ab
        _set_region(mask, np.divide(d1, np.subtract(d1, d3, out=t), out=t), w2, w1, w0)
        for mask, one in (((d6 >= 0) & (d5 <= d6), w2), ((d3 >= 0) & (d4 <= d3), w1),  # vertex c, vertex b
                          ((d1 <= 0) & (d2 <= 0), w0)):  # vertex a
            for w in (w0, w1, w2):
                np.copyto(w, 1.0 if w is one else 0.0, where=mask)
    del d, d1, d2, d3, d4, d5, d6, va, vb, vc, mask
    bary = np.stack((w0, w1, w2))
    del w0, w1, w2
    if not np.isfinite(bary).all():  # rare: an edge region of a zero-length edge (0 / 0)
        bary = np.nan_to_num(bary, nan=1.0 / 3.0)
    # area2 = |ab x ac|^2: a triangle with (nearly) no area has no interior, and rounding can leave a point of
    # it in none of the edge regions, where the interior formula divides by ~0. Its closest point is then
    # the nearest of its three edges.
    if flat_tol is None:
        flat_tol = 1e-9 * _dot3_soa(ab, ab) * _dot3_soa(ac, ac)
    flat = np.broadcast_to(np.abs(area2, out=area2) <= flat_tol, bary.shape[1:])
    if flat.any():
        bary[:, flat] = _closest_on_edges(*(np.broadcast_to(x, bary.shape)[:, flat] for x in (p, a, b, c)))
    closest = bary[0] * a
    scratch = bary[1] * b
    closest += scratch
    closest += np.multiply(bary[2], c, out=scratch)
    return closest, bary


def _dot3_into(u: np.ndarray, v: np.ndarray, scratch: np.ndarray) -> np.ndarray:
    """`_dot3_soa(u, v)` (the same sums in the same order) in a new array, with `scratch` (same shape) for the
    products."""
    out = u[0] * v[0]
    out += np.multiply(u[1], v[1], out=scratch)
    out += np.multiply(u[2], v[2], out=scratch)
    return out


def _set_region(mask: np.ndarray, w: np.ndarray, w_zero: np.ndarray, w_w: np.ndarray, w_rest: np.ndarray) -> None:
    """Where `mask`, the coordinates of a point on an edge: `w` into `w_w`, `1 - w` into `w_rest` (`w` is
    overwritten with it), 0 into `w_zero`."""
    np.copyto(w_zero, 0.0, where=mask)
    np.copyto(w_w, w, where=mask)
    np.copyto(w_rest, np.subtract(1.0, w, out=w), where=mask)


def _closest_on_edges(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Barycentric coordinates (3, N) of the nearest point to p on the three edges of triangles abc ((3, N) each)."""
    best_d, best = np.full(p.shape[1], np.inf), np.zeros((3,) + p.shape[1:])
    for i, j in ((0, 1), (0, 2), (1, 2)):
        u, v = (a, b, c)[i], (a, b, c)[j]
        e = v - u
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.nan_to_num(np.clip(_dot3_soa(p - u, e) / _dot3_soa(e, e), 0.0, 1.0))
        off = u + t * e - p
        d = _dot3_soa(off, off)
        take = d < best_d
        best_d = np.where(take, d, best_d)
        w = np.zeros_like(best)
        w[i], w[j] = 1.0 - t, t
        best = np.where(take, w, best)
    return best


def _subtriangle_centroids(n: int) -> np.ndarray:
    """Barycentric centroids of the n*n sub-triangles of a triangle split n times per edge: (n*n, 3)."""
    out = []
    for i in range(n):
        for j in range(n - i):
            out.append(((i + 1 / 3) / n, (j + 1 / 3) / n))  # upward sub-triangle
            if i + j <= n - 2:
                out.append(((i + 2 / 3) / n, (j + 2 / 3) / n))  # downward sub-triangle
    uv = np.array(out)
    return np.column_stack([1 - uv.sum(axis=1), uv])


@dataclass(frozen=True)
class ClosestPoints:
    """Result of `closest_points_on_mesh` for N query points.

    distance: (N,) metres. face_index: (N,) int64. barycentric: (N, 3). closest: (N, 3).
    """

    distance: np.ndarray
    face_index: np.ndarray
    barycentric: np.ndarray
    closest: np.ndarray


def outward_faces(verts: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Faces of a closed mesh wound so that its signed volume is positive (normals point outward).

    verts: (V, 3); faces: (F, 3). Returns (F, 3) int64, reversed when the volume was negative.
    """
    faces = np.asarray(faces, dtype=np.int64)
    tri = np.asarray(verts, dtype=np.float64)[faces]
    volume = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6.0
    return faces[:, ::-1].copy() if volume < 0 else faces


_EDGE_INDEX_CACHE: dict = {}


def _face_edge_index(faces: np.ndarray) -> tuple[int, np.ndarray]:
    """Unique-edge index of each face's three edges (edge k is opposite corner k): (E, (3F,) int64).

    Depends on topology only, so it is cached: a body posed over many frames computes it once.
    """
    key = hash(faces.tobytes())
    if key not in _EDGE_INDEX_CACHE:
        edges = np.stack([faces[:, [1, 2]], faces[:, [2, 0]], faces[:, [0, 1]]], axis=1)  # (F, 3, 2)
        uniq, inv = np.unique(np.sort(edges, axis=-1).reshape(-1, 2), axis=0, return_inverse=True)
        if len(_EDGE_INDEX_CACHE) > 16:
            _EDGE_INDEX_CACHE.clear()
        _EDGE_INDEX_CACHE[key] = (len(uniq), inv.reshape(-1))
    return _EDGE_INDEX_CACHE[key]


def _bincount_rows(index: np.ndarray, values: np.ndarray, n: int) -> np.ndarray:
    """out[i] = sum of values[j] over j with index[j] == i: (n, C) from index (N,) and values (N, C).

    What `np.add.at` does, column by column with `np.bincount` (many times faster).
    """
    return np.stack([np.bincount(index, values[:, c], minlength=n) for c in range(values.shape[1])], axis=1)


def _kd_tree(points: np.ndarray) -> cKDTree:
    """A KD-tree for one mesh pose's queries: unbalanced and without shrunk node boxes, it builds faster and,
    on a posed body's face centroids, also answers 16-nearest queries faster (15 ms against 21 for a dress)."""
    return cKDTree(points, balanced_tree=False, compact_nodes=False)


#: Candidate (point, face) pairs `TriangleMesh.closest` works through at a time: the ~20 float64 arrays of the
#: closest-point formulas then stay in the core's cache (the 2-core AMD EPYC Zen 4: 1 MB L2); 600k pairs at a
#: time streamed them through memory, 1.2x slower.
CLOSEST_CHUNK_PAIRS = 16_384
#: Threads `TriangleMesh.closest` runs its chunks on, each chunk's KD-tree query and closest-point formulas on
#: one (both release the GIL): the formulas, 40 % of the time, ran on one core when only the query was threaded.
CLOSEST_THREADS = min(8, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1)
#: A face whose radius (its farthest corner from its centroid) exceeds this many times the median is found by
#: `TriangleMesh.any_within` in a tree of the large faces' centroids, not in the tree of all of them.
LARGE_FACE_RADII = 4.0
#: (point, face) pairs `TriangleMesh.any_within` works through at a time, about (taken as 64 faces a point).
WITHIN_CHUNK_PAIRS = 200_000


def _z_order(points: np.ndarray) -> np.ndarray:
    """A permutation of points (N, 3) along a Z-order (Morton) curve on a 1024^3 grid over their bounding box.

    Queried in this order, consecutive points share KD-tree nodes and candidate faces, which the caches then
    hold (the 16-nearest queries of a 51k-vertex garment: 1.15x); each point's answer is its own either way.
    """
    with np.errstate(invalid="ignore", over="ignore"):
        low = points.min(axis=0)
        scale = 1023.0 / max(float(np.ptp(points, axis=0).max()), 1e-300)
        grid = np.nan_to_num((points - low) * scale).clip(0, 1023).astype(np.int64)
    code = np.zeros(len(points), dtype=np.int64)
    for axis in range(3):  # spread the 10 bits of each coordinate to every third bit
        x = grid[:, axis]
        x = (x | (x << 16)) & 0x030000FF
        x = (x | (x << 8)) & 0x0300F00F
        x = (x | (x << 4)) & 0x030C30C3
        x = (x | (x << 2)) & 0x09249249
        code |= x << axis
    return np.argsort(code, kind="stable")


def in_threads(fn, starts) -> None:
    """fn(s) for every s of `starts` on up to CLOSEST_THREADS threads (inline for one); fn writes its own slice."""
    starts = list(starts)
    workers = min(CLOSEST_THREADS, len(starts))
    if workers <= 1:
        for s in starts:
            fn(s)
        return
    with ThreadPoolExecutor(workers) as pool:
        for _ in pool.map(fn, starts):
            pass


class TriangleMesh:
    """A triangle mesh prepared for repeated closest-point and signed-distance queries.

    verts: (V, 3) float, metres; faces: (F, 3) int. Build once per mesh pose and
    query many points: the KD-tree and pseudo-normals are computed here.
    """

    def __init__(self, verts: np.ndarray, faces: np.ndarray):
        self.verts = np.asarray(verts, dtype=np.float64)
        self.faces = np.asarray(faces, dtype=np.int64)
        # Coordinates first (see _closest_on_triangles_soa): vertices (3, V), corner k of every face (3, F).
        self._verts_soa = np.ascontiguousarray(self.verts.T)
        self._corners_soa = [self._verts_soa.take(self.faces[:, k], axis=1) for k in range(3)]
        c = self._corners_soa
        self._centroids_soa = (c[0] + c[1] + c[2]) / 3.0
        self.centroids = self._centroids_soa.T  # (F, 3), what verts[faces].mean(axis=1) gives
        self._trees: dict = {}
        self._pseudo = None
        self._flat = None
        self._radii = None

    def _tree(self, exact: bool):
        """(KD-tree, sample -> face map, cover radius), built on first use.

        Approximate queries index face centroids. Exact queries index points that
        cover every face within a fixed radius (a large face gets the centroids of
        an n x n subdivision), so the exclusion bound in `closest` is tight on
        meshes whose triangle sizes vary a lot.
        """
        if exact not in self._trees:
            radius = self._face_radii()
            if not exact:
                self._trees[exact] = (_kd_tree(self.centroids), np.arange(len(self.faces)), float(radius.max(initial=0)))
            else:
                cover = max(float(np.median(radius)) if len(radius) else 0.0, 1e-9)
                n_sub = np.clip(np.ceil(radius / cover), 1, 16).astype(np.int64)
                samples, owner = [self.centroids[n_sub == 1]], [np.flatnonzero(n_sub == 1)]
                for n in np.unique(n_sub[n_sub > 1]):
                    fi = np.flatnonzero(n_sub == n)
                    w = _subtriangle_centroids(int(n))  # (S, 3) barycentric
                    samples.append(np.einsum("sk,fkc->fsc", w, self.verts[self.faces[fi]]).reshape(-1, 3))
                    owner.append(np.repeat(fi, len(w)))
                cover_radius = float((radius / n_sub).max()) if len(radius) else 0.0
                self._trees[exact] = (_kd_tree(np.concatenate(samples)), np.concatenate(owner), cover_radius)
        return self._trees[exact]

    def closest(self, points: np.ndarray, k: int = 16, exact: bool = True) -> ClosestPoints:
        """Closest points on the mesh for points (N, 3).

        Candidates are the faces of the k nearest sample points; with `exact`,
        points for which the bound cannot exclude every other face are
        re-queried with 4x more samples (vectorised, up to 1024), and only the
        rare rest one by one. Without it, one pass: the best of the k candidates
        (what per-frame penetration statistics use; a miss needs a face nearer
        than the k nearest samples of the surface, which a smooth body rarely has).
        """
        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        tree, sample_face, cover_radius = self._tree(exact)
        N, S = len(points), tree.n
        dist = np.full(N, np.inf)
        face = np.zeros(N, dtype=np.int64)
        bary = np.zeros((N, 3))
        cp = np.zeros((N, 3))
        k = max(1, min(k, S))
        flat_tol = self._flat_tol()
        todo = _z_order(points) if N > CLOSEST_CHUNK_PAIRS // k else np.arange(N)  # neighbours in one chunk
        while len(todo):
            kth = np.empty(len(todo))
            step = max(1, CLOSEST_CHUNK_PAIRS // k)

            def candidate_pass(s: int, todo=todo, k=k, step=step, kth=kth) -> None:
                idx = todo[s:s + step]
                cd, si = tree.query(points[idx], k=k, workers=1)
                ci = sample_face[si.reshape(len(idx), k)]
                p = points[idx].T[:, :, None]  # (3, n, 1): coordinates first, see _closest_on_triangles_soa
                c, b = _closest_on_triangles_soa(p, *(x.take(ci, axis=1) for x in self._corners_soa),
                                                 flat_tol=flat_tol.take(ci))
                off = c - p
                d = np.sqrt(_dot3_soa(off, off))  # (n, k)
                best = np.argmin(d, axis=1)
                rows = np.arange(len(idx))
                better = d[rows, best] < dist[idx]
                upd = idx[better]
                dist[upd], face[upd] = d[rows, best][better], ci[rows, best][better]
                bary[upd], cp[upd] = b[:, rows, best].T[better], c[:, rows, best].T[better]
                kth[s:s + step] = cd.reshape(len(idx), k)[:, -1]

            in_threads(candidate_pass, range(0, len(todo), step))
            if k >= S or not exact:
                break
            # Every point of a face lies within cover_radius of one of its samples; a face none of whose
            # samples is among the k nearest is therefore at least kth - cover_radius away.
            todo = todo[kth - cover_radius < dist[todo]]
            if k >= 1024:
                break
            k = min(4 * k, S)
        for i in todo if (k < S and exact) else ():
            near = tree.query_ball_point(points[i], dist[i] + cover_radius)
            cand = np.unique(sample_face[np.asarray(near, dtype=np.int64)])
            t = self.verts[self.faces[cand]]
            c2, b2 = closest_point_on_triangles(points[i][None], t[:, 0], t[:, 1], t[:, 2])
            d2 = np.linalg.norm(c2 - points[i], axis=-1)
            j = int(np.argmin(d2))
            if d2[j] < dist[i]:
                dist[i], face[i], bary[i], cp[i] = d2[j], cand[j], b2[j], c2[j]
        return ClosestPoints(dist, face, bary, cp)

    def any_within(self, points: np.ndarray, radius: float) -> np.ndarray:
        """(N,) bool: whether some face of the mesh comes within `radius` (metres, >= 0) of each point (N, 3), exactly.

        Candidates are the faces whose centroid lies within `radius` plus their own radius of the point: the
        ordinary faces found in the tree of every centroid, the few large ones (over `LARGE_FACE_RADII` times the
        median radius: a body's 3.7 cm against 0.48) in a tree of their own, so a large face neither goes unseen
        (the faces of the 16 nearest centroids missed the top of a box of two faces beside fine sides: 1 mm read as
        3-8 cm) nor widens every point's search. Chunked: memory stays flat however many points are inside.
        """
        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        out = np.zeros(len(points), dtype=bool)
        for pi, _, _, _ in self.faces_within(points, np.full(len(points), float(radius))):
            out[np.unique(pi)] = True
        return out

    def faces_within(self, points: np.ndarray, radius: np.ndarray):
        """Every face within its point's radius, exactly: yields, chunk after chunk, (point index (P,), face index
        (P,), barycentric coordinates of the face's closest point (P, 3), its distance (P,)) for points (N, 3) and
        radii (N,) metres (>= 0; the search of `any_within`). A point's pairs all come in one chunk.

        The ordinary faces are those of a point's k nearest centroids, k growing fourfold (from 16) until the k-th
        lies beyond the radius plus the largest ordinary face's (arrays throughout: a ball search's lists of a
        125k-vertex garment's 11M candidates took 4 of its 9 s); the large faces come from their own tree."""
        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        radius = np.asarray(radius, dtype=np.float64).reshape(-1)
        if not len(points) or not len(self.faces):
            return
        c = self._corners_soa
        rad = self._face_radii()
        cut = LARGE_FACE_RADII * float(np.median(rad))
        large = np.flatnonzero(rad > cut)
        large_tree = _kd_tree(self.centroids[large]) if len(large) else None
        ordinary = rad <= cut
        tree, F = self._tree(False)[0], len(self.faces)
        todo, k = _z_order(points) if len(points) > 1 else np.arange(len(points)), min(16, F)
        while len(todo):
            step = max(1, WITHIN_CHUNK_PAIRS // k)
            later = []
            for s in range(0, len(todo), step):
                idx = todo[s:s + step]
                d, fi = tree.query(points[idx], k=k, workers=1)
                d, fi = d.reshape(len(idx), k), fi.reshape(len(idx), k)
                found = (d[:, -1] > radius[idx] + cut) | (k >= F)  # every ordinary face that may be within
                later.append(idx[~found])
                idx, d, fi = idx[found], d[found], fi[found]
                keep = ordinary[fi] & (d <= radius[idx, None] + rad[fi] + 1e-12)
                pi, fi = np.nonzero(keep)[0], fi[keep]
                if large_tree is not None:
                    near = large_tree.query_ball_point(points[idx], radius[idx] + float(rad[large].max()))
                    pi = np.concatenate([pi, np.repeat(np.arange(len(idx)), [len(n) for n in near])])
                    fi = np.concatenate([fi, large[np.fromiter((f for n in near for f in n), dtype=np.int64,
                                                                count=len(pi) - len(fi))]])
                pi = idx[pi]
                cp, bary = _closest_on_triangles_soa(points[pi].T, *(x[:, fi] for x in c),
                                                     flat_tol=self._flat_tol()[fi])
                gap = cp - points[pi].T
                dist = np.sqrt(_dot3_soa(gap, gap))
                hit = dist <= radius[pi]
                yield pi[hit], fi[hit], bary[:, hit].T, dist[hit]
            todo, k = np.concatenate(later), min(4 * k, F)

    def _face_radii(self) -> np.ndarray:
        """(F,) each face's farthest corner from its centroid, metres (once per mesh)."""
        if self._radii is None:
            self._radii = np.max([np.sqrt(_dot3_soa(x - self._centroids_soa, x - self._centroids_soa))
                                  for x in self._corners_soa], axis=0)
        return self._radii

    def _flat_tol(self) -> np.ndarray:
        """(F,) each face's `1e-9 * |ab|^2 * |ac|^2`, the threshold below which `_closest_on_triangles_soa` takes
        it for flat: per face once instead of per candidate pair."""
        if self._flat is None:
            c = self._corners_soa
            ab, ac = c[1] - c[0], c[2] - c[0]
            self._flat = 1e-9 * _dot3_soa(ab, ab) * _dot3_soa(ac, ac)
        return self._flat

    def _pseudo_normals(self):
        """(angle-weighted vertex normals (V, 3), edge normals (E, 3: sum of the adjacent faces' normals), each
        face's edge opposite each corner (F, 3) into them, face normals (F, 3))."""
        if self._pseudo is None:
            f = self.faces
            # Coordinates first (see _closest_on_triangles_soa): corners (3, F) each, edge k from corner k to k + 1.
            c = self._corners_soa
            e = [c[1] - c[0], c[2] - c[1], c[0] - c[2]]
            fn = face_normals(self.verts, f)  # (F, 3)
            # The angle at corner k, between its outgoing edge k and the reversed incoming edge k - 1.
            length = [np.sqrt(_dot3_soa(x, x)) for x in e]
            angle = np.stack([np.arccos(np.clip(-_dot3_soa(e[k], e[k - 1]) / np.maximum(length[k] * length[k - 1], _EPS),
                                                -1, 1)) for k in range(3)])  # (3 corners, F)
            corner_vertex = f.T.reshape(-1)  # corner-major, like angle.reshape(-1)
            vn = _bincount_rows(corner_vertex, (fn.T[:, None] * angle).reshape(3, -1).T, len(self.verts))
            n_edges, inv = _face_edge_index(f)  # face-major: face f's edges at 3f, 3f + 1, 3f + 2
            en = _bincount_rows(inv, np.repeat(fn, 3, axis=0), n_edges)
            self._pseudo = (vn, en, inv.reshape(len(f), 3), fn)
        return self._pseudo

    def signed_distance(self, points: np.ndarray, exact: bool = True) -> np.ndarray:
        """Signed distance (N,) in metres: negative inside a closed, outward-oriented mesh.

        exact=False: one candidate pass (see `closest`), for statistics over many frames.
        """
        return self.signed_closest(points, exact)[1]

    def signed_closest(self, points: np.ndarray, exact: bool = True) -> tuple[ClosestPoints, np.ndarray]:
        """The closest points (see `closest`) and the signed distances (N,) they give, negative inside."""
        res = self.closest(points, exact=exact)
        return res, res.distance * self._sign(np.asarray(points, dtype=np.float64).reshape(-1, 3), res)

    def _sign(self, points: np.ndarray, res: ClosestPoints) -> np.ndarray:
        vn, en, face_edge, fn = self._pseudo_normals()
        b = res.barycentric
        tol = 1e-9
        zero = b < tol  # (N, 3) which barycentric coordinates vanish
        n_zero = zero.sum(axis=1)
        normal = fn[res.face_index].copy()
        # On an edge: one coordinate zero, the edge opposite that corner.
        on_edge = n_zero == 1
        corner = np.argmax(zero, axis=1)
        normal[on_edge] = en[face_edge[res.face_index[on_edge], corner[on_edge]]]
        # At a vertex: two coordinates zero, the corner with the remaining weight.
        on_vertex = n_zero >= 2
        vid = self.faces[res.face_index, np.argmax(b, axis=1)]
        normal[on_vertex] = vn[vid[on_vertex]]
        s = np.einsum("ij,ij->i", points - res.closest, normal)
        return np.where(s < 0, -1.0, 1.0)


def outward_offsets(points: np.ndarray, verts: np.ndarray, faces: np.ndarray,
                    exact: bool = False, mesh: TriangleMesh | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where each point sits against a closed, outward-oriented mesh.

    points: (N, 3); verts: (V, 3); faces: (F, 3) (or `mesh`, already built of them). Returns (signed distance (N,)
    negative inside, closest surface point (N, 3), outward unit direction at it (N, 3)): from the surface to the
    point for a point outside, from the point to the surface for one inside, the face's normal for a point on the
    surface.
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    mesh = TriangleMesh(verts, faces) if mesh is None else mesh
    res, signed = mesh.signed_closest(p, exact=exact)
    away = p - res.closest
    length = np.linalg.norm(away, axis=1, keepdims=True)
    direction = np.where(length > 1e-12, away / np.maximum(length, 1e-12), 0.0)
    direction *= np.where(signed < 0, -1.0, 1.0)[:, None]
    flat = length[:, 0] <= 1e-12
    if flat.any():
        direction[flat] = face_normals(mesh.verts, mesh.faces[res.face_index[flat]])
    return signed, res.closest, direction


def closest_points_on_mesh(points: np.ndarray, verts: np.ndarray, faces: np.ndarray) -> ClosestPoints:
    """Exact closest points on a triangle mesh. points: (N, 3); verts: (V, 3); faces: (F, 3)."""
    return TriangleMesh(verts, faces).closest(points)


def signed_distance(points: np.ndarray, verts: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Signed distance (N,) metres to a closed mesh, negative inside."""
    return TriangleMesh(verts, faces).signed_distance(points)


def points_inside_mesh(points: np.ndarray, verts: np.ndarray, faces: np.ndarray, depth: float = 0.0) -> np.ndarray:
    """(N,) bool: points more than `depth` metres inside a closed mesh, which may pass through itself (a posed
    body's arm pressed into its torso); wound either way (the faces turned outward first: an inverted body read
    as holding nothing).

    Inside is the winding number along a ray both ways (`core.ray_winding`): the sign of the nearest face's normal
    calls a point between the arm and the torso outside, the nearest face being the arm's, inside the torso. Where
    the two rays disagree (a hole of an open mesh in one's way), and on a mesh with holes wherever the rays say
    outside (both may have left through holes: a point in a sleeve open at both ends), that sign decides, as it
    did alone before. A point inside is more than `depth` inside where no face comes within `depth` of it
    (`TriangleMesh.any_within`, after a one-pass search over the faces of the 16 nearest centroids: a point no
    deeper there is no deeper).
    """
    return InsideTest(verts, faces)(points, depth)


class InsideTest:
    """`points_inside_mesh` of one mesh prepared once (faces turned outward, the rays' grid, the mesh's closest-point
    search, whether it has holes) for many queries in the same pose."""

    def __init__(self, verts: np.ndarray, faces: np.ndarray):
        from core.ray_winding import RayWindings

        faces = outward_faces(verts, faces)
        self.windings = RayWindings(verts, faces)
        self.mesh = TriangleMesh(verts, faces)
        n_edges, face_edge = _face_edge_index(self.mesh.faces)
        self.face_edge = face_edge.reshape(-1, 3)
        self.rim = np.bincount(face_edge, minlength=n_edges) == 1  # (E,) the holes' edges
        self.holes = bool(self.rim.any())
        if self.holes:
            self._holes(np.asarray(verts, dtype=np.float64))

    def _holes(self, verts: np.ndarray) -> None:
        """Each hole's rim (a loop of edges each of one face): which hole each rim edge and vertex is on
        ("hole_of_edge" (E,), "hole_of_vertex" (V,), -1 where none), and the plane of the cap that would close it
        (its rim's mean point, "cap_point" (H, 3), and its vector area facing out of the mesh, "cap_normal" (H, 3):
        the sum over the rim's edges, each as the cap would run it, against its face's direction)."""
        from scipy.sparse.csgraph import connected_components

        faces = self.mesh.faces
        f, c = np.nonzero(self.rim[self.face_edge])  # the rim edges, as corners opposite them
        a, b = faces[f, (c + 1) % 3], faces[f, (c + 2) % 3]  # each in its face's direction
        n = len(verts)
        graph = sp.coo_matrix((np.ones(len(a)), (a, b)), shape=(n, n))
        _, label = connected_components(graph, directed=False)
        holes, hole = np.unique(label[a], return_inverse=True)
        self.hole_of_edge = np.full(len(self.rim), -1)
        self.hole_of_edge[self.face_edge[f, c]] = hole
        self.hole_of_vertex = np.full(n, -1)
        self.hole_of_vertex[a] = hole
        self.hole_of_vertex[b] = hole
        self.cap_normal = np.zeros((len(holes), 3))
        np.add.at(self.cap_normal, hole, 0.5 * np.cross(verts[b], verts[a]))
        count = np.bincount(hole, minlength=len(holes))[:, None]
        self.cap_point = np.zeros((len(holes), 3))
        np.add.at(self.cap_point, hole, verts[a])
        self.cap_point /= np.maximum(count, 1)

    def _beyond_a_hole(self, points: np.ndarray, res: ClosestPoints) -> np.ndarray:
        """(N,) bool: the points whose closest point `res` is on a hole's rim and which lie outside the plane of
        the cap that would close that hole: in front of the opening (past a body's cut wrist), where the nearest
        face's sign says nothing (the rim's faces turn their backs to it)."""
        b, face = res.barycentric, res.face_index
        zero = b < 1e-9
        n_zero = zero.sum(axis=1)
        hole = np.full(len(points), -1)
        on_edge = n_zero == 1
        hole[on_edge] = self.hole_of_edge[self.face_edge[face[on_edge], np.argmax(zero[on_edge], axis=1)]]
        on_vertex = n_zero >= 2
        hole[on_vertex] = self.hole_of_vertex[self.mesh.faces[face[on_vertex], np.argmax(b[on_vertex], axis=1)]]
        rim = hole >= 0
        out = np.zeros(len(points), dtype=bool)
        out[rim] = np.einsum("ij,ij->i", points[rim] - self.cap_point[hole[rim]], self.cap_normal[hole[rim]]) > 0
        return out

    def __call__(self, points: np.ndarray, depth: float = 0.0) -> np.ndarray:
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        plus, minus = self.windings(p)
        inside = (plus > 0) & (minus > 0)
        ask = ~inside if self.holes else (plus > 0) != (minus > 0)  # the nearest face's sign decides these
        todo = np.flatnonzero(inside | ask)
        if not len(todo):
            return np.zeros(len(p), dtype=bool)
        mesh = self.mesh
        res = mesh.closest(p[todo], exact=False)  # one pass: never nearer than the surface
        signed_in = ask[todo] & (res.distance * mesh._sign(p[todo], res) < 0)
        if self.holes:
            signed_in &= ~self._beyond_a_hole(p[todo], res)
        inside[todo] |= signed_in
        deep = inside[todo] & (res.distance > depth)
        todo = todo[deep]
        out = np.zeros(len(p), dtype=bool)
        out[todo] = ~mesh.any_within(p[todo], depth) if depth > 0 else True
        return out


def penetration_per_frame(points: np.ndarray, body_points: np.ndarray, body_faces: np.ndarray,
                          depth: float = 0.0) -> np.ndarray:
    """Share of points inside the body, per frame.

    points: (T, N, 3) garment vertices; body_points: (T, Vb, 3); body_faces: (Fb, 3).
    depth: metres a point must be inside to count (e.g. 0.002 for 2 mm).
    Returns (T,) fractions in [0, 1].
    """
    return np.array([points_inside_mesh(p, b, body_faces, depth).mean() for p, b in zip(points, body_points)])


def segment_triangle_hits(p0: np.ndarray, p1: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray,
                          eps: float = 1e-9) -> np.ndarray:
    """Whether each segment p0-p1 crosses the interior of triangle abc (Moller-Trumbore), row by row.

    All inputs (N, 3) float64, metres. A segment lying in the triangle's plane does not count.
    Returns (N,) bool.
    """
    d = p1 - p0
    e1, e2 = b - a, c - a
    h = np.cross(d, e2)
    det = np.einsum("ij,ij->i", e1, h)
    ok = np.abs(det) > eps * np.linalg.norm(e1, axis=1) * np.linalg.norm(e2, axis=1) * np.linalg.norm(d, axis=1)
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    s = p0 - a
    u = inv * np.einsum("ij,ij->i", s, h)
    q = np.cross(s, e1)
    v = inv * np.einsum("ij,ij->i", d, q)
    t = inv * np.einsum("ij,ij->i", e2, q)
    return ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t >= 0) & (t <= 1)


def self_intersecting_faces(verts: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Faces of a triangle mesh that intersect another face of the same mesh (cloth passing through itself).

    verts: (V, 3) metres; faces: (F, 3) int. An edge crossing a face that shares none of its
    vertices is an intersection; both that face and the faces on the edge are marked. Candidate
    pairs come from a k-d tree of face centroids (edge midpoint within half the edge plus the
    face's circumradius bound), so the cost grows with the number of close pairs, not F^2.
    Returns (F,) bool.
    """
    from scipy.spatial import cKDTree

    from core.garment import mesh_edges

    v = np.asarray(verts, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    marked = np.zeros(len(faces), dtype=bool)
    if len(faces) < 2:
        return marked
    edges = mesh_edges(faces)
    tri = v[faces]
    centroid = tri.mean(axis=1)
    radius = np.linalg.norm(tri - centroid[:, None], axis=-1).max(axis=1)
    mid = 0.5 * (v[edges[:, 0]] + v[edges[:, 1]])
    half = 0.5 * np.linalg.norm(v[edges[:, 0]] - v[edges[:, 1]], axis=1)
    pairs = cKDTree(mid).query_ball_tree(cKDTree(centroid), r=float(half.max() + radius.max()))
    ei = np.repeat(np.arange(len(edges)), [len(p) for p in pairs])
    if len(ei) == 0:
        return marked
    fi = np.fromiter((f for p in pairs for f in p), dtype=np.int64, count=len(ei))
    near = np.linalg.norm(mid[ei] - centroid[fi], axis=1) <= half[ei] + radius[fi] + 1e-12
    shares = (faces[fi] == edges[ei, :1]).any(axis=1) | (faces[fi] == edges[ei, 1:]).any(axis=1)
    ei, fi = ei[near & ~shares], fi[near & ~shares]
    hit = segment_triangle_hits(v[edges[ei, 0]], v[edges[ei, 1]], tri[fi, 0], tri[fi, 1], tri[fi, 2])
    if not hit.any():
        return marked
    marked[fi[hit]] = True
    # The faces on each crossing edge are intersecting too (mesh_edges order = the cached face-edge index's).
    _, face_edge = _face_edge_index(faces)
    marked |= np.isin(face_edge.reshape(-1, 3), np.unique(ei[hit])).any(axis=1)
    return marked
