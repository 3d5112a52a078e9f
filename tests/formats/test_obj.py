"""Tests for formats/obj.py: the parser on hand-written OBJ text, cleaning, errors, round trips."""

import logging
import warnings

import numpy as np
import pytest

from core.errors import InputError
from formats.obj import parse_obj, read_obj, triangulate, write_obj

# Every accepted feature but UVs on all faces: comments, ignored statements,
# v with w and with vertex colours, a quad, v//vn, negative indices, v/vt,
# v/vt/vn, two objects, an unused vertex, a repeated-vertex face, a zero-area
# face, and two duplicate faces.
MIXED_OBJ = """\
# a garment panel pair
mtllib test.mtl
o first
g panel_a
usemtl cloth
s off
v 0.0 0.0 0.0 1.0
v 1.0 0.0 0.0 0.2 0.3 0.4
v 1.5 1.0 0.0
v 0.0 1.0 0.0
v 9.0 9.0 9.0
vt 0.0 0.0
vt 1.0 0.0
vt 1.0 1.0 0.0
vn 0 0 1
f 1 2 3 4
o second
g panel_b
s 1
v 2.0 0.0 0.0
v 3.0 0.0 0.0
v 2.0 1.0 0.0
v 3.0 1.0 0.0
v 2.5 0.5 0.0
f 6//1 7//1 8//1
f -4/1 -2/2 -3/3
f 6 9 10
f 1 1 2
f 8 6 7
f 7/2/1 9/3/1 8/1/1
"""

UV_OBJ = """\
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
vt 0 0
vt 1 0
vt 1 1
vt 0 1
vn 0 0 1
f 1/1 2/2 3/3 4/4
v 2 0 0
vt 0.5 0.5
f 2/2/1 -1/-1/1 3/3/1
"""


def _write(tmp_path, text, name="g.obj"):
    path = tmp_path / name
    path.write_text(text)
    return path


def _grid(n=6):
    x, y = np.meshgrid(np.linspace(-0.5, 0.5, n), np.linspace(0.0, 1.2, n))
    v = np.stack([x.ravel(), y.ravel(), 0.1 * np.sin(3 * x.ravel())], axis=1).astype(np.float32)
    idx = np.arange(n * n).reshape(n, n)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    f = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)]).astype(np.int64)
    return v, f


def test_read_mixed_features(tmp_path, caplog):
    path = _write(tmp_path, MIXED_OBJ)
    with caplog.at_level(logging.WARNING, logger="formats.obj"):
        g = read_obj(path)
    expected_v = np.array([[0, 0, 0], [1, 0, 0], [1.5, 1, 0], [0, 1, 0],
                           [2, 0, 0], [3, 0, 0], [2, 1, 0], [3, 1, 0]], dtype=np.float32)
    np.testing.assert_array_equal(g.vertices, expected_v)
    assert g.vertices.dtype == np.float32 and g.faces.dtype == np.int64
    # The quad's diagonal b-d (1.41) is shorter than a-c (1.80): (a b d)(b c d).
    np.testing.assert_array_equal(g.faces, [[0, 1, 3], [1, 2, 3], [4, 5, 6], [5, 7, 6]])
    # Not every face had texture indices: those without get (0, 0), the others keep theirs (they were all dropped).
    np.testing.assert_array_equal(g.uvs[g.face_uvs[:3]], 0.0)
    np.testing.assert_array_equal(g.uvs[g.face_uvs[3]], [[0, 0], [1, 0], [1, 1]])
    assert "5 of 7 faces have no texture coordinates (from line 16" in caplog.text
    assert g.name == "g"
    # Both objects ended up in one mesh, and they share no vertex.
    assert set(np.unique(g.faces[:2])) == {0, 1, 2, 3} and set(np.unique(g.faces[2:])) == {4, 5, 6, 7}
    text = caplog.text
    assert "dropped 2 degenerate faces (1 with a repeated vertex, 1 with zero area)" in text
    assert "dropped 2 duplicate faces" in text
    assert "removed 2 unused vertices" in text


def test_faces_flat_to_the_files_precision_are_dropped_and_a_face_lines_comment_is_left_aside(tmp_path, caplog):
    """Faces on three points of a line written to 6 decimals (an n-gon over a subdivided hem fanned into
    triangles) are degenerate like exactly flat ones; a thin but real face stays; a comment after a face's
    indices is left aside as after a vertex's numbers (it refused the file)."""
    v, f = _grid(6)
    mid = (v[f[:12, 0]] + v[f[:12, 1]]) / 2 + np.float32(4e-7)  # off the line by the file's rounding
    thin = np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.05, 0.002, 0.0]]) + [3.0, 0.0, 0.0]  # 1:50 sliver
    verts = np.concatenate([v, mid, thin])
    faces = np.concatenate([f, np.stack([f[:12, 0], f[:12, 1], len(v) + np.arange(12)], 1),
                            [len(v) + 12 + np.arange(3)]])
    lines = [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in verts]
    lines += [f"f {a + 1} {b + 1} {c + 1}" + (" # a comment" if i % 7 == 0 else "") for i, (a, b, c) in
              enumerate(faces)]
    with caplog.at_level(logging.WARNING, logger="formats.obj"):
        g = read_obj(_write(tmp_path, "\n".join(lines) + "\n"))
    assert len(g.faces) == len(f) + 1  # the grid and the sliver
    assert "dropped 12 degenerate faces (0 with a repeated vertex, 12 with zero area)" in caplog.text


