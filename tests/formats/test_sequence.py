"""Tests for formats/sequence.py: every form round-trips through read_sequence; bad input."""

import json
import warnings

import numpy as np
import pytest

from core.errors import InputError
from formats.obj import write_obj
from formats.sequence import _natural_key, read_sequence, write_npz_sequence, write_obj_sequence
from formats.usd import MeshTrack, write_usd_stage


def _animated(n_frames=3, n=4):
    x, y = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n))
    rest = np.stack([x.ravel(), y.ravel(), np.zeros(n * n)], axis=1)
    t = np.arange(n_frames)[:, None, None]
    points = (rest[None] + 0.05 * t * np.sin(rest[None] * 3 + t)).astype(np.float32)
    idx = np.arange(n * n).reshape(n, n)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    faces = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)]).astype(np.int64)
    return points, faces


def _body(n_frames=3):
    rng = np.random.default_rng(2)
    return rng.normal(size=(n_frames, 6, 3)).astype(np.float32), np.array([[0, 1, 2], [3, 4, 5]])


def test_obj_sequence_round_trip(tmp_path):
    points, faces = _animated()
    uvs = points[0, :, :2]
    out = tmp_path / "frames"
    paths = write_obj_sequence(out, points, faces, uvs=uvs, face_uvs=faces, fps=30)
    assert [p.name for p in paths] == ["frame_0000.obj", "frame_0001.obj", "frame_0002.obj"]
    assert json.loads((out / "sequence.json").read_text())["fps"] == 30
    assert "f 1/1 2/2 6/6" in paths[0].read_text()
    seq = read_sequence(out)
    assert seq.points.shape == points.shape and seq.points.dtype == np.float32
    np.testing.assert_allclose(seq.points, points, atol=1e-6)
    np.testing.assert_array_equal(seq.faces, faces)
    assert seq.faces.dtype == np.int64
    assert seq.fps == 30 and seq.body_points is None and seq.source == str(out)


def test_obj_frames_written_y_up_read_back_in_the_z_up_world(tmp_path):
    """up="y" (a bake's OBJ frames: the frame OBJ importers assume) writes the points turned -90 degrees about X
    and records it; read_sequence turns them back; an unknown 'up' recorded is one line."""
    from core.geometry import Y_UP_TO_Z_UP_MATRIX

    points, faces = _animated()
    paths = write_obj_sequence(tmp_path / "y", points, faces, fps=24, up="y")
    first = np.array([[float(x) for x in line.split()[1:]] for line in paths[0].read_text().splitlines()
                      if line.startswith("v ")])
    np.testing.assert_allclose(first, points[0] @ Y_UP_TO_Z_UP_MATRIX, atol=1e-6)  # (x, y, z) -> (x, z, -y)
    np.testing.assert_allclose(first[:, 1], points[0, :, 2], atol=1e-6)
    assert json.loads((tmp_path / "y" / "sequence.json").read_text())["up"] == "y"
    np.testing.assert_allclose(read_sequence(tmp_path / "y").points, points, atol=1e-6)
    meta = json.loads((tmp_path / "y" / "sequence.json").read_text())
    (tmp_path / "y" / "sequence.json").write_text(json.dumps({**meta, "up": "x"}))
    with pytest.raises(InputError, match="expected 'up' as \"y\" \\(frames written Y-up\\) or \"z\", got 'x'"):
        read_sequence(tmp_path / "y")


def test_obj_sequence_padding_and_no_fps(tmp_path):
    points, _ = _animated(n_frames=12)
    paths = write_obj_sequence(tmp_path / "long", points[:, :3], np.array([[0, 1, 2]]), prefix="f")
    assert paths[-1].name == "f0011.obj"
    assert read_sequence(tmp_path / "long").fps is None
    assert sorted(["f10000.obj", "f9999.obj", "f0002.obj"], key=_natural_key) == \
        ["f0002.obj", "f9999.obj", "f10000.obj"]


def test_obj_directory_sorted_by_frame_number(tmp_path):
    points, faces = _animated(n_frames=11)
    for t in range(11):  # unpadded names: lexical order would put 10 before 2
        write_obj(tmp_path / f"shot_{t}.obj", points[t], faces)
    seq = read_sequence(tmp_path, up="z")
    np.testing.assert_allclose(seq.points, points, atol=1e-6)


