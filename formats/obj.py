"""Wavefront OBJ: reading a garment mesh, writing meshes and animation frames.

`read_obj` turns a user's OBJ (triangles, quads and larger polygons, any of the `v`, `v/vt`,
`v//vn`, `v/vt/vn` face forms, negative indices, several objects or groups)
into one cleaned, validated `core.garment.Garment`. `parse_obj` and
`triangulate` are the raw layers under it, used as they are by the OBJ
sequence reader (which must keep every frame's vertex numbering). `write_obj`
builds the whole file with one string formatting per block, because the
sequence writers call it for thousands of frames.
"""

from __future__ import annotations

import logging
import os
import warnings
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from core.errors import InputError, require_input, warnings_held
from core.garment import Garment, SourceMesh, validate_garment

log = logging.getLogger(__name__)

#: Vertices closer than this (and than 1 % of the median edge) are one vertex: seams of separately exported
#: panels (Marvelous Designer, CLO) repeat every seam vertex once per panel, at the same position.
WELD_DISTANCE_M = 1e-5
#: Faces of up to this many vertices are read (5 or more split by `ear_clip`); larger ones are refused.
MAX_POLYGON_VERTICES = 256
#: The largest coordinate read: every reader keeps points as float32, where a larger one becomes Inf (and its square
#: overflows float64 in the weld's distances); no garment in any unit comes near it.
MAX_COORDINATE = float(np.finfo(np.float32).max)

#: Statement keywords that carry nothing a garment needs (materials, smoothing, grouping).
_IGNORED = frozenset({"vn", "o", "g", "s", "vp", "l", "p",
                      "cstype", "deg", "curv", "curv2", "surf", "parm", "trim", "hole",
                      "end", "bmat", "step", "con", "mg", "lod", "shadow_obj", "trace_obj",
                      "ctech", "stech", "bevel", "c_interp", "d_interp", "maplib", "usemap"})


@dataclass(frozen=True, eq=False)
class ObjPolygons:
    """The geometry of an OBJ file as written, before triangulation or cleaning.

    vertices: (V, 3) float64, file units. polygons: (P, 4) int64, 0-based vertex
    indices, -1 in the last column of a triangle; a face of more than 4 corners is already split into
    triangles (`ear_clip`), its first in the face's row, the others after the file's faces. uvs: (U, 2) float64 or None;
    polygon_uvs: (P, 4) int64 like `polygons` but into `uvs`, or None unless
    every face gave texture indices. `face_lines`: the file's face lines as
    written; `n_uv_rows`: its number of `vt` lines; `relative`: whether any face
    uses negative indices. Two files with equal face lines, vertex and `vt`
    counts and no relative indices have equal polygons.
    """

    vertices: np.ndarray
    polygons: np.ndarray
    uvs: np.ndarray | None
    polygon_uvs: np.ndarray | None
    face_lines: tuple
    n_uv_rows: int
    relative: bool
    #: (P,) the material (`usemtl`) of each polygon row ("" before any), or None when the file names none.
    materials: np.ndarray | None = None
    #: The file's faces as written where one has more than 4 corners (`FilePolygons`), else None (`polygons`).
    written: FilePolygons | None = None
    #: The `mtllib` statements' arguments, as written.
    libraries: tuple = ()

    def same_faces(self, face_lines, n_vertices: int, n_uv_rows: int) -> bool:
        """Whether a file with these face lines and counts has exactly this file's polygons."""
        return (not self.relative and n_vertices == self.vertices.shape[0] and n_uv_rows == self.n_uv_rows
                and len(face_lines) == len(self.face_lines) and tuple(face_lines) == self.face_lines)


@dataclass(frozen=True, eq=False)
class FilePolygons:
    """A file's faces as written, n-gons whole: polygons (P, K) int64 (K >= 4 the most corners of a face, -1
    after a face's last), polygon_uvs (P, K) int64 into the file's uvs or None, materials (P,) or None."""

    polygons: np.ndarray
    polygon_uvs: np.ndarray | None
    materials: np.ndarray | None


def file_polygons(polygons: np.ndarray, polygon_uvs: np.ndarray, ngons: list,
                  materials: np.ndarray | None = None) -> FilePolygons:
    """The faces as written (`FilePolygons`) of (P, 4) `polygons` and `polygon_uvs` whose n-gons (`ngons`, as
    `split_ngons` takes them) are not split yet: each n-gon's row gets all its corners."""
    k = max([4] + [len(corners) for _, corners, _ in ngons])
    rows = np.pad(polygons, ((0, 0), (0, k - 4)), constant_values=-1)
    uv_rows = np.pad(polygon_uvs, ((0, 0), (0, k - 4)), constant_values=-1)
    for face, corners, corner_uvs in ngons:
        rows[face, :len(corners)] = corners
        uv_rows[face, :len(corners)] = corner_uvs
    return FilePolygons(rows, uv_rows, materials)


def _read_text(path: Path, label: str) -> str:
    if path.is_dir():
        raise InputError(f"{label} '{path}': expected an OBJ file, got a directory")
    require_input(path, f"{label} '{path}'")
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise InputError(f"{label} '{path}': cannot be read ({exc.strerror or exc})") from None
    # Comments and material names in legacy encodings must not stop a read; a byte-order mark (Windows tools
    # write one) must not hide the first line.
    return data.decode("utf-8-sig", errors="replace")


def _physical_lines(text: str) -> list[str]:
    """The lines of an OBJ's text, ended by \\n, \\r\\n or \\r alone as editors count them (not `str.splitlines`,
    which also breaks at form feeds, \\x1c-\\x1e, NEL and U+2028, shifting every line number an error names after them;
    within a line they are whitespace, as `str.split` takes them)."""
    if "\r" in text:
        text = text.replace("\r\n", "\n").replace("\r", "\n")
    lines = text.split("\n")
    if lines[-1] == "":
        lines.pop()
    return lines


def _logical_lines(text: str):
    """(line number, line) of an OBJ's text, a line ending in a backslash joined with the next (the format's
    line continuation); a joined line is numbered by its last physical line. Comments are never continued: an
    exporter's "# C:\\models\\" must not swallow the vertex after it."""
    pending = ""
    for lineno, line in enumerate(_physical_lines(text), 1):
        stripped = line.rstrip()
        if stripped.endswith("\\") and not (pending + stripped).lstrip().startswith("#"):
            pending += stripped[:-1] + " "
            continue
        yield lineno, pending + line
        pending = ""
    if pending:
        yield lineno, pending