@pytest.mark.parametrize("far", [40.0, 5.0])
def test_a_stray_vertex_is_named_not_taken_for_the_files_units(tmp_path, far):
    """One vertex of a garment dragged 40 m off was blamed on the file's units (following the advice made a 5 mm
    garment), one 5 m off baked a spike: one line naming where it is; the garment in centimetres still gets the
    unit's advice."""
    v, f = _grid(12)
    spike = np.concatenate([v, [[far, 0.5, 0.0]]])
    faces = np.concatenate([f, [[0, 1, len(v)]]])
    lines = [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in spike] + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces]
    with pytest.raises(InputError) as info:
        read_obj(_write(tmp_path, "\n".join(lines) + "\n"))
    message = str(info.value)
    assert "expected one garment, got 1 vertex far from the rest (the furthest at (" in message
    assert f"{far:g}, 0.5, 0)" in message and "stray vertices a tool left? remove them" in message
    assert "units;" not in message and "\n" not in message
    lines = [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in v * 100] + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in f]
    with pytest.raises(InputError, match="is it in centimetres"):
        read_obj(_write(tmp_path, "\n".join(lines) + "\n", "cm.obj"))


def test_a_byte_order_mark_and_line_continuations_are_read(tmp_path):
    """A UTF-8 byte-order mark (Windows exporters) does not hide the first vertex; a line ending in a backslash
    continues on the next, except a comment (a Windows path ending in one must not swallow a vertex). Each
    file reads as the plain one, also through a sequence frame's fast path."""
    plain = parse_obj(_write(tmp_path, UV_OBJ, "plain.obj"))
    lines = UV_OBJ.splitlines(keepends=True)
    first_face = next(i for i, line in enumerate(lines) if line.startswith("f "))
    a, b = lines[first_face].rsplit(" ", 1)  # "f 1/1 2/2 3/3", "4/4\n"
    variants = {
        "bom.obj": ("\ufeff" + UV_OBJ).encode("utf-8"),
        "continued.obj": "".join(lines[:first_face] + [a + " \\\n", "   " + b] + lines[first_face + 1:]).encode(),
        "comment.obj": ("# exported from C:\\garments\\\n" + UV_OBJ).encode(),
    }
    for name, data in variants.items():
        (tmp_path / name).write_bytes(data)
        for like in (None, plain):
            got = parse_obj(tmp_path / name, like=like)
            np.testing.assert_array_equal(got.vertices, plain.vertices, err_msg=name)
            np.testing.assert_array_equal(got.polygons, plain.polygons, err_msg=name)
            np.testing.assert_array_equal(got.polygon_uvs, plain.polygon_uvs, err_msg=name)


def test_materials_are_kept_per_polygon_and_written_back(tmp_path):
    """`usemtl` names each polygon's material (an n-gon's extra triangles take its name); a file whose mesh is
    otherwise the garment's keeps a source mesh for them; written back, each run of faces gets its usemtl and
    the pentagon is one face again."""
    text = ("mtllib cloth.mtl # its library\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\nv 3 0.5 0\nv 2 1 0\n"
            "usemtl cotton # the front\nf 1 2 3 4\nusemtl silk lining\nf 2 5 6 7 3\n")
    obj = parse_obj(_write(tmp_path, text, "m.obj"))
    assert obj.libraries == ("cloth.mtl",)  # a comment after a name is no part of it (it was: 'cotton # the front')
    assert parse_obj(_write(tmp_path, "v 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl cloth#2\nf 1 2 3\n", "h.obj")).materials \
        .tolist() == ["cloth#2"]
    assert obj.materials.tolist() == ["cotton", "silk lining", "silk lining", "silk lining"]
    assert obj.written.materials.tolist() == ["cotton", "silk lining"]
    g = read_obj(tmp_path / "m.obj")
    assert g.source.materials.tolist() == ["cotton", "silk lining"]
    assert g.source.polygons.tolist() == [[0, 1, 2, 3, -1], [1, 4, 5, 6, 2]]
    assert {k: v.tolist() for k, v in g.source.material_groups().items()} == {"cotton": [0], "silk lining": [1]}
    tri = read_obj(_write(tmp_path, "v 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\n", "t.obj"))
    assert tri.source is not None and tri.source.materials.tolist() == ["a"]
    assert read_obj(_write(tmp_path, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "p.obj")).source is None
    write_obj(tmp_path / "back.obj", g.source.points(g.vertices), g.source.polygons, materials=g.source.materials)
    lines = [line for line in (tmp_path / "back.obj").read_text().splitlines() if not line.startswith("v ")]
    assert lines == ["usemtl cotton", "f 1 2 3 4", "usemtl silk lining", "f 2 5 6 7 3"]
    assert parse_obj(tmp_path / "back.obj").materials.tolist() == obj.materials.tolist()


