"""Tests for formats/usd.py: round trips, the stage as pxr sees it, bad input."""

import logging
from pathlib import Path

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, UsdShade, Vt

from core.errors import InputError
from formats.usd import MeshTrack, read_usd, read_usd_stage, write_usd_stage


def _tracks(n_frames=4):
    rng = np.random.default_rng(1)
    quad = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], dtype=np.float32)
    t = np.arange(n_frames, dtype=np.float32)[:, None, None]
    garment_points = quad[None] + t * np.array([0, 0, 0.1], dtype=np.float32) + \
        rng.normal(scale=0.01, size=(n_frames, 4, 3)).astype(np.float32)
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    uvs = rng.random((6, 2)).astype(np.float32)
    body_points = rng.normal(size=(n_frames, 5, 3)).astype(np.float32)
    body_faces = np.array([[0, 1, 2], [2, 3, 4], [0, 2, 4]])
    return [MeshTrack("garment", garment_points, faces, uvs=uvs, color=(0.8, 0.2, 0.1)),
            MeshTrack("body", body_points, body_faces)]


def usd_problems(path) -> list[str]:
    """What USD's own validators (every one this pxr registers: stage metadata, subsets, material bindings,
    shaders, composition, ...) find wrong with the stage at `path`, one line each; [] for a clean stage."""
    from pxr import UsdValidation

    context = UsdValidation.ValidationContext(UsdValidation.ValidationRegistry().GetOrLoadAllValidators())
    return [f"{e.GetName()}: {e.GetMessage()}" for e in context.Validate(Usd.Stage.Open(str(path)))]


def _mesh_stage(path, points, counts, indices):
    """A new stage at `path` with one mesh /cloth of these points and polygons: (stage, mesh), unsaved."""
    stage = Usd.Stage.CreateNew(str(path))
    mesh = UsdGeom.Mesh.Define(stage, "/cloth")
    mesh.CreatePointsAttr(points)
    mesh.CreateFaceVertexCountsAttr(counts)
    mesh.CreateFaceVertexIndicesAttr(indices)
    return stage, mesh


@pytest.mark.parametrize("suffix", [".usd", ".usda", ".usdc"])
def test_round_trip(tmp_path, suffix):
    tracks = _tracks()
    path = tmp_path / f"bake{suffix}"
    meta = {"method": "lbs", "frames": 4, "timings_s": [0.5, 1.25], "skipped": ["self_collision"],
            "options": {"push_out": True}}
    write_usd_stage(path, tracks, fps=59.94, start_frame=10, metadata=meta)
    seq = read_usd(path)
    assert set(seq.tracks) == {"garment", "body"}
    assert seq.fps == pytest.approx(59.94) and seq.start_frame == 10
    assert seq.metadata == {"method": "lbs", "frames": 4, "timings_s": [0.5, 1.25],
                            "skipped": ["self_collision"], "options": {"push_out": True}}
    for written in tracks:
        got = seq.tracks[written.name]
        np.testing.assert_array_equal(got.points, written.points)
        np.testing.assert_array_equal(got.faces, written.faces)
        assert got.points.dtype == np.float32 and got.faces.dtype == np.int64
    np.testing.assert_array_equal(seq.tracks["garment"].uvs, tracks[0].uvs)
    np.testing.assert_allclose(seq.tracks["garment"].color, [0.8, 0.2, 0.1], atol=1e-7)
    assert seq.tracks["body"].uvs is None and seq.tracks["body"].color is None
    by_name, fps = read_usd_stage(path)
    assert set(by_name) == {"garment", "body"} and fps == pytest.approx(59.94)