def _shown(token: str) -> str:
    """A file's token as an error quotes it: control characters (a NUL, a form feed) escaped, not printed raw."""
    return token if token.isprintable() else token.encode("unicode_escape").decode("ascii")


def _plain_number(token: str) -> bool:
    """Whether `token` is a number as C's strtod reads it: Python's float() also takes `1_000` and other scripts'
    digits (`\u0663`), which other OBJ readers refuse: a corrupted or mistyped file, not a coordinate."""
    return token.isascii() and "_" not in token


def _floats(rows: list, line_numbers: list, width: int, what: str, label: str, path: Path) -> np.ndarray:
    """Rows of number strings -> (N, width) float64; on failure name the first bad line."""
    if not rows:
        return np.zeros((0, width), dtype=np.float64)
    joined = " ".join(" ".join(row) for row in rows)
    try:
        if not _plain_number(joined):
            raise ValueError(joined)
        return np.array(rows, dtype=np.float64).reshape(len(rows), width)
    except ValueError:
        for row, lineno in zip(rows, line_numbers):
            for tok in row:
                try:
                    if not _plain_number(tok):
                        raise ValueError(tok)
                    float(tok)
                except ValueError:
                    raise InputError(f"{label} '{path}': expected a number in the {what} on line {lineno}, "
                                     f"got '{_shown(tok)}'") from None
        raise


def _index(tok: str, count: int, lineno: int, kind: str, label: str, path: Path) -> int:
    """One OBJ index (1-based, or negative = relative to the `count` defined so far) -> 0-based."""
    try:
        if not _plain_number(tok):  # int() takes `1_0` and other scripts' digits too
            raise ValueError(tok)
        i = int(tok)
    except ValueError:
        raise InputError(f"{label} '{path}': expected an integer {kind} index on line {lineno}, "
                         f"got '{_shown(tok)}'") from None
    if i > _MAX_INDEX:
        raise InputError(f"{label} '{path}': {kind} index {i} out of range on line {lineno}, beyond any file's "
                         f"{kind} count")
    if i > 0:
        return i - 1
    if i == 0:
        raise InputError(f"{label} '{path}': {kind} index 0 out of range on line {lineno}: OBJ indices start at 1 "
                         f"(or count back from -1, the last defined)")
    if count + i >= 0:
        return count + i
    raise InputError(f"{label} '{path}': {kind} index {i} out of range on line {lineno}, "
                     f"only {count} defined before it")


#: The largest OBJ index held: the polygons are int64.
_MAX_INDEX = int(np.iinfo(np.int64).max)


def _without_comment(words: list[str]) -> str:
    """A statement's argument words joined, up to a word that starts a comment (`#`): a `#` inside a name
    (`cloth#2`) is kept."""
    kept = []
    for word in words:
        if word.startswith("#"):
            break
        kept.append(word)
    return " ".join(kept)


