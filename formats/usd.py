"""USD stages of baked animation: time-sampled meshes a DCC tool or usdview can play.

`write_usd_stage` writes one `UsdGeom.Mesh` per `MeshTrack` (garment, body, ...)
under `/Root`, with points and extent sampled at integer time codes (one per
frame), `timeCodesPerSecond = framesPerSecond = fps`, and the stage metadata
the design fixes (`upAxis = Z`, `metersPerUnit = 1`). `read_usd` reads such a
stage (or any stage of triangle/polygon meshes) back into arrays.
"""

from __future__ import annotations

import json
import logging
import os
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from pxr import Gf, Sdf, Tf, Usd, UsdGeom, UsdShade, Vt

from core.errors import InputError, content_kind, counted, require_input
from core.geometry import Y_UP_TO_Z_UP_MATRIX
from formats.atomic import atomic_file, low_space_note
from formats.obj import STAGE_SUFFIXES

log = logging.getLogger(__name__)

ROOT = "/Root"


@dataclass(frozen=True, eq=False)
class MeshTrack:
    """One animated mesh of a stage.

    name: prim name (sanitised on write). points: (T, V, 3) float32, metres.
    faces: (F, 3) int64, 0-based, or (F, K) polygons of 3 to K corners, -1 after each one's last.
    uvs: (corners, 2) float32, face-varying texture coordinates in face-corner order (F*3 for triangles), or
    None. color: (3,) float RGB in [0, 1] or None. groups: {material name: face indices}, written as
    GeomSubsets of the "materialBind" family (to bind a shader to each), or None. looks: {material name:
    `formats.mtl.MtlMaterial`}: a group whose material is here gets a UsdPreviewSurface of its colour, opacity
    and diffuse texture (read through `st`), bound to its subset.
    """

    name: str
    points: np.ndarray
    faces: np.ndarray
    uvs: np.ndarray | None = None
    color: np.ndarray | None = None
    groups: dict | None = None
    looks: dict | None = None


@dataclass(frozen=True, eq=False)
class UsdSequence:
    """A stage read back: tracks by prim name, frames per second, first frame, custom layer data."""

    tracks: dict
    fps: float
    start_frame: int
    metadata: dict = field(default_factory=dict)


def _prim_names(names: list[str]) -> list[str]:
    """Valid, unique prim names for the given track names."""
    out, seen = [], set()
    for name in names:
        base = Tf.MakeValidIdentifier(str(name)) or "mesh"
        cand, k = base, 1
        while cand in seen:
            cand, k = f"{base}_{k}", k + 1
        seen.add(cand)
        out.append(cand)
    return out


def _to_vt(value):
    """A JSON-like value -> something customLayerData can hold (None values are dropped)."""
    if isinstance(value, dict):
        return {str(k): _to_vt(v) for k, v in value.items() if v is not None}
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value)
    if isinstance(value, (str, Path)):
        return str(value)
    if isinstance(value, (list, tuple, np.ndarray)):
        items = list(np.asarray(value).tolist()) if isinstance(value, np.ndarray) else list(value)
        if all(isinstance(v, str) for v in items):
            return Vt.StringArray(items)
        if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in items):
            return Vt.DoubleArray([float(v) for v in items])
    return json.dumps(value, default=str)


def _from_vt(value):
    if isinstance(value, dict):
        return {k: _from_vt(v) for k, v in value.items()}
    if isinstance(value, (Vt.StringArray, Vt.DoubleArray, Vt.FloatArray, Vt.IntArray)):
        return list(value)
    return value


def _check_track(track: MeshTrack, n_frames: int | None) -> None:
    p, f = np.asarray(track.points), np.asarray(track.faces)
    if p.ndim != 3 or p.shape[2] != 3 or p.shape[0] == 0:
        raise InputError(f"USD track '{track.name}': expected points (T, V, 3) with T >= 1, got {p.shape}")
    if n_frames is not None and p.shape[0] != n_frames:
        raise InputError(f"USD track '{track.name}': expected {n_frames} frames like the first track, "
                         f"got {p.shape[0]}")
    if f.ndim != 2 or f.shape[1] < 3 or (f[:, :3] < 0).any() or (np.diff((f < 0).astype(np.int8), axis=1) < 0).any():
        raise InputError(f"USD track '{track.name}': expected faces (F, 3), or (F, K > 3) with -1 after each "
                         f"face's last corner, got {f.shape}")
    corners = f[f >= 0]
    if corners.size and corners.max() >= p.shape[1]:
        raise InputError(f"USD track '{track.name}': face index {int(corners.max())} out of range for "
                         f"{p.shape[1]} points")
    if track.uvs is not None and np.asarray(track.uvs).shape != (corners.size, 2):
        raise InputError(f"USD track '{track.name}': expected uvs ({corners.size}, 2) face-varying, "
                         f"got {np.asarray(track.uvs).shape}")


