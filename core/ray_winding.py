"""Winding numbers of points in a triangle mesh by signed ray crossings: inside a body that passes through itself.

A posed body is a closed surface that crosses itself where it touches itself (an arm pressed to the torso, the
thighs of a crouch): there the face nearest a point can lie inside the body, and the sign of its normal (what
`TriangleMesh.signed_closest` reads) calls a point between the arm and the torso outside. The winding number
counts how many times the surface wraps a point: 1 inside a closed outward-oriented mesh, 2 inside two parts
that overlap, 0 outside, whatever the nearest face. It is counted here along the ray from each point in +d and
in -d (d one of the axes): each face the ray passes through counts +1 where the ray leaves through it (its normal
along the ray), -1 where it enters. On a closed mesh both rays give the same number; where they differ the ray
went through a hole of an open mesh, and neither is to be trusted.

Exactness: the test of a point against a face's shadow on the plane across d is written so that a point on the
shadow of an edge or a vertex counts in exactly one of the faces around it (each edge's function computed once
from its lower-numbered vertex and negated for the face that runs it the other way, a tie broken as for the point
moved by an infinitesimal (e, e^2) in the plane), so a ray through an edge or a vertex is neither counted twice
nor lost: where the faces share the edge's vertices by index (a mesh split into faces of their own at a seam
computes the edge twice, and float rounding can count a point exactly on its shadow twice or not at all; the two
rays then disagree, and `core.geometry.points_inside_mesh` asks the nearest face).
"""

from __future__ import annotations

import numpy as np

#: (point, face) pairs tested at a time: about 25 float64 arrays of this length live at once (50 MB).
RAY_CHUNK_PAIRS = 250_000
#: Grid cells of the plane across the ray per face of the mesh (a body's cells then hold a few faces of each sheet
#: the ray passes through).
CELLS_PER_FACE = 0.35
#: Face-cell entries of the grid at most per face before its cells are made coarser (a mesh of a few large faces).
MAX_ENTRIES_PER_FACE = 64
#: Cells of the grid at most: a cell index fits 16 bits, which numpy's stable sort orders by radix (int64: 14x
#: slower, half the time of a body's test).
MAX_CELLS = 65_535


def _ray_axis(verts: np.ndarray, faces: np.ndarray) -> int:
    """The axis along which the faces' shadows are smallest (the fewest faces a ray meets on average)."""
    a, b, c = (verts.T[:, faces[:, k]] for k in range(3))  # coordinates first: (3, F) each
    e, f = b - a, c - a
    shadows = [np.abs(e[(d + 1) % 3] * f[(d + 2) % 3] - e[(d + 2) % 3] * f[(d + 1) % 3]).sum() for d in range(3)]
    return int(np.argmin(shadows))


def _grid(uv: np.ndarray, faces: np.ndarray):
    """The faces' shadows binned in a uniform grid of the (u, v) plane: (origin (2,), cell size, shape (nu, nv),
    CSR offsets (nu * nv + 1,), face of each entry)."""
    a, b, c = (uv[faces[:, k]] for k in range(3))
    lo_f, hi_f = np.minimum(np.minimum(a, b), c), np.maximum(np.maximum(a, b), c)
    lo, hi = uv.min(axis=0), uv.max(axis=0)
    span = np.maximum(hi - lo, 1e-12)
    size = float(np.sqrt(span[0] * span[1] / max(CELLS_PER_FACE * len(faces), 1.0)))
    size = max(size, float(span.max()) / 4096.0)
    while True:
        shape = np.floor(span / size).astype(np.int64) + 1
        if shape[0] * shape[1] > MAX_CELLS:
            size *= 1.1
            continue
        i0 = np.clip(np.floor((lo_f - lo) / size).astype(np.int32), 0, shape - 1)
        i1 = np.clip(np.floor((hi_f - lo) / size).astype(np.int32), 0, shape - 1)
        extent = i1 - i0 + 1  # (F, 2) cells in u and in v
        counts = extent[:, 0] * extent[:, 1]
        if counts.sum() <= MAX_ENTRIES_PER_FACE * len(faces) + 1024:
            break
        size *= 2.0
    face = np.repeat(np.arange(len(faces)), counts)
    k = np.arange(len(face), dtype=np.int32) - np.repeat((np.cumsum(counts) - counts).astype(np.int32), counts)
    row, col = np.divmod(k, np.repeat(extent[:, 0], counts))
    cell = (np.repeat(i0[:, 1], counts) + row) * shape[0] + np.repeat(i0[:, 0], counts) + col
    order = np.argsort(cell.astype(np.uint16), kind="stable")
    offsets = np.zeros(shape[0] * shape[1] + 1, dtype=np.int64)
    np.cumsum(np.bincount(cell, minlength=shape[0] * shape[1]), out=offsets[1:])
    return lo, size, shape, offsets, face[order]