def parse_obj(path: str | os.PathLike, label: str = "garment mesh",
              like: ObjPolygons | None = None, finite: bool = False) -> ObjPolygons:
    """Read an OBJ's vertices, texture coordinates and triangle/quad faces as written (larger polygons split).

    Nothing is cleaned or validated beyond syntax and index ranges. `label` starts
    every error message ("garment mesh 'dress.obj': ..."). `like`: a previously
    parsed file (e.g. frame 0 of a sequence); when this file's face lines are the
    same, its polygon arrays are reused instead of parsed again. `finite`: a NaN or Inf vertex is refused here,
    naming its vertex and line (a garment's is `validate_garment`'s to report; a sequence frame's is not validated).
    Raises InputError for a missing file, a directory, an unparseable number or
    index, an index out of range, a face with fewer than 3 or more than
    MAX_POLYGON_VERTICES vertices or one that `ear_clip` cannot split, no vertices, or no faces.
    """
    path = Path(path)
    text = _read_text(path, label)
    if like is not None:
        fast = _parse_like(text, like)
        if fast is not None:
            return fast

    v_rows, v_lines, vt_rows, vt_lines = [], [], [], []
    f_lines, f_numbers, f_nv, f_nvt, f_materials = [], [], [], [], []
    material = ""
    libraries = []
    unknown = 0
    for lineno, line in _logical_lines(text):
        parts = line.split()
        if not parts:
            continue
        key = parts[0]
        if key == "v":
            if len(parts) < 4:
                raise InputError(f"{label} '{path}': expected 3 coordinates on the vertex on line {lineno}, "
                                 f"got {len(parts) - 1}")
            v_rows.append(parts[1:4])  # w or vertex colours follow: ignored
            v_lines.append(lineno)
        elif key == "f":
            f_lines.append(line.split("#", 1)[0])  # a comment after the indices (as after a vertex's numbers)
            f_numbers.append(lineno)
            f_nv.append(len(v_rows))
            f_nvt.append(len(vt_rows))
            f_materials.append(material)
        elif key == "usemtl":  # a comment after the name, after a space (`usemtl cloth # the back`), is no name
            material = _without_comment(parts[1:])
        elif key == "mtllib":
            libraries.append(_without_comment(parts[1:]))
        elif key == "vt":
            if len(parts) < 2:
                raise InputError(f"{label} '{path}': expected texture coordinates u v on line {lineno}, got none")
            vt_rows.append((parts[1:3] + ["0"])[:2])
            vt_lines.append(lineno)
        elif key[0] == "#" or key in _IGNORED:
            continue
        else:
            unknown += 1
    if unknown:
        log.debug("%s '%s': ignored %d lines with unknown keywords", label, path, unknown)

    vertices = _floats(v_rows, v_lines, 3, "vertex", label, path)
    uvs = _floats(vt_rows, vt_lines, 2, "texture coordinate", label, path)
    _refuse_beyond_float32(vertices, v_lines, "vertex", label, path)
    if finite and not np.isfinite(vertices).all():
        k = int(np.argmax(~np.isfinite(vertices).all(axis=1)))
        raise InputError(f"{label} '{path}': expected finite coordinates, got {_nonfinite_text(vertices[k])} at "
                         f"vertex {k + 1} on line {v_lines[k]}")
    if vertices.shape[0] == 0:
        raise InputError(f"{label} '{path}': expected vertices ('v' lines), got none")
    if not f_lines:
        raise InputError(f"{label} '{path}': expected faces ('f' lines), got none")

    if like is not None and like.same_faces(f_lines, len(v_rows), len(vt_rows)):
        return ObjPolygons(vertices, like.polygons, uvs if like.polygon_uvs is not None else None,
                           like.polygon_uvs, like.face_lines, like.n_uv_rows, False)

    n_faces = len(f_lines)
    ngons = []  # (face, corners, corner uvs) of the faces with more than 4 vertices
    polygons = np.full((n_faces, 4), -1, dtype=np.int64)
    polygon_uvs = np.full((n_faces, 4), -1, dtype=np.int64)
    any_uv, missing = False, []  # faces with texture coordinates; the faces of corners without
    for k, line in enumerate(f_lines):
        parts = line.split()
        lineno = f_numbers[k]
        n = len(parts) - 1
        if n < 3 or n > MAX_POLYGON_VERTICES:
            raise InputError(f"{label} '{path}': expected faces of 3 to {MAX_POLYGON_VERTICES} vertices, got a face "
                             f"with {n} vertices (face {k + 1}, line {lineno})")
        nv, nvt = f_nv[k], f_nvt[k]
        row, row_uv = polygons[k], polygon_uvs[k]
        if n > 4:  # an n-gon: its corners now, its triangles once every index is known to be in range
            row, row_uv = np.full(n, -1, dtype=np.int64), np.full(n, -1, dtype=np.int64)
            ngons.append((k, row, row_uv))
        with_uv = 0
        for j in range(n):
            tok = parts[j + 1]
            if "/" in tok:
                sub = tok.split("/")
                row[j] = _index(sub[0], nv, lineno, "vertex", label, path)
                if len(sub) > 1 and sub[1]:
                    row_uv[j] = _index(sub[1], nvt, lineno, "texture coordinate", label, path)
                    any_uv, with_uv = True, with_uv + 1
                    continue
            else:
                row[j] = _index(tok, nv, lineno, "vertex", label, path)
            row_uv[j] = _NO_UV
            if not missing or missing[-1] != k:
                missing.append(k)
        if 0 < with_uv < n:  # no exporter writes one; a file cut short in its last corner (2015/2015 -> 201) does
            raise InputError(f"{label} '{path}': expected texture coordinates at every corner of a face or at none, "
                             f"got them at {with_uv} of {n} on line {lineno} ({line.strip()[:60]!r}): "
                             "a file cut short or broken?")
    all_uv = any_uv
    if any_uv and missing:  # some faces without: given (0, 0), so that the others keep theirs
        uvs = np.concatenate([uvs, np.zeros((1, 2))])
        for rows in [polygon_uvs] + [ngon[2] for ngon in ngons]:
            rows[rows == _NO_UV] = len(uvs) - 1
        log.warning("%s '%s': %d of %d faces have no texture coordinates (from line %d, as 'f a//n' or 'f a'): "
                    "given (0, 0), so that the others keep theirs", label, path, len(missing), n_faces,
                    f_numbers[missing[0]])

    n_v = vertices.shape[0]
    checks = [("vertex", polygons, n_v, 1, "vertices")]
    if all_uv:
        checks.append(("texture coordinate", polygon_uvs, uvs.shape[0], 2, "texture coordinates"))
    for what, rows, count, column, plural in checks:
        largest = rows.max(axis=1)
        for ngon in ngons:
            largest[ngon[0]] = ngon[column].max()
        bad = largest >= count
        if bad.any():
            k = int(np.argmax(bad))
            raise InputError(f"{label} '{path}': {what} index {int(largest[k]) + 1} out of range on line "
                             f"{f_numbers[k]}, the file has {count} {plural}")
    if all_uv:  # NaN or Inf texture coordinates that a face uses would be written into every output
        used = np.unique(np.concatenate([polygon_uvs[polygon_uvs >= 0]] + [ngon[2] for ngon in ngons]))
        bad = used[~np.isfinite(uvs[used]).all(axis=1)]
        if len(bad):
            raise InputError(f"{label} '{path}': expected finite texture coordinates, got "
                             f"{_nonfinite_text(uvs[bad[0]])} on line {vt_lines[bad[0]]}")
    named = any(f_materials)
    written = None
    if ngons:
        written = file_polygons(polygons, polygon_uvs, ngons,
                                np.array(f_materials, dtype=object) if named else None)
        if not all_uv:
            written = replace(written, polygon_uvs=None)
        polygons, polygon_uvs = split_ngons(vertices, polygons, polygon_uvs, ngons,
                                            lambda k: f"on line {f_numbers[k]}", label, path)
        # An n-gon's triangles after its first go after the file's faces, in n-gon order: its material too.
        f_materials += [f_materials[k] for k, corners, _ in ngons for _ in range(len(corners) - 3)]
    relative = any("-" in line for line in f_lines)
    materials = np.array(f_materials, dtype=object) if named else None
    return ObjPolygons(vertices, polygons, uvs if all_uv else None, polygon_uvs if all_uv else None,
                       tuple(f_lines), len(vt_rows), relative, materials, written, tuple(libraries))


#: A face corner without a texture coordinate, while the faces are read.
_NO_UV = -2


def _nonfinite_text(values: np.ndarray) -> str:
    return "NaN" if np.isnan(values).any() else "Inf"


def _refuse_beyond_float32(vertices: np.ndarray, line_numbers: list, what: str, label: str, path: Path) -> None:
    """InputError naming the line of the first finite coordinate past `MAX_COORDINATE` (NaN and Inf are
    `validate_garment`'s to report, naming the vertex)."""
    with np.errstate(invalid="ignore"):
        big = np.isfinite(vertices) & (np.abs(vertices) > MAX_COORDINATE)
    if big.any():
        k = int(np.argmax(big.any(axis=1)))
        value = float(vertices[k][big[k]][0])
        raise InputError(f"{label} '{path}': expected coordinates within float32's range (+-3.4e+38), got {value:g} "
                         f"in the {what} on line {line_numbers[k]}")


def split_ngons(vertices, polygons, polygon_uvs, ngons, where, label, path):
    """Polygons and polygon uvs with each n-gon's row replaced by its first triangle, the others appended.

    ngons: (face, corners (n,), corner uvs (n,)); triangles by `ear_clip` in the polygon's plane. where(face):
    how an error names the face ("on line 8"). Raises InputError for an n-gon that crosses itself or has no area.
    """
    rows, uv_rows = [polygons], [polygon_uvs]
    for k, corners, corner_uvs in ngons:
        tris = ear_clip(vertices[corners])
        if tris is None:
            raise InputError(f"{label} '{path}': cannot split the face with {len(corners)} vertices {where(k)} "
                             f"into triangles: it crosses itself or has no area")
        tri_rows = np.full((len(tris), 4), -1, dtype=np.int64)
        tri_rows[:, :3] = corners[tris]
        tri_uvs = np.full((len(tris), 4), -1, dtype=np.int64)
        tri_uvs[:, :3] = corner_uvs[tris]
        polygons[k], polygon_uvs[k] = tri_rows[0], tri_uvs[0]
        rows.append(tri_rows[1:])
        uv_rows.append(tri_uvs[1:])
    log.info("%s '%s': split %d faces of more than 4 vertices into triangles", label, path, len(ngons))
    return np.concatenate(rows), np.concatenate(uv_rows)