def test_obj_directory_quads_keep_frame0_split(tmp_path):
    # A quad whose shorter diagonal flips between frames: every frame keeps frame 0's split.
    q0 = "v 0 0 0\nv 1 0 0\nv 1.5 1 0\nv 0 1 0\nf 1 2 3 4\n"
    q1 = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv -0.5 1 0\nf 1 2 3 4\n"
    (tmp_path / "frame_0000.obj").write_text(q0)
    (tmp_path / "frame_0001.obj").write_text(q1)
    seq = read_sequence(tmp_path, up="z")
    np.testing.assert_array_equal(seq.faces, [[0, 1, 3], [1, 2, 3]])
    np.testing.assert_allclose(seq.points[1, 3], [-0.5, 1, 0])


def test_single_obj_is_one_frame(tmp_path):
    points, faces = _animated(n_frames=1)
    write_obj(tmp_path / "g.obj", points[0], faces)
    seq = read_sequence(tmp_path / "g.obj")
    assert seq.points.shape == (1,) + points.shape[1:] and seq.fps is None


def test_obj_frames_without_a_record_are_read_y_up_and_a_bake_frame_alone_as_its_folder_records(tmp_path):
    """OBJ frames with no sequence.json (Blender's, Maya's, Houdini's exports) and a single OBJ (a garment, a frame
    exported alone) were read as Z-up, so `render` drew them lying on their backs: they are read Y-up, as OBJ files
    are written, unless --up says otherwise; a sequence.json of fps alone too (another tool's: it was read Z-up,
    as the bakes before 2026-12-06 are, which record their prefix and count); one frame of a bake's folder is read as the folder records it (Y-up, its number and rate)."""
    from core.geometry import Y_UP_TO_Z_UP_MATRIX

    points, faces = _animated(n_frames=3)
    y_up = (points @ Y_UP_TO_Z_UP_MATRIX).astype(np.float32)  # as written Y-up: rows turned back
    exported = tmp_path / "exported"
    exported.mkdir()
    for t in range(3):
        write_obj(exported / f"cloth_{t + 1:04d}.obj", y_up[t], faces)
    np.testing.assert_allclose(read_sequence(exported).points, points, atol=1e-6)
    np.testing.assert_allclose(read_sequence(exported, up="z").points, y_up, atol=1e-6)
    np.testing.assert_allclose(read_sequence(exported / "cloth_0002.obj").points, points[1:2], atol=1e-6)
    (exported / "sequence.json").write_text('{"fps": 24}')  # a record of the rate alone: another tool's, Y-up
    np.testing.assert_allclose(read_sequence(exported).points, points, atol=1e-6)
    one = read_sequence(exported / "cloth_0002.obj")  # one of its frames read alone: as the folder is read
    np.testing.assert_allclose(one.points, points[1:2], atol=1e-6)
    assert one.fps == 24 and one.first_frame == 2
    (exported / "sequence.json").write_text('{"fps": 24, "up": "x"}')
    with pytest.raises(InputError, match="expected 'up' as"):
        read_sequence(exported / "cloth_0002.obj")
    (exported / "sequence.json").write_text("{broken")  # the folder's to refuse, not a garment's beside it
    write_obj(exported / "garment.obj", y_up[0], faces)
    np.testing.assert_allclose(read_sequence(exported / "garment.obj").points, points[:1], atol=1e-6)
    baked = tmp_path / "baked"
    write_obj_sequence(baked, points, faces, fps=24, up="y", start=40)
    one = read_sequence(baked / "frame_0041.obj")
    np.testing.assert_allclose(one.points, points[1:2], atol=1e-6)
    assert one.first_frame == 41 and one.fps == 24
    (baked / "other.obj").write_bytes((baked / "frame_0041.obj").read_bytes())  # not one of the recorded frames
    other = read_sequence(baked / "other.obj")
    assert other.first_frame == 0 and other.fps is None


@pytest.mark.parametrize("with_body", [False, True])
def test_npz_round_trip(tmp_path, with_body):
    points, faces = _animated()
    body_points, body_faces = _body() if with_body else (None, None)
    path = tmp_path / "bake.seq"  # any name: written exactly there
    write_npz_sequence(path, points.astype(np.float64), faces, fps=59.94,
                       body_points=body_points, body_faces=body_faces)
    path = path.rename(tmp_path / "bake.npz")
    seq = read_sequence(path)
    np.testing.assert_array_equal(seq.points, points)
    np.testing.assert_array_equal(seq.faces, faces)
    assert seq.fps == pytest.approx(59.94)
    if with_body:
        np.testing.assert_array_equal(seq.body_points, body_points)
        np.testing.assert_array_equal(seq.body_faces, body_faces)
    else:
        assert seq.body_points is None and seq.body_faces is None
    with np.load(path) as data:
        assert data["points"].dtype == np.float32


