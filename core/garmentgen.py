"""Example garments generated on a body's rest pose (dress, skirt, t-shirt, trousers, jumpsuit).

Sample garments for a new user (and for tests and benchmarks) are built here
from any SMPL-format `Body` in its rest frame (Y-up, T-pose, facing +Z,
metres): nothing depends on the vertex indices of a particular body, only on
its rest vertices, faces, skinning weights and the first 22 (SMPL) joints.

Two constructions, both deterministic:

- Loose tubes (dress, skirt): a (theta, height) grid around the vertical axis
  through the pelvis. For each height row the radius along each direction is
  the ray distance to the convex hull of the body's cross-section (arms
  excluded) plus ease; from the hips down the radius never decreases and
  grows linearly (flare), so the hem encloses both legs and never wraps
  between them. UVs are (theta / 2 pi, height fraction) with the seam column
  at the back duplicated in UV only.
- Offset surfaces (t-shirt, trousers, jumpsuit): the body surface is cut along
  smooth level sets (neck ellipsoid, sleeve planes across the upper arms, a hem
  plane, a waist plane, ankle planes), the component around the torso is kept,
  pushed out along the body normals by a per-joint ease (blended by the
  skinning weights, capped at half the gap to facing body parts such as the
  inner thighs) and smoothed, then pushed back to a minimum clearance. Sleeves
  and legs are therefore one connected piece with the torso. UVs are a
  cylindrical projection around the body's vertical axis (seam at the back),
  rescaled into [0, 1]; they are a valid texture parameterisation, not a
  flattened sewing pattern.

Every garment is a manifold triangle mesh with boundaries only at its
openings, faces oriented so normals point away from the body, and no vertex
inside the body.
"""

from __future__ import annotations

import logging
from typing import Callable

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import ConvexHull, cKDTree

from core.body import SMPL_JOINT_NAMES, Body
from core.errors import InputError
from core.garment import Garment

log = logging.getLogger(__name__)

#: Vertex-count range every example garment is built to.
MIN_VERTICES = 2000
MAX_VERTICES = 8000
#: Vertex count the offset garments (t-shirt, trousers, jumpsuit) are refined towards.
TARGET_VERTICES = 3000
#: Offset garments: tries of halving the ease where the garment passes through itself, how far (edges) around
#: the crossing faces the ease is reduced, and the smallest ease left (metres).
UNTANGLE_TRIES = 8
UNTANGLE_RINGS = 2
SNUG_EASE_M = 0.003

_J = {name: i for i, name in enumerate(SMPL_JOINT_NAMES[:22])}
_ARM_JOINTS = ("left_shoulder", "right_shoulder", "left_elbow", "right_elbow", "left_wrist", "right_wrist")


# --------------------------------------------------------------------------- rest body