def ear_clip(points: np.ndarray) -> np.ndarray | None:
    """Triangles (n - 2, 3) of corner indices of a simple polygon (n, 3), in its winding, or None.

    The polygon is projected onto its plane (Newell's normal) and ears are cut from it; None when it has
    no area or two of its edges cross (or touch anywhere but at a shared corner).
    """
    p = np.asarray(points, dtype=np.float64)
    n = len(p)
    nxt = np.roll(p, -1, axis=0)
    normal = np.array([np.sum((p[:, 1] - nxt[:, 1]) * (p[:, 2] + nxt[:, 2])),
                       np.sum((p[:, 2] - nxt[:, 2]) * (p[:, 0] + nxt[:, 0])),
                       np.sum((p[:, 0] - nxt[:, 0]) * (p[:, 1] + nxt[:, 1]))])  # twice the vector area
    size = float(np.ptp(p, axis=0).max())
    if np.linalg.norm(normal) <= 1e-12 * size * size:
        return None
    drop = int(np.argmax(np.abs(normal)))
    q = p[:, [(drop + 1) % 3, (drop + 2) % 3]]  # right-handed with the dropped axis: (y, z), (z, x), (x, y)
    if normal[drop] < 0:  # counter-clockwise in the projection
        q = q[:, ::-1]
    if _edges_cross(q):
        return None

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    eps = 1e-12 * size * size
    left = list(range(n))
    tris = []
    while len(left) > 3:
        for j in range(len(left)):
            a, b, c = left[j - 1], left[j], left[(j + 1) % len(left)]
            if cross(q[a], q[b], q[c]) <= eps:
                continue  # reflex or flat corner: not an ear
            inside = [m for m in left if m not in (a, b, c) and cross(q[a], q[b], q[m]) >= -eps
                      and cross(q[b], q[c], q[m]) >= -eps and cross(q[c], q[a], q[m]) >= -eps]
            if not inside:
                tris.append((a, b, c))
                del left[j]
                break
        else:
            return None
    tris.append(tuple(left))
    return np.array(tris, dtype=np.int64)


def _edges_cross(q: np.ndarray) -> bool:
    """Whether two edges of the closed 2-D polygon q (n, 2) that share no corner meet."""
    n = len(q)
    a, b = q, np.roll(q, -1, axis=0)
    i, j = np.triu_indices(n, k=2)
    keep = ~((i == 0) & (j == n - 1))  # the first and last edges share corner 0
    i, j = i[keep], j[keep]

    def side(p, r, s):  # sign of the turn p -> r -> s
        return np.sign((r[:, 0] - p[:, 0]) * (s[:, 1] - p[:, 1]) - (r[:, 1] - p[:, 1]) * (s[:, 0] - p[:, 0]))

    d1, d2 = side(a[i], b[i], a[j]), side(a[i], b[i], b[j])
    d3, d4 = side(a[j], b[j], a[i]), side(a[j], b[j], b[i])
    return bool(np.any((d1 * d2 <= 0) & (d3 * d4 <= 0)))


def _numbers(rows: list, width: int) -> np.ndarray | None:
    """Rows of exactly `width` numbers -> (N, width) float64, or None if any row is not that."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # numpy warns, not raises, on text it cannot read
        try:
            flat = np.fromstring(" ".join(rows), dtype=np.float64, sep=" ")
        except (ValueError, DeprecationWarning):
            return None
    return flat.reshape(len(rows), width) if flat.size == width * len(rows) else None


def _parse_like(text: str, like: ObjPolygons) -> ObjPolygons | None:
    """The fast path for a file shaped like `like` (a sequence frame): only numbers are parsed.

    Returns None whenever the file is not plainly `like` with other coordinates
    (different face lines, `v` lines with w or colours, ...); the full parser then decides.
    """
    if "\\\n" in text or "\\\r" in text:
        return None  # line continuations: the full parser joins them
    lines = _physical_lines(text)
    v_rows = [line[2:] for line in lines if line.startswith(("v ", "v\t"))]
    if len(v_rows) != like.vertices.shape[0]:
        return None
    vt_rows = [line[3:] for line in lines if line.startswith(("vt ", "vt\t"))]
    f_lines = [line for line in lines if line.startswith(("f ", "f\t"))]
    if not like.same_faces(f_lines, len(v_rows), len(vt_rows)):
        return None
    vertices = _numbers(v_rows, 3)
    if vertices is None or not (np.abs(vertices) <= MAX_COORDINATE).all():
        return None  # NaN, Inf or past float32: the full parser names the line
    uvs = None
    if like.polygon_uvs is not None:
        uvs = _numbers(vt_rows, 2)
        if uvs is None:
            return None
    return ObjPolygons(vertices, like.polygons, uvs, like.polygon_uvs, like.face_lines, like.n_uv_rows, False)


def triangulate(vertices: np.ndarray, polygons: np.ndarray, polygon_uvs: np.ndarray | None = None,
                split_ac: np.ndarray | None = None):
    """Split quads into two triangles along their shorter diagonal.

    vertices: (V, 3) float. polygons: (P, 4) int64 with -1 in the last column of
    triangles. polygon_uvs: (P, 4) int64 or None. split_ac: (P,) bool, the
    diagonal choice to reuse (True = split quad abcd along a-c); None = choose
    the shorter diagonal from `vertices`.
    Returns faces (F, 3) int64, face_uvs (F, 3) int64 or None, split_ac (P,) bool.
    Triangles keep their order; each quad's two triangles follow it.
    """
    polygons = np.asarray(polygons, dtype=np.int64)
    is_quad = polygons[:, 3] >= 0
    if split_ac is None:
        split_ac = np.ones(len(polygons), dtype=bool)
        q = polygons[is_quad]
        if len(q):
            ac = np.linalg.norm(vertices[q[:, 0]] - vertices[q[:, 2]], axis=1)
            bd = np.linalg.norm(vertices[q[:, 1]] - vertices[q[:, 3]], axis=1)
            split_ac[is_quad] = ac <= bd

    def split(p: np.ndarray) -> np.ndarray:
        # quad a b c d: along a-c -> (a b c)(a c d); along b-d -> (a b d)(b c d)
        first = np.where(split_ac[:, None], p[:, [0, 1, 2]], p[:, [0, 1, 3]])
        second = np.where(split_ac[:, None], p[:, [0, 2, 3]], p[:, [1, 2, 3]])
        out = np.stack([first, second], axis=1)  # (P, 2, 3)
        keep = np.stack([np.ones(len(p), dtype=bool), is_quad], axis=1)
        return out[keep]

    faces = split(polygons)
    face_uvs = split(np.asarray(polygon_uvs, dtype=np.int64)) if polygon_uvs is not None else None
    return faces, face_uvs, split_ac


def _weld_tolerance(edge_lengths: np.ndarray) -> float:
    """The weld's distance, metres: WELD_DISTANCE_M, at most 1 % of the (finite) median edge length."""
    return min(WELD_DISTANCE_M, 0.01 * float(np.median(edge_lengths[np.isfinite(edge_lengths)])))