def test_npz_without_fps(tmp_path):
    points, faces = _animated()
    write_npz_sequence(tmp_path / "a.npz", points, faces)
    assert read_sequence(tmp_path / "a.npz").fps is None


@pytest.mark.parametrize("suffix", [".usd", ".usda"])
def test_usd_garment_and_body(tmp_path, suffix):
    points, faces = _animated()
    body_points, body_faces = _body()
    path = tmp_path / f"bake{suffix}"
    write_usd_stage(path, [MeshTrack("body", body_points, body_faces), MeshTrack("garment", points, faces)], fps=50)
    seq = read_sequence(path)
    np.testing.assert_array_equal(seq.points, points)
    np.testing.assert_array_equal(seq.faces, faces)
    np.testing.assert_array_equal(seq.body_points, body_points)
    np.testing.assert_array_equal(seq.body_faces, body_faces)
    assert seq.fps == 50
    # Another track by name: the body is still attached.
    as_body = read_sequence(path, track="body")
    np.testing.assert_array_equal(as_body.points, body_points)
    assert as_body.body_points is None


def test_a_bake_directory_reads_as_its_stage_else_its_obj_frames(tmp_path):
    """`garment metrics pred/ gt/` and `render` take a bake's own directory (<garment>_<motion>/): its USD stage
    (with the body), or its obj/ frames when there is no stage; a directory with neither is refused."""
    points, faces = _animated()
    body_points, body_faces = _body()
    d = tmp_path / "shirt_walk"
    write_usd_stage(d / "shirt_walk.usd", [MeshTrack("garment", points, faces), MeshTrack("body", body_points,
                                                                                          body_faces)], fps=30)
    write_obj_sequence(d / "obj", points + 1.0, faces, fps=30)
    (d / "summary.json").write_text("{}")
    seq = read_sequence(d)
    np.testing.assert_array_equal(seq.points, points)  # the stage, not the frames
    np.testing.assert_array_equal(seq.body_points, body_points)
    (d / "shirt_walk.usd").unlink()
    np.testing.assert_allclose(read_sequence(d).points, points + 1.0, atol=1e-6)
    (tmp_path / "neither").mkdir()
    (tmp_path / "neither" / "summary.json").write_text("{}")
    with pytest.raises(InputError, match=r"expected OBJ frames \(frame_0000.obj, ...\) or a `garment bake` output"):
        read_sequence(tmp_path / "neither")


def test_usd_only_mesh_and_ambiguous_tracks(tmp_path):
    points, faces = _animated()
    single = tmp_path / "single.usd"
    write_usd_stage(single, [MeshTrack("shirt", points, faces)], fps=30)
    np.testing.assert_array_equal(read_sequence(single).points, points)
    two = tmp_path / "two.usd"
    write_usd_stage(two, [MeshTrack("shirt", points, faces), MeshTrack("skirt", points, faces)], fps=30)
    with pytest.raises(InputError, match=r"expected a mesh named 'garment', got meshes \['shirt', 'skirt'\]"):
        read_sequence(two)
    assert read_sequence(two, track="skirt").points.shape == points.shape


def test_bad_paths(tmp_path):
    with pytest.raises(InputError, match=r"garment sequence '.*nothing\.npz': not found"):
        read_sequence(tmp_path / "nothing.npz")
    odd = tmp_path / "bake.abc"
    odd.write_text("x")
    with pytest.raises(InputError, match=r"expected a directory of OBJ frames, .npz, .obj or .usd/.usda/.usdc, "
                                         r"got '.abc'"):
        read_sequence(odd)
    empty = tmp_path / "empty"
    empty.mkdir()
    (empty / "notes.txt").write_text("no frames here")
    with pytest.raises(InputError, match=r"garment sequence '.*empty': expected OBJ frames"):
        read_sequence(empty)