class _RestBody:
    """The rest body prepared for fitting: vertices, outward faces, normals, joints, weights, distance queries."""

    def __init__(self, body: Body):
        if body.n_joints < 22:
            raise InputError(f"body '{body.name}': expected an SMPL-format skeleton with at least 22 joints "
                             f"for example garments, got {body.n_joints}")
        from core.geometry import TriangleMesh, outward_faces, vertex_normals

        verts, joints = body.shaped(None)
        self.verts = verts.astype(np.float64)
        # Orient faces outward whatever the file's convention.
        faces = outward_faces(self.verts, body.faces)
        self.faces = faces
        self.normals = vertex_normals(self.verts, faces).astype(np.float64)
        self.joints = joints.astype(np.float64)
        self.weights = np.asarray(body.weights, dtype=np.float64)
        self.mesh = TriangleMesh(self.verts, faces)
        # Largest distance from a face's centroid to its corners: bounds vertex-to-surface gaps.
        tri = self.verts[faces]
        self.max_radius = float(np.linalg.norm(tri - tri.mean(axis=1, keepdims=True), axis=-1).max())
        self.vertex_tree = cKDTree(self.verts)
        # Joints past the 22 SMPL body joints are hands (SMPL/SMPL+H) or jaw, eyes and hands (SMPL-X).
        arm = [_J[n] for n in _ARM_JOINTS] + list(range(22, body.n_joints))
        self.arm_weight = self.weights[:, arm].sum(axis=1)
        self.n_joints = body.n_joints

    def joint(self, name: str) -> np.ndarray:
        return self.joints[_J[name]]

    def armpit_height(self) -> float:
        """Height (metres) of the armpits: the lowest point of the upper arms near the shoulders."""
        heights = []
        for side in ("left", "right"):
            s, e = self.joint(f"{side}_shoulder"), self.joint(f"{side}_elbow")
            u = (e - s) / np.linalg.norm(e - s)
            rel = self.verts - s
            along = rel @ u
            radial = np.linalg.norm(rel - along[:, None] * u, axis=1)
            near_shoulder = (along > 0) & (along < 0.5 * np.linalg.norm(e - s))
            upper_arm = (self.weights[:, _J[f"{side}_shoulder"]] > 0.5) & near_shoulder
            r_arm = np.median(radial[upper_arm]) if upper_arm.any() else 0.05
            heights.append(s[1] - 1.3 * r_arm)
        return float(min(heights))

    def push_out(self, points: np.ndarray, clearance: np.ndarray | float, iterations: int = 3) -> np.ndarray:
        """Move points that are inside the body or nearer than `clearance` (metres) to `clearance` outside.

        points: (N, 3) float64; clearance: scalar or (N,). Returns the moved points (N, 3).
        """
        points = points.copy()
        clearance = np.broadcast_to(np.asarray(clearance, dtype=np.float64), (len(points),))
        for _ in range(iterations):
            # Exact queries only where needed: points near the surface or on the inner side of
            # their nearest vertex (the exact query is slow for points far from the surface).
            d_vertex, nearest = self.vertex_tree.query(points)
            facing = np.einsum("ij,ij->i", points - self.verts[nearest], self.normals[nearest])
            check = np.flatnonzero((d_vertex < clearance + 2 * self.max_radius) | (facing < 0))
            if len(check) == 0:
                break
            closest, normal = self.closest_with_normals(points[check])
            sd = np.einsum("ij,ij->i", points[check] - closest, normal)
            bad = sd < clearance[check] - 1e-6
            if not bad.any():
                break
            points[check[bad]] = closest[bad] + normal[bad] * clearance[check[bad], None]
        return points

    def closest_with_normals(self, points: np.ndarray, k: int = 24) -> tuple[np.ndarray, np.ndarray]:
        """Closest body points (N, 3) among the faces of the k nearest surface samples, and the
        interpolated unit vertex normal there (N, 3). Exact for points within a few centimetres of
        the surface, which is all the fitting needs (one candidate pass, no exactness proof)."""
        hit = self.mesh.closest(points, k=k, exact=False)
        normal = np.einsum("ik,ikc->ic", hit.barycentric, self.normals[self.faces[hit.face_index]])
        normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-12)
        return hit.closest, normal


# --------------------------------------------------------------------------- tubes (dress, skirt)


def _ray_radius_to_hull(points_xz: np.ndarray, dirs: np.ndarray) -> np.ndarray:
    """Distance from the origin along each unit direction to the boundary of the points' convex hull.

    points_xz: (P, 2) relative to the tube axis; dirs: (K, 2) unit. Returns (K,) metres.
    Falls back to the support function (always enclosing) when the origin is outside the hull.
    """
    support = (points_xz @ dirs.T).max(axis=0)
    try:
        hull = ConvexHull(points_xz)
    except Exception:  # degenerate slab (collinear points)
        return np.maximum(support, 0.0)
    normal, offset = hull.equations[:, :2], hull.equations[:, 2]  # inside: normal . x + offset <= 0
    if np.any(offset > -1e-4):
        return np.maximum(support, 0.0)
    nd = normal @ dirs.T  # (E, K)
    with np.errstate(divide="ignore"):
        t = np.where(nd > 1e-12, -offset[:, None] / nd, np.inf)
    return t.min(axis=0)


def _smooth_periodic_rows(r: np.ndarray, sigma_cols: float, sigma_rows: float) -> np.ndarray:
    """Gaussian smoothing of a (rows, theta) grid: periodic in theta, edge-padded in rows."""
    out = r
    for axis, sigma, mode in ((1, sigma_cols, "wrap"), (0, sigma_rows, "edge")):
        if sigma <= 0:
            continue
        half = int(np.ceil(3 * sigma))
        k = np.exp(-0.5 * (np.arange(-half, half + 1) / sigma) ** 2)
        k /= k.sum()
        pad = [(0, 0), (0, 0)]
        pad[axis] = (half, half)
        padded = np.pad(out, pad, mode=mode)
        out = sum(w * np.take(padded, np.arange(i, i + out.shape[axis]), axis=axis) for i, w in enumerate(k))
    return out