def _weld(vertices: np.ndarray, faces: np.ndarray, label: str, path: Path) -> tuple[np.ndarray, int]:
    """(faces with every vertex that lies within WELD_DISTANCE_M, and 1 % of the median edge, of an earlier
    used one replaced by the earliest, how many were); warns when any were. Vertices are left in place
    (`_clean` drops the unused ones and the faces that collapsed)."""
    from scipy.spatial import cKDTree

    used = np.unique(faces)
    used = used[np.isfinite(vertices[used]).all(axis=1)]  # NaN is validate_garment's to report
    if len(used) < 2:
        return faces, 0
    edges = np.linalg.norm(vertices[faces] - vertices[np.roll(faces, 1, axis=1)], axis=2)
    tol = _weld_tolerance(edges)
    pairs = cKDTree(vertices[used]).query_pairs(tol, output_type="ndarray")
    if not len(pairs):
        return faces, 0
    from core.graph import connected_components

    _, labels = connected_components(used[pairs], len(vertices))  # one cluster per position
    _, first = np.unique(labels, return_index=True)  # each cluster's smallest vertex index
    root = first[labels]
    n = int(np.sum(root[used] != used))
    what = ("the cloth written twice: a two-sided export?" if n >= 0.4 * len(used) else
            "the seams of separately exported panels")  # most of it: no seams (a skirt's 2,016 of 4,032)
    log.warning("%s '%s': welded %d vertices onto others at the same position (within %.2g mm; %s)", label, path, n,
                tol * 1e3, what)
    return root[faces], n


#: Open-edge vertices of two pieces of a garment (connected components) that are each other's nearest within this
#: (metres; and half the median edge) are one seam's, welded (`_weld_seams`): Marvelous Designer's and CLO's panels
#: exported unwelded keep their sewn seams' vertices 1-3 mm apart, baked as separate pieces whose seams gape (the
#: example skirt cut into 4 panels 1.5-2.8 mm apart: 232 mm on the walk with LBS, 100 with the model, unwarned).
SEAM_WELD_M = 0.005
#: Two pieces are layers (a cloth given thickness), not panels to sew, where more than this share of the smaller
#: one's inner vertices lie within SEAM_WELD_M plus a median edge of the other's; a piece pair of fewer than
#: SEAM_MIN_PAIRS pairs is no seam (an outfit's shirt hem crossing the trousers' waistband).
SEAM_LAYER_SHARE = 0.5
SEAM_MIN_PAIRS = 4


def _weld_seams(vertices: np.ndarray, faces: np.ndarray, label: str, path: Path
                ) -> tuple[np.ndarray, np.ndarray, int]:
    """(vertices, faces, how many were welded) with each seam pair (`SEAM_WELD_M`) of open-edge vertices of two
    pieces made one vertex, at their midpoint (faces renumbered to the earlier; the other is left unused for
    `_clean` to drop); warns naming how many and how far apart."""
    from scipy.spatial import cKDTree

    from core.garment import edge_face_counts
    from core.graph import connected_components

    if not len(faces):
        return vertices, faces, 0
    edges, counts = edge_face_counts(faces)
    _, labels = connected_components(edges, len(vertices))
    rim = np.unique(edges[counts == 1])
    rim = rim[np.isfinite(vertices[rim]).all(axis=1)]
    if len(np.unique(labels[np.unique(faces)])) < 2 or len(rim) < 2:
        return vertices, faces, 0
    lengths = np.linalg.norm(vertices[edges[:, 0]] - vertices[edges[:, 1]], axis=1)
    median = float(np.median(lengths[np.isfinite(lengths)]))
    reach = min(SEAM_WELD_M, 0.5 * median)
    tree = cKDTree(vertices[rim])
    dist, near = tree.query(vertices[rim], k=min(8, len(rim)), distance_upper_bound=reach)
    other = np.full(len(rim), -1, dtype=np.int64)  # each rim vertex's nearest rim vertex of another piece
    for k in range(dist.shape[1]):
        found = near[:, k] < len(rim)
        idx = np.where(found, near[:, k], 0)
        take = found & (other < 0) & (labels[rim[idx]] != labels[rim])
        other[take] = idx[take]
    a = np.flatnonzero(other >= 0)
    a = a[other[other[a]] == a]  # mutual nearest
    a = a[a < other[a]]
    if not len(a):
        return vertices, faces, 0
    pairs = np.stack([rim[a], rim[other[a]]], axis=1)
    pieces = np.sort(labels[pairs], axis=1)
    keys, inverse, sizes = np.unique(pieces, axis=0, return_inverse=True, return_counts=True)
    inner = np.setdiff1d(np.unique(faces), rim)
    keep = sizes >= SEAM_MIN_PAIRS
    for k, (p, q) in enumerate(keys):
        if not keep[k]:
            continue
        small, large = (p, q) if np.sum(labels[inner] == p) <= np.sum(labels[inner] == q) else (q, p)
        mine, theirs = inner[labels[inner] == small], np.flatnonzero(labels == large)
        if len(mine) and len(theirs):
            d, _ = cKDTree(vertices[theirs]).query(vertices[mine], distance_upper_bound=reach + median)
            keep[k] = np.mean(np.isfinite(d)) <= SEAM_LAYER_SHARE  # a layer over the other: no seam
    pairs = pairs[keep[inverse.ravel()]]
    if not len(pairs):
        return vertices, faces, 0
    gap = np.linalg.norm(vertices[pairs[:, 0]] - vertices[pairs[:, 1]], axis=1)
    vertices = np.array(vertices, dtype=np.float64)
    vertices[pairs[:, 0]] = (vertices[pairs[:, 0]] + vertices[pairs[:, 1]]) / 2.0
    root = np.arange(len(vertices))
    root[pairs[:, 1]] = pairs[:, 0]
    joined = len(np.unique(np.sort(labels[pairs], axis=1), axis=0))
    log.warning("%s '%s': welded %d seam vertices of separate pieces lying %.2g-%.2g mm apart, each pair at its "
                "midpoint (%d seams: panels exported unwelded, whose seams would open when baked)", label, path,
                len(pairs), gap.min() * 1e3, gap.max() * 1e3, joined)
    return vertices, root[faces], len(pairs)