def test_stage_as_pxr_reads_it(tmp_path):
    tracks = _tracks(n_frames=3)
    path = tmp_path / "bake.usd"
    write_usd_stage(path, tracks, fps=30, start_frame=0)
    assert path.read_bytes()[:8] == b"PXR-USDC"  # .usd is written as a binary crate
    stage = Usd.Stage.Open(str(path))
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    assert stage.GetTimeCodesPerSecond() == 30 and stage.GetFramesPerSecond() == 30
    assert stage.GetStartTimeCode() == 0 and stage.GetEndTimeCode() == 2
    assert stage.GetDefaultPrim().GetPath() == Sdf.Path("/Root")
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/Root/garment"))
    assert mesh and mesh.GetSubdivisionSchemeAttr().Get() == UsdGeom.Tokens.none
    assert mesh.GetDoubleSidedAttr().Get() is True
    assert list(mesh.GetFaceVertexCountsAttr().Get()) == [3, 3]
    assert list(mesh.GetFaceVertexIndicesAttr().Get()) == [0, 1, 2, 0, 2, 3]
    p0 = np.asarray(mesh.GetPointsAttr().Get(Usd.TimeCode(0)))
    p2 = np.asarray(mesh.GetPointsAttr().Get(Usd.TimeCode(2)))
    assert p0.shape == (4, 3) and p2.shape == (4, 3)
    np.testing.assert_array_equal(p0, tracks[0].points[0])
    np.testing.assert_array_equal(p2, tracks[0].points[2])
    assert not np.allclose(p0, p2)
    extent = np.asarray(mesh.GetExtentAttr().Get(Usd.TimeCode(2)))
    np.testing.assert_allclose(extent, [tracks[0].points[2].min(0), tracks[0].points[2].max(0)])
    st = UsdGeom.PrimvarsAPI(mesh).GetPrimvar("st")
    assert st.GetInterpolation() == UsdGeom.Tokens.faceVarying and len(st.Get()) == 6
    assert mesh.GetDisplayColorPrimvar().GetInterpolation() == UsdGeom.Tokens.constant
    body = UsdGeom.Mesh(stage.GetPrimAtPath("/Root/body"))
    assert len(body.GetPointsAttr().Get(Usd.TimeCode(1))) == 5
    assert usd_problems(path) == []


def test_usd_problems_finds_what_usds_validators_find(tmp_path):
    """The check the written stages pass is not empty: a stage without up axis, scale or default prim and a
    subset bound without MaterialBindingAPI to faces the mesh does not have is refused on each count."""
    path = tmp_path / "bad.usda"
    stage, mesh = _mesh_stage(path, [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [3], [0, 1, 2])
    subset = UsdGeom.Subset.CreateGeomSubset(mesh, "a", UsdGeom.Tokens.face, Vt.IntArray([0, 5]),
                                             UsdShade.Tokens.materialBind, UsdGeom.Tokens.nonOverlapping)
    subset.GetPrim().CreateRelationship("material:binding").AddTarget(UsdShade.Material.Define(stage, "/m").GetPath())
    stage.Save()
    found = " ".join(usd_problems(path))
    for name in ("MissingUpAxisMetadata", "MissingMetersPerUnitMetadata", "MissingDefaultPrim",
                 "MissingMaterialBindingAPI", "InvalidSubsetFamily"):
        assert name in found, found


def test_names_are_sanitised_and_unique(tmp_path):
    points = np.zeros((1, 3, 3), dtype=np.float32)
    points[0, 1, 0] = points[0, 2, 1] = 1
    faces = np.array([[0, 1, 2]])
    path = tmp_path / "names.usda"
    write_usd_stage(path, [MeshTrack("my dress!", points, faces), MeshTrack("my dress?", points, faces),
                           MeshTrack("3d", points, faces)], fps=24)
    assert set(read_usd(path).tracks) == {"my_dress_", "my_dress__1", "_d"}


def test_rewrite_replaces_content(tmp_path):
    path = tmp_path / "again.usd"
    tracks = _tracks(n_frames=2)
    write_usd_stage(path, tracks, fps=30)
    assert read_usd(path).tracks["garment"].points.shape[0] == 2
    write_usd_stage(path, _tracks(n_frames=5), fps=30)
    assert read_usd(path).tracks["garment"].points.shape[0] == 5
    assert sorted(p.name for p in tmp_path.iterdir()) == ["again.usd"]  # no temporary left


def test_read_quads_fan_triangulated(tmp_path):
    path = tmp_path / "quad.usda"
    stage, _ = _mesh_stage(path, [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (2, 0, 0)], [4, 3],
                              [0, 1, 2, 3, 1, 4, 2])
    stage.GetRootLayer().Save()
    seq = read_usd(path)
    cloth = seq.tracks["cloth"]
    assert cloth.points.shape == (1, 5, 3)
    np.testing.assert_array_equal(cloth.faces, [[0, 1, 2], [0, 2, 3], [1, 4, 2]])


def test_a_y_up_centimetre_stage_with_transforms_reads_in_metres_z_up(tmp_path):
    """Another tool's stage (Y-up, centimetres, the mesh under a moving Xform, as Houdini or Blender export it)
    reads as the same mesh in this tool's world (metres, Z-up): what `metrics` compares a bake against."""
    ours = np.array([[0.0, 0.0, 1.0], [0.5, 0.0, 1.0], [0.0, 0.2, 1.5]])  # metres, Z-up, two frames apart by t
    path = tmp_path / "houdini.usda"
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 0.01)
    xf = UsdGeom.Xform.Define(stage, "/scene")
    op = xf.AddTranslateOp()
    mesh = UsdGeom.Mesh.Define(stage, "/scene/cloth")
    mesh.CreateFaceVertexCountsAttr([3])
    mesh.CreateFaceVertexIndicesAttr([0, 1, 2])
    for t in (0, 1):
        world_yup_cm = (ours + [0.1 * t, 0, 0]) @ np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]]) * 100  # Z-up -> Y-up
        shift = np.array([30.0 * t, 0, 0])  # cm, along x: the Xform carries part of the motion
        mesh.GetPointsAttr().Set(Vt.Vec3fArray([Gf.Vec3f(*p) for p in (world_yup_cm - shift).tolist()]), t)
        op.Set(Gf.Vec3d(*shift.tolist()), t)
    stage.GetRootLayer().Save()
    cloth = read_usd(path).tracks["cloth"]
    np.testing.assert_allclose(cloth.points, [ours, ours + [0.1, 0, 0]], atol=1e-5)