def _tube_grid_faces(n_rows: int, n_theta: int) -> tuple[np.ndarray, np.ndarray]:
    """Faces (geometry, periodic in theta) and face UVs (seam duplicated) of a (rows, theta) grid."""
    i, k = np.meshgrid(np.arange(n_rows - 1), np.arange(n_theta), indexing="ij")
    i, k = i.ravel(), k.ravel()
    k1 = (k + 1) % n_theta
    a, b, c, d = i * n_theta + k, i * n_theta + k1, (i + 1) * n_theta + k, (i + 1) * n_theta + k1
    faces = np.concatenate([np.stack([a, b, c], 1), np.stack([b, d, c], 1)])
    m = n_theta + 1
    ua, ub, uc, ud = i * m + k, i * m + k + 1, (i + 1) * m + k, (i + 1) * m + k + 1
    face_uvs = np.concatenate([np.stack([ua, ub, uc], 1), np.stack([ub, ud, uc], 1)])
    return faces.astype(np.int64), face_uvs.astype(np.int64)


def _tube_garment(rest: _RestBody, name: str, y_top: float, y_bottom: float, ease: float, flare_from_y: float,
                  flare_slope: float, spacing: float = 0.018) -> Garment:
    """A loose tube around the vertical axis through the pelvis, from `y_top` down to `y_bottom` (metres).

    ease: clearance (metres) added to the convex hull of each cross-section; flare_from_y:
    height below which the radius never decreases downward and grows by `flare_slope`
    metres per metre of drop.
    """
    height = y_top - y_bottom
    n_theta = 72
    n_rows = int(np.clip(round(height / spacing) + 1, MIN_VERTICES // n_theta + 1, MAX_VERTICES // n_theta))
    ys = np.linspace(y_top, y_bottom, n_rows)
    theta = 2 * np.pi * np.arange(n_theta) / n_theta
    # theta = 0 at the back (-Z), increasing towards the body's left (+X), front (+Z), right.
    dirs = np.stack([np.sin(theta), -np.cos(theta)], axis=1)
    centre = rest.joint("pelvis")[[0, 2]]

    torso = rest.verts[rest.arm_weight < 0.5]
    half = max(0.012, 0.75 * (ys[0] - ys[-1]) / (n_rows - 1))
    hull_r = np.zeros((n_rows, n_theta))
    empty = np.zeros(n_rows, dtype=bool)
    for i, y in enumerate(ys):
        slab = torso[np.abs(torso[:, 1] - y) < half][:, [0, 2]] - centre
        if len(slab) < 3:
            empty[i] = True
            continue
        hull_r[i] = _ray_radius_to_hull(slab, dirs)
    if empty.all():
        raise InputError(f"body: no body surface between heights {y_bottom:.2f} and {y_top:.2f} m for the {name}")
    for i in np.flatnonzero(empty):  # rows without body (e.g. below the feet): copy the nearest filled row
        j = np.flatnonzero(~empty)[np.argmin(np.abs(np.flatnonzero(~empty) - i))]
        hull_r[i] = hull_r[j]

    need = hull_r + ease
    flare_rows = ys <= flare_from_y
    r = need.copy()
    if flare_rows.any():
        first = int(np.argmax(flare_rows))
        r[first:] = np.maximum.accumulate(r[first:], axis=0)
        r[first:] += flare_slope * (flare_from_y - ys[first:])[:, None]
    # Smooth while keeping the ease: alternate "at least the need" and Gaussian smoothing, then
    # accept at most a third of the ease lost at the end so no kink is reintroduced.
    for _ in range(6):
        r = np.maximum(r, need)
        if flare_rows.any():
            r[first:] = np.maximum.accumulate(r[first:], axis=0)
        r = _smooth_periodic_rows(r, sigma_cols=2.5, sigma_rows=3.0)
    r = np.maximum(r, need - ease / 3)

    verts = np.empty((n_rows, n_theta, 3))
    verts[..., 0] = centre[0] + r * dirs[None, :, 0]
    verts[..., 1] = ys[:, None]
    verts[..., 2] = centre[1] + r * dirs[None, :, 1]
    verts = verts.reshape(-1, 3)
    faces, face_uvs = _tube_grid_faces(n_rows, n_theta)
    u, v = np.meshgrid(np.arange(n_theta + 1) / n_theta, (ys - y_bottom) / height)
    uvs = np.stack([u.ravel(), v.ravel()], axis=1)
    verts = rest.push_out(verts, 0.5 * ease)
    return _finish(rest, name, verts, faces, uvs, face_uvs)


# --------------------------------------------------------------------------- offset surfaces (t-shirt, trousers, ...)


def _clip_by_level_set(verts: np.ndarray, faces: np.ndarray, field: np.ndarray, snap: float):
    """Keep the part of a triangle mesh where `field >= 0`, cutting triangles along the zero level set.

    verts: (V, 3); faces: (F, 3); field: (V,) roughly metres; values within `snap` of zero are
    snapped to zero so that the cut passes through those vertices instead of making slivers.
    Returns (parents (N, 2) int64, t (N,) float64, faces (F', 3) int64): new vertex n is
    (1 - t[n]) * x[parents[n, 0]] + t[n] * x[parents[n, 1]] for any per-vertex attribute x.
    Face winding is preserved.
    """
    f = np.where(np.abs(field) < snap, 0.0, field)
    pos = f >= 0
    inside = pos[faces]
    keep = faces[inside.all(axis=1)]
    cut = faces[inside.any(axis=1) & ~inside.all(axis=1)]
    parents = [np.stack([np.arange(len(verts)), np.arange(len(verts))], axis=1)]
    ts = [np.zeros(len(verts))]
    edge_vertex: dict[tuple[int, int], int] = {}
    n_next = len(verts)
    extra_parents, extra_t, new_faces = [], [], []
    for tri in cut.tolist():
        poly = []
        for k in range(3):
            a, b = tri[k], tri[(k + 1) % 3]
            if pos[a]:
                poly.append(a)
            if pos[a] != pos[b]:
                p, n = (a, b) if pos[a] else (b, a)
                if f[p] == 0.0:
                    poly.append(p)
                    continue
                key = (p, n)
                if key not in edge_vertex:
                    edge_vertex[key] = n_next
                    n_next += 1
                    extra_parents.append((p, n))
                    extra_t.append(f[p] / (f[p] - f[n]))
                poly.append(edge_vertex[key])
        dedup = [x for i, x in enumerate(poly) if x != poly[i - 1]] if len(poly) > 1 else poly
        for j in range(1, len(dedup) - 1):
            new_faces.append((dedup[0], dedup[j], dedup[j + 1]))
    if extra_parents:
        parents.append(np.asarray(extra_parents, dtype=np.int64))
        ts.append(np.asarray(extra_t))
    out_faces = np.concatenate([keep, np.asarray(new_faces, dtype=np.int64).reshape(-1, 3)])
    return np.concatenate(parents).astype(np.int64), np.concatenate(ts), out_faces


def _face_components(faces: np.ndarray) -> np.ndarray:
    """Label (F,) of the edge-connected component of each face."""
    F = len(faces)
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    e.sort(axis=1)
    fid = np.tile(np.arange(F), 3)
    order = np.lexsort((e[:, 1], e[:, 0]))
    e, fid = e[order], fid[order]
    same = np.all(e[1:] == e[:-1], axis=1)
    a, b = fid[:-1][same], fid[1:][same]
    graph = coo_matrix((np.ones(len(a)), (a, b)), shape=(F, F))
    return connected_components(graph, directed=False)[1]


def _compact(faces: np.ndarray, n_vertices: int) -> tuple[np.ndarray, np.ndarray]:
    """Indices of used vertices (U,) and faces renumbered into them."""
    used = np.unique(faces)
    remap = np.full(n_vertices, -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    return used, remap[faces]


def _subdivide_midpoint(attrs: list[np.ndarray], faces: np.ndarray) -> tuple[list[np.ndarray], np.ndarray]:
    """1-to-4 midpoint subdivision; every per-vertex attribute (V, ...) is averaged onto the new edge vertices."""
    V = len(attrs[0])
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    e.sort(axis=1)
    uniq, inv = np.unique(e, axis=0, return_inverse=True)
    inv = inv.reshape(3, -1) + V
    new_attrs = [np.concatenate([a, 0.5 * (a[uniq[:, 0]] + a[uniq[:, 1]])]) for a in attrs]
    a, b, c = faces.T
    ab, bc, ca = inv
    out = np.concatenate([np.stack(x, 1) for x in ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))])
    return new_attrs, out


def _refine_long_edges(attrs: list[np.ndarray], faces: np.ndarray, target: int) -> tuple[list[np.ndarray], np.ndarray]:
    """One pass of red-green refinement that splits the edges longer than the spacing of a
    `target`-vertex mesh of the same area (never above MAX_VERTICES in all).

    Faces with all three edges split become four (red), faces with one split edge two (green);
    a face with two split edges gets its third split too. Attributes (V, ...) are averaged
    onto the new edge vertices; attrs[0] are the positions (V, 3).
    """
    pts = attrs[0]
    V = len(pts)
    e = np.stack([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]], axis=1)  # edge k joins corners k, k+1
    uniq, inv = np.unique(np.sort(e, axis=-1).reshape(-1, 2), axis=0, return_inverse=True)
    inv = inv.reshape(-1, 3)
    length = np.linalg.norm(pts[uniq[:, 0]] - pts[uniq[:, 1]], axis=1)
    cross = np.cross(pts[faces[:, 1]] - pts[faces[:, 0]], pts[faces[:, 2]] - pts[faces[:, 0]])
    area = 0.5 * np.linalg.norm(cross, axis=1).sum()
    spacing = np.sqrt(2 * area / (np.sqrt(3) * target))
    for _ in range(20):
        split = length > spacing
        while True:
            promote = split[inv].sum(axis=1) == 2
            if not promote.any():
                break
            split[inv[promote].ravel()] = True
        if V + split.sum() <= MAX_VERTICES:
            break
        spacing *= 1.15
    if not split.any():
        return attrs, faces
    new_index = np.full(len(uniq), -1, dtype=np.int64)
    new_index[split] = V + np.arange(split.sum())
    su = uniq[split]
    attrs = [np.concatenate([a, 0.5 * (a[su[:, 0]] + a[su[:, 1]])]) for a in attrs]
    mid = new_index[inv]  # (F, 3) new vertex on edge k, or -1
    n_split = (mid >= 0).sum(axis=1)
    out = [faces[n_split == 0]]
    red = n_split == 3
    a, b, c = faces[red].T
    ab, bc, ca = mid[red].T
    out += [np.stack(x, 1) for x in ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))]
    green = np.flatnonzero(n_split == 1)
    k = np.argmax(mid[green] >= 0, axis=1)
    v0 = faces[green, k]
    v1 = faces[green, (k + 1) % 3]
    v2 = faces[green, (k + 2) % 3]
    m = mid[green, k]
    out += [np.stack([v0, m, v2], 1), np.stack([m, v1, v2], 1)]
    return attrs, np.concatenate(out)