def test_obj_frames_with_differing_topology(tmp_path, caplog):
    points, faces = _animated(n_frames=4)
    write_obj_sequence(tmp_path, points, faces)
    write_obj(tmp_path / "frame_0002.obj", points[2], faces[::-1])  # its faces in another order: frame 0's taken
    with caplog.at_level("WARNING"):
        np.testing.assert_array_equal(read_sequence(tmp_path).faces, faces)
    assert "1 of its frames split their polygons otherwise than frame_0000.obj (frame_0002.obj: face 1 is" in \
        caplog.text
    renumbered = np.roll(np.arange(16), 1)  # the same mesh, its vertices numbered otherwise: refused, not read
    write_obj(tmp_path / "frame_0002.obj", points[2][np.argsort(renumbered)], renumbered[faces])
    with pytest.raises(InputError, match=r"expected every frame to share the faces of frame_0000.obj \(or to split "
                                         r"its polygons otherwise\), got other faces in frame_0002.obj \(face 1 is "
                                         r".*\): its vertices numbered otherwise\?"):
        read_sequence(tmp_path)
    write_obj(tmp_path / "frame_0002.obj", points[2, :-1], faces[faces.max(axis=1) < 15])
    with pytest.raises(InputError, match=r"got 15 vertices, 16 faces in frame_0002.obj"):
        read_sequence(tmp_path)
    (tmp_path / "frame_0003.obj").write_text("v 0 0 0\nf 1 2\n")
    write_obj(tmp_path / "frame_0002.obj", points[2], faces)  # (not deleted: a gap is refused before parsing)
    with pytest.raises(InputError, match=r"'.*frame_0003.obj': expected faces of 3 to 256 vertices, got a face with 2"):
        read_sequence(tmp_path)


def test_bad_sequence_json(tmp_path):
    points, faces = _animated()
    write_obj_sequence(tmp_path, points, faces, fps=30)
    (tmp_path / "sequence.json").write_text("{fps: 30")
    with pytest.raises(InputError, match=r"sequence.json': expected JSON like"):
        read_sequence(tmp_path)
    (tmp_path / "sequence.json").write_text('{"fps": -3}')
    with pytest.raises(InputError, match=r"sequence.json': expected fps > 0, got -3"):
        read_sequence(tmp_path)


@pytest.mark.parametrize("arrays, message", [
    ({"faces": np.zeros((1, 3), int)}, "expected key 'points', got keys ['faces']"),
    ({"points": np.zeros((3, 4)), "faces": np.zeros((1, 3), int)}, "expected points (T, V, 3)"),
    ({"points": np.zeros((2, 4, 3)), "faces": np.zeros((1, 4), int)}, "expected faces (F, 3) integers"),
    ({"points": np.zeros((2, 4, 3)), "faces": np.array([[0, 1, 4]])}, "faces index 4 out of range for 4 vertices"),
    ({"points": np.zeros((2, 4, 3)), "faces": np.array([[0, 1, 2]]), "fps": np.float64(0)}, "expected fps > 0"),
    ({"points": np.zeros((2, 4, 3)), "faces": np.array([[0, 1, 2]]), "body_points": np.zeros((3, 5, 3))},
     "expected body_points with 2 frames like points, got 3"),
    ({"points": np.zeros((2, 4, 3)), "faces": np.array([[0, 1, 2]]), "body_points": np.zeros((2, 5, 3)),
      "body_faces": np.array([[0, 1, 7]])}, "body_faces index 7 out of range for 5 vertices"),
])
def test_bad_npz(tmp_path, arrays, message):
    path = tmp_path / "bad.npz"
    np.savez(path, **arrays)
    with pytest.raises(InputError) as err:
        read_sequence(path)
    assert message in str(err.value) and f"'{path}'" in str(err.value)


def test_corrupt_npz(tmp_path):
    path = tmp_path / "corrupt.npz"
    path.write_bytes(b"not a zip")
    with pytest.raises(InputError, match=r"cannot be read as .npz"):
        read_sequence(path)


def test_obj_frames_with_a_polygon_of_five_corners_keep_frame_0s_triangles(tmp_path):
    """Each frame a pentagon, its corners moving (frame 2 makes it concave elsewhere): every frame gets frame 0's
    three triangles, so vertex and face numbering hold through the sequence."""
    base = np.array([[0, 0, 0], [2, 0, 0], [2.5, 1, 0], [1, 2, 0], [-0.5, 1, 0]], float)
    for t in range(3):
        pts = base + [0, 0, 0.1 * t]
        if t == 2:
            pts[1] = [1, 1.2, 0.2]  # a dent: frame 2 alone would be split differently
        (tmp_path / f"frame_{t:04d}.obj").write_text(
            "".join(f"v {x} {y} {z}\n" for x, y, z in pts) + "f 1 2 3 4 5\n")
    seq = read_sequence(tmp_path, up="z")
    assert seq.points.shape == (3, 5, 3) and seq.faces.shape == (3, 3)
    np.testing.assert_allclose(seq.points[2, 1], [1, 1.2, 0.2])