def test_bad_input(tmp_path):
    with pytest.raises(InputError, match=r"USD stage '.*missing\.usd': file not found"):
        read_usd(tmp_path / "missing.usd")
    with pytest.raises(InputError, match=r"expected a USD file, got a directory"):
        read_usd(tmp_path)
    corrupt = tmp_path / "corrupt.usd"
    corrupt.write_bytes(b"this is not a usd file at all\x00\x01")
    with pytest.raises(InputError, match=r"USD stage '.*corrupt\.usd': cannot be opened as USD") as err:
        read_usd(corrupt)
    assert "\n" not in str(err.value)
    assert str(err.value).endswith("got binary data starting b'this is ')")
    for name, content, said in [("nothing.usd", b"", "got an empty file)"),
                                ("mesh.usd", b"v 0 0 0\nf 1 2 3\n", "got text ('v 0 0 0'...))"),
                                ("noise.usdc", b"\xc1\xce\x00\x84", "got binary data starting b'\\xc1\\xce\\x00\\x84')"),
                                ("broken.usda", b"#usda 1.0\n(\n broken", "(line 3:2: Expected ) at 'broken' in </>)"),
                                ("bom.usda", b"\xef\xbb\xbf#usda 1.0\n", "byte-order mark before '#usda', which USD does "
                                 "not read: save it without one)")]:
        (tmp_path / name).write_bytes(content)
        with pytest.raises(InputError, match="cannot be opened as USD") as err:
            read_usd(tmp_path / name)
        assert str(err.value).endswith(said), err.value
    (tmp_path / "real").mkdir()
    (tmp_path / "real" / "broken.usda").write_bytes(b"#usda 1.0\n(\n broken")
    (tmp_path / "link").symlink_to(tmp_path / "real")
    with pytest.raises(InputError, match=r"\(line 3:2: Expected \) at 'broken' in </>\)$"):  # through a link too
        read_usd(tmp_path / "link" / "broken.usda")
    empty = tmp_path / "empty.usda"
    stage = Usd.Stage.CreateNew(str(empty))
    UsdGeom.Xform.Define(stage, "/Root")
    stage.GetRootLayer().Save()
    with pytest.raises(InputError, match=r"expected at least one UsdGeom.Mesh, got none"):
        read_usd(empty)