def garment_track(garment, written: tuple, name: str = "garment", color=(0.80, 0.33, 0.25)) -> MeshTrack:
    """`garment` (a `core.garment.Garment`) as its file has it: `written` = `garment.written(points)` (its point
    numbering, polygons, UVs), the UV seams as a face-varying `st`, material subsets and their looks from its
    material libraries."""
    from formats.mtl import read_libraries

    points, faces, uvs, face_uvs, _ = written
    face_uv = None
    if uvs is not None and face_uvs is not None:
        face_uv = uvs[face_uvs[faces >= 0]].reshape(-1, 2)  # face-varying, in corner order
    source = garment.source
    return MeshTrack(name, points, faces, uvs=face_uv, color=color,
                     groups=None if source is None else source.material_groups(),
                     looks=read_libraries(() if source is None else source.libraries)
                     or (None if source is None else source.looks))


def write_usd_stage(path: str | os.PathLike, meshes: list[MeshTrack], fps: float, start_frame: int = 0,
                    up_axis: str = "Z", meters_per_unit: float = 1.0, metadata: dict | None = None) -> None:
    """Write time-sampled meshes to a USD stage.

    meshes: tracks sharing T frames; each becomes /Root/<name> with points and
    extent sampled at time codes start_frame .. start_frame + T - 1, its
    polygons (triangles, quads, n-gons), subdivisionScheme "none", doubleSided, a face-varying `st`
    primvar when `uvs` is given and a constant displayColor when `color` is.
    fps: frames per second (> 0), stored as timeCodesPerSecond and
    framesPerSecond. up_axis: "Y" or "Z"; meters_per_unit: length of one stage
    unit in metres. metadata: JSON-like dict stored as the root layer's
    customLayerData. `.usd`/`.usdc` write the binary crate format, `.usda` text.
    The file is written beside `path` and renamed into place, so a failed write
    leaves no partial stage.
    """
    path = Path(path)
    if path.suffix.lower() not in STAGE_SUFFIXES:
        raise InputError(f"USD stage '{path}': expected a .usd, .usda or .usdc file name, got '{path.suffix}'")
    if not meshes:
        raise InputError(f"USD stage '{path}': expected at least one mesh track, got none")
    if not (np.isfinite(fps) and fps > 0):
        raise InputError(f"USD stage '{path}': expected fps > 0, got {fps}")
    if up_axis not in ("Y", "Z"):
        raise InputError(f"USD stage '{path}': expected up_axis 'Y' or 'Z', got {up_axis!r}")
    n_frames = None
    for track in meshes:
        _check_track(track, n_frames)
        n_frames = np.asarray(track.points).shape[0]
    start_frame = int(start_frame)

    stage = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z if up_axis == "Z" else UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, float(meters_per_unit))
    stage.SetTimeCodesPerSecond(float(fps))
    stage.SetFramesPerSecond(float(fps))
    stage.SetStartTimeCode(start_frame)
    stage.SetEndTimeCode(start_frame + n_frames - 1)
    root = UsdGeom.Xform.Define(stage, ROOT)
    stage.SetDefaultPrim(root.GetPrim())
    if metadata:
        stage.GetRootLayer().customLayerData = _to_vt(dict(metadata))

    looks_made = set()  # /Root/Looks/<material>: named as the file names it (the mesh's name first on a clash)
    for track, prim_name in zip(meshes, _prim_names([m.name for m in meshes])):
        points = np.ascontiguousarray(track.points, dtype=np.float32)
        faces = np.asarray(track.faces, dtype=np.int32)
        mesh = UsdGeom.Mesh.Define(stage, f"{ROOT}/{prim_name}")
        mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
        mesh.CreateDoubleSidedAttr(True)
        mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.ascontiguousarray((faces >= 0).sum(axis=1),
                                                                                   dtype=np.int32)))
        mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(np.ascontiguousarray(faces[faces >= 0])))
        points_attr = mesh.CreatePointsAttr()
        extent_attr = mesh.CreateExtentAttr()
        lo, hi = points.min(axis=1), points.max(axis=1)  # (T, 3) each
        for t in range(n_frames):
            code = Usd.TimeCode(start_frame + t)
            points_attr.Set(Vt.Vec3fArray.FromNumpy(points[t]), code)
            extent_attr.Set(Vt.Vec3fArray([Gf.Vec3f(*lo[t].tolist()), Gf.Vec3f(*hi[t].tolist())]), code)
        if track.uvs is not None:
            st = UsdGeom.PrimvarsAPI(mesh).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray,
                                                         UsdGeom.Tokens.faceVarying)
            st.Set(Vt.Vec2fArray.FromNumpy(np.ascontiguousarray(track.uvs, dtype=np.float32)))
        for (group, faces_of), subset_name in zip((track.groups or {}).items(),
                                                  _prim_names([g or "unnamed" for g in (track.groups or {})])):
            subset = UsdGeom.Subset.CreateGeomSubset(mesh, subset_name, UsdGeom.Tokens.face,
                                                     Vt.IntArray.FromNumpy(np.asarray(faces_of, dtype=np.int32)),
                                                     UsdShade.Tokens.materialBind, UsdGeom.Tokens.nonOverlapping)
            look = (track.looks or {}).get(group)
            if look is not None:
                look_name = subset_name if subset_name not in looks_made else f"{prim_name}_{subset_name}"
                looks_made.add(look_name)
                material = _preview_material(stage, f"{ROOT}/Looks/{look_name}", look, path.parent,
                                             textured=track.uvs is not None)
                UsdShade.MaterialBindingAPI.Apply(subset.GetPrim()).Bind(material)
        if track.color is not None:
            color = np.asarray(track.color, dtype=np.float64).reshape(3)
            mesh.CreateDisplayColorPrimvar(UsdGeom.Tokens.constant).Set(
                Vt.Vec3fArray([Gf.Vec3f(*color.tolist())]))

    with atomic_file(path) as tmp:
        try:
            ok = stage.GetRootLayer().Export(str(tmp))
        except Tf.ErrorException as exc:
            raise InputError(f"USD stage '{path}': could not be written ({' '.join(str(exc).split())[-200:]}"
                             f"{low_space_note(path)})") from None
        if not ok:
            note = low_space_note(path)
            raise InputError(f"USD stage '{path}': could not be written" + (f" ({note[2:]})" if note else ""))
    # A layer of the same path still open in this process would otherwise keep the old content.
    layer = Sdf.Layer.Find(str(path))
    if layer:
        layer.Reload(True)