#: Open-edge vertices of a garment closer than this (metres; and a quarter of its median edge) to another, not welded
#: and not its neighbour along an edge, are warned about (`_warn_open_seams`): panels exported apart, just beyond
#: the weld, are baked as separate pieces, and their seam opens (the example skirt's centre seam split 1e-5 m apart
#: plus 2e-11 gaped 19 cm on the walk with LBS, without a word).
OPEN_SEAM_M = 0.001


def _warn_open_seams(vertices: np.ndarray, faces: np.ndarray, label: str, path: Path) -> None:
    """Warn where open-edge vertices lie within OPEN_SEAM_M (and a quarter of the median edge) of others, not
    joined to them by an edge: a seam left open by a weld that just missed."""
    from scipy.spatial import cKDTree

    from core.garment import edge_face_counts

    if not len(faces):
        return
    edges, counts = edge_face_counts(faces)
    rim = np.unique(edges[counts == 1])
    rim = rim[np.isfinite(vertices[rim]).all(axis=1)]
    if len(rim) < 2:
        return
    lengths = np.linalg.norm(vertices[edges[:, 0]] - vertices[edges[:, 1]], axis=1)
    near = min(OPEN_SEAM_M, 0.25 * float(np.median(lengths[np.isfinite(lengths)])))
    pairs = rim[cKDTree(vertices[rim]).query_pairs(near, output_type="ndarray")]
    if not len(pairs):
        return
    n = np.int64(len(vertices))
    pairs = np.sort(pairs, axis=1)
    pairs = pairs[~np.isin(pairs[:, 0] * n + pairs[:, 1], edges[:, 0] * n + edges[:, 1])]  # neighbours: no seam
    if len(pairs):
        gap = np.linalg.norm(vertices[pairs[:, 0]] - vertices[pairs[:, 1]], axis=1)
        log.warning("%s '%s': %d pairs of open-edge vertices lie %.3g-%.3g mm apart, not welded (the weld takes "
                    "%.3g mm): panels exported apart? they are baked as separate pieces and their seam opens: "
                    "join them in the tool that made the garment", label, path, len(pairs), gap.min() * 1e3,
                    gap.max() * 1e3, _weld_tolerance(lengths) * 1e3)


#: A face with a corner's angle within this (radians: 0.57 degrees) of 180 degrees is degenerate (dropped): flat
#: but for rounding.
FLAT_FACE_ANGLE = 0.01


def _clean(vertices: np.ndarray, faces: np.ndarray, face_uvs: np.ndarray | None, label: str, path: Path,
           welded: int = 0):
    """Drop degenerate and duplicate faces and unused vertices, logging what went (not the `welded` ones)."""
    repeated = (faces[:, 0] == faces[:, 1]) | (faces[:, 1] == faces[:, 2]) | (faces[:, 0] == faces[:, 2])
    finite = np.isfinite(vertices).all(axis=1)
    used = np.unique(faces)
    scale = float(np.ptp(vertices[used][finite[used]], axis=0).max()) if finite[used].any() else 0.0
    tri = vertices[faces]
    area2 = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    # Zero area relative to the mesh size, or a face flat to the file's precision: a corner's angle within
    # FLAT_FACE_ANGLE of 180 degrees (three points of a line written to 6 decimals lie 1e-6 off it: such faces
    # were kept, their normals noise; a face to a stray vertex far off is thin, not flat, and stays for
    # validate_garment to name). NaN areas are left for validate_garment to report.
    with np.errstate(invalid="ignore", divide="ignore"):
        out = [tri[:, (k + 1) % 3] - tri[:, k] for k in range(3)]  # edge k leaves corner k
        cosines = [-np.einsum("fc,fc->f", out[k], out[k - 1]) / (np.linalg.norm(out[k], axis=1) *
                                                                 np.linalg.norm(out[k - 1], axis=1)) for k in range(3)]
        flat = np.min(cosines, axis=0) < -np.cos(FLAT_FACE_ANGLE)
    zero_area = ~repeated & ((area2 <= 1e-12 * scale * scale) | flat)
    keep = ~(repeated | zero_area)
    if (~keep).any():
        log.warning("%s '%s': dropped %d degenerate faces (%d with a repeated vertex, %d with zero area)",
                    label, path, int((~keep).sum()), int(repeated.sum()), int(zero_area.sum()))
    faces = faces[keep]
    face_uvs = face_uvs[keep] if face_uvs is not None else None

    if len(faces):
        _, first = np.unique(np.sort(faces, axis=1), axis=0, return_index=True)
        if len(first) < len(faces):
            log.warning("%s '%s': dropped %d duplicate faces (same vertices as an earlier face)",
                        label, path, len(faces) - len(first))
            first.sort()
            faces = faces[first]
            face_uvs = face_uvs[first] if face_uvs is not None else None

    used = np.zeros(len(vertices), dtype=bool)
    used[faces.ravel()] = True
    n_unused = int((~used).sum())
    if n_unused and len(faces):
        if n_unused > welded:
            log.warning("%s '%s': removed %d unused vertices", label, path, n_unused - welded)
        remap = np.cumsum(used) - 1
        vertices = vertices[used]
        faces = remap[faces]
    return vertices, faces, face_uvs


#: Garment files read as USD stages (`formats.usd.read_usd_garment`); every other is read as OBJ.
USD_SUFFIXES = (".usd", ".usda", ".usdc", ".usdz")
#: The USD files `formats.usd.write_usd_stage` writes: the crate (binary) format, or text for .usda.
STAGE_SUFFIXES = (".usd", ".usda", ".usdc")


#: Mesh formats that are not read, by suffix: what the refusal calls them.
OTHER_MESH_FORMATS = {".ply": "PLY", ".stl": "STL", ".fbx": "FBX", ".glb": "glTF", ".gltf": "glTF",
                      ".abc": "Alembic", ".dae": "COLLADA", ".blend": "Blender", ".zprj": "Marvelous Designer project",
                      ".zpac": "Marvelous Designer garment", ".avt": "Marvelous Designer avatar"}