def _neighbour_matrix(faces: np.ndarray, n: int):
    """Row-normalised vertex adjacency (n, n) sparse, and the boundary-vertex mask with boundary-only adjacency."""
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    key = np.sort(e, axis=1)
    uniq, counts = np.unique(key, axis=0, return_counts=True)
    boundary_edges = uniq[counts == 1]
    on_boundary = np.zeros(n, dtype=bool)
    on_boundary[boundary_edges.ravel()] = True

    def normalised(edges):
        i = np.concatenate([edges[:, 0], edges[:, 1]])
        j = np.concatenate([edges[:, 1], edges[:, 0]])
        m = coo_matrix((np.ones(len(i)), (i, j)), shape=(n, n)).tocsr()
        deg = np.asarray(m.sum(axis=1)).ravel()
        return m.multiply(1.0 / np.maximum(deg, 1)[:, None]).tocsr(), deg

    interior, _ = normalised(uniq)
    boundary, _ = normalised(boundary_edges)
    return interior, boundary, on_boundary


def _taubin(points: np.ndarray, faces: np.ndarray, iterations: int, lam: float = 0.5, mu: float = -0.53) -> np.ndarray:
    """Taubin smoothing; boundary vertices are smoothed along their boundary loop only."""
    interior, boundary, on_b = _neighbour_matrix(faces, len(points))
    p = points.copy()
    for _ in range(iterations):
        for w in (lam, mu):
            avg = interior @ p
            avg[on_b] = (boundary @ p)[on_b]
            p = p + w * (avg - p)
    return p