def test_faces_of_no_material_after_named_ones_are_written_back_as_none(tmp_path):
    """A bare `usemtl` (or none at all before the first) marks faces of no material: written back, the faces after
    a named run took that run's material (no line was written where the name became '')."""
    text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nusemtl cloth\nf 1 3 4\nusemtl\nf 2 3 4\nusemtl cloth\nf 1 2 4\n"
    obj = parse_obj(_write(tmp_path, text, "m.obj"))
    assert obj.materials.tolist() == ["", "cloth", "", "cloth"]
    write_obj(tmp_path / "back.obj", obj.vertices, obj.polygons, materials=obj.materials)
    lines = [line for line in (tmp_path / "back.obj").read_text().splitlines() if not line.startswith("v ")]
    assert lines == ["f 1 2 3", "usemtl cloth", "f 1 3 4", "usemtl", "f 2 3 4", "usemtl cloth", "f 1 2 4"]
    assert parse_obj(tmp_path / "back.obj").materials.tolist() == ["", "cloth", "", "cloth"]


def test_ngons_are_written_back_whole(tmp_path):
    """A file of triangles and n-gons alone (nothing welded) keeps a source mesh, so its outputs have the
    n-gons with their UVs: a concave L hexagon and a pentagon come back as the file's faces, point for point."""
    text = ("v 0 0 0\nv 2 0 0\nv 2 1 0\nv 1 1 0\nv 1 2 0\nv 0 2 0\nv 3 0 0\nv 3 1 0\nv -1 1 0\n"
            "vt 0 0\nvt 1 0\nvt 1 0.5\nvt 0.5 0.5\nvt 0.5 1\nvt 0 1\nvt 1 0.2\nvt 1 0.4\nvt 0 0.5\n"
            "f 1/1 2/2 3/3 4/4 5/5 6/6\nf 2/2 7/7 8/8 3/3\nf 1/1 6/6 9/9\n")
    g = read_obj(_write(tmp_path, text, "l.obj"))
    assert g.n_faces == 4 + 2 + 1 and g.source is not None
    assert g.source.polygons.shape == (3, 6) and (g.source.polygons >= 0).sum(axis=1).tolist() == [6, 4, 3]
    write_obj(tmp_path / "back.obj", g.source.points(g.vertices), g.source.polygons, g.source.uvs,
              g.source.polygon_uvs)
    faces = [line for line in (tmp_path / "back.obj").read_text().splitlines() if line.startswith("f ")]
    assert faces == ["f 1/1 2/2 3/3 4/4 5/5 6/6", "f 2/2 7/7 8/8 3/3", "f 1/1 6/6 9/9"]
    back = read_obj(tmp_path / "back.obj")
    np.testing.assert_array_equal(back.faces, g.faces)
    np.testing.assert_array_equal(back.vertices, g.vertices)


def test_read_uvs_when_every_face_has_them(tmp_path, caplog):
    with caplog.at_level(logging.WARNING, logger="formats.obj"):
        g = read_obj(_write(tmp_path, UV_OBJ))
    assert caplog.text == ""
    # A square: equal diagonals, split along a-c.
    np.testing.assert_array_equal(g.faces, [[0, 1, 2], [0, 2, 3], [1, 4, 2]])
    np.testing.assert_allclose(g.uvs, [[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0.5]])
    np.testing.assert_array_equal(g.face_uvs, [[0, 1, 2], [0, 2, 3], [1, 4, 2]])
    assert g.uvs.dtype == np.float32 and g.face_uvs.dtype == np.int64


@pytest.mark.parametrize("bare", ["5//1", "5"])
def test_a_face_without_texture_coordinates_leaves_the_others_theirs(tmp_path, caplog, bare):
    """One face written without texture coordinates ('f a//n', or 'f a': a hanger exported with a dress) dropped
    every face's, without a word: the USD and OBJ outputs had none. That face's corners are given (0, 0), with
    one warning naming the count and its line."""
    text = UV_OBJ.replace("f 2/2/1 -1/-1/1 3/3/1", f"f 2//1 {bare} 3//1")
    assert text != UV_OBJ
    with caplog.at_level(logging.WARNING, logger="formats.obj"):
        g = read_obj(_write(tmp_path, text, "part.obj"))
    np.testing.assert_array_equal(g.faces, [[0, 1, 2], [0, 2, 3], [1, 4, 2]])
    np.testing.assert_allclose(g.uvs, [[0, 0], [1, 0], [1, 1], [0, 1], [0, 0]])  # 'vt 0.5 0.5', unused, left out
    np.testing.assert_array_equal(g.face_uvs, [[0, 1, 2], [0, 2, 3], [4, 4, 4]])
    assert "part.obj" in caplog.text and "1 of 2 faces have no texture coordinates (from line" in caplog.text


@pytest.mark.parametrize("corner", ["3", "3//1"])
def test_a_face_with_texture_coordinates_at_some_corners_only_is_refused(tmp_path, corner):
    """A file cut short in its last corner ('f 1873/1971 1945/2044 2015/2015' -> '... 201') baked a wrong triangle
    without a word; no exporter mixes corners with and without texture coordinates in one face."""
    text = UV_OBJ.replace("f 2/2/1 -1/-1/1 3/3/1", f"f 2/2/1 -1/-1/1 {corner}")
    assert text != UV_OBJ
    with pytest.raises(InputError, match=r"part.obj': expected texture coordinates at every corner of a face or at "
                                         r"none, got them at 2 of 3 on line \d+ \('f 2/2/1 -1/-1/1 3.*'\): a file cut "
                                         r"short or broken\?"):
        read_obj(_write(tmp_path, text, "part.obj"))