@pytest.mark.parametrize("names, missing", [
    ([f"frame_{t:04d}" for t in (0, 1, 2, 4, 5)], "frame_0003.obj"),  # write_obj_sequence / bake names
    ([f"skirt_{t:06d}" for t in (1, 2, 4)], "skirt_000003.obj"),  # Blender
    ([f"skirt.{t:04d}" for t in (1, 2, 3, 5)], "skirt.0004.obj"),  # Houdini
    ([f"f{t}" for t in (8, 9, 11)], "f10.obj"),  # unpadded
])
def test_obj_frames_with_a_gap_are_refused_naming_the_missing_frame(tmp_path, names, missing):
    points, faces = _animated(n_frames=len(names))
    for name, pts in zip(names, points):
        write_obj(tmp_path / f"{name}.obj", pts, faces)
    with pytest.raises(InputError) as info:
        read_sequence(tmp_path)
    assert str(info.value).startswith(f"garment sequence '{tmp_path}': expected consecutive frames")
    assert f"got no {missing} " in str(info.value) and "\n" not in str(info.value)


def test_obj_frames_fewer_than_the_sequence_json_records_are_refused(tmp_path):
    """A frame missing at the end leaves no gap among the files: `sequence.json`'s frame count tells."""
    points, faces = _animated(n_frames=5)
    write_obj_sequence(tmp_path, points, faces, fps=30)
    (tmp_path / "frame_0004.obj").unlink()
    with pytest.raises(InputError, match=r"sequence.json says 5 frames were written, got 4 frames "
                                         r"\(frame_0000.obj to frame_0003.obj\): frames missing at the end\?"):
        read_sequence(tmp_path)


@pytest.mark.parametrize("names", [
    [f"skirt_{t:06d}" for t in (1, 2, 3)], [f"skirt.{t:04d}" for t in (101, 102, 103)], ["a_9", "a_10", "a_11"]])
def test_obj_frames_numbered_from_any_start_are_read_in_order(tmp_path, names):
    points, faces = _animated(n_frames=3)
    for name, pts in zip(names, points):
        write_obj(tmp_path / f"{name}.obj", pts, faces)
    np.testing.assert_allclose(read_sequence(tmp_path, up="z").points, points, atol=1e-6)


def test_a_stray_obj_among_the_frames_is_left_out_with_a_warning(tmp_path, caplog):
    points, faces = _animated(n_frames=3)
    write_obj_sequence(tmp_path, points, faces, fps=30)
    write_obj(tmp_path / "other.obj", points[0] + 1, faces)
    write_obj(tmp_path / "shot_7.obj", points[0] + 2, faces)
    with caplog.at_level("WARNING"):
        seq = read_sequence(tmp_path)
    np.testing.assert_allclose(seq.points, points, atol=1e-6)
    assert [r.getMessage() for r in caplog.records if "left out" in r.getMessage()] == [
        f"garment sequence '{tmp_path}': left out 2 OBJ files not numbered like the frames (frame_0000.obj): "
        "other.obj, shot_7.obj"]


def test_obj_frames_with_a_repeated_frame_number_are_refused(tmp_path):
    points, faces = _animated(n_frames=3)
    for name, pts in zip(["f1", "f01", "f2"], points):
        write_obj(tmp_path / f"{name}.obj", pts, faces)
    with pytest.raises(InputError, match="one file per frame number, got f0?1.obj and f0?1.obj for frame 1"):
        read_sequence(tmp_path)


def test_a_refused_sequence_is_its_one_line_without_the_warnings_before_it(tmp_path, caplog):
    """The stray file's warning comes before the frames are found wanting: the refusal alone is said."""
    points, faces = _animated(n_frames=3)
    for name, pts in zip(["f1", "f01", "f2"], points):
        write_obj(tmp_path / f"{name}.obj", pts, faces)
    write_obj(tmp_path / "other.obj", points[0] + 1, faces)
    with caplog.at_level("WARNING"), pytest.raises(InputError, match="one file per frame number"):
        read_sequence(tmp_path)
    assert not caplog.records
    (tmp_path / "f01.obj").unlink()
    with caplog.at_level("WARNING"):
        read_sequence(tmp_path)
    assert [r.getMessage() for r in caplog.records if "left out 1 OBJ file" in r.getMessage()]


def test_one_frame_is_one_frame_in_messages(tmp_path):
    points, faces = _animated(n_frames=1)
    body_points, body_faces = _body(n_frames=2)
    np.savez(tmp_path / "s.npz", points=points, faces=faces, body_points=body_points, body_faces=body_faces)
    with pytest.raises(InputError, match="expected body_points with 1 frame like points, got 2$"):
        read_sequence(tmp_path / "s.npz")