@warnings_held
def read_garment(path: str | os.PathLike, scale: float = 1.0) -> Garment:
    """A garment file: a USD stage (by its suffix, `USD_SUFFIXES`) or else an OBJ (`read_obj`); its coordinates
    times `scale` (metres per unit of a file in other units: `garment unpose --scale`)."""
    suffix = Path(path).suffix.lower()
    if suffix in USD_SUFFIXES:
        from formats.usd import read_usd_garment

        return read_usd_garment(path, scale)
    if suffix in OTHER_MESH_FORMATS and Path(path).is_file():
        raise InputError(f"garment mesh '{path}': expected an OBJ or USD garment, got a {OTHER_MESH_FORMATS[suffix]} "
                         "file: export the garment as OBJ (or USD) on the body's rest pose from the tool that made it")
    if not Path(path).is_dir():  # a pipe blocks the open below (read_obj says what a folder is)
        require_input(path, f"garment mesh '{path}'")
    try:  # binary content is no OBJ: say what it is instead of finding no 'v' lines in it
        with open(path, "rb") as fh:
            head = fh.read(4096)
    except OSError:
        head = b""  # read_obj says why the file cannot be read
    if head.startswith(b"PK\x03\x04") or head.startswith(b"PK\x05\x06"):
        raise InputError(f"garment mesh '{path}': expected an OBJ or USD garment, got a NumPy .npz archive (a motion?)")
    if head.startswith(b"\x93NUMPY"):
        raise InputError(f"garment mesh '{path}': expected an OBJ or USD garment, got a NumPy .npy array")
    if head.startswith(b"PXR-USDC"):
        raise InputError(f"garment mesh '{path}': expected an OBJ or USD garment, got a binary USD (.usdc) file "
                         f"named '{Path(path).suffix or 'without a suffix'}' (name it .usd or .usdc)")
    if b"\x00" in head:
        raise InputError(f"garment mesh '{path}': expected an OBJ or USD garment, got binary content")
    return read_obj(path, scale)


def read_obj(path: str | os.PathLike, scale: float = 1.0) -> Garment:
    """Read a garment mesh from an OBJ file into a validated `Garment`.

    Triangles, quads (split along the shorter diagonal) and larger polygons (`ear_clip`); all objects,
    groups and components form one mesh; vertices at one position (the seams of panels exported
    separately) are welded into one (`WELD_DISTANCE_M`, warned). Degenerate faces (a repeated vertex or
    zero area), duplicate faces (same vertex set) and unused vertices are
    removed with a logged warning. `uvs`/`face_uvs` are set when any face has
    texture indices (the faces without are given (0, 0), warned). Normals, groups and smoothing are ignored.
    Returns Garment(vertices (V, 3) float32 metres, faces (F, 3) int64,
    uvs (U, 2) float32 | None, face_uvs (F, 3) int64 | None, name = file stem); the coordinates times `scale`
    first (a file in other units). Raises InputError (one line naming the file) for bad input; see `parse_obj`
    and `core.garment.validate_garment`.
    """
    path = Path(path)
    label = "garment mesh"
    obj = parse_obj(path, label)
    garment = garment_from_polygons(obj.vertices, obj.polygons, obj.uvs, obj.polygon_uvs, label, path, obj.materials,
                                    obj.written, scale)
    if garment.source is None or garment.source.materials is None or not obj.libraries:
        return garment
    return replace(garment, source=replace(garment.source, libraries=material_libraries(path, obj.libraries)))


def material_libraries(path: Path, statements) -> tuple[str, ...]:
    """The material library files (absolute paths) an OBJ at `path` names in its `mtllib` statements, resolved
    against its folder: the whole argument as one file name, else each of its names (several in one
    statement); a library that is not there is warned about (its materials are then written by name only)."""
    found = []
    for statement in statements:
        whole = path.parent / statement
        names = [statement] if _is_file(whole) else statement.split()
        for name in names:
            library = path.parent / name
            if _is_file(library):
                found.append(str(library.resolve()))
            else:
                log.warning("garment mesh '%s': its material library '%s' is not there; the outputs name its "
                            "materials only", path, _shown(name))
    return tuple(dict.fromkeys(found))


def _is_file(path: Path) -> bool:
    """`Path.is_file`, False for a name no file can have (too long, a NUL in it) instead of raising."""
    try:
        return path.is_file()
    except (OSError, ValueError):
        return False


def garment_from_polygons(vertices: np.ndarray, polygons: np.ndarray, uvs: np.ndarray | None,
                          polygon_uvs: np.ndarray | None, label: str, path: Path,
                          materials: np.ndarray | None = None, written: FilePolygons | None = None,
                          scale: float = 1.0) -> Garment:
    """The validated `Garment` of a file's polygons (see `ObjPolygons`), its coordinates times `scale`: quads split,
    seams welded, degenerate and duplicate faces and unused vertices and UVs dropped (each warned), named after the
    file's stem. written: the file's faces as written where it has n-gons (its source mesh keeps them), else
    None."""
    if scale != 1.0:
        with np.errstate(invalid="ignore", over="ignore"):
            vertices = np.asarray(vertices, dtype=np.float64) * scale
    file_vertices = vertices
    with np.errstate(invalid="ignore", over="ignore"):  # Inf coordinates: validate_garment names the vertex
        faces, face_uvs, _ = triangulate(vertices, polygons, polygon_uvs)
        faces, welded = _weld(vertices, faces, label, path)
        vertices, faces, seams = _weld_seams(vertices, faces, label, path)
        vertices, faces, face_uvs = _clean(vertices, faces, face_uvs, label, path, welded + seams)
        _warn_open_seams(vertices, faces, label, path)
    garment_uvs = None
    if face_uvs is not None and len(faces):
        used_uv = np.unique(face_uvs)
        uv_remap = np.full(len(uvs), -1, dtype=np.int64)
        uv_remap[used_uv] = np.arange(len(used_uv))
        garment_uvs = uvs[used_uv].astype(np.float32)
        face_uvs = uv_remap[face_uvs]
    else:
        face_uvs = None
    garment = Garment(vertices=vertices.astype(np.float32), faces=faces.astype(np.int64),
                      uvs=garment_uvs, face_uvs=face_uvs, name=path.stem)
    validate_garment(garment, source=str(path), scale=scale)
    if written is not None:
        polygons, polygon_uvs, materials = written.polygons, written.polygon_uvs, written.materials
    return replace(garment, source=source_mesh(file_vertices, polygons, uvs, polygon_uvs, garment, materials))