def test_triangulate_against_naive_split():
    rng = np.random.default_rng(0)
    v = rng.normal(size=(30, 3))
    polys = np.stack([rng.choice(30, 4, replace=False) for _ in range(20)])
    polys[::3, 3] = -1  # every third polygon a triangle
    faces, _, split_ac = triangulate(v, polys)
    expected = []
    for a, b, c, d in polys:
        if d < 0:
            expected.append([a, b, c])
        elif np.linalg.norm(v[a] - v[c]) <= np.linalg.norm(v[b] - v[d]):
            expected += [[a, b, c], [a, c, d]]
        else:
            expected += [[a, b, d], [b, c, d]]
    np.testing.assert_array_equal(faces, expected)
    # A given diagonal choice is honoured whatever the geometry.
    faces2, _, _ = triangulate(v * [1, 5, 1], polys, split_ac=split_ac)
    np.testing.assert_array_equal(faces2, faces)


@pytest.mark.parametrize("with_uvs", [False, True])
def test_parse_like_reuses_polygons_of_an_identical_face_block(tmp_path, with_uvs):
    v, f = _grid()
    uvs = v[:, :2] if with_uvs else None
    write_obj(tmp_path / "a.obj", v, f, uvs, f if with_uvs else None)
    write_obj(tmp_path / "b.obj", v + 0.25, f, uvs, f if with_uvs else None)
    first = parse_obj(tmp_path / "a.obj")
    second = parse_obj(tmp_path / "b.obj", like=first)
    full = parse_obj(tmp_path / "b.obj")
    assert second.polygons is first.polygons
    np.testing.assert_array_equal(second.vertices, full.vertices)
    np.testing.assert_array_equal(second.polygons, full.polygons)
    assert (second.uvs is None) == (not with_uvs)
    if with_uvs:
        np.testing.assert_array_equal(second.uvs, full.uvs)
        np.testing.assert_array_equal(second.polygon_uvs, full.polygon_uvs)


def test_parse_like_falls_back_to_the_full_parser(tmp_path):
    first = parse_obj(_write(tmp_path, UV_OBJ, "a.obj"))
    # Negative indices: polygons are parsed again, not reused, and still agree.
    second = parse_obj(_write(tmp_path, UV_OBJ.replace("v 2 0 0", "v 2 0.5 0"), "b.obj"), like=first)
    assert second.polygons is not first.polygons
    np.testing.assert_array_equal(second.polygons, first.polygons)
    assert second.vertices[4, 1] == 0.5
    # A frame with a bad number is reported by the full parser with its line.
    v, f = _grid()
    write_obj(tmp_path / "c.obj", v, f)
    text = (tmp_path / "c.obj").read_text().replace("v -0.300000", "v -0.3x0000", 1)
    with pytest.raises(InputError, match=r"expected a number in the vertex on line 2, got '-0.3x0000'"):
        parse_obj(_write(tmp_path, text, "d.obj"), like=parse_obj(tmp_path / "c.obj"))


@pytest.mark.parametrize("with_uvs", [False, True])
def test_write_read_round_trip(tmp_path, with_uvs):
    v, f = _grid()
    uvs = v[:, :2] + 0.5 if with_uvs else None
    path = tmp_path / "rt.obj"
    write_obj(path, v, f, uvs=uvs, face_uvs=f if with_uvs else None, header="written by a test\nsecond line")
    text = path.read_text()
    assert text.startswith("# written by a test\n# second line\n")
    assert ("\nf 1/1 2/2 8/8\n" in text) == with_uvs
    assert "\nv -0.500000 0.000000 -0.099749\n" in text  # 6 decimals
    g = read_obj(path)
    np.testing.assert_allclose(g.vertices, v, atol=1e-6)
    np.testing.assert_array_equal(g.faces, f)
    if with_uvs:
        np.testing.assert_allclose(g.uvs, uvs, atol=1e-6)
        np.testing.assert_array_equal(g.face_uvs, f)
    else:
        assert g.uvs is None