def test_write_rejects_bad_tracks(tmp_path):
    tracks = _tracks()
    short = MeshTrack("body", tracks[1].points[:2], tracks[1].faces)
    with pytest.raises(InputError, match=r"USD track 'body': expected 4 frames like the first track, got 2"):
        write_usd_stage(tmp_path / "x.usd", [tracks[0], short], fps=30)
    with pytest.raises(InputError, match=r"expected fps > 0"):
        write_usd_stage(tmp_path / "x.usd", tracks, fps=0)
    flat = MeshTrack("garment", tracks[0].points[0], tracks[0].faces)
    with pytest.raises(InputError, match=r"expected points \(T, V, 3\)"):
        write_usd_stage(tmp_path / "x.usd", [flat], fps=30)
    bad_uv = MeshTrack("garment", tracks[0].points, tracks[0].faces, uvs=np.zeros((4, 2)))
    with pytest.raises(InputError, match=r"expected uvs \(6, 2\) face-varying"):
        write_usd_stage(tmp_path / "x.usd", [bad_uv], fps=30)
    with pytest.raises(InputError, match=r"expected a .usd, .usda or .usdc file name, got '.abc'"):
        write_usd_stage(tmp_path / "x.abc", tracks, fps=30)
    assert not (tmp_path / "x.usd").exists()


def test_a_usd_garment_reads_as_its_obj(tmp_path):
    """The example skirt written by another tool as USD (Z-up, centimetres, under a translated Xform, UVs
    face-varying) reads as the OBJ garment; `bake` takes it."""
    from pathlib import Path

    from formats.obj import read_garment, read_obj

    skirt = read_obj(Path(__file__).resolve().parents[2] / "examples" / "skirt.obj")
    path = tmp_path / "skirt.usda"
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 0.01)
    UsdGeom.Xform.Define(stage, "/set").AddTranslateOp().Set(Gf.Vec3d(10.0, 20.0, 30.0))
    mesh = UsdGeom.Mesh.Define(stage, "/set/skirt_geo")
    z_up_cm = skirt.vertices.astype(np.float64) @ np.array([[1, 0, 0], [0, 0, 1], [0, -1, 0]]) * 100  # Y-up m -> Z-up cm
    mesh.CreatePointsAttr(Vt.Vec3fArray([Gf.Vec3f(*p) for p in (z_up_cm - [10, 20, 30]).tolist()]))
    mesh.CreateFaceVertexCountsAttr([3] * skirt.n_faces)
    mesh.CreateFaceVertexIndicesAttr(skirt.faces.ravel().tolist())
    st = UsdGeom.PrimvarsAPI(mesh).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray,
                                                 UsdGeom.Tokens.faceVarying)
    st.Set(Vt.Vec2fArray([Gf.Vec2f(*uv) for uv in skirt.uvs[skirt.face_uvs.ravel()].tolist()]))
    stage.GetRootLayer().Save()
    g = read_garment(path)
    assert g.name == "skirt" and g.n_vertices == skirt.n_vertices
    np.testing.assert_array_equal(g.faces, skirt.faces)
    np.testing.assert_allclose(g.vertices, skirt.vertices, atol=1e-5)
    np.testing.assert_allclose(g.uvs[g.face_uvs], skirt.uvs[skirt.face_uvs], atol=1e-6)
    from tests.garmentcli.cli import invoke

    motion = Path(__file__).resolve().parents[2] / "examples" / "walk.npz"
    r = invoke(["bake", path, motion, "--frames", "0:4", "--out", tmp_path / "out", "--no-obj"])
    assert r.exit_code == 0 and (tmp_path / "out" / "skirt_walk" / "summary.json").is_file(), r.output