@pytest.mark.parametrize("written, recorded, found, message", [
    # frames renamed after writing: the prefix (and first number) differ
    pytest.param(dict(prefix="shirt_", start=5), dict(prefix="frame_", start=0, frames=10),
                 "shirt_0005.obj to shirt_0014.obj",
                 "expected frames frame_0000.obj to frame_0009.obj (it records prefix 'frame_' and start 0), got "
                 "shirt_0005.obj to shirt_0014.obj: frames renamed or renumbered, or the sequence.json of other "
                 "frames?", id="other prefix"),
    # the first frame is not the one recorded
    pytest.param(dict(), dict(prefix="frame_", start=3, frames=10), "frame_0000.obj to frame_0009.obj",
                 "expected frames frame_0003.obj to frame_0012.obj (it records start 3), got frame_0000.obj to "
                 "frame_0009.obj: frames renamed or renumbered, or the sequence.json of other frames?",
                 id="other start"),
    # `start` alone (no prefix, no count) is held to the files too
    pytest.param(dict(start=1001), dict(fps=30, start=1000), "frame_1001.obj to frame_1010.obj",
                 "expected frames frame_1000.obj to frame_1009.obj (it records start 1000), got frame_1001.obj to "
                 "frame_1010.obj: frames renamed or renumbered, or the sequence.json of other frames?",
                 id="start alone"),
])
def test_obj_frames_other_than_sequence_json_records_are_refused(tmp_path, written, recorded, found, message):
    """`write_obj_sequence` records its `prefix` and `start` beside `frames`: files that do not begin where the
    record says, or carry another prefix, are refused naming sequence.json, the frames it records and those found."""
    points, faces = _animated(n_frames=10, n=2)
    write_obj_sequence(tmp_path, points, faces[:1], fps=30, **written)
    (tmp_path / "sequence.json").write_text(json.dumps(recorded))
    with pytest.raises(InputError) as info:
        read_sequence(tmp_path)
    assert str(info.value) == f"garment sequence '{tmp_path / 'sequence.json'}': {message}"
    assert found in str(info.value)


def test_obj_frames_missing_at_the_start_are_refused_by_the_sequence_json_start(tmp_path):
    """A frame missing at the start leaves no gap among the files, and the count alone would blame the end."""
    points, faces = _animated(n_frames=5)
    write_obj_sequence(tmp_path, points, faces, fps=30)
    (tmp_path / "frame_0000.obj").unlink()
    with pytest.raises(InputError) as info:
        read_sequence(tmp_path)
    assert str(info.value) == (f"garment sequence '{tmp_path / 'sequence.json'}': expected frames frame_0000.obj "
                               "to frame_0004.obj (it records start 0), got frame_0001.obj to frame_0004.obj: "
                               "frames missing at the start?")


@pytest.mark.parametrize("key, value, message", [
    ("start", "3", "expected 'start' as a whole number >= 0, got '3'"),
    ("start", -1, "expected 'start' as a whole number >= 0, got -1"),
    ("frames", 2.5, "expected 'frames' as a whole number >= 0, got 2.5"),
    ("prefix", 7, "expected 'prefix' as a string (frame_ of frame_0000.obj), got 7"),
])
def test_a_sequence_json_start_prefix_or_frames_of_the_wrong_kind_is_refused(tmp_path, key, value, message):
    points, faces = _animated()
    write_obj_sequence(tmp_path, points, faces, fps=30)
    meta = json.loads((tmp_path / "sequence.json").read_text())
    (tmp_path / "sequence.json").write_text(json.dumps({**meta, key: value}))
    with pytest.raises(InputError) as info:
        read_sequence(tmp_path)
    assert str(info.value) == f"garment sequence '{tmp_path / 'sequence.json'}': {message}"