def _preview_material(stage: Usd.Stage, where: str, look, folder: Path, textured: bool) -> UsdShade.Material:
    """A UsdPreviewSurface material at `where` of an OBJ material (`formats.mtl.MtlMaterial`): its diffuse colour
    (grey without one), its opacity, and its diffuse texture when it exists and the mesh has `st` (`textured`),
    by a path relative to `folder` (the stage's), as usdview, Houdini and Blender read it."""
    material = UsdShade.Material.Define(stage, where)
    surface = UsdShade.Shader.Define(stage, f"{where}/PreviewSurface")
    surface.CreateIdAttr("UsdPreviewSurface")
    surface.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(0.9)  # cloth: matte
    diffuse = surface.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f)
    diffuse.Set(Gf.Vec3f(*(look.diffuse if look.diffuse is not None else (0.8, 0.8, 0.8))))
    if look.opacity is not None:
        surface.CreateInput("opacity", Sdf.ValueTypeNames.Float).Set(float(look.opacity))
    material.CreateSurfaceOutput().ConnectToSource(surface.ConnectableAPI(), "surface")
    texture_path = look.diffuse_texture
    if textured and texture_path is not None and Path(texture_path).is_file():
        reader = UsdShade.Shader.Define(stage, f"{where}/stReader")
        reader.CreateIdAttr("UsdPrimvarReader_float2")
        reader.CreateInput("varname", Sdf.ValueTypeNames.String).Set("st")
        texture = UsdShade.Shader.Define(stage, f"{where}/DiffuseTexture")
        texture.CreateIdAttr("UsdUVTexture")
        relative = os.path.relpath(Path(texture_path).resolve(), folder.resolve()).replace(os.sep, "/")
        texture.CreateInput("file", Sdf.ValueTypeNames.Asset).Set(Sdf.AssetPath(relative))
        texture.CreateInput("st", Sdf.ValueTypeNames.Float2).ConnectToSource(
            reader.ConnectableAPI(), "result")
        texture.CreateOutput("rgb", Sdf.ValueTypeNames.Float3)
        diffuse.ConnectToSource(texture.ConnectableAPI(), "rgb")
    return material


def _polygon_starts(counts: np.ndarray) -> np.ndarray:
    """(P,) int64: where each polygon's corners begin in the face vertex indices, for (P,) corner `counts`."""
    return np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64) if len(counts) else np.zeros(0, np.int64)


def _counter_clockwise(mesh: UsdGeom.Mesh, counts: np.ndarray, code: Usd.TimeCode) -> np.ndarray | None:
    """None where `mesh`'s faces wind counter-clockwise seen from their front once placed (orientation
    rightHanded, as OBJ and this tool's outputs, under a transform that does not mirror), else the order of the face
    vertex arrays that makes them: each face's corners after its first reversed (the fan's diagonals kept).
    Houdini writes its meshes leftHanded; a mirroring transform (a scale of -1) turns the winding as well."""
    left = mesh.GetOrientationAttr().Get() == UsdGeom.Tokens.leftHanded
    m = np.array(UsdGeom.Xformable(mesh.GetPrim()).ComputeLocalToWorldTransform(code), dtype=np.float64)
    if left == (np.linalg.det(m[:3, :3]) < 0) or not len(counts):
        return None
    starts = _polygon_starts(counts)
    face = np.repeat(np.arange(len(counts)), counts)
    local = np.arange(int(counts.sum())) - starts[face]
    return starts[face] + np.where(local == 0, 0, counts[face] - local)