def test_a_usd_garment_of_several_meshes_is_read_as_one_its_seams_welded(tmp_path, caplog):
    """Marvelous Designer's "unweld" USD export writes each panel as a mesh: it was refused ("expected one mesh")
    where the same panels as OBJ objects were welded. The example skirt's 4 panels, 1.5 mm apart, each a mesh of
    its own (two with UVs, two without; one under a transform): read as one skirt, its 112 seam pairs welded, a
    warning naming the meshes and the UVs left out; a mesh named 'garment' is still read alone."""
    from core.garment import mesh_edges
    from core.graph import connected_components
    from formats.obj import read_garment
    from tests.formats.test_obj import _panels

    panels_obj, skirt = _panels(tmp_path, gap=1.5e-3)
    v, f = _obj_pieces(panels_obj)
    path = tmp_path / "unwelded.usda"
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    for k, (pv, pf) in enumerate(zip(v, f)):
        xform = UsdGeom.Xform.Define(stage, f"/panels/p{k}")
        shift = np.array([0.0, 0.5, 0.0]) if k == 3 else np.zeros(3)
        if k == 3:
            xform.AddTranslateOp().Set(Gf.Vec3d(*shift))
        mesh = UsdGeom.Mesh.Define(stage, f"/panels/p{k}/cloth")
        mesh.CreatePointsAttr(Vt.Vec3fArray([Gf.Vec3f(*p) for p in (pv - shift).tolist()]))
        mesh.CreateFaceVertexCountsAttr([3] * len(pf))
        mesh.CreateFaceVertexIndicesAttr(pf.ravel().tolist())
        if k < 2:
            st = UsdGeom.PrimvarsAPI(mesh).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray,
                                                          UsdGeom.Tokens.vertex)
            st.Set(Vt.Vec2fArray([Gf.Vec2f(*uv) for uv in pv[:, [0, 1]].tolist()]))
    stage.GetRootLayer().Save()
    with caplog.at_level(logging.WARNING):
        g = read_garment(path)
    counts = ", ".join(f"/panels/p{k}/cloth of {len(pv):,} points" for k, pv in enumerate(v))
    assert f"4 meshes ({counts}), none named 'garment': read as one garment" in caplog.text
    assert "welded 112 seam vertices of separate pieces" in caplog.text
    assert "mesh '/panels/p2/cloth' has no UVs that fit: the garment's UVs (its other meshes') are left out" \
        in caplog.text and g.uvs is None
    assert g.n_vertices == skirt.n_vertices and g.n_faces == skirt.n_faces
    assert connected_components(mesh_edges(g.faces), g.n_vertices)[0] == 1
    d = np.linalg.norm(g.vertices[:, None] - skirt.vertices[None], axis=2).min(axis=1)
    assert d.max() <= 3 * 1.5e-3 + 1e-5
    assert len(v) == 4 and sum(map(len, v)) > skirt.n_vertices  # the panels as written: seams repeated
    # one of them named 'garment': that one alone, as a bake's stage (garment and body) is read
    named = tmp_path / "named.usda"
    stage2 = Usd.Stage.CreateNew(str(named))
    for name, (pv, pf) in (("garment", (v[0], f[0])), ("body", (v[1], f[1]))):
        mesh = UsdGeom.Mesh.Define(stage2, f"/Root/{name}")
        mesh.CreatePointsAttr(Vt.Vec3fArray([Gf.Vec3f(*p) for p in pv.tolist()]))
        mesh.CreateFaceVertexCountsAttr([3] * len(pf))
        mesh.CreateFaceVertexIndicesAttr(pf.ravel().tolist())
    stage2.GetRootLayer().Save()
    assert read_garment(named).n_vertices == len(v[0])


@pytest.mark.parametrize("half", [0.5, 10.0])
def test_a_ground_plane_beside_a_usd_garment_is_refused_naming_it(tmp_path, half):
    """A stage of the example skirt and a ground quad under the body's feet: a 1 m quad was baked as part of the
    skirt (2,020 vertices, the quad skinned to the feet), a 20 m one refused as "stray vertices a tool left"
    without naming its mesh. Now the small one is refused by the bake as a piece resting on the body nowhere,
    the large one on reading, naming the mesh; named 'garment', the skirt is read alone."""
    from formats.obj import read_garment
    from tests.garmentcli.cli import invoke

    examples = Path(__file__).resolve().parents[2] / "examples"
    skirt = read_garment(examples / "skirt.obj")
    quad = np.array([[-half, -1.15, -half], [half, -1.15, -half], [half, -1.15, half], [-half, -1.15, half]])
    path = tmp_path / "scene.usda"
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    for name, (pv, counts, indices) in (("skirt", (skirt.vertices, [3] * skirt.n_faces, skirt.faces.ravel())),
                                        ("ground", (quad, [4], [0, 3, 2, 1]))):
        mesh = UsdGeom.Mesh.Define(stage, f"/Root/{name}")
        mesh.CreatePointsAttr(Vt.Vec3fArray([Gf.Vec3f(*p) for p in np.asarray(pv, dtype=float).tolist()]))
        mesh.CreateFaceVertexCountsAttr(counts)
        mesh.CreateFaceVertexIndicesAttr([int(i) for i in indices])
    stage.GetRootLayer().Save()
    r = invoke(["bake", path, examples / "walk.npz", "--frames", "0:2", "--out", tmp_path / "out", "--no-obj"])
    assert r.exit_code != 0 and not (tmp_path / "out").exists(), r.output
    if half < 1.0:
        assert (f"'{path}': expected the garment alone, got piece 2 of 2 (4 vertices, flat at the body's soles): a "
                f"ground plane or a prop") in r.output
        assert "name the garment's mesh 'garment'" in r.output
    else:
        assert (f"'{path}': expected one garment, got mesh '/Root/ground' (4 points) far from the others (14.2 units "
                f"from their middle") in r.output and "name the garment's mesh 'garment'" in r.output
    # the skirt named 'garment' (copied so): read alone
    Sdf.CopySpec(stage.GetRootLayer(), "/Root/skirt", stage.GetRootLayer(), "/Root/garment")
    stage.GetRootLayer().Save()
    assert read_garment(path).n_vertices == skirt.n_vertices