def _gap_limited_ease(rest: _RestBody, points: np.ndarray, normals: np.ndarray, ease: np.ndarray) -> np.ndarray:
    """Cap each point's ease so the offset stays on its own side of a facing body part (e.g. the inner thighs).

    points, normals: (N, 3) on the body surface; ease: (N,) metres. Returns (N,) metres.
    """
    out = ease.copy()
    alive = np.ones(len(points), dtype=bool)
    for frac in (0.25, 0.5, 0.75, 1.0):
        t = ease * frac
        q = points + normals * t[:, None]
        d, _ = rest.vertex_tree.query(q)
        # Another surface is nearer than the one we start from: past the half-gap.
        blocked = alive & (d < 0.8 * t - 1e-3)
        out[blocked] = np.maximum(ease[blocked] * (frac - 0.25), 0.003)
        alive &= ~blocked
    return out


def _offset_surface(rest: _RestBody, points: np.ndarray, normals: np.ndarray, ease: np.ndarray, faces: np.ndarray,
                    smooth_iterations: int) -> np.ndarray:
    """The body-surface patch `points` (N, 3) moved `ease` (N,) metres along `normals`, smoothed, kept outside the body."""
    garment = points + normals * ease[:, None]
    clearance = np.maximum(0.6 * ease, 0.002)
    for _ in range(3):
        garment = _taubin(garment, faces, smooth_iterations)
        garment = rest.push_out(garment, clearance)
    return garment