def ray_windings(points: np.ndarray, verts: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Winding numbers of points (N, 3) in the mesh (verts (V, 3), faces (F, 3)) counted along the ray in +d and
    in -d from each point (d the axis of the smallest shadows): (N,) int each, equal on a closed mesh (1 inside an
    outward-oriented one, 0 outside). A point on the surface may count either way."""
    return RayWindings(verts, faces)(points)


class RayWindings:
    """`ray_windings` of one mesh prepared once (its edges' functions and the grid of its faces' shadows) for
    many queries: the points of a garment, then those a post-process moved, in the same posed body."""

    def __init__(self, verts: np.ndarray, faces: np.ndarray):
        verts = np.asarray(verts, dtype=np.float64)
        faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
        self.n_faces = len(faces)
        if not len(faces):
            return
        d = _ray_axis(verts, faces)
        u, v = (d + 1) % 3, (d + 2) % 3  # (u, v, d) right-handed: a face turning counter-clockwise in (u, v) faces +d
        self.axes = u, v, d
        uv, depth = verts[:, [u, v]], verts[:, d]
        # Each face's edge k (corner k -> corner k + 1) kept as the edge from its lower-numbered vertex, with the
        # sign that turns the edge's function into the face's direction; coordinates first, one (F,) array each.
        start, end = faces.T, np.roll(faces, -1, axis=1).T  # (3, F)
        low, high = np.minimum(start, end), np.maximum(start, end)
        self.flip = np.where(start == low, 1.0, -1.0)
        self.low_u, self.low_v = uv[low, 0], uv[low, 1]
        self.edge_u, self.edge_v = uv[high, 0] - self.low_u, uv[high, 1] - self.low_v
        # The sign of the edge's function at a point exactly on it, moved by (e, e^2): -edge_v, else edge_u.
        self.tie = np.where(self.edge_v != 0, -np.sign(self.edge_v), np.sign(self.edge_u)) * self.flip
        self.corner_depth = depth[faces.T]  # (3, F)
        self.grid = _grid(uv, faces)

    def __call__(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        plus = np.zeros(len(points), dtype=np.int64)
        minus = np.zeros(len(points), dtype=np.int64)
        if not len(points) or not self.n_faces:
            return plus, minus
        u, v, d = self.axes
        flip, low_u, low_v, edge_u, edge_v, tie = self.flip, self.low_u, self.low_v, self.edge_u, self.edge_v, self.tie
        corner_depth = self.corner_depth
        lo, size, shape, offsets, cell_face = self.grid
        p_u, p_v, p_d = points[:, u], points[:, v], points[:, d]
        cell_at = np.floor((points[:, [u, v]] - lo) / size).astype(np.int64)
        on_grid = np.all((cell_at >= 0) & (cell_at < shape), axis=1)
        cell = np.where(on_grid, cell_at[:, 1] * shape[0] + cell_at[:, 0], 0)
        n_cand = np.where(on_grid, offsets[cell + 1] - offsets[cell], 0)
        ends = np.cumsum(n_cand)
        first = 0
        while first < len(points):
            last = max(int(np.searchsorted(ends, (ends[first - 1] if first else 0) + RAY_CHUNK_PAIRS, "right")),
                       first + 1)
            counts = n_cand[first:last]
            pi = np.repeat(np.arange(first, last), counts)
            fi = cell_face[np.repeat(offsets[cell[first:last]] - (np.cumsum(counts) - counts), counts)
                           + np.arange(len(pi))]
            w, s = [], None
            for k in range(3):  # each edge's function at the point in the face's direction; on while signs agree
                wk = (edge_u[k, fi] * (p_v[pi] - low_v[k, fi]) - edge_v[k, fi] * (p_u[pi] - low_u[k, fi])) \
                    * flip[k, fi]
                sk = np.where(wk != 0, np.sign(wk), tie[k, fi])
                keep = sk != 0 if s is None else sk == s
                pi, fi, s = pi[keep], fi[keep], sk[keep]
                w = [x[keep] for x in w] + [wk[keep]]
            # Where the ray meets the face: the corners' depths weighted by the edge functions opposite them
            # (corner k is opposite edge k + 1).
            total = w[0] + w[1] + w[2]
            ok = total != 0
            at = (w[1] * corner_depth[0, fi] + w[2] * corner_depth[1, fi] + w[0] * corner_depth[2, fi]) \
                / np.where(ok, total, 1)
            ahead, behind = ok & (at > p_d[pi]), ok & (at < p_d[pi])
            # s = +1: the face faces +d (the ray in +d leaves through it, the ray in -d enters).
            plus += np.bincount(pi[ahead], weights=s[ahead], minlength=len(points)).astype(np.int64)
            minus -= np.bincount(pi[behind], weights=s[behind], minlength=len(points)).astype(np.int64)
            first = last
        return plus, minus