def _obj_pieces(path):
    """The connected pieces of an OBJ as written (vertices (N, 3), faces (F, 3) of each), unwelded."""
    from core.garment import mesh_edges
    from core.graph import connected_components

    lines = Path(path).read_text().splitlines()
    verts = np.array([[float(x) for x in ln.split()[1:4]] for ln in lines if ln.startswith("v ")])
    faces = np.array([[int(t.split("/")[0]) - 1 for t in ln.split()[1:4]] for ln in lines if ln.startswith("f ")])
    n, labels = connected_components(mesh_edges(faces), len(verts))
    out_v, out_f = [], []
    for k in range(n):
        used = np.flatnonzero(labels == k)
        remap = np.full(len(verts), -1)
        remap[used] = np.arange(len(used))
        rows = faces[(labels[faces] == k).all(axis=1)]
        out_v.append(verts[used])
        out_f.append(remap[rows])
    return out_v, out_f


def test_read_a_concave_polygon_split_inside_it(tmp_path):
    """An L-shaped hexagon (concave): its four triangles cover the L (area 3), not its hull, as a fan from the
    first corner would; the triangle before it keeps its row."""
    path = tmp_path / "ell.usda"
    stage, _ = _mesh_stage(path, [(1, 1, 0), (1, 2, 0), (0, 2, 0), (0, 0, 0), (2, 0, 0), (2, 1, 0), (3, 0, 0)], [3, 6],
                              [4, 6, 5, 2, 3, 4, 5, 0, 1])  # from (0, 2): its fan crosses the notch
    stage.GetRootLayer().Save()
    cloth = read_usd(path).tracks["cloth"]
    tri = cloth.points[0][cloth.faces]
    area = 0.5 * np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])[:, 2]
    np.testing.assert_array_equal(cloth.faces[0], [4, 6, 5])
    assert len(cloth.faces) == 5 and np.all(area[1:] > 0) and area[1:].sum() == pytest.approx(3.0)


def test_a_usd_garment_keeps_its_ngons_for_the_outputs(tmp_path):
    """A garment stage's hexagon is deformed as triangles, but its source mesh (what the outputs write) has
    the hexagon whole, after the triangle, and the file's face-varying UVs per corner."""
    from formats.obj import read_garment

    path = tmp_path / "ell.usda"
    stage, mesh = _mesh_stage(path, [(1, 1, 0), (1, 2, 0), (0, 2, 0), (0, 0, 0), (2, 0, 0), (2, 1, 0), (3, 0, 0)], [3, 6],
                              [4, 6, 5, 2, 3, 4, 5, 0, 1])
    st = UsdGeom.PrimvarsAPI(mesh).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray,
                                                  UsdGeom.Tokens.faceVarying)
    st.Set([(k / 10, k / 20) for k in range(9)])
    stage.GetRootLayer().Save()
    g = read_garment(path)
    assert g.n_faces == 5
    assert g.source.polygons.tolist() == [[4, 6, 5, -1, -1, -1], [2, 3, 4, 5, 0, 1]]
    np.testing.assert_allclose(g.source.uvs[g.source.polygon_uvs[g.source.polygon_uvs >= 0]],
                               [(k / 10, k / 20) for k in range(9)], atol=1e-6)