def _placed(points: np.ndarray, prim: Usd.Prim, code: Usd.TimeCode, to_frame: np.ndarray | None) -> np.ndarray:
    """(V, 3) `points` of `prim` at `code` placed by its local-to-world transform and then by `to_frame` (4, 4)
    for row vectors (the stage's units and up axis into ours; None: none); float64, or `points` itself when
    nothing moves them."""
    m = np.array(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(code), dtype=np.float64)  # p' = [p, 1] M
    if to_frame is not None:
        m = m @ to_frame
    if np.allclose(m, np.eye(4)):
        return points
    return np.asarray(points, dtype=np.float64) @ m[:3, :3] + m[3, :3]


def _triangles(counts: np.ndarray, indices: np.ndarray, points: np.ndarray | None = None):
    """Triangulate polygons: a fan, and polygons of more than 4 corners by `formats.obj.ear_clip` in their
    plane at `points` (V, 3) when given (a concave one's fan would leave it). Returns faces (F, 3) int64 and
    the (F, 3) face-corner ids they use."""
    faces, corners = _fan(counts, indices)
    big = np.flatnonzero(counts > 4)
    if points is not None and len(big):
        from formats.obj import ear_clip

        starts, first = _polygon_starts(counts), _polygon_starts(np.maximum(counts - 2, 0))
        for k in big:  # ear clipping makes n - 2 triangles, as the fan: they take the fan's rows
            local = ear_clip(points[indices[starts[k]:starts[k] + counts[k]]])
            if local is not None:
                rows = slice(first[k], first[k] + counts[k] - 2)
                corners[rows] = starts[k] + local
                faces[rows] = indices[corners[rows]]
    return faces, corners


def _fan(counts: np.ndarray, indices: np.ndarray):
    """Fan-triangulate polygons. Returns faces (F, 3) int64 and the (F, 3) face-corner ids they use."""
    counts = counts.astype(np.int64)
    if counts.size and (counts == 3).all():
        corners = np.arange(len(indices), dtype=np.int64).reshape(-1, 3)
        return indices.reshape(-1, 3).astype(np.int64), corners
    starts = _polygon_starts(counts)
    n_tri = np.maximum(counts - 2, 0)
    poly = np.repeat(np.arange(len(counts)), n_tri)
    k = np.arange(n_tri.sum()) - np.repeat(np.cumsum(n_tri) - n_tri, n_tri)  # 0..n-3 within a polygon
    s = starts[poly]
    corners = np.stack([s, s + k + 1, s + k + 2], axis=1)
    return indices[corners].astype(np.int64), corners


def _read_mesh(mesh: UsdGeom.Mesh, name: str, where: str, to_world: np.ndarray | None = None) -> MeshTrack:
    """The mesh's points at every time sample, placed by its transforms (each sample's local-to-world matrix)
    and then by `to_world` (4, 4), the stage's units and up axis into metres Z-up (None: as they are)."""
    points_attr = mesh.GetPointsAttr()
    times = points_attr.GetTimeSamples()
    codes = [Usd.TimeCode(t) for t in times] if times else [Usd.TimeCode.Default()]
    frames = [points_attr.Get(code) for code in codes]
    if not frames or frames[0] is None:
        raise InputError(f"{where}: mesh '{name}' has no points")
    sizes = {len(f) for f in frames}
    if len(sizes) != 1:
        raise InputError(f"{where}: mesh '{name}' expected the same point count at every time sample, "
                         f"got {sorted(sizes)}")
    points = np.stack([np.asarray(f, dtype=np.float32) for f in frames]).reshape(len(frames), -1, 3)
    for k, code in enumerate(codes):
        points[k] = _placed(points[k], mesh.GetPrim(), code, to_world)
    counts = np.asarray(mesh.GetFaceVertexCountsAttr().Get() or [], dtype=np.int64)
    indices = np.asarray(mesh.GetFaceVertexIndicesAttr().Get() or [], dtype=np.int64)
    if counts.sum() != len(indices):
        raise InputError(f"{where}: mesh '{name}' expected {int(counts.sum())} face vertex indices, "
                         f"got {len(indices)}")
    order = _counter_clockwise(mesh, counts, codes[0])
    if order is not None:
        indices = indices[order]
    faces, corners = _triangles(counts, indices, points[0])
    if faces.size and (faces.min() < 0 or faces.max() >= points.shape[1]):
        raise InputError(f"{where}: mesh '{name}' face index {int(faces.max())} out of range for "
                         f"{points.shape[1]} points")
    uvs = None
    st = UsdGeom.PrimvarsAPI(mesh).GetPrimvar("st")
    if st and st.HasValue() and st.GetInterpolation() == UsdGeom.Tokens.faceVarying:
        flat = st.ComputeFlattened()
        if flat is not None and len(flat) == len(indices):
            corner = corners.ravel() if order is None else order[corners.ravel()]
            uvs = np.asarray(flat, dtype=np.float32).reshape(-1, 2)[corner]
    color = None
    dc = mesh.GetDisplayColorPrimvar()
    if dc and dc.HasValue():
        value = dc.Get()
        if value is not None and len(value):
            color = np.asarray(value[0], dtype=np.float32)
    return MeshTrack(name=name, points=points, faces=faces, uvs=uvs, color=color)