@pytest.mark.parametrize("text, message", [
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nv 2 2 0\nv 3 1 0\nv 3 0 0\nf 1 2 3 4 5 6 7\n",
     "cannot split the face with 7 vertices on line 8 into triangles: it crosses itself or has no area"),
    ("v 0 0 0\nv 1 0 0\nv 2 0 0\nv 3 0 0\nv 4 0 0\nf 1 2 3 4 5\n",
     "cannot split the face with 5 vertices on line 6 into triangles: it crosses itself or has no area"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3 4 9\n", "vertex index 9 out of range on line 5, the file has 4 vertices"),
    ("v 0 0 0\nv 1 0 0\nf 1 2 3\nf 1 2\n",
     "expected faces of 3 to 256 vertices, got a face with 2 vertices (face 2, line 4)"),
    ("v 0 0 0\nv 1 abc 0\nv 0 1 0\nf 1 2 3\n", "expected a number in the vertex on line 2, got 'abc'"),
    ("v 0 0 0\nv 1 0\n", "expected 3 coordinates on the vertex on line 2, got 2"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 x\nf 1 2 3\n", "expected a number in the texture coordinate on line 4, got 'x'"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 9\n", "vertex index 9 out of range on line 5, the file has 3 vertices"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -4 1 2\n", "vertex index -4 out of range on line 4, only 3 defined before it"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 0\n", "vertex index 0 out of range on line 4"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n", "expected an integer vertex index on line 4, got 'x'"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3/2\n",
     "texture coordinate index 2 out of range on line 5, the file has 1 texture coordinates"),
    ("# nothing\nf 1 2 3\n", "expected vertices ('v' lines), got none"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\n", "expected faces ('f' lines), got none"),
    ("v 0 0 0\nv 100 0 0\nv 0 100 0\nf 1 2 3\n", "is it in centimetres? scale it by 0.01"),
    ("v 0 0 0\nv 1000 0 0\nv 0 1000 0\nf 1 2 3\n", "is it in millimetres? scale it by 0.001"),
    # 20 units: a 20 cm or a 51 cm (20 inch) garment, both named; 15 units: inches alone (15 cm is no garment).
    ("v 0 0 0\nv 20.1 0 0\nv 0 20 0\nf 1 2 3\n", "got an extent of 20.1 units; is it in centimetres (scale it by "
     "0.01) or inches (scale it by 0.0254)?"),
    ("v 0 0 0\nv 15 0 0\nv 0 15 0\nf 1 2 3\n", "got an extent of 15.0 units; is it in inches? scale it by 0.0254"),
    ("v 0 0 0\nv 1e5 0 0\nv 0 1e5 0\nf 1 2 3\n", "got an extent of 100000.0 units"),  # no unit fits: no guess
    ("v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n", "expected finite coordinates, got NaN/Inf at vertex 1"),
    ("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n", "got no faces"),
])
def test_bad_input(tmp_path, text, message):
    path = _write(tmp_path, text, "bad.obj")
    with pytest.raises(InputError) as err:
        read_obj(path)
    msg = str(err.value)
    assert message in msg
    assert f"'{path}'" in msg and "\n" not in msg


def test_a_file_in_other_units_is_named_the_unpose_that_scales_it_and_read_scaled(tmp_path):
    """A file in centimetres: the error names `garment unpose ... --scale 0.01`; read with that scale (as unpose
    reads it), it is the garment in metres, its seams welded in metres; read already scaled by 1.5 (150 units:
    centimetres), the scale named is still the file's."""
    path = _write(tmp_path, "v 0 0 0\nv 100 0 0\nv 0 100 0\nv 100 0.0005 0\nf 1 2 3\nf 4 3 2\n", "cm.obj")
    with pytest.raises(InputError) as err:
        read_obj(path)
    assert str(err.value).endswith(f"is it in centimetres? scale it by 0.01: `garment unpose {path} --pose tpose "
                                   f"--scale 0.01`")
    with pytest.raises(InputError) as err:
        read_obj(path, scale=1.5)
    assert str(err.value).endswith(f"scale it by 0.015: `garment unpose {path} --pose tpose --scale 0.015`")
    g = read_obj(path, scale=0.01)
    assert np.allclose(g.vertices.max(axis=0), [1.0, 1.0, 0.0]) and len(g.vertices) == 3  # 5 um apart: welded


def test_missing_file_and_directory(tmp_path):
    with pytest.raises(InputError, match=r"garment mesh '.*nope\.obj': file not found"):
        read_obj(tmp_path / "nope.obj")
    with pytest.raises(InputError, match=r"garment mesh '.*': expected an OBJ file, got a directory"):
        read_obj(tmp_path)


def test_ear_clip_covers_simple_polygons_exactly_in_their_winding():
    """Star-shaped polygons (random radii at sorted angles, concave ones among them) on a tilted plane, both
    windings: n - 2 triangles whose areas sum to the polygon's (shoelace), every one turning as the polygon
    turns, none holding another corner inside."""
    from formats.obj import ear_clip

    rng = np.random.default_rng(3)
    basis = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    for n in (5, 6, 9, 17, 40):
        for flip in (False, True):
            angles = np.sort(rng.uniform(0, 2 * np.pi, n))
            flat = np.stack([np.cos(angles), np.sin(angles)], 1) * rng.uniform(0.3, 1.0, (n, 1))
            flat = flat[::-1] if flip else flat
            pts = np.c_[flat, np.zeros(n)] @ basis.T + [0.5, -1.0, 2.0]
            tris = ear_clip(pts)
            assert tris is not None and tris.shape == (n - 2, 3) and set(tris.ravel()) == set(range(n))
            area = 0.5 * np.sum(flat[:, 0] * np.roll(flat[:, 1], -1) - np.roll(flat[:, 0], -1) * flat[:, 1])
            a, b, c = (flat[tris[:, k]] for k in range(3))
            tri_area = 0.5 * ((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))
            assert np.all(np.sign(tri_area) == np.sign(area)) and tri_area.sum() == pytest.approx(area)
            for t in tris:
                for m in set(range(n)) - set(t):
                    bary = np.linalg.solve(np.vstack([flat[t].T, np.ones(3)]), np.r_[flat[m], 1.0])
                    assert bary.min() < 1e-9  # not strictly inside


def test_read_obj_splits_polygons_of_more_than_four_corners(tmp_path):
    """A concave L hexagon with UVs and a pentagon in one file: 4 + 3 triangles, UVs carried, the faces' normals
    along the polygons' (+Z), every corner used."""
    text = ("v 0 0 0\nv 2 0 0\nv 2 1 0\nv 1 1 0\nv 1 2 0\nv 0 2 0\n"
            "v 3 0 0\nv 4 0 0\nv 4 1 0\nv 3.5 1.5 0\nv 3 1 0\n"
            + "".join(f"vt {u} {v}\n" for u, v in [(0, 0), (1, 0), (1, .5), (.5, .5), (.5, 1), (0, 1)] * 2)
            + "f 1/1 2/2 3/3 4/4 5/5 6/6\nf 7/7 8/8 9/9 10/10 11/11\n")
    (tmp_path / "ngon.obj").write_text(text)
    g = read_obj(tmp_path / "ngon.obj")
    assert g.n_faces == 7 and g.n_vertices == 11 and set(g.faces.ravel()) == set(range(11))
    tri = g.vertices[g.faces]
    assert np.all(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])[:, 2] > 0)
    assert g.face_uvs is not None and np.array_equal(g.face_uvs, g.faces)  # corner k took vt k
    areas = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    assert areas[:4].sum() == pytest.approx(3.0)  # the L, not its convex hull