def test_a_usd_garment_keeps_its_material_subsets(tmp_path):
    """Face subsets of the materialBind family (named by their bound material, else their own name) become the
    garment's materials, per polygon of its source mesh; a subset of another family without a binding does not."""
    from formats.obj import read_garment

    path = tmp_path / "panels.usda"
    stage, mesh = _mesh_stage(path, [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (2, 0, 0), (2, 1, 0), (3, 0.5, 0)], [4, 5],
                              [0, 1, 2, 3, 1, 4, 6, 5, 2])
    front = UsdGeom.Subset.CreateGeomSubset(mesh, "front", UsdGeom.Tokens.face, [0], UsdShade.Tokens.materialBind)
    UsdGeom.Subset.CreateGeomSubset(mesh, "back", UsdGeom.Tokens.face, [1], UsdShade.Tokens.materialBind)
    UsdGeom.Subset.CreateGeomSubset(mesh, "selection", UsdGeom.Tokens.face, [0, 1], "userGroup")
    UsdShade.MaterialBindingAPI.Apply(front.GetPrim()).Bind(UsdShade.Material.Define(stage, "/Looks/cotton"))
    stage.GetRootLayer().Save()
    g = read_garment(path)
    assert g.source.materials.tolist() == ["cotton", "back"]
    assert g.source.polygons.tolist() == [[0, 1, 2, 3, -1], [1, 4, 6, 5, 2]]


def test_a_usd_garments_uvs_of_another_name_and_a_material_bound_to_the_mesh_are_kept(tmp_path, caplog):
    """Blender's `UVMap` (a mesh without `st`) is its UVs, a second UV set is said to be left out, and a material
    bound to the mesh itself covers its faces in no subset (all three were dropped without a word)."""
    import logging

    from formats.obj import read_garment

    path = tmp_path / "panels.usda"
    stage, mesh = _mesh_stage(path, [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (2, 0, 0), (2, 1, 0)], [4, 4],
                              [0, 1, 2, 3, 1, 4, 5, 2])
    api = UsdGeom.PrimvarsAPI(mesh)
    uv = api.CreatePrimvar("UVMap", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.faceVarying)
    uv.Set(Vt.Vec2fArray([(k / 8, 1 - k / 8) for k in range(8)]))
    UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(UsdShade.Material.Define(stage, "/Looks/denim"))
    back = UsdGeom.Subset.CreateGeomSubset(mesh, "back", UsdGeom.Tokens.face, [1], UsdShade.Tokens.materialBind)
    UsdShade.MaterialBindingAPI.Apply(back.GetPrim()).Bind(UsdShade.Material.Define(stage, "/Looks/lining"))
    stage.GetRootLayer().Save()
    with caplog.at_level(logging.WARNING):
        g = read_garment(path)
    assert caplog.text == ""
    assert g.source.materials.tolist() == ["denim", "lining"]
    assert g.uvs is not None and sorted(map(tuple, np.round(g.uvs, 4))) == sorted(
        {(round(k / 8, 4), round(1 - k / 8, 4)) for k in range(8)})
    api.CreatePrimvar("st1", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.faceVarying).Set(
        Vt.Vec2fArray([(0.5, 0.5)] * 8))
    stage.GetRootLayer().Save()
    with caplog.at_level(logging.WARNING):
        read_garment(path)
    assert "UVs read from primvar 'UVMap'; 'st1' left out" in caplog.text