#: Y-up to Z-up for row vectors (4 x 4), (x, y, z) -> (x, -z, y); its transpose turns Z-up to Y-up.
_Y_TO_Z = np.eye(4)
_Y_TO_Z[:3, :3] = Y_UP_TO_Z_UP_MATRIX.T


def open_stage(path: Path, where: str) -> Usd.Stage:
    if path.is_dir():
        raise InputError(f"{where}: expected a USD file, got a directory")
    require_input(path, where)
    try:
        stage = Usd.Stage.Open(str(path))
    except Tf.ErrorException as exc:
        try:
            detail = " ".join(str(exc).split())
        except UnicodeDecodeError:  # pxr quotes the offending bytes
            raise InputError(f"{where}: cannot be opened as USD (its text is not UTF-8)") from None
        # pxr prefixes each reason with the C++ function and source line: keep the first reason that says more
        # than "Failed to open layer" (a text file's parse error names its line and column).
        reasons = [part.rsplit(" : '", 1)[1].strip().rstrip("'").strip() for part in detail.split("Error in '")
                   if " : '" in part] or [detail]
        detail = next((r for r in reasons if not r.startswith("Failed to open layer")), reasons[-1])
        for name in (str(path.resolve()), os.path.abspath(path), str(path)):  # pxr's own path: resolved or not
            if detail.startswith(f"{name}:"):
                detail = "line " + detail[len(name) + 1:]
                break
        detail = detail[:200]
        raise InputError(f"{where}: cannot be opened as USD ({_not_usd(path) or detail})") from None
    if stage is None:
        raise InputError(f"{where}: cannot be opened as USD ({_not_usd(path) or 'no reason given'})")
    return stage


#: The first bytes of USD's three file forms: text, binary crate, usdz package (a zip).
USD_MAGIC = (b"#usda", b"PXR-USDC", b"PK\x03\x04")