def source_mesh(vertices: np.ndarray, polygons: np.ndarray, uvs: np.ndarray | None,
                polygon_uvs: np.ndarray | None, garment: Garment,
                materials: np.ndarray | None = None) -> SourceMesh | None:
    """The file's mesh (`SourceMesh`) of `garment`, read from `vertices` (Vs, 3), `polygons` (P, K >= 4), their
    UVs and their materials (P,); None when it is the garment's own (triangles only, nothing welded or dropped,
    no materials named)."""
    from scipy.spatial import cKDTree

    vertices = np.asarray(vertices, dtype=np.float64)
    polygons = np.asarray(polygons, dtype=np.int64)
    same_uvs = (polygon_uvs is None) == (garment.face_uvs is None)
    if (materials is None and len(vertices) == garment.n_vertices and (polygons[:, 3:] < 0).all() and same_uvs
            and np.array_equal(polygons[:, :3], garment.faces)
            and np.array_equal(vertices.astype(np.float32), garment.vertices)):
        return None
    # Every used vertex is a garment vertex (distance 0), a welded one lies within the weld distance of its
    # own, an unused one goes with the nearest (one with NaN coordinates, which no face uses, with any).
    finite = np.isfinite(vertices).all(axis=1)
    _, vertex_of = cKDTree(np.asarray(garment.vertices, dtype=np.float64)).query(
        np.where(finite[:, None], vertices, 0.0))
    return SourceMesh(vertex_of=np.asarray(vertex_of, dtype=np.int64), polygons=polygons,
                      uvs=None if polygon_uvs is None else np.asarray(uvs, dtype=np.float32),
                      polygon_uvs=None if polygon_uvs is None else np.asarray(polygon_uvs, dtype=np.int64),
                      materials=materials)


def obj_vertex_text(vertices: np.ndarray) -> str:
    """`v x y z` lines (6 decimals) for vertices (V, 3) float, one string formatting in C."""
    v = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    return ("v %.6f %.6f %.6f\n" * len(v)) % tuple(v.ravel().tolist())


def obj_face_text(faces: np.ndarray, uvs: np.ndarray | None = None, face_uvs: np.ndarray | None = None,
                  materials: np.ndarray | None = None) -> str:
    """`vt` and `f` lines for faces (F, 3) int 0-based; with uvs (U, 2) and face_uvs (F, 3), `f a/b` forms.
    Faces (F, K >= 4), -1 after each face's last corner (`SourceMesh.polygons`), write each polygon whole, and
    `materials` (F,) names, a `usemtl` line where the name changes."""
    if (uvs is None) != (face_uvs is None):
        raise ValueError("uvs and face_uvs must be given together")
    if materials is not None or (np.asarray(faces).ndim == 2 and np.asarray(faces).shape[1] >= 4):
        faces = np.asarray(faces, dtype=np.int64)
        if faces.shape[1] == 3:  # triangles as polygons: -1 in the fourth column
            faces = np.pad(faces, ((0, 0), (0, 1)), constant_values=-1)
            face_uvs = None if face_uvs is None else np.pad(np.asarray(face_uvs, dtype=np.int64), ((0, 0), (0, 1)),
                                                           constant_values=-1)
        return _polygon_text(faces, uvs, face_uvs, materials)
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3) + 1
    if uvs is None:
        return ("f %d %d %d\n" * len(f)) % tuple(f.ravel().tolist())
    ft = np.asarray(face_uvs, dtype=np.int64).reshape(-1, 3) + 1
    if ft.shape != f.shape:
        raise ValueError(f"face_uvs {ft.shape} must match faces {f.shape}")
    inter = np.stack([f, ft], axis=2).reshape(len(f), 6)
    return _vt_text(uvs) + ("f %d/%d %d/%d %d/%d\n" * len(f)) % tuple(inter.ravel().tolist())


def _vt_text(uvs: np.ndarray) -> str:
    """`vt u v` lines for uvs (U, 2) float (6 decimals)."""
    t = np.asarray(uvs, dtype=np.float64).reshape(-1, 2)
    return ("vt %.6f %.6f\n" * len(t)) % tuple(t.ravel().tolist())


def _polygon_text(polygons: np.ndarray, uvs: np.ndarray | None, polygon_uvs: np.ndarray | None,
                  materials: np.ndarray | None = None) -> str:
    """`vt` and `f` lines of (P, K) polygons, -1 after each one's last corner (and their (P, K) UV indices),
    a `usemtl` line before each run of polygons of one material (`materials` (P,) or None; "" none)."""
    corners = [row[row >= 0] + 1 for row in polygons]
    if uvs is None:
        lines = ["f " + " ".join(map(str, c.tolist())) + "\n" for c in corners]
        head = ""
    else:
        uv_corners = [row[row >= 0] + 1 for row in np.asarray(polygon_uvs, dtype=np.int64)]
        lines = ["f " + " ".join(f"{a}/{b}" for a, b in zip(c.tolist(), u.tolist())) + "\n"
                 for c, u in zip(corners, uv_corners)]
        head = _vt_text(uvs)
    if materials is not None:
        current = ""
        for i, name in enumerate(materials.tolist()):
            if name != current:  # a bare `usemtl` where faces of no material follow named ones (read back as none)
                lines[i] = (f"usemtl {name}\n" if name else "usemtl\n") + lines[i]
                current = name
    return head + "".join(lines)


def _header_text(header: str | None) -> str:
    if not header:
        return ""
    return "".join(f"# {line}\n" for line in str(header).splitlines())


def mtllib_text(libraries) -> str:
    """The `mtllib` lines naming material library files (relative to the OBJ), one a line so that a name with
    spaces reads as one file (`material_libraries`), or "" for none."""
    return "".join(f"mtllib {name}\n" for name in libraries)


def write_obj(path: str | os.PathLike, vertices: np.ndarray, faces: np.ndarray,
              uvs: np.ndarray | None = None, face_uvs: np.ndarray | None = None,
              header: str | None = None, materials: np.ndarray | None = None, libraries=()) -> None:
    """Write a triangle mesh as OBJ.

    vertices: (V, 3) float, metres (written with 6 decimals); faces: (F, 3) int,
    0-based; uvs: (U, 2) float and face_uvs: (F, 3) int 0-based, both or neither
    (then `vt` lines and `f a/b` faces are written); header: text written as
    `#` comment lines at the top; materials: (F,) names, written as `usemtl` lines (faces (F, K): polygons, as
    `obj_face_text`); libraries: material library file names for an `mtllib` line.
    """
    text = (_header_text(header) + mtllib_text(libraries) + obj_vertex_text(vertices)
            + obj_face_text(faces, uvs, face_uvs, materials))
    Path(path).write_bytes(text.encode("utf-8"))