def test_a_left_handed_or_mirrored_garment_reads_with_the_faces_of_its_right_handed_twin(tmp_path):
    """Houdini writes meshes leftHanded (corners clockwise seen from the front); a mirroring transform turns the
    winding too. Either reads as the same garment as its rightHanded twin: the same triangles (the fans' diagonals
    kept) and face-varying UVs, so the model sees its normals facing out (facing the body, the example dress's
    bake moved 48 mm on average, 245 mm at most); both at once cancel."""
    from formats.usd import read_usd_garment

    xs, ys = np.meshgrid(np.arange(4.0), np.arange(3.0), indexing="ij")
    points = np.stack([xs.ravel() * 0.1, ys.ravel() * 0.1, 0.2 + 0.01 * xs.ravel() ** 2], 1)
    quads = [[3 * i + j, 3 * (i + 1) + j, 3 * (i + 1) + j + 1, 3 * i + j + 1] for i in range(3) for j in range(2)]
    clockwise = [[q[0], q[3], q[2], q[1]] for q in quads]

    def write(name, pts, polygons, orientation=None, mirror=False):
        stage = Usd.Stage.CreateNew(str(tmp_path / name))
        UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
        if mirror:
            UsdGeom.Xform.Define(stage, "/set").AddScaleOp().Set(Gf.Vec3f(-1.0, 1.0, 1.0))
        mesh = UsdGeom.Mesh.Define(stage, "/set/cloth" if mirror else "/cloth")
        mesh.CreatePointsAttr([Gf.Vec3f(*map(float, p)) for p in pts])
        mesh.CreateFaceVertexCountsAttr([len(q) for q in polygons])
        mesh.CreateFaceVertexIndicesAttr([int(i) for q in polygons for i in q])
        uv = UsdGeom.PrimvarsAPI(mesh).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray,
                                                     UsdGeom.Tokens.faceVarying)
        uv.Set([Gf.Vec2f(float(points[i][0]), float(points[i][1])) for q in polygons for i in q])
        if orientation:
            mesh.CreateOrientationAttr(orientation)
        stage.Save()
        return read_usd_garment(tmp_path / name)

    def facing(g):  # the sum of the faces' area vectors
        v = g.vertices[g.faces]
        return np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]).sum(axis=0)

    twin = write("right.usda", points, quads)
    # The same surface, front side alike: clockwise corners in a leftHanded mesh, or in a rightHanded one under a
    # mirroring scale (the points mirrored back by it).
    for g in (write("left.usda", points, clockwise, UsdGeom.Tokens.leftHanded),
              write("mirrored.usda", points * [-1, 1, 1], clockwise, mirror=True)):
        np.testing.assert_allclose(g.vertices, twin.vertices, atol=1e-6)
        np.testing.assert_array_equal(g.faces, twin.faces)
        np.testing.assert_allclose(g.uvs[g.face_uvs], twin.uvs[twin.face_uvs], atol=1e-6)
    both = write("both.usda", points * [-1, 1, 1], clockwise, UsdGeom.Tokens.leftHanded, mirror=True)
    np.testing.assert_allclose(facing(both), -facing(twin), atol=1e-6)  # its front is the other side


def test_a_usd_garments_preview_materials_of_loose_types_are_read_or_left_out(tmp_path):
    """Other tools type a UsdPreviewSurface's inputs loosely: a float grey for diffuseColor, a color4f, a color3f
    opacity, a string texture file. Each is read where it means a colour (its first three), else left out; none
    stops the garment's reading (they raised TypeError and AttributeError)."""
    from formats.obj import read_garment

    path = tmp_path / "loose.usda"
    stage = Usd.Stage.CreateNew(str(path))
    mesh = UsdGeom.Mesh.Define(stage, "/garment")
    mesh.CreatePointsAttr(Vt.Vec3fArray([Gf.Vec3f(*p) for p in
                                         [(0, 1, 0), (0.3, 1, 0), (0, 1.3, 0), (0.3, 1.3, 0), (0.6, 1, 0), (0.6, 1.3, 0)]]))
    mesh.CreateFaceVertexCountsAttr([3, 3, 3, 3])
    mesh.CreateFaceVertexIndicesAttr([0, 1, 2, 1, 3, 2, 1, 4, 3, 4, 5, 3])
    inputs = {"grey": [("diffuseColor", Sdf.ValueTypeNames.Float, 0.5)],
              "rgba": [("diffuseColor", Sdf.ValueTypeNames.Color4f, Gf.Vec4f(0.1, 0.2, 0.3, 1.0)),
                       ("opacity", Sdf.ValueTypeNames.Color3f, Gf.Vec3f(1, 1, 1))],
              "text": [("diffuseColor", Sdf.ValueTypeNames.String, "red")]}
    for k, (name, values) in enumerate(inputs.items()):
        material = UsdShade.Material.Define(stage, f"/Looks/{name}")
        shader = UsdShade.Shader.Define(stage, f"/Looks/{name}/surface")
        shader.CreateIdAttr("UsdPreviewSurface")
        for input_name, kind, value in values:
            shader.CreateInput(input_name, kind).Set(value)
        material.CreateSurfaceOutput().ConnectToSource(shader.ConnectableAPI(), "surface")
        subset = UsdGeom.Subset.CreateGeomSubset(mesh, name, UsdGeom.Tokens.face, Vt.IntArray([k]),
                                                 UsdShade.Tokens.materialBind)
        UsdShade.MaterialBindingAPI.Apply(subset.GetPrim()).Bind(material)
    stage.GetRootLayer().Save()
    looks = read_garment(path).source.looks
    assert looks["grey"].diffuse == (0.5, 0.5, 0.5)
    assert looks["rgba"].diffuse == pytest.approx((0.1, 0.2, 0.3)) and looks["rgba"].opacity is None
    assert looks["text"].diffuse is None