def _panels(tmp_path, name="panels.obj", gap=0.0):
    """The example skirt cut into 4 panels exported separately: every seam vertex repeated once per panel,
    `gap` metres apart along x (0: at the same position). Returns (path, the skirt as read)."""
    from pathlib import Path

    skirt = read_obj(Path(__file__).resolve().parents[2] / "examples" / "skirt.obj")
    v, f = skirt.vertices, skirt.faces
    centre = v[f].mean(axis=1)
    panel = (((np.arctan2(centre[:, 0], centre[:, 2]) + np.pi) / (np.pi / 2)).astype(int)) % 4
    verts, faces = [], np.zeros_like(f)
    for p in range(4):
        rows = np.flatnonzero(panel == p)
        used = np.unique(f[rows])
        remap = np.full(len(v), -1)
        remap[used] = len(verts) + np.arange(len(used))
        verts.extend(v[used] + [gap * p, 0, 0])
        faces[rows] = remap[f[rows]]
    write_obj(tmp_path / name, np.array(verts), faces)
    return tmp_path / name, skirt


def test_panels_exported_separately_are_welded_at_their_seams(tmp_path, caplog):
    from core.garment import mesh_edges
    from core.graph import connected_components

    path, skirt = _panels(tmp_path)
    with caplog.at_level(logging.WARNING):
        g = read_obj(path)
    assert "welded 112 vertices onto others at the same position" in caplog.text
    assert "unused" not in caplog.text  # the welded copies are not reported a second time
    assert g.n_vertices == skirt.n_vertices and g.n_faces == skirt.n_faces
    assert connected_components(mesh_edges(g.faces), g.n_vertices)[0] == 1  # one garment, not 4 loose panels
    np.testing.assert_allclose(np.sort(g.vertices, axis=0), np.sort(skirt.vertices, axis=0), atol=1e-6)


@pytest.mark.parametrize("gap", [1e-4, 1.5e-3])
def test_panels_exported_apart_are_welded_at_their_seams_at_the_midpoints(tmp_path, caplog, gap):
    """Panels 0.1 mm or 2 mm apart (Marvelous Designer's and CLO's unwelded exports keep sewn seams 1-3 mm apart)
    were baked as 4 loose panels whose seams gaped (232 mm on the walk with LBS; at 0.1 mm with a warning only):
    each seam pair of open-edge vertices of two pieces is one vertex, at its midpoint."""
    from core.garment import mesh_edges
    from core.graph import connected_components

    path, skirt = _panels(tmp_path, gap=gap)
    with caplog.at_level(logging.WARNING):
        g = read_obj(path)
    assert f"welded 112 seam vertices of separate pieces lying {gap * 1e3:.2g}-" in caplog.text
    assert "open-edge" not in caplog.text and "unused" not in caplog.text
    assert g.n_vertices == skirt.n_vertices and g.n_faces == skirt.n_faces
    assert connected_components(mesh_edges(g.faces), g.n_vertices)[0] == 1
    # every vertex where the skirt has one, as its panel was moved (panel 3 by 3 gaps; a seam at its midpoint)
    d = np.linalg.norm(g.vertices[:, None] - skirt.vertices[None], axis=2).min(axis=1)
    assert d.max() <= 3 * gap + 1e-6