def _not_usd(path: Path) -> str | None:
    """What the file `path` holds where it is none of USD's forms by its first bytes ("expected ..., got an empty
    file", "got text ('v 0 0 0'...)"), else None (a USD file that pxr could not read: its own reason tells why)."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(16)
    except OSError:
        return None
    if head.startswith(USD_MAGIC):
        return None
    if head.startswith(b"\xef\xbb\xbf#usda"):
        return "got text with a UTF-8 byte-order mark before '#usda', which USD does not read: save it without one"
    got = content_kind(path) or f"binary data starting {head[:8]!r}"
    return f"expected text starting '#usda', a binary crate 'PXR-USDC' or a usdz package, got {got}"


def _stage_to(stage: Usd.Stage, up: str) -> np.ndarray:
    """(4, 4) for row vectors: the stage's units to metres and its up axis to `up` ("Y" or "Z").

    Only authored metadata counts: USD's fallbacks (centimetres, Y-up) would turn a stage written without
    them, as simple exporters write, into something it did not mean; unauthored, a stage is metres in `up`.
    """
    unit = UsdGeom.GetStageMetersPerUnit(stage) if stage.HasAuthoredMetadata("metersPerUnit") else 1.0
    m = np.diag([unit] * 3 + [1.0])
    if stage.HasAuthoredMetadata("upAxis"):
        axis = "Y" if UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.y else "Z"
        if axis != up:
            m = m @ (_Y_TO_Z if up == "Z" else _Y_TO_Z.T)
    return m


def read_usd_garment(path: str | os.PathLike, scale: float = 1.0):
    """A garment from a USD stage: its mesh named 'garment' (as a bake's stage has), else all its meshes as one
    (the panels Marvelous Designer's "unweld" export writes each as a mesh: a warning names them), each at its
    static value or else its first time sample, placed by its transforms, in the body's rest frame (metres,
    Y-up: a stage that authors Z-up is turned, other units scaled; then times `scale`). Quads and larger polygons
    split, seams welded and the result cleaned as `formats.obj.read_obj` does; `st` (face-varying or per vertex)
    kept where every mesh has it.
    Raises InputError naming the file.
    """
    from formats.obj import file_polygons, garment_from_polygons, split_ngons

    path = Path(path)
    label = "garment mesh"
    where = f"{label} '{path}'"
    stage = open_stage(path, where)
    meshes = [UsdGeom.Mesh(p) for p in stage.Traverse() if p.IsA(UsdGeom.Mesh)]
    named = [m for m in meshes if m.GetPrim().GetName() == "garment"]
    if not meshes:
        raise InputError(f"{where}: expected a mesh (or one named 'garment'), got none")
    if len(named) == 1:
        meshes = named
    parts = [_garment_part(mesh, stage, where if len(meshes) == 1 else f"{where} (mesh '{mesh.GetPath()}')")
             for mesh in meshes]
    if len(parts) > 1:  # each with its size: a ground plane or a prop among them shows
        names = ", ".join(f"{p['path']} of {counted(len(p['vertices']), 'point')}" for p in parts[:6])
        log.warning("%s: %d meshes (%s%s), none named 'garment': read as one garment, their seams welded where "
                    "they meet (name the garment's mesh 'garment' to read it alone)", where, len(parts), names,
                    ", ..." if len(parts) > 6 else "")
        _refuse_stray_part(parts, where)
    vertices, counts, indices, uvs, uv_index, materials, bound = _joined_parts(parts, where)
    starts = _polygon_starts(counts)
    polygons = np.full((len(counts), 4), -1, dtype=np.int64)
    polygon_uvs = np.full((len(counts), 4), -1, dtype=np.int64)
    ngons = []
    for k, (start, n) in enumerate(zip(starts.tolist(), counts.tolist())):
        corners = indices[start:start + n]
        corner_uvs = uv_index[start:start + n] if uv_index is not None else np.full(n, -1, dtype=np.int64)
        if n <= 4:
            polygons[k, :n], polygon_uvs[k, :n] = corners, corner_uvs
        else:
            ngons.append((k, corners, corner_uvs))
    # The faces as written (n-gons whole) with their materials: what the outputs keep.
    written = file_polygons(polygons, polygon_uvs, ngons, materials)
    if uvs is None:
        written = replace(written, polygon_uvs=None)
    if ngons:
        polygons, polygon_uvs = split_ngons(vertices, polygons, polygon_uvs, ngons, lambda k: f"(face {k})",
                                            label, path)
    garment = garment_from_polygons(vertices, polygons, uvs, polygon_uvs if uvs is not None else None, label, path,
                                    written=written, scale=scale)
    looks = {name: look for name, material in bound.items() if (look := _preview_look(material, name, path))}
    if looks and garment.source is not None:  # their colours and textures, for the outputs' materials
        garment = replace(garment, source=replace(garment.source, looks=looks))
    return garment


def _garment_part(mesh: UsdGeom.Mesh, stage: Usd.Stage, where: str) -> dict:
    """One mesh of a garment stage (`read_usd_garment`): its points placed in the body's rest frame ("vertices"),
    "counts" and "indices" of its faces (counter-clockwise), "uvs" and their "uv_index" per face corner (None
    where it has no `st` that fits), each face's "materials" (None: none bound) and the "bound" materials."""
    from formats.obj import MAX_POLYGON_VERTICES

    points_attr = mesh.GetPointsAttr()
    times = points_attr.GetTimeSamples()
    code = Usd.TimeCode.Default() if points_attr.Get(Usd.TimeCode.Default()) is not None or not times \
        else Usd.TimeCode(times[0])
    value = points_attr.Get(code)
    if value is None or len(value) == 0:
        raise InputError(f"{where}: mesh '{mesh.GetPath()}' has no points")
    vertices = _placed(np.asarray(value, dtype=np.float64).reshape(-1, 3), mesh.GetPrim(), code,
                       _stage_to(stage, "Y"))
    counts = np.asarray(mesh.GetFaceVertexCountsAttr().Get() or [], dtype=np.int64)
    indices = np.asarray(mesh.GetFaceVertexIndicesAttr().Get() or [], dtype=np.int64)
    if counts.sum() != len(indices):
        raise InputError(f"{where}: expected {int(counts.sum())} face vertex indices, got {len(indices)}")
    if len(indices) and (indices.min() < 0 or indices.max() >= len(vertices)):
        raise InputError(f"{where}: face vertex index {int(indices.max())} out of range for {len(vertices)} points")
    bad = (counts < 3) | (counts > MAX_POLYGON_VERTICES)
    if bad.any():
        raise InputError(f"{where}: expected faces of 3 to {MAX_POLYGON_VERTICES} vertices, got a face with "
                         f"{int(counts[np.argmax(bad)])} vertices (face {int(np.argmax(bad))})")
    order = _counter_clockwise(mesh, counts, code)
    if order is not None:
        indices = indices[order]
    uvs, uv_index = None, None
    st = _uv_primvar(mesh, where)
    if st is not None:
        flat = st.ComputeFlattened(code)
        if flat is not None and st.GetInterpolation() == UsdGeom.Tokens.faceVarying and len(flat) == len(indices):
            uvs = np.asarray(flat, dtype=np.float64).reshape(-1, 2)
            uv_index = np.arange(len(indices)) if order is None else order
        elif flat is not None and st.GetInterpolation() in (UsdGeom.Tokens.vertex, UsdGeom.Tokens.varying) \
                and len(flat) == len(vertices):
            uvs, uv_index = np.asarray(flat, dtype=np.float64).reshape(-1, 2), indices
        else:
            log.warning("%s: its UVs '%s' (%s, %d values for %d points and %d face corners) fit neither its points "
                        "nor its face corners: left out of the outputs", where, st.GetPrimvarName(),
                        st.GetInterpolation(), 0 if flat is None else len(flat), len(vertices), len(indices))
    materials, bound = _face_materials(mesh, len(counts))
    return {"vertices": vertices, "counts": counts, "indices": indices, "uvs": uvs, "uv_index": uv_index,
            "materials": materials, "bound": bound, "path": str(mesh.GetPath())}


def _refuse_stray_part(parts: list[dict], where: str) -> None:
    """InputError naming the mesh where a whole `_garment_part` of several lies far from the others
    (`core.garment.stray_points`: a 20 m ground plane was refused as "stray vertices a tool left")."""
    from core.garment import stray_points

    used = [p["vertices"][np.unique(p["indices"])] for p in parts]
    found = stray_points(np.concatenate(used))
    if found is None:
        return
    stray, distance = found
    ends = np.cumsum([len(u) for u in used])
    for part, u, end in zip(parts, used, ends):
        start = end - len(u)
        if stray[start:end].all():
            points = counted(end - start, "point")
            raise InputError(f"{where}: expected one garment, got mesh '{part['path']}' ({points}) far from the "
                             f"others ({distance[start:end].max():.3g} units from their middle; the others within "
                             f"{distance[~stray].max():.3g}): a ground plane or a prop? name the garment's mesh "
                             f"'garment' to read it alone, or remove that mesh")


def _joined_parts(parts: list[dict], where: str) -> tuple:
    """The `_garment_part`s of a stage as one mesh: (vertices, counts, indices, uvs, uv_index, materials, bound),
    each part's indices after the points before it; UVs only where every part has them (else left out, with a
    warning naming a part without), materials "" on a part of none."""
    if len(parts) == 1:
        p = parts[0]
        return p["vertices"], p["counts"], p["indices"], p["uvs"], p["uv_index"], p["materials"], p["bound"]
    offsets = np.cumsum([0] + [len(p["vertices"]) for p in parts])
    indices = np.concatenate([p["indices"] + o for p, o in zip(parts, offsets)])
    uvs = uv_index = None
    bare = [p["path"] for p in parts if p["uvs"] is None]
    if not bare:
        uv_offsets = np.cumsum([0] + [len(p["uvs"]) for p in parts])
        uvs = np.concatenate([p["uvs"] for p in parts])
        uv_index = np.concatenate([p["uv_index"] + o for p, o in zip(parts, uv_offsets)])
    elif len(bare) < len(parts):
        log.warning("%s: mesh '%s' has no UVs that fit: the garment's UVs (its other meshes') are left out of the "
                    "outputs", where, bare[0])
    materials = None
    if any(p["materials"] is not None for p in parts):
        materials = np.concatenate([p["materials"] if p["materials"] is not None
                                    else np.full(len(p["counts"]), "", dtype=object) for p in parts])
    bound = {k: m for p in parts for k, m in p["bound"].items()}
    return (np.concatenate([p["vertices"] for p in parts]), np.concatenate([p["counts"] for p in parts]), indices,
            uvs, uv_index, materials, bound)


def _preview_look(material: UsdShade.Material, name: str, path: Path):
    """The `formats.mtl.MtlMaterial` of a material whose surface is a UsdPreviewSurface (its diffuse colour, or
    the file of the UsdUVTexture feeding it, and its opacity, where given as a value), as `_preview_material`
    writes one; None for another kind of surface (a renderer's own: only its name is kept)."""
    from formats.mtl import MtlMaterial

    shader = material.ComputeSurfaceSource()[0]
    if not shader or shader.GetIdAttr().Get() != "UsdPreviewSurface":
        return None
    diffuse, opacity, texture = None, None, None
    colour, alpha = shader.GetInput("diffuseColor"), shader.GetInput("opacity")
    if colour and colour.HasConnectedSource():
        source = UsdShade.Shader(colour.GetConnectedSource()[0].GetPrim())
        asset = source.GetInput("file").Get() if source and source.GetInput("file") else None
        if isinstance(asset, Sdf.AssetPath) and asset.path:
            texture = Path(asset.resolvedPath) if asset.resolvedPath else (path.parent / asset.path).resolve()
    elif colour and colour.Get() is not None:  # of other tools' types: color3f, a float grey, a color4f's first three
        value = np.asarray(colour.Get(), dtype=object).reshape(-1).tolist()
        if len(value) in (1, 3, 4) and all(isinstance(v, (int, float)) for v in value):
            diffuse = tuple(float(np.clip(v, 0.0, 1.0)) for v in (value * 3 if len(value) == 1 else value)[:3])
    if alpha and not alpha.HasConnectedSource() and isinstance(alpha.Get(), (int, float)):
        opacity = float(np.clip(alpha.Get(), 0.0, 1.0))
    return MtlMaterial(name, diffuse, opacity, texture)


#: Texture-coordinate primvars other tools name (Blender's, Maya's), read where a mesh has no `st`.
UV_PRIMVAR_NAMES = ("UVMap", "map1", "uv", "st0", "uv0")


def _uv_primvar(mesh: UsdGeom.Mesh, where: str):
    """The primvar of `mesh`'s UVs: `st`, else the one texture-coordinate primvar it has (Blender writes `UVMap`
    where not told to write `st`, Maya `map1`: read silently as none before), else the first of UV_PRIMVAR_NAMES;
    the other texture-coordinate primvars (a second UV set) are said to be left out. None where it has none."""
    api = UsdGeom.PrimvarsAPI(mesh)
    pairs = ("texCoord2f[]", "texCoord2d[]", "texCoord2h[]", "float2[]", "double2[]", "half2[]")
    found = [p for p in api.GetPrimvarsWithValues() if str(p.GetTypeName()) in pairs
             and (str(p.GetTypeName()).startswith("texCoord") or p.GetPrimvarName() in ("st", *UV_PRIMVAR_NAMES))]
    if not found:
        return None
    names = [p.GetPrimvarName() for p in found]
    pick = next((found[names.index(n)] for n in ("st", *UV_PRIMVAR_NAMES) if n in names), found[0])
    others = [n for n in names if n != pick.GetPrimvarName()]
    if others:
        log.warning("%s: UVs read from primvar '%s'; %s left out (the outputs carry one UV set)", where,
                    pick.GetPrimvarName(), ", ".join(f"'{n}'" for n in others))
    return pick


def _face_materials(mesh: UsdGeom.Mesh, n_faces: int) -> tuple[np.ndarray | None, dict]:
    """((P,) each face's material: the bound material's name of the face subset holding it (family materialBind,
    or any face subset with a material bound; the subset's own name where none is bound), else the material bound
    to the mesh itself (its faces in no such subset: all of them where it has none, as USD binds), "" for a face of
    neither; None for a mesh of neither. {name: the bound UsdShade.Material} of the faces' materials.)"""
    materials = np.full(n_faces, "", dtype=object)
    found = {}
    whole = UsdShade.MaterialBindingAPI(mesh.GetPrim()).GetDirectBinding().GetMaterial()
    if whole:
        materials[:] = whole.GetPrim().GetName()
        found[whole.GetPrim().GetName()] = whole
    named = bool(whole)
    for subset in UsdGeom.Subset.GetGeomSubsets(mesh, UsdGeom.Tokens.face):
        bound = UsdShade.MaterialBindingAPI(subset.GetPrim()).GetDirectBinding().GetMaterial()
        if subset.GetFamilyNameAttr().Get() != UsdShade.Tokens.materialBind and not bound:
            continue
        faces = np.asarray(subset.GetIndicesAttr().Get() or [], dtype=np.int64)
        faces = faces[(faces >= 0) & (faces < n_faces)]
        materials[faces] = bound.GetPrim().GetName() if bound else subset.GetPrim().GetName()
        if bound:
            found.setdefault(bound.GetPrim().GetName(), bound)
        named = named or len(faces) > 0
    used = set(materials.tolist()) if named else set()
    return (materials if named else None), {k: m for k, m in found.items() if k in used}


def read_usd(path: str | os.PathLike) -> UsdSequence:
    """Read every UsdGeom.Mesh of a stage as a `MeshTrack` keyed by prim name.

    Points are all time samples of each mesh in time order (T, V, 3) float32, placed by the mesh's
    transforms and converted from the stage's authored units (`metersPerUnit`) and up axis (a Y-up stage
    is turned +90 degrees about X) into this tool's world, metres Z-up (unauthored: read as metres Z-up); faces
    (F, 3) int64 by `_triangles` (a fan, ear clipping above 4 corners); uvs the face-varying `st` primvar per
    triangle corner. Returns UsdSequence(tracks, fps = timeCodesPerSecond,
    start_frame = startTimeCode or the first sample, metadata = customLayerData).
    Raises InputError for a missing or unreadable file or a stage without meshes.
    """
    path = Path(path)
    where = f"USD stage '{path}'"
    stage = open_stage(path, where)
    to_world = _stage_to(stage, "Z")
    tracks: dict[str, MeshTrack] = {}
    first_time = None
    for prim in stage.Traverse():
        if not prim.IsA(UsdGeom.Mesh):
            continue
        name = prim.GetName()
        if name in tracks:
            name = str(prim.GetPath()).strip("/").replace("/", "_")
        mesh = UsdGeom.Mesh(prim)
        tracks[name] = _read_mesh(mesh, name, where, to_world)
        times = mesh.GetPointsAttr().GetTimeSamples()
        if times and (first_time is None or times[0] < first_time):
            first_time = times[0]
    if not tracks:
        raise InputError(f"{where}: expected at least one UsdGeom.Mesh, got none")
    if stage.HasAuthoredTimeCodeRange():
        start = stage.GetStartTimeCode()
    else:
        start = first_time if first_time is not None else 0.0
    metadata = _from_vt(dict(stage.GetRootLayer().customLayerData))
    return UsdSequence(tracks=tracks, fps=float(stage.GetTimeCodesPerSecond()),
                       start_frame=int(round(start)), metadata=metadata)


def read_usd_stage(path: str | os.PathLike) -> tuple[dict, float]:
    """The meshes of a stage by name and its frames per second: `(tracks, fps)`; see `read_usd`."""
    seq = read_usd(path)
    return seq.tracks, seq.fps