@pytest.mark.parametrize("names, meta", [
    ([f"skirt_{t:06d}" for t in (1, 2, 3)], {"fps": 24}),  # Blender, a sequence.json of another tool: fps alone
    ([f"skirt.{t:04d}" for t in (101, 102, 103)], {"fps": 24, "frames": 3}),  # Houdini
    (["a_9", "a_10", "a_11"], {"fps": 24, "start": 9.0}),  # unpadded, natural order; a JSON number 9.0 is 9
    ([f"f1{t:04d}" for t in (0, 1, 2)], {"fps": 24, "prefix": "f1", "start": 0, "frames": 3}),  # prefix ends in 1
    ([f"Frame_{t:04d}" for t in (7, 8, 9)], {"fps": 24, "prefix": "frame_", "start": 7, "frames": 3}),  # any case
])
def test_obj_frames_that_agree_with_sequence_json_or_meet_one_without_prefix_and_start_are_read(tmp_path, names,
                                                                                                 meta):
    points, faces = _animated(n_frames=3)
    for name, pts in zip(names, points):
        write_obj(tmp_path / f"{name}.obj", pts, faces)
    (tmp_path / "sequence.json").write_text(json.dumps(meta))
    seq = read_sequence(tmp_path, up="z")  # (the frames' names and numbers tested here; another tool's: Y-up)
    np.testing.assert_allclose(seq.points, points, atol=1e-6)
    assert seq.fps == 24
    write_obj_sequence(tmp_path / "from_1001", points, faces, fps=30, start=1001, prefix="take2_")
    np.testing.assert_allclose(read_sequence(tmp_path / "from_1001").points, points, atol=1e-6)


def test_the_frames_sequence_json_records_are_read_beside_more_other_numbered_objs(tmp_path, caplog):
    """The prefix sequence.json records picks the frames, even where other numbered OBJs outnumber them."""
    points, faces = _animated(n_frames=3)
    write_obj_sequence(tmp_path, points, faces, fps=30)
    for t in range(5):
        write_obj(tmp_path / f"shirt_{t:04d}.obj", points[0] + 1, faces)
    with caplog.at_level("WARNING"):
        seq = read_sequence(tmp_path)
    np.testing.assert_allclose(seq.points, points, atol=1e-6)
    assert any("left out 5 OBJ files not numbered like the frames (frame_0000.obj): shirt_0000.obj" in r.getMessage()
               for r in caplog.records)


# Found by fuzzing the readers (2026-12-04).
def _fuzz_points():
    return np.zeros((2, 3, 3), np.float32) + np.eye(3, dtype=np.float32)


@pytest.mark.parametrize("points, needle", [
    (_fuzz_points() + 1j, "real numbers"),  # complex: the imaginary part was dropped (ComplexWarning), values read
])
def test_points_of_the_wrong_kind_are_refused(tmp_path, points, needle):
    np.savez(tmp_path / "s.npz", points=points, faces=np.array([[0, 1, 2]]))
    with pytest.raises(InputError, match=needle):
        read_sequence(tmp_path / "s.npz")


def test_points_past_float32_are_refused_without_an_overflow_warning(tmp_path):
    np.savez(tmp_path / "s.npz", points=_fuzz_points().astype(np.float64) * 1e39, faces=np.array([[0, 1, 2]]))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        seq = read_sequence(tmp_path / "s.npz")  # Inf: the caller names the frame and vertex (metrics, render)
    assert np.isinf(seq.points).any()


def test_an_npy_named_npz_is_named_for_what_it_is(tmp_path):
    np.save(tmp_path / "s.npy", _fuzz_points())
    (tmp_path / "s.npy").rename(tmp_path / "s.npz")
    with pytest.raises(InputError, match="it is a single .npy array"):
        read_sequence(tmp_path / "s.npz")