def test_a_cloth_written_twice_is_welded_and_told_for_what_it_is(tmp_path, caplog):
    """A two-sided export of zero thickness (every vertex and face twice) was told "the seams of separately exported
    panels"."""
    path, skirt = _panels(tmp_path)
    write_obj(tmp_path / "twice.obj", np.concatenate([skirt.vertices, skirt.vertices]),
              np.concatenate([skirt.faces, skirt.faces[:, ::-1] + skirt.n_vertices]))
    with caplog.at_level(logging.WARNING):
        g = read_obj(tmp_path / "twice.obj")
    assert g.n_vertices == skirt.n_vertices and "(within 0.01 mm; the cloth written twice: a two-sided export?)" in \
        caplog.text


def test_pieces_far_apart_or_layers_of_a_thick_cloth_are_not_welded(tmp_path, caplog):
    """Panels 3 cm apart are pieces of their own (no seam to name); a cloth given thickness (two shells 2.5 mm
    apart, their rims side by side) is two layers, not panels to sew."""
    path, skirt = _panels(tmp_path, gap=0.03, name="apart.obj")
    with caplog.at_level(logging.WARNING):
        g = read_obj(path)
    assert g.n_vertices == skirt.n_vertices + 112 and "welded" not in caplog.text and "open-edge" not in caplog.text
    from core.geometry import vertex_normals

    normals = vertex_normals(skirt.vertices.astype(np.float64), skirt.faces)
    outer = skirt.vertices + 0.0025 * normals
    write_obj(tmp_path / "shells.obj", np.concatenate([skirt.vertices, outer]),
              np.concatenate([skirt.faces, skirt.faces + skirt.n_vertices]))
    caplog.clear()
    with caplog.at_level(logging.WARNING):
        g = read_obj(tmp_path / "shells.obj")
    assert g.n_vertices == 2 * skirt.n_vertices and "seam vertices" not in caplog.text


def test_welding_keeps_uv_seams():
    """Two quads sharing an edge through repeated vertices, each with its own UV island: one edge, two UVs."""
    import tempfile
    from pathlib import Path

    text = ("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 1 0 0\nv 2 0 0\nv 2 1 0\nv 1 1 0\n"
            "vt 0 0\nvt .4 0\nvt .4 1\nvt 0 1\nvt .6 0\nvt 1 0\nvt 1 1\nvt .6 1\n"
            "f 1/1 2/2 3/3 4/4\nf 5/5 6/6 7/7 8/8\n")
    with tempfile.TemporaryDirectory() as d:
        (Path(d) / "two.obj").write_text(text)
        g = read_obj(Path(d) / "two.obj")
    assert g.n_vertices == 6 and g.uvs.shape == (8, 2)
    shared = np.intersect1d(g.faces[:2], g.faces[2:])
    assert len(shared) == 2  # the seam edge's two vertices
    for vertex in shared:
        uv = {tuple(g.uvs[g.face_uvs[k, j]]) for k, j in zip(*np.nonzero(g.faces == vertex))}
        assert len(uv) == 2  # one UV on each side of the seam


def test_material_libraries_are_found_beside_the_file(tmp_path, caplog):
    """`mtllib` names (one with a space, two in one statement) resolve against the OBJ's folder for its source
    mesh; one that is not there is warned about; a file without `usemtl` keeps none."""
    (tmp_path / "my shirt.mtl").write_text("newmtl a\n")
    (tmp_path / "extra.mtl").write_text("newmtl b\n")
    tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n"
    path = _write(tmp_path, "mtllib my shirt.mtl\nmtllib extra.mtl gone.mtl\n" + tri + "usemtl a\nf 1 2 3\n", "s.obj")
    with caplog.at_level(logging.WARNING, logger="formats.obj"):
        g = read_obj(path)
    assert g.source.libraries == (str((tmp_path / "my shirt.mtl").resolve()), str((tmp_path / "extra.mtl").resolve()))
    assert "material library 'gone.mtl' is not there" in caplog.text
    assert read_obj(_write(tmp_path, "mtllib extra.mtl\n" + tri + "f 1 2 3\n", "n.obj")).source is None


def test_written_material_libraries_read_back_with_spaces_in_their_names(tmp_path):
    """Several libraries, one named with a space (as a bake's OBJ frames name the garment's copies): one `mtllib`
    line each, so that reading the file back finds every one (in one statement, 'my shirt.mtl' split in two)."""
    (tmp_path / "extra.mtl").write_text("newmtl b\n")
    (tmp_path / "my shirt.mtl").write_text("newmtl a\n")
    path = tmp_path / "w.obj"
    write_obj(path, np.eye(3), np.array([[0, 1, 2]]), materials=np.array(["a"]), libraries=["extra.mtl", "my shirt.mtl"])
    assert read_obj(path).source.libraries == (str((tmp_path / "extra.mtl").resolve()),
                                               str((tmp_path / "my shirt.mtl").resolve()))


@pytest.mark.parametrize("name, kind", [("dress.ply", "PLY"), ("dress.FBX", "FBX"), ("dress.glb", "glTF"),
                                        ("dress.abc", "Alembic"), ("dress.zprj", "Marvelous Designer project")])
