"""Garments: a validated triangle mesh authored on a body's rest pose.

A `Garment` lives in the body's rest frame (Y-up, T-pose, metres). Readers in
`formats/` build one from a file; `validate_garment` applies the checks a
user's mesh must pass (finite, non-empty, metres, near the body).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from core.errors import InputError


@dataclass(frozen=True, eq=False)
class SourceMesh:
    """The mesh as its file has it, where that differs from the triangle mesh deformed (quads, seams welded,
    vertices or faces dropped): what the bake's outputs are written in, so that they keep the file's point
    numbering and polygons.

    vertex_of: (Vs,) int64, the garment vertex each of the file's vertices moves with (itself; the vertex it
    was welded onto; for a vertex no face uses, the nearest one). polygons: (P, K) int64 indices into the
    file's vertices, K >= 4 the most corners of a face, -1 after each face's last corner (triangles, quads
    and n-gons as the file has them). uvs: (U, 2) float32 or None; polygon_uvs: (P, K) int64 into uvs, or None.
    materials: (P,) str, each polygon's material (an OBJ's `usemtl`, "" for none), or None. libraries: the
    material library files (.mtl, absolute paths) that define them, as the OBJ's `mtllib` names them. looks:
    {material: `formats.mtl.MtlMaterial`} of a file with no libraries whose materials carry their looks (a USD
    stage's preview surfaces), or None.
    """

    vertex_of: np.ndarray
    polygons: np.ndarray
    uvs: np.ndarray | None = None
    polygon_uvs: np.ndarray | None = None
    materials: np.ndarray | None = None
    libraries: tuple[str, ...] = ()
    looks: dict | None = None

    def material_groups(self) -> dict[str, np.ndarray] | None:
        """{material: its polygons' indices (sorted)} in order of first use, or None without materials."""
        if self.materials is None:
            return None
        names = list(dict.fromkeys(self.materials.tolist()))
        return {name: np.flatnonzero(self.materials == name) for name in names}

    @property
    def n_vertices(self) -> int:
        return int(self.vertex_of.shape[0])

    def points(self, garment_points: np.ndarray) -> np.ndarray:
        """(..., Vs, 3): the file's vertices where the garment's (..., V, 3) `garment_points` put them."""
        return np.asarray(garment_points)[..., self.vertex_of, :]


@dataclass(frozen=True, eq=False)
class Garment:
    """A triangle mesh in the body's rest frame.

    vertices: (V, 3) float32, metres. faces: (F, 3) int64.
    uvs: (U, 2) float32 or None; face_uvs: (F, 3) int64 indices into uvs, or None.
    source: the file's own mesh (`SourceMesh`) where it differs from this one (not part of `content_hash`).
    """

    vertices: np.ndarray
    faces: np.ndarray
    uvs: np.ndarray | None = None
    face_uvs: np.ndarray | None = None
    name: str = "garment"
    source: SourceMesh | None = None

    @property
    def n_vertices(self) -> int:
        return int(self.vertices.shape[0])

    @property
    def n_faces(self) -> int:
        return int(self.faces.shape[0])

    @cached_property
    def pieces(self) -> tuple[int, np.ndarray]:
        """(N, labels (V,) int64 0..N-1): the garment's connected pieces (computed once per garment)."""
        from core.graph import connected_components

        return connected_components(mesh_edges(self.faces), self.n_vertices)

    def written(self, points: np.ndarray) -> tuple:
        """How outputs write the garment at `points` (..., V, 3): (points (..., Vs, 3), faces (F, 3) or polygons
        (P, K), uvs, face or polygon uvs, materials (P,) or None), the file's own mesh (`source`) where it has
        one, else this one."""
        if self.source is None:
            return points, self.faces, self.uvs, self.face_uvs, None
        s = self.source
        return s.points(points), s.polygons, s.uvs, s.polygon_uvs, s.materials

    def content_hash(self) -> str:
        """SHA-256 of vertices and faces (hex), the key for caches of derived data."""
        h = hashlib.sha256()
        h.update(np.ascontiguousarray(self.vertices, dtype=np.float32).tobytes())
        h.update(np.ascontiguousarray(self.faces, dtype=np.int64).tobytes())
        return h.hexdigest()


def frames_at_once(n_vertices: int, vertex_frames: int, least: int, most: int) -> int:
    """Frames of a garment of `n_vertices` to work on at once: the largest power of two whose frames hold at most
    `vertex_frames` vertex-frames, within [least, most] (a large garment's temporaries stay in cache and memory)."""
    fit = 1 << max(int(vertex_frames // max(n_vertices, 1)).bit_length() - 1, 0)
    return min(most, max(least, fit))


def mesh_edges(faces: np.ndarray) -> np.ndarray:
    """Unique undirected edges of a triangle mesh.

    faces: (F, 3) int -> (E, 2) int64 with edges[:, 0] < edges[:, 1], sorted.
    """
    return edge_face_counts(faces)[0]


def edge_face_counts(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unique undirected edges (E, 2) int64 (sorted rows, as `mesh_edges`) and how many faces use each (E,).
    Each edge is made one number (low * n + high: the rows' order kept) for `np.unique`, several times faster than
    its row search (`axis=0`)."""
    faces = np.asarray(faces, dtype=np.int64)
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    e.sort(axis=1)
    n = np.int64(e.max(initial=-1) + 1)
    keys, counts = np.unique(e[:, 0] * n + e[:, 1], return_counts=True)
    return np.stack([keys // n, keys % n], axis=1) if n else np.zeros((0, 2), np.int64), counts


def boundary_edges(faces: np.ndarray) -> np.ndarray:
    """Edges used by exactly one face: faces (F, 3) int -> (B, 2) int64, sorted rows."""
    edges, counts = edge_face_counts(faces)
    return edges[counts == 1]


def boundary_loops(faces: np.ndarray, n_vertices: int) -> list[np.ndarray]:
    """The vertices of each boundary loop (opening) of a triangle mesh.

    faces: (F, 3) int. A boundary edge is used by exactly one face; each connected set of
    boundary edges is one loop. Returns a list of sorted (k,) int64 vertex-index arrays, one
    per loop (unordered along the loop), in order of their smallest vertex index.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    border = boundary_edges(faces)
    if len(border) == 0:
        return []
    adjacency = coo_matrix((np.ones(len(border)), (border[:, 0], border[:, 1])), shape=(n_vertices, n_vertices))
    _, label = connected_components(adjacency, directed=False)
    on_border = np.unique(border)
    loops = [on_border[label[on_border] == lab] for lab in np.unique(label[on_border])]
    return sorted(loops, key=lambda loop: int(loop[0]))


#: Units a garment or body file too large for metres may be in, named in this order: (name, scale to metres).
UNIT_GUESSES = (("centimetres", 0.01), ("millimetres", 0.001), ("inches", 0.0254))
#: The extent (metres) a garment has: the units of `UNIT_GUESSES` that give it are named (a skirt to a T-posed
#: jumpsuit: 0.5-1.3 m).
GARMENT_SPAN_M = (0.2, 2.5)


def unit_guesses(extent: float, span_m: tuple[float, float], scaled: float = 1.0) -> list[tuple[str, float]]:
    """[(unit, the file's scale)] of each of `UNIT_GUESSES` that makes a file `extent` units across (its
    coordinates multiplied by `scaled`) span_m (low, high) metres."""
    return [(name, s * scaled) for name, s in UNIT_GUESSES if span_m[0] <= extent * s <= span_m[1]]


class UnitsError(InputError):
    """A garment file refused as too large for metres (`validate_garment`): `head`, its message without the hint
    of units, and `units`, the `unit_guesses` that fit a garment (a body placed by tells which: see
    `core.skinning.fit_in_units`)."""

    def __init__(self, message: str, head: str, units: list[tuple[str, float]]):
        super().__init__(message)
        self.head, self.units = head, units


def unit_hint(extent: float, span_m: tuple[float, float], command: str = "", scaled: float = 1.0) -> str:
    """The hint for a file `extent` units across that is too large for metres: each of `UNIT_GUESSES` that makes
    it span_m (low, high) metres, as "; is it in centimetres? scale it by 0.01", or "; is it in centimetres
    (scale it by 0.01) or inches (scale it by 0.0254)?" where several do (a 51-unit skirt: 51 cm or 1.3 m); ""
    where none does. command: the command that scales the file, "{scale}" standing for the scale (after the
    single unit's hint it is given with that scale: ": `garment unpose ... --scale 0.01`"). scaled: what the
    file's coordinates were multiplied by to give `extent`: the scales named are the file's."""
    units = unit_guesses(extent, span_m, scaled)
    if len(units) == 1:
        return f"; is it in {units[0][0]}? scale it by {units[0][1]:g}" + (
            f": {command.format(scale=f'{units[0][1]:g}')}" if command else "")
    if units:
        return "; is it in " + " or ".join(f"{name} (scale it by {s:g})" for name, s in units) + "?" + (
            f" {command.format(scale='S')} scales it" if command else "")
    return ""


#: A vertex further from the garment's middle (the median point) than STRAY_FACTOR times the median vertex's
#: distance, and STRAY_LEAST_M at least, is a stray: a garment's own reach no more than about 3 times the median
#: (the example dress 2.3, a scarf or a sleeve of a T-posed shirt more), one vertex dragged off by a slip of a tool
#: far more.
STRAY_FACTOR = 10.0
STRAY_LEAST_M = 1.0


def stray_points(points: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """(stray (N,) bool, distance (N,) from the middle) where a few of a garment's used vertices `points` (N, 3)
    lie far from the rest (`STRAY_FACTOR`), else None."""
    distance = np.linalg.norm(points - np.median(points, axis=0), axis=1)
    typical = float(np.median(distance))
    stray = distance > max(STRAY_FACTOR * typical, STRAY_LEAST_M * (typical > 0))
    if not stray.any() or stray.mean() > 0.05:  # more than a few: the garment itself (its units are checked next)
        return None
    return stray, distance


def _refuse_strays(points: np.ndarray, source: str) -> None:
    """InputError naming `source` where a few of a garment's used vertices `points` lie far from the rest
    (`stray_points`): one stray vertex 40 m off was blamed on the file's units, one 5 m off baked a spike."""
    found = stray_points(points)
    if found is None:
        return
    stray, distance = found
    worst = int(np.argmax(distance))
    rest = float(distance[~stray].max())
    where = ", ".join(f"{x:.4g}" for x in points[worst])
    raise InputError(f"garment mesh '{source}': expected one garment, got {int(stray.sum())} "
                     f"{'vertex' if stray.sum() == 1 else 'vertices'} far from the rest (the furthest at ({where}), "
                     f"{distance[worst]:.3g} units from its middle; the other vertices within {rest:.3g}): stray "
                     f"vertices a tool left? remove them" + ("" if stray.sum() < 3 else " (or a ground plane or "
                                                             "a prop exported with the garment? export it without)"))


def validate_garment(garment: Garment, source: str, scale: float = 1.0) -> None:
    """Checks every garment must pass before it is deformed; raise InputError naming `source`. scale: what the
    file's coordinates were multiplied by (`garment unpose --scale`): a unit's scale named is relative to the file."""
    v, f = garment.vertices, garment.faces
    if v.shape[0] == 0:
        raise InputError(f"garment mesh '{source}': expected vertices, got an empty mesh")
    if f.shape[0] == 0:
        raise InputError(f"garment mesh '{source}': expected faces with an area, got no faces")
    bad = ~np.isfinite(v).all(axis=1)
    if bad.any():
        raise InputError(f"garment mesh '{source}': expected finite coordinates, got NaN/Inf at vertex {int(np.argmax(bad))}")
    used = v[np.unique(f)].astype(np.float64)
    _refuse_strays(used, source)
    extent = float(np.max(used.max(0) - used.min(0)))
    if extent > 10.0:
        # The units whose metres fit a garment: centimetres or millimetres (Marvelous Designer's and CLO's default
        # export), inches; all of those that could be it, as the file does not say.
        hint = unit_hint(extent, GARMENT_SPAN_M, f"`garment unpose {source} --pose tpose --scale {{scale}}`", scale)
        head = (f"garment mesh '{source}': expected metres (a garment spans under 3 m), got an extent of "
                f"{extent:.1f} units")
        raise UnitsError(head + hint, head, unit_guesses(extent, GARMENT_SPAN_M, scale))
    if extent < 1e-3:
        raise InputError(f"garment mesh '{source}': expected metres, got an extent of {extent:.2e} units")


def consistent_winding(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Faces wound alike across every edge two of them share, per connected piece (faces joined by such edges).

    faces: (F, 3) int. Returns (faces (F, 3) int64, each face that disagreed with the piece's first face (its
    smallest index) turned by swapping its last two corners; piece (F,) int64 label of each face). Across a
    shared edge, faces wound alike run it in opposite directions. An edge of three or more faces joins nothing; a
    piece that cannot be wound alike (a Moebius strip) keeps the winding of a spanning tree from its first face.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import breadth_first_order, connected_components

    faces = np.asarray(faces, dtype=np.int64)
    F = len(faces)
    if F == 0:
        return faces, np.zeros(0, dtype=np.int64)
    directed = np.stack([faces, np.roll(faces, -1, axis=1)], axis=2).reshape(-1, 2)  # (3F, 2): a->b, b->c, c->a
    key = np.sort(directed, axis=1)
    _, edge, uses = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    edge = edge.reshape(-1)
    shared = np.flatnonzero(uses[edge] == 2)  # half-edges of the edges exactly two faces share
    order = shared[np.argsort(edge[shared], kind="stable")]
    first, second = order[0::2], order[1::2]
    fa, fb = first // 3, second // 3
    alike = directed[first, 0] == directed[second, 0]  # both run the edge the same way: wound oppositely
    graph = coo_matrix((np.ones(len(fa)), (fa, fb)), shape=(F, F)).tocsr()
    _, piece = connected_components(graph, directed=False)
    # A spanning tree of each piece from its first face; a face turns when the turns along its path to the root
    # do not cancel (the path's XOR, by pointer jumping).
    up = np.arange(F)
    for root in np.unique(piece, return_index=True)[1]:
        visit, parent = breadth_first_order(graph, int(root), directed=False, return_predecessors=True)
        up[visit[1:]] = parent[visit[1:]]
    pair = np.concatenate([fa * F + fb, fb * F + fa])
    sorter = np.argsort(pair)
    bits = np.concatenate([alike, alike])[sorter]
    has_parent = up != np.arange(F)
    turn = np.zeros(F, dtype=bool)
    turn[has_parent] = bits[np.searchsorted(pair[sorter], up[has_parent] * F + np.flatnonzero(has_parent))]
    while np.any(up != up[up]):
        turn, up = turn ^ turn[up], up[up]
    out = faces.copy()
    out[turn] = out[turn][:, [0, 2, 1]]
    return out, piece.astype(np.int64)