def _untangled_offset(rest: _RestBody, name: str, points: np.ndarray, normals: np.ndarray, ease: np.ndarray,
                      faces: np.ndarray, smooth_iterations: int) -> np.ndarray:
    """`_offset_surface` with the ease halved, try by try, where the result passes through itself.

    Offsetting a concave region (the crotch, an armpit) by more than its radius of curvature folds the
    surface over itself; a garment authored that way starts the simulation tangled (with self-contact
    on, crossing cloth is pushed apart or locked). Each try finds the self-intersecting faces
    (`core.geometry.self_intersecting_faces`) and halves the ease (down to SNUG_EASE_M) of their
    vertices and of every vertex within UNTANGLE_RINGS edges of them.
    """
    from core.geometry import self_intersecting_faces

    adjacency = _neighbour_matrix(faces, len(points))[0]
    ease = ease.copy()
    for _ in range(UNTANGLE_TRIES):
        garment = _offset_surface(rest, points, normals, ease, faces, smooth_iterations)
        crossing = self_intersecting_faces(garment, faces)
        if not crossing.any():
            return garment
        near = np.zeros(len(points))
        near[faces[crossing].ravel()] = 1.0
        for _ in range(UNTANGLE_RINGS):
            near = near + adjacency @ near
        ease[near > 0] = np.maximum(0.5 * ease[near > 0], SNUG_EASE_M)
    log.warning("%s: %d faces still pass through others after %d tries of reducing the ease", name,
                int(crossing.sum()), UNTANGLE_TRIES)
    return garment


def _ease_per_joint(n_joints: int, torso: float, arms: float, legs: float, neck: float) -> np.ndarray:
    ease = np.full(n_joints, arms)
    for name in ("pelvis", "spine1", "spine2", "spine3"):
        ease[_J[name]] = torso
    for name in ("left_hip", "right_hip", "left_knee", "right_knee", "left_ankle", "right_ankle",
                 "left_foot", "right_foot"):
        ease[_J[name]] = legs
    for name in ("neck", "left_collar", "right_collar", "head"):
        ease[_J[name]] = neck
    return ease


def _offset_garment(rest: _RestBody, name: str, fields: list[Callable[[np.ndarray], np.ndarray]], seed: np.ndarray,
                    ease_per_joint: np.ndarray, smooth_iterations: int = 12) -> Garment:
    """Cut the body surface where every field is >= 0, keep the piece around `seed`, offset and smooth it.

    fields: functions (V, 3) points -> (V,) values, positive on the garment side, roughly metres.
    seed: (3,) a point near the body surface inside the garment. ease_per_joint: (J,) metres.
    """
    value = np.min(np.stack([fn(rest.verts) for fn in fields]), axis=0)
    mean_edge = float(np.mean(np.linalg.norm(rest.verts[rest.faces[:, 0]] - rest.verts[rest.faces[:, 1]], axis=1)))
    parents, t, faces = _clip_by_level_set(rest.verts, rest.faces, value, snap=0.3 * mean_edge)
    if len(faces) == 0:
        raise InputError(f"body: the {name} region of the body is empty; is the body in a T-pose, Y-up, in metres?")
    labels = _face_components(faces)
    cut_points = (1 - t[:, None]) * rest.verts[parents[:, 0]] + t[:, None] * rest.verts[parents[:, 1]]
    centroids = cut_points[faces].mean(axis=1)
    faces = faces[labels == labels[np.argmin(np.linalg.norm(centroids - seed, axis=1))]]
    used, faces = _compact(faces, len(cut_points))

    def interp(x):
        return (1 - t[used, None]) * x[parents[used, 0]] + t[used, None] * x[parents[used, 1]]

    attrs = [interp(rest.verts), interp(rest.normals), interp(rest.weights)]
    attrs, faces = _refine_long_edges(attrs, faces, TARGET_VERTICES)
    while len(attrs[0]) < MIN_VERTICES:
        attrs, faces = _subdivide_midpoint(attrs, faces)
    points, normals, weights = attrs
    if len(points) > MAX_VERTICES:
        log.warning("%s: %d vertices on this body, above the %d aimed for", name, len(points), MAX_VERTICES)
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
    ease = _gap_limited_ease(rest, points, normals, weights @ ease_per_joint)
    garment = _untangled_offset(rest, name, points, normals, ease, faces, smooth_iterations)
    u, v = _cylindrical_uvs(garment, rest.joint("pelvis"))
    uvs, face_uvs = _seamed_uvs(u, v, faces)
    return _finish(rest, name, garment, faces, uvs, face_uvs)