def test_a_boolean_fps_is_refused(tmp_path):
    (tmp_path / "seq").mkdir()
    for t in range(2):
        (tmp_path / "seq" / f"frame_{t:04d}.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    (tmp_path / "seq" / "sequence.json").write_text(json.dumps({"fps": True}))
    with pytest.raises(InputError, match="expected fps as one positive number, got True"):
        read_sequence(tmp_path / "seq")


def test_a_folder_of_two_numbered_sequences_is_refused_naming_both(tmp_path):
    """Houdini's and Maya's export folders hold the body's frames beside the cloth's (body.0001.obj, cloth.0001.obj):
    the first by name was read (the body) with a warning calling the cloth's frames "not numbered like the
    frames". Refused, naming both; a sequence.json's prefix picks one."""
    points, faces = _animated(n_frames=3)
    for t in range(3):
        write_obj(tmp_path / f"body.{t + 1:04d}.obj", points[t] + 1, faces)
        write_obj(tmp_path / f"cloth.{t + 1:04d}.obj", points[t], faces)
    with pytest.raises(InputError) as e:
        read_sequence(tmp_path)
    assert str(e.value) == (f"garment sequence '{tmp_path}': expected the frames of one garment, got 2 numbered "
                            "sequences: body.0001.obj (3 files), cloth.0001.obj (3 files): give a folder holding one "
                            "(or a sequence.json naming its 'prefix')")
    (tmp_path / "sequence.json").write_text(json.dumps({"prefix": "cloth.", "start": 1, "up": "z"}))
    np.testing.assert_allclose(read_sequence(tmp_path).points, points, atol=1e-6)
    # fewer numbered files of another name beside the frames (backup1.obj, backup2.obj): left out, warned
    (tmp_path / "sequence.json").unlink()
    for t in range(3):
        (tmp_path / f"body.{t + 1:04d}.obj").unlink()
    for k in (1, 2):
        write_obj(tmp_path / f"backup{k}.obj", points[0] + 1, faces)
    np.testing.assert_allclose(read_sequence(tmp_path, up="z").points, points, atol=1e-6)


def test_a_sequence_json_of_fps_alone_reads_other_tools_frames_y_up(tmp_path, caplog):
    """Another tool's folder given a sequence.json of its rate alone ({"fps": 24}, as the render help suggests
    recording one) was read Z-up, on its back; a bake's of before 2026-12-06 (its prefix and count recorded, no
    up) stays Z-up. An --up against the one recorded is warned of, and taken."""
    from core.geometry import Y_UP_TO_Z_UP_MATRIX

    points, faces = _animated(n_frames=2)
    y_up = points @ Y_UP_TO_Z_UP_MATRIX  # as Blender writes this tool's Z-up points
    for t in range(2):
        write_obj(tmp_path / f"shirt_{t + 1:06d}.obj", y_up[t], faces)
    (tmp_path / "sequence.json").write_text(json.dumps({"fps": 24}))
    seq = read_sequence(tmp_path)
    np.testing.assert_allclose(seq.points, points, atol=1e-5)
    assert seq.fps == 24
    (tmp_path / "sequence.json").write_text(json.dumps({"fps": 24, "up": "Y"}))  # in capitals: the same
    np.testing.assert_allclose(read_sequence(tmp_path).points, points, atol=1e-5)
    old = tmp_path / "old_bake"
    write_obj_sequence(old, points, faces, fps=30, up="z")
    meta = json.loads((old / "sequence.json").read_text())
    del meta["up"]
    (old / "sequence.json").write_text(json.dumps(meta))
    np.testing.assert_allclose(read_sequence(old).points, points, atol=1e-6)
    new = tmp_path / "bake"
    write_obj_sequence(new, points, faces, fps=30, up="y")
    with caplog.at_level("WARNING"):
        np.testing.assert_allclose(read_sequence(new, up="y").points, points, atol=1e-5)
        assert not caplog.records  # as recorded: nothing to say
        np.testing.assert_allclose(read_sequence(new, up="z").points, y_up, atol=1e-5)
    assert [r.getMessage() for r in caplog.records] == [
        f"--up z: garment sequence '{new}' records its frames written Y-up (sequence.json): read Z-up"]


def test_frames_triangulated_again_take_the_first_frames_faces_with_a_warning(tmp_path, caplog):
    """Blender's Triangulate (Beauty) and Houdini's Divide split a deforming quad mesh along other diagonals from
    frame to frame: refused with "expected ... (16 vertices, 18 faces), got 16 vertices, 18 faces". The points
    correspond vertex by vertex: read with the first frame's faces, the first difference named."""
    points, faces = _animated(n_frames=3)
    other = faces.copy()
    other[0] = [faces[0][0], faces[0][1], faces[9][2]]  # the first quad split along its other diagonal
    other[9] = [faces[0][1], faces[9][1], faces[9][2]]
    for t in range(3):
        write_obj(tmp_path / f"cloth_{t:04d}.obj", points[t], faces if t != 1 else other)
    with caplog.at_level("WARNING"):
        seq = read_sequence(tmp_path, up="z")
    np.testing.assert_allclose(seq.points, points, atol=1e-6)
    np.testing.assert_array_equal(seq.faces, faces)
    a, b = " ".join(str(i + 1) for i in other[0]), " ".join(str(i + 1) for i in faces[0])
    assert [r.getMessage() for r in caplog.records] == [
        f"garment sequence '{tmp_path}': 1 of its frames split their polygons otherwise than cloth_0000.obj "
        f"(cloth_0001.obj: face 1 is {a}, the first frame's {b}): read with cloth_0000.obj's faces (triangulated "
        "again in each frame? export the polygons, or triangulate once before the animation)"]
    write_obj(tmp_path / "cloth_0002.obj", np.vstack([points[2], [[9, 9, 9]]]), faces)  # a vertex more: refused
    with pytest.raises(InputError, match=r"expected every frame to share the vertices of cloth_0000.obj \(16 "
                                         r"vertices, 18 faces\), got 17 vertices, 18 faces in cloth_0002.obj"):
        read_sequence(tmp_path)