def test_a_mesh_of_another_format_is_named_for_what_it_is(tmp_path, name, kind):
    """A PLY (ASCII, so no binary content to tell) said "expected vertices ('v' lines), got none"."""
    from formats.obj import read_garment

    path = tmp_path / name
    path.write_text("ply\nformat ascii 1.0\nelement vertex 3\n")
    with pytest.raises(InputError) as info:
        read_garment(path)
    assert str(info.value) == (f"garment mesh '{path}': expected an OBJ or USD garment, got a {kind} file: export the "
                               "garment as OBJ (or USD) on the body's rest pose from the tool that made it")


_TRIANGLE = "v 0 0 0\nv 0.5 0 0\nv 0 0.5 0\n"


@pytest.mark.parametrize("text, message", [
    # an index past int64 raised OverflowError (a traceback) while filling the polygon array
    (_TRIANGLE + "f 1 2 100000000000000000000000000000\n", "vertex index 100000000000000000000000000000 out of range on "
     "line 4, beyond any file's vertex count"),
    # 1e200 is finite, but its squared distances overflowed the weld's k-d tree (ValueError, a traceback)
    ("v 0 0 0\nv 1e200 0 0\nv 0 0.5 0\nf 1 2 3\n", "expected coordinates within float32's range (+-3.4e+38), got "
     "1e+200 in the vertex on line 2"),
    # texture coordinates that every face uses, NaN: they went silently into every output
    (_TRIANGLE + "vt 0 0\nvt nan 1\nvt 1 1\nf 1/1 2/2 3/3\n", "expected finite texture coordinates, got NaN on line 5"),
    # Python's int() and float() take these, C's strtod (other OBJ readers) does not: read as 10, 1000 and 3
    (_TRIANGLE + "f 1 2 1_0\n", "expected an integer vertex index on line 4, got '1_0'"),
    ("v 0 0 0\nv 1_000 0 0\nv 0 0.5 0\nf 1 2 3\n", "expected a number in the vertex on line 2, got '1_000'"),
    ("v 0 0 0\nv \u0663 0 0\nv 0 0.5 0\nf 1 2 3\n", "expected a number in the vertex on line 2, got '\u0663'"),
    # a form feed inside a line ended it (str.splitlines), so every later line number was one too many
    ("v 0 0 0\nv 0.5\x0c0 0\nv 0 0.5 0\nf 1 2 3\nf 1 2 9\n", "vertex index 9 out of range on line 5, the file has 3"),
    # a NUL in a number was printed raw into the message
    ("v 0 0 0\nv 0.5\x00 0 0\nv 0 0.5 0\nf 1 2 3\n", "expected a number in the vertex on line 2, got '0.5\\x00'"),
    # index 0 said "only 3 defined before it", as if the file were short of vertices
    (_TRIANGLE + "f 1 2 0\n", "vertex index 0 out of range on line 4: OBJ indices start at 1"),
])
def test_bad_input_found_by_fuzzing_is_one_clear_line(tmp_path, text, message):
    path = tmp_path / "bad.obj"
    path.write_bytes(text.encode())
    with pytest.raises(InputError) as info:
        read_obj(path)
    assert f"garment mesh '{path}': " in str(info.value) and message in str(info.value)
    assert "\n" not in str(info.value) and "\x00" not in str(info.value)


def test_an_inf_coordinate_is_refused_without_numpy_warnings_on_stderr(tmp_path):
    """The weld and the degenerate-face check printed RuntimeWarnings (with source lines) before the error."""
    path = tmp_path / "inf.obj"
    path.write_text("v 0 0 0\nv inf 0 0\nv 0 0.5 0\nv 0.5 0.5 0\nf 1 2 3\nf 2 4 3\n")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(InputError, match="expected finite coordinates"):
            read_obj(path)


def test_a_material_library_name_no_file_can_have_is_warned_about_not_raised(tmp_path, caplog):
    """`mtllib` with a 300-character name raised OSError (File name too long) from Path.is_file."""
    path = tmp_path / "m.obj"
    path.write_text("mtllib " + "m" * 300 + ".mtl\nusemtl a\n" + _TRIANGLE + "f 1 2 3\n")
    with caplog.at_level(logging.WARNING):
        garment = read_obj(path)
    assert garment.source.libraries == () and "is not there" in caplog.text


def test_a_refused_garment_is_one_line_without_the_warnings_before_it(tmp_path, caplog):
    """A garment of one point was warned about twice (its welded vertices, its dropped face) and then refused:
    the refusal is the one line (`core.errors.warnings_held`); a garment read is warned about as before, once."""
    from formats.obj import read_garment

    one = tmp_path / "one.obj"
    one.write_text("v 0 1 0\nv 0 1 0\nv 0 1 0\nf 1 2 3\n")
    with caplog.at_level(logging.WARNING), pytest.raises(InputError, match="expected faces with an area"):
        read_garment(one)
    assert caplog.records == []
    kept = tmp_path / "kept.obj"
    kept.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 1 0\nf 1 2 3\nf 1 2 4\n")  # a face twice once welded
    with caplog.at_level(logging.WARNING):
        g = read_garment(kept)
    messages = [r.getMessage() for r in caplog.records]
    assert g.faces.shape == (1, 3) and len(messages) == len(set(messages)) >= 2
    assert any("welded 1 vertices" in m for m in messages)