def _cylindrical_uvs(points: np.ndarray, centre: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """u = angle around the vertical axis through `centre` / 2 pi (0 at the back), v = height in [0, 1]."""
    rel = points - centre
    u = (np.arctan2(rel[:, 0], -rel[:, 2]) / (2 * np.pi)) % 1.0
    y = points[:, 1]
    v = (y - y.min()) / max(float(np.ptp(y)), 1e-9)
    return u, v


def _seamed_uvs(u: np.ndarray, v: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """UVs with faces that straddle the u = 0/1 seam given duplicated corners (u + 1), rescaled into [0, 1]."""
    fu = u[faces]
    wraps = (fu.max(axis=1) - fu.min(axis=1)) > 0.5
    face_uvs = faces.copy()
    low = wraps[:, None] & (fu < 0.5)
    dup_src = np.unique(faces[low])
    dup_index = np.full(len(u), -1, dtype=np.int64)
    dup_index[dup_src] = len(u) + np.arange(len(dup_src))
    face_uvs[low] = dup_index[faces[low]]
    uu = np.concatenate([u, u[dup_src] + 1.0])
    vv = np.concatenate([v, v[dup_src]])
    uu = uu / max(float(uu.max()), 1.0)
    return np.stack([uu, vv], axis=1), face_uvs


# --------------------------------------------------------------------------- shared finishing


def _finish(rest: _RestBody, name: str, verts: np.ndarray, faces: np.ndarray, uvs: np.ndarray,
            face_uvs: np.ndarray) -> Garment:
    """Orient faces away from the body and pack the arrays into a Garment."""
    from core.geometry import vertex_normals

    _, nearest = rest.vertex_tree.query(verts)
    outward = np.einsum("ij,ij->i", vertex_normals(verts, faces), verts - rest.verts[nearest])
    if outward.sum() < 0:
        faces = faces[:, ::-1].copy()
        face_uvs = face_uvs[:, ::-1].copy()
    return Garment(vertices=verts.astype(np.float32), faces=faces.astype(np.int64),
                   uvs=np.clip(uvs, 0.0, 1.0).astype(np.float32), face_uvs=face_uvs.astype(np.int64), name=name)


# --------------------------------------------------------------------------- the garments


def _neck_field(rest: _RestBody) -> Callable[[np.ndarray], np.ndarray]:
    """Positive outside an ellipsoid around the neck (a crew neckline, lower at the front)."""
    centre = rest.joint("neck") + np.array([0.0, 0.03, 0.02])
    axes = np.array([0.085, 0.075, 0.11])
    return lambda p: (np.linalg.norm((p - centre) / axes, axis=1) - 1.0) * axes.min()


def _sleeve_field(rest: _RestBody, side: str, fraction: float) -> Callable[[np.ndarray], np.ndarray]:
    """Positive on the torso side of a plane across the upper arm at `fraction` from shoulder to elbow."""
    s, e = rest.joint(f"{side}_shoulder"), rest.joint(f"{side}_elbow")
    u = (e - s) / np.linalg.norm(e - s)
    cut = s + fraction * (e - s)
    radius = 0.6 * np.linalg.norm(e - s)

    def field(p):
        rel = p - s
        radial = np.linalg.norm(rel - (rel @ u)[:, None] * u, axis=1)
        # Points far from the arm's axis are never cut by this plane.
        return np.maximum((cut - p) @ u, radial - radius)
    return field


def _below(y: float) -> Callable[[np.ndarray], np.ndarray]:
    return lambda p: y - p[:, 1]


def _above(y: float) -> Callable[[np.ndarray], np.ndarray]:
    return lambda p: p[:, 1] - y


def _levels(rest: _RestBody) -> dict[str, float]:
    """Key heights (metres) of the rest body, from its joints."""
    pelvis, spine1 = rest.joint("pelvis")[1], rest.joint("spine1")[1]
    hips = 0.5 * (rest.joint("left_hip")[1] + rest.joint("right_hip")[1])
    knees = 0.5 * (rest.joint("left_knee")[1] + rest.joint("right_knee")[1])
    ankles = 0.5 * (rest.joint("left_ankle")[1] + rest.joint("right_ankle")[1])
    return {"pelvis": pelvis, "spine1": spine1, "hips": hips, "knees": knees, "ankles": ankles,
            "armpits": rest.armpit_height()}


def _dress(rest: _RestBody) -> Garment:
    """A strapless A-line tube dress from just under the armpits to just below the knees."""
    lv = _levels(rest)
    return _tube_garment(rest, "dress", y_top=lv["armpits"] - 0.03, y_bottom=lv["knees"] - 0.06, ease=0.012,
                         flare_from_y=lv["hips"] + 0.3 * (lv["pelvis"] - lv["hips"]), flare_slope=0.22)


def _skirt(rest: _RestBody) -> Garment:
    """A flared skirt from the waist to above the knees."""
    lv = _levels(rest)
    y_top = lv["pelvis"] + 0.5 * (lv["spine1"] - lv["pelvis"])
    return _tube_garment(rest, "skirt", y_top=y_top, y_bottom=lv["knees"] + 0.3 * (lv["hips"] - lv["knees"]),
                         ease=0.015, flare_from_y=lv["hips"] + 0.3 * (lv["pelvis"] - lv["hips"]), flare_slope=0.3)


def _tshirt(rest: _RestBody) -> Garment:
    """A short-sleeved t-shirt: crew neck, sleeves to mid upper arm, hem at the hips; one piece."""
    lv = _levels(rest)
    fields = [_neck_field(rest), _sleeve_field(rest, "left", 0.5), _sleeve_field(rest, "right", 0.5),
              _above(lv["hips"] + 0.25 * (lv["pelvis"] - lv["hips"]))]
    ease = _ease_per_joint(rest.n_joints, torso=0.016, arms=0.02, legs=0.016, neck=0.008)
    return _offset_garment(rest, "tshirt", fields, rest.joint("spine2"), ease)


def _trousers(rest: _RestBody) -> Garment:
    """Straight trousers from the waist to just above the ankles; one piece."""
    lv = _levels(rest)
    y_waist = lv["pelvis"] + 0.5 * (lv["spine1"] - lv["pelvis"])
    fields = [_below(y_waist), _above(lv["ankles"] + 0.04)]
    ease = _ease_per_joint(rest.n_joints, torso=0.012, arms=0.02, legs=0.03, neck=0.008)
    return _offset_garment(rest, "trousers", fields, rest.joint("pelvis"), ease)


def _jumpsuit(rest: _RestBody) -> Garment:
    """A short-sleeved jumpsuit: crew neck, sleeves to mid upper arm, legs to just above the ankles; one piece."""
    lv = _levels(rest)
    fields = [_neck_field(rest), _sleeve_field(rest, "left", 0.5), _sleeve_field(rest, "right", 0.5),
              _above(lv["ankles"] + 0.04)]
    ease = _ease_per_joint(rest.n_joints, torso=0.016, arms=0.02, legs=0.03, neck=0.008)
    return _offset_garment(rest, "jumpsuit", fields, rest.joint("spine2"), ease, smooth_iterations=10)


_BUILDERS: dict[str, Callable[[_RestBody], Garment]] = {
    "dress": _dress, "skirt": _skirt, "tshirt": _tshirt, "trousers": _trousers, "jumpsuit": _jumpsuit,
}


def _public(name: str) -> Callable[[Body], Garment]:
    def make(body: Body) -> Garment:
        return _BUILDERS[name](_RestBody(body))
    make.__name__ = f"make_{name}"
    make.__doc__ = (_BUILDERS[name].__doc__
                    + "\n\n    body: SMPL-format Body in its rest pose. Returns a Garment (metres, rest frame).")
    return make


make_dress = _public("dress")
make_skirt = _public("skirt")
make_tshirt = _public("tshirt")
make_trousers = _public("trousers")
make_jumpsuit = _public("jumpsuit")

#: Example garments by name: each builds a Garment fitted to a body's rest pose.
EXAMPLE_GARMENTS: dict[str, Callable[[Body], Garment]] = {
    "dress": make_dress, "skirt": make_skirt, "tshirt": make_tshirt, "trousers": make_trousers,
    "jumpsuit": make_jumpsuit,
}


def generate_example_garments(body: Body, names: tuple[str, ...] | None = None) -> dict[str, Garment]:
    """Every example garment (or those in `names`) fitted to `body` in its rest pose.

    body: an SMPL-format Body (Y-up, T-pose, metres) with at least the 22 SMPL body joints.
    Returns {name: Garment} with vertices (V, 3) float32 in metres in the body's rest frame,
    2,000-8,000 vertices each, UVs (U, 2) in [0, 1] and face_uvs (F, 3). Deterministic.
    """
    names = tuple(EXAMPLE_GARMENTS) if names is None else tuple(names)
    unknown = [n for n in names if n not in EXAMPLE_GARMENTS]
    if unknown:
        raise InputError(f"example garments: expected names among {sorted(EXAMPLE_GARMENTS)}, got {unknown}")
    rest = _RestBody(body)
    return {n: _BUILDERS[n](rest) for n in names}
