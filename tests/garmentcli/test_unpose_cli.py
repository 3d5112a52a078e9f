"""`garment unpose`: an A-posed garment to the rest pose, written as an OBJ that `bake` takes; bad input."""

import logging
from pathlib import Path

import numpy as np
import pytest

from formats.obj import read_obj, write_obj
from tests.garmentcli.cli import invoke
from tests.garmentcli.conftest import write_motion

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


@pytest.fixture(scope="module")
def a_posed(tmp_path_factory):
    """The example t-shirt skinned into the A-pose (what a garment modelled on an A-posed avatar looks like)."""
    from tests.core.test_unpose import _posed

    from core.body import default_body
    from core.unpose import a_pose

    body = default_body()
    g = read_obj(EXAMPLES / "tshirt.obj")
    path = tmp_path_factory.mktemp("unpose") / "shirt.obj"
    posed = _posed(g, body, a_pose(body))
    write_obj(path, posed.vertices, posed.faces, posed.uvs, posed.face_uvs)
    return path, g


def test_unpose_writes_the_rest_garment_that_bake_takes(a_posed, tmp_path):
    path, rest = a_posed
    out = tmp_path / "rest.obj"
    r = invoke(["unpose", path, "--pose", "apose", "--out", out])
    assert r.exit_code == 0, r.output
    assert "6698 vertices moved to the rest pose from A-pose, arms lowered 45 degrees" in r.output
    g = read_obj(out)
    assert np.percentile(np.linalg.norm(g.vertices - rest.vertices, axis=1), 99) < 5e-3
    assert g.uvs is not None and np.array_equal(g.face_uvs, rest.face_uvs)
    r = invoke(["bake", out, EXAMPLES / "walk.npz", "--frames", "0:3", "--out", tmp_path / "bake"])
    assert r.exit_code == 0, r.output
    # The default output sits beside the input; a second run is refused without --overwrite, nothing touched.
    r = invoke(["unpose", path, "--pose", "apose"])
    assert r.exit_code == 0 and (path.parent / "shirt_rest.obj").is_file()
    before = (path.parent / "shirt_rest.obj").stat().st_mtime_ns
    r = invoke(["unpose", path, "--pose", "apose"])
    assert r.exit_code != 0 and "exists: pass --overwrite" in r.output
    assert (path.parent / "shirt_rest.obj").stat().st_mtime_ns == before


def test_the_round_trip_printed_is_that_of_the_file_written(a_posed, tmp_path):
    """The round trip `unpose` prints was that of the garment in memory, its polygons split at the posed positions;
    bake reads the file written and splits them at the rest ones (an A-posed t-shirt of quads: 1.8 mm printed, 4.5
    mm baked): it is the file's, baked back by lbs's defaults (`core.unpose.baked_back_error`)."""
    import re

    from core.body import default_body
    from core.unpose import a_pose, baked_back_error

    path, _ = a_posed
    out = tmp_path / "rest.obj"
    r = invoke(["unpose", path, "--pose", "apose", "--out", out])
    assert r.exit_code == 0, r.output
    printed = float(re.search(r"skinned back into the pose, ([0-9.]+) mm", r.output).group(1))
    body = default_body()
    expected = baked_back_error(read_obj(out), body, a_pose(body), None, read_obj(path).vertices) * 1e3
    assert printed == pytest.approx(expected, abs=0.051) and 0.1 < printed < 10.0


def test_unpose_keeps_the_material_library(a_posed, tmp_path):
    """A garment naming a material library: written beside it, the result names the same library; written
    elsewhere, a copy goes beside the result (its texture path leading to the texture), refused over an
    existing file without --overwrite."""
    path, _ = a_posed
    folder = tmp_path / "asset"
    folder.mkdir()
    (folder / "t.png").write_bytes(b"png")
    (folder / "shirt.mtl").write_text("newmtl cotton\nmap_Kd t.png\n")
    shirt = folder / "shirt.obj"
    shirt.write_text("mtllib shirt.mtl\nusemtl cotton\n" + path.read_text())
    r = invoke(["unpose", shirt, "--pose", "apose"])
    assert r.exit_code == 0, r.output
    assert "mtllib shirt.mtl" in (folder / "shirt_rest.obj").read_text().splitlines()
    out = tmp_path / "elsewhere" / "rest.obj"
    r = invoke(["unpose", shirt, "--pose", "apose", "--out", out])
    assert r.exit_code == 0, r.output
    assert "mtllib shirt.mtl" in out.read_text().splitlines() and "usemtl cotton" in out.read_text()
    assert (out.parent / "shirt.mtl").read_text().splitlines()[1] == "map_Kd ../asset/t.png"
    out.unlink()
    r = invoke(["unpose", shirt, "--pose", "apose", "--out", out])
    assert r.exit_code != 0 and "shirt.mtl' (GARMENT's material library" in r.output and not out.exists()


def test_unpose_writes_usd_that_reads_back_as_its_obj_and_bakes(a_posed, tmp_path):
    """--out .usda/.usd: one static mesh in the rest frame (Y-up, metres) with the OBJ's points, UVs and material
    subsets (it was refused: unpose wrote OBJ only); bake takes it."""
    from pxr import Usd, UsdGeom

    from formats.obj import read_garment

    path, _ = a_posed
    folder = tmp_path / "asset"
    folder.mkdir()
    (folder / "shirt.mtl").write_text("newmtl cotton\nKd 0.2 0.4 0.6\n")
    shirt = folder / "shirt.obj"
    shirt.write_text("mtllib shirt.mtl\nusemtl cotton\n" + path.read_text())
    obj, usd = tmp_path / "rest.obj", tmp_path / "rest.usda"
    for out in (obj, usd):
        r = invoke(["unpose", shirt, "--pose", "apose", "--out", out])
        assert r.exit_code == 0, r.output
    stage = Usd.Stage.Open(str(usd))
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.y and UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/Root/garment"))
    assert [s.GetPrim().GetName() for s in UsdGeom.Subset.GetAllGeomSubsets(mesh)] == ["cotton"]
    a, b = read_garment(obj), read_garment(usd)
    np.testing.assert_allclose(b.vertices, a.vertices, atol=1e-6)
    assert np.array_equal(b.faces, a.faces) and np.allclose(b.uvs[b.face_uvs], a.uvs[a.face_uvs], atol=1e-6)
    r = invoke(["bake", usd, EXAMPLES / "walk.npz", "--frames", "0:2", "--method", "lbs", "--out", tmp_path / "b"])
    assert r.exit_code == 0, r.output
    # that USD unposed (as it is) to an OBJ: its material's colour in a library beside it (it wrote `usemtl cotton`
    # alone: the colour lost); an existing library of that name is not replaced without --overwrite
    back = tmp_path / "back.obj"
    r = invoke(["unpose", usd, "--pose", "tpose", "--betas", "0", "--out", back])
    assert r.exit_code == 0, r.output
    assert back.read_text().splitlines()[1] == "mtllib back.mtl"
    assert (tmp_path / "back.mtl").read_text() == "newmtl cotton\nKd 0.2 0.4 0.6\n"
    back.unlink()
    r = invoke(["unpose", usd, "--pose", "tpose", "--betas", "0", "--out", back])
    assert r.exit_code != 0 and f"output '{tmp_path / 'back.mtl'}' (GARMENT's material library, written beside " \
        "the result) exists: pass --overwrite" in r.output and not back.exists()


def test_unpose_writes_the_files_own_points(a_posed, tmp_path):
    """A stray vertex no face uses (the file's last) is written back where its nearest vertex went: the output has
    the input's points, in order."""
    path, _ = a_posed
    lines = path.read_text().splitlines()
    last_v = max(i for i, line in enumerate(lines) if line.startswith("v "))
    stray = tmp_path / "stray.obj"
    stray.write_text("\n".join(lines[:last_v + 1] + ["v 0.0 0.1 0.0"] + lines[last_v + 1:]) + "\n")
    out = tmp_path / "rest.obj"
    r = invoke(["unpose", stray, "--pose", "apose", "--out", out])
    assert r.exit_code == 0, r.output
    written = [line for line in out.read_text().splitlines() if line.startswith("v ")]
    assert len(written) == 6699
    rest = np.array([[float(x) for x in line.split()[1:]] for line in written])
    plain = read_obj(out)  # the stray dropped again on reading
    assert plain.n_vertices == 6698
    nearest = np.argmin(np.linalg.norm(read_obj(stray).vertices - [0.0, 0.1, 0.0], axis=1))
    np.testing.assert_allclose(rest[-1], rest[nearest], atol=1e-6)


def test_unpose_takes_off_the_body_shape_the_garment_was_authored_on(tmp_path, caplog):
    """The example trousers shaped to betas (2, -1, 0.5) as bake shapes them (the garment authored on that body):
    `--pose tpose --betas 2,-1,0.5` brings them back to the mean shape, within a few millimetres; the A-pose and
    that shape together too."""
    from core.body import default_body
    from core.skinning import bind_garment, shaped_garment
    from core.unpose import a_pose
    from tests.core.test_unpose import _posed

    body = default_body()
    g = read_obj(EXAMPLES / "trousers.obj")
    betas = np.array([2.0, -1.0, 0.5], np.float32)
    shaped = shaped_garment(g.vertices, bind_garment(g, body), body.fit_betas(betas))
    write_obj(tmp_path / "shaped.obj", shaped, g.faces)
    assert np.linalg.norm(shaped - g.vertices, axis=1).max() > 0.02  # the shape moved it by centimetres
    caplog.clear()  # fit_betas above padded them, as it says
    with caplog.at_level(logging.WARNING):
        r = invoke(["unpose", tmp_path / "shaped.obj", "--pose", "tpose", "--betas", "2,-1,0.5",
                    "--out", tmp_path / "back.obj"])
    assert r.exit_code == 0, r.output
    assert "moved to the rest pose and mean shape from the rest pose, shape 2,-1,0.5" in r.output
    assert "padded" not in caplog.text  # the rest are 0, as --betas' help says
    err = np.linalg.norm(read_obj(tmp_path / "back.obj").vertices - g.vertices, axis=1)
    assert np.percentile(err, 99) < 3e-3 and err.mean() < 1e-3
    posed = _posed(g, body, a_pose(body), betas=betas)
    write_obj(tmp_path / "both.obj", posed.vertices, posed.faces)
    r = invoke(["unpose", tmp_path / "both.obj", "--pose", "apose", "--betas", "2,-1,0.5" + ",0" * 13,
                "--out", tmp_path / "back2.obj"])
    assert r.exit_code == 0, r.output
    assert "shape 2,-1,0.5,0,0,0,0,0,0,0,... (16 betas)" in r.output  # a long list not echoed whole
    err = np.linalg.norm(read_obj(tmp_path / "back2.obj").vertices - g.vertices, axis=1)
    assert np.percentile(err, 99) < 5e-3


def test_unpose_from_a_pose_file_uses_its_frame(a_posed, tmp_path):
    """A pose file holding the A-pose at frame 1 (root turned into the Z-up world, as AMASS writes) gives the
    same garment as --pose apose."""
    from core.body import default_body
    from core.unpose import a_pose

    path, _ = a_posed
    poses = np.zeros((2, 24, 3), np.float32)
    poses[1] = a_pose(default_body())
    poses[:, 0] = [np.pi / 2, 0, 0]
    write_motion(tmp_path / "apose.npz", n_frames=2, poses=poses.reshape(2, 72))
    r = invoke(["unpose", path, "--pose", tmp_path / "apose.npz", "--frame", 1, "--out", tmp_path / "a.obj"])
    assert r.exit_code == 0, r.output
    r = invoke(["unpose", path, "--pose", "apose", "--out", tmp_path / "b.obj"])
    assert r.exit_code == 0, r.output
    np.testing.assert_allclose(read_obj(tmp_path / "a.obj").vertices, read_obj(tmp_path / "b.obj").vertices,
                               atol=1e-5)


def test_a_garment_authored_lower_is_refused_by_bake_and_moved_back_by_the_command_it_names(tmp_path, caplog):
    """The example t-shirt as it sits authored on SMPL's rest body (0.23 m lower): bake refuses it with one line
    naming `garment unpose ... --move`; that command, run as named, writes the t-shirt back within the move's
    rounding (1 cm at most) and bake takes it without a warning."""
    import re

    g = read_obj(EXAMPLES / "tshirt.obj")
    low = tmp_path / "low.obj"
    write_obj(low, g.vertices - np.float32([0.0, 0.23, 0.0]), g.faces, g.uvs, g.face_uvs)
    r = invoke(["bake", low, EXAMPLES / "walk.npz", "--frames", "0:2", "--out", tmp_path / "bake"])
    assert r.exit_code != 0 and "Traceback" not in r.output and not (tmp_path / "bake").exists()
    command = re.search(r"`garment unpose (\S+) --pose tpose --move (0,0\.\d\d?,0)`$", r.output.strip())
    assert command and command[1] == str(low), r.output
    r = invoke(["unpose", low, "--pose", "tpose", "--move", command[2]])
    assert r.exit_code == 0, r.output
    assert f"6698 vertices moved by {command[2]} m (largest move {float(command[2].split(',')[1]) * 100:.1f} cm" \
        in r.output
    back = read_obj(tmp_path / "low_rest.obj")
    assert np.abs(back.vertices - g.vertices - [0.0, float(command[2].split(",")[1]) - 0.23, 0.0]).max() < 1e-5
    assert np.abs(back.vertices - g.vertices).max() < 0.0101
    caplog.clear()
    with caplog.at_level(logging.WARNING):
        r = invoke(["bake", tmp_path / "low_rest.obj", EXAMPLES / "walk.npz", "--frames", "0:3", "--out",
                    tmp_path / "bake"])  # two frames at 30 fps (0:2 is one, warned about)
    assert r.exit_code == 0, r.output
    assert not [rec for rec in caplog.records if rec.levelno >= logging.WARNING], caplog.text


@pytest.mark.parametrize("turns", [("z-up",), ("x+90",), ("backwards",), ("z-up", "backwards"), ("y-90",)],
                         ids=["z-up", "x+90", "backwards", "unreal-z-up-facing-y", "y-up-facing-x"])
def test_a_garment_in_another_frame_is_turned_back_by_the_command_bake_names(tmp_path, turns):
    """The example trousers written Z-up, turned the other way about X, facing backwards, in Unreal's Z-up facing
    +Y or Y-up facing +X (and lifted onto a floor, for the Z-up one): bake refuses them naming `garment unpose ...
    --turn T [--turn T2] [--move ...]`; that command, run as named, writes the trousers back (within the drop's
    rounding) and bake takes them."""
    import re

    from core.skinning import _turns_rotation

    g = read_obj(EXAMPLES / "trousers.obj")
    lift = 0.9 if turns == ("z-up",) else 0.0
    off = tmp_path / "off.obj"
    write_obj(off, ((g.vertices.astype(np.float64) + [0.0, lift, 0.0]) @ _turns_rotation(turns)).astype(np.float32),
              g.faces, g.uvs, g.face_uvs)
    r = invoke(["bake", off, EXAMPLES / "walk.npz", "--frames", "0:2", "--out", tmp_path / "bake"])
    assert r.exit_code != 0 and "Traceback" not in r.output and not (tmp_path / "bake").exists()
    command = re.search(r"`garment unpose (\S+) --pose tpose((?: --turn \S+)+)( --move \S+)?`$", r.output.strip())
    assert command and command[1] == str(off) and command[2].split()[1::2] == list(turns), r.output
    assert bool(command[3]) == bool(lift)
    r = invoke(["unpose", off, "--pose", "tpose", *command[2].split(), *(command[3].split() if command[3] else [])])
    assert r.exit_code == 0, r.output
    assert ", ".join(f"turned {turn}" for turn in turns) in r.output
    back = read_obj(tmp_path / "off_rest.obj")
    assert np.abs(back.vertices - g.vertices).max() < 0.0051
    r = invoke(["bake", tmp_path / "off_rest.obj", EXAMPLES / "walk.npz", "--frames", "0:2", "--out",
                tmp_path / "bake", "--method", "lbs"])
    assert r.exit_code == 0, r.output


def test_the_turns_unpose_takes_are_those_bake_names():
    """`unpose --turn`'s choices are `core.skinning.TURNS`, and every one of the 24 axis-aligned turns (the cube's)
    is made by at most two of them, as bake names it: each of the 23 fixes tried once, none the identity."""
    from core.skinning import _TURNS, TURNS, _turns_rotation
    from garmentcli.unpose import unpose

    choices = next(p.type.choices for p in unpose.params if p.name == "turns")
    assert list(choices) == list(TURNS)
    rotations = {_turns_rotation(t).round().astype(int).tobytes() for _, t in _TURNS}
    assert len(_TURNS) == len(rotations) == 23 and np.eye(3, dtype=int).tobytes() not in rotations
    assert all(1 <= len(t) <= 2 for _, t in _TURNS)


def test_a_garment_in_other_units_is_scaled_back_by_the_command_bake_names(tmp_path):
    """The example dress written in inches: bake refuses it naming the units that put it on the body and `garment
    unpose --scale 0.0254` (since 2026-12-08; it named both units it may be in and `--scale S`); scaled by the
    wrong guess (centimetres: a doll's dress), unpose refuses it naming the file's
    scale, which, run as named, writes the dress back, and bake takes it. Unposed from the A-pose with the wrong
    scale, the scale named keeps the pose."""
    import re

    g = read_obj(EXAMPLES / "dress.obj")
    inches = tmp_path / "dress_in.obj"
    write_obj(inches, (g.vertices / np.float32(0.0254)), g.faces, g.uvs, g.face_uvs)
    r = invoke(["bake", inches, EXAMPLES / "walk.npz", "--frames", "0:2", "--out", tmp_path / "bake"])
    assert r.exit_code != 0 and not (tmp_path / "bake").exists()
    assert r.output.strip().endswith("got an extent of 31.4 units; in inches (scaled by 0.0254) it rests on the "
                                     f"body: `garment unpose {inches} --pose tpose --scale 0.0254`"), r.output
    r = invoke(["unpose", inches, "--pose", "tpose", "--scale", "0.01"])
    assert r.exit_code != 0 and not (tmp_path / "dress_in_rest.obj").exists()
    command = re.search(r"it fits when scaled by 2\.54 \(inches read as centimetres\?\): `garment unpose (\S+) "
                        r"--pose tpose --scale (\S+)`$", r.output.strip())
    assert command and command[1] == str(inches) and command[2] == "0.0254", r.output
    r = invoke(["unpose", inches, "--pose", "tpose", "--scale", command[2]])
    assert r.exit_code == 0 and "3240 vertices scaled by 0.0254 (largest move after the scale " in r.output, r.output
    back = read_obj(tmp_path / "dress_in_rest.obj")
    assert np.abs(back.vertices - g.vertices).max() < 1e-5
    r = invoke(["bake", tmp_path / "dress_in_rest.obj", EXAMPLES / "walk.npz", "--frames", "0:2", "--out",
                tmp_path / "bake", "--method", "lbs"])
    assert r.exit_code == 0, r.output
    r = invoke(["unpose", inches, "--pose", "apose", "--scale", "0.01", "--out", tmp_path / "a.obj"])
    assert r.exit_code != 0 and r.output.strip().endswith(
        f"`garment unpose {inches} --pose apose --scale 0.0254`"), r.output


def test_an_a_posed_garment_in_centimetres_is_told_both_in_one_command(a_posed, tmp_path):
    """The A-posed t-shirt written in centimetres: bake names the A-pose and the scale in one command (the A-pose's
    command left out the scale given: run as named, unpose refused the file's units again); run, it bakes."""
    path, rest = a_posed
    cm = tmp_path / "shirt_cm.obj"
    posed = read_obj(path)
    write_obj(cm, posed.vertices * np.float32(100.0), posed.faces, posed.uvs, posed.face_uvs)
    r = invoke(["bake", cm, EXAMPLES / "walk.npz", "--frames", "0:2", "--out", tmp_path / "bake", "--method", "lbs"])
    assert r.exit_code != 0 and r.output.strip().endswith(
        "in centimetres (scaled by 0.01) it fits when unposed from an A-pose (arms lowered 45 degrees): "
        f"`garment unpose {cm} --pose apose --scale 0.01`"), r.output
    r = invoke(["unpose", cm, "--pose", "apose", "--scale", "0.01", "--out", tmp_path / "rest.obj"])
    assert r.exit_code == 0, r.output
    assert np.abs(read_obj(tmp_path / "rest.obj").vertices - rest.vertices).max() < 0.005
    r = invoke(["bake", tmp_path / "rest.obj", EXAMPLES / "walk.npz", "--frames", "0:2", "--out", tmp_path / "bake",
                "--method", "lbs", "--no-obj"])
    assert r.exit_code == 0, r.output


def test_an_a_posed_garment_on_the_floor_in_millimetres_is_told_all_three_in_one_command(a_posed, tmp_path):
    """The A-posed t-shirt standing on the floor (y = 0 at the soles) in millimetres, as Marvelous Designer's
    avatars export: bake named the units and the drop, then, once made, the A-pose; now one command names all
    three, which run as named gives the t-shirt back within the drop's rounding."""
    from core.body import default_body

    path, rest = a_posed
    soles = -float(default_body().v_template[:, 1].min())
    posed = read_obj(path)
    mm = tmp_path / "md.obj"
    write_obj(mm, (posed.vertices + np.float32([0.0, soles, 0.0])) * np.float32(1000.0), posed.faces, posed.uvs,
              posed.face_uvs)
    r = invoke(["bake", mm, EXAMPLES / "walk.npz", "--frames", "0:2", "--out", tmp_path / "bake", "--method", "lbs"])
    assert r.exit_code != 0 and r.output.strip().endswith(
        "in millimetres (scaled by 0.001) it fits when moved down by 0.90 m (authored on a body standing at y = 0), "
        f"then unposed from an A-pose (arms lowered 45 degrees): `garment unpose {mm} --pose apose --scale 0.001 "
        "--move 0,-0.9,0`"), r.output
    r = invoke(["unpose", mm, "--pose", "apose", "--scale", "0.001", "--move", "0,-0.9,0", "--out", tmp_path / "r.obj"])
    assert r.exit_code == 0, r.output
    assert np.abs(read_obj(tmp_path / "r.obj").vertices - rest.vertices).max() < 0.006


def test_a_move_unpose_names_adds_to_the_move_it_was_given(tmp_path):
    """The example t-shirt lifted 0.3 m and moved down by only 0.1 m: the move named is the whole of it, on the
    file as given (it was the rest of it, as if on the file: run as named, the shirt stayed 0.1 m high)."""
    import re

    g = read_obj(EXAMPLES / "tshirt.obj")
    up = tmp_path / "up.obj"
    write_obj(up, g.vertices + np.float32([0.0, 0.3, 0.0]), g.faces, g.uvs, g.face_uvs)
    r = invoke(["unpose", up, "--pose", "tpose", "--move", "0,-0.1,0"])
    assert r.exit_code != 0
    command = re.search(rf"`garment unpose {re.escape(str(up))} --pose tpose --move (0,-0\.\d+,0)`$",
                        r.output.strip())
    assert command and abs(float(command[1].split(",")[1]) + 0.3) <= 0.02, r.output
    r = invoke(["unpose", up, "--pose", "tpose", "--move", command[1]])
    assert r.exit_code == 0, r.output
    assert np.abs(read_obj(tmp_path / "up_rest.obj").vertices - g.vertices).max() <= 0.0201
    # a file placed right, given a move it did not need: the move that undoes it leaves none (it named
    # `--move 0,-0.01,0`, the search's step, left over)
    r = invoke(["unpose", EXAMPLES / "tshirt.obj", "--pose", "tpose", "--move", "0,0.3,0", "--out",
                tmp_path / "x.obj"])
    assert r.exit_code != 0 and r.output.strip().endswith(
        f"bake the file as it is (`garment bake {EXAMPLES / 'tshirt.obj'} ...`), without `garment unpose`"), r.output


@pytest.mark.parametrize("args, needle", [
    (["--pose", "bpose"], "expected 'tpose', 'apose' or a motion file (.npz, .smpl, .npy, .bvh, .fbx, .glb, .gltf, "
                          ".vrm, .vrma, .usd, .usda, .usdc, .usdz, .dae, .mvnx, .pkl, .pickle, .joblib, .pt, .pth), got "
                          "'bpose'"),
    (["--pose", "tpose"], "--pose tpose takes off the body shape, place, frame and units only: give them with "
                          "--betas B0,B1,..., --move DX,DY,DZ, --turn or --scale"),
    (["--pose", "tpose", "--scale", "0"], "--scale: expected metres per unit of the file, 0.0001 to 1000 (0.01: "
                                          "centimetres, 0.001: millimetres, 0.0254: inches), got 0"),
    (["--pose", "tpose", "--scale", "cm"], "'cm' is not a valid float"),
    (["--pose", "tpose", "--turn", "sideways"], "Invalid value for '--turn': expected one of z-up, x+90, backwards, "
                                                "x+180, y+90, y-90, z+90, z-90, z+180 or an axis and degrees (y-15), "
                                                "got 'sideways'"),
    (["--pose", "tpose", "--turn", "y15"], "Invalid value for '--turn': expected one of z-up"),
    (["--pose", "tpose", "--move", "0,0.2"], "--move: expected 3 comma-separated numbers, got 2 in '0,0.2'"),
    (["--pose", "tpose", "--move", "0,up,0"], "--move: expected 3 comma-separated numbers, got '0,up,0'"),
    (["--pose", "tpose", "--move", "0,inf,0"], "--move: expected finite numbers, got '0,inf,0'"),
    (["--pose", "tpose", "--move", "0,25,0"], "--move: expected metres, at most 10 on each axis, got '0,25,0'"),
    (["--pose", "tpose", "--betas", "1,x"], "expected comma-separated numbers, got '1,x'"),
    (["--pose", "tpose", "--betas", "50"], "--betas: expected betas within +-20"),  # wrote it 27 % inside the body
    (["--pose", "tpose", "--betas", "1e30"], "--betas: expected betas within +-20"),  # numpy overflow warnings
    (["--pose", "tpose", "--betas", "1", "--frame", 1], "--frame applies to a motion file only"),
    (["--pose", "tpose", "--betas", "1", "--arm-angle", 30], "--arm-angle applies to --pose apose only"),
    (["--pose", "nope.npz"], "'nope.npz': no such file"),
    (["--pose", "NOPE.NPZ"], "'NOPE.NPZ': no such file"),  # a pose file, whatever the case of its suffix
    (["--pose", "apose", "--frame", 2], "--frame applies to a motion file only"),
    (["--pose", "apose", "--arm-angle", 200], "--arm-angle': 200.0 is not in the range -90.0<=x<=90.0"),
    (["--pose", str(EXAMPLES / "walk.npz"), "--arm-angle", 30], "--arm-angle applies to --pose apose only"),
    (["--pose", str(EXAMPLES / "walk.npz"), "--frame", 9999], "expected a frame in 0..180"),
    (["--pose", "apose", "--out", "SELF"], "is GARMENT itself"),
    (["--pose", "apose", "--out", "up9.usdz"], "expected an .obj, .usd, .usda or .usdc file, got 'up9.usdz'"),
    (["--pose", "apose", "--out", "up15"], "expected an .obj, .usd, .usda or .usdc file, got 'up15'"),
])
def test_unpose_bad_input_one_line_nothing_written(a_posed, args, needle):
    path, _ = a_posed
    args = [str(path) if a == "SELF" else a for a in args]
    before = sorted(p.name for p in path.parent.iterdir())
    r = invoke(["unpose", path, *args])
    assert r.exit_code != 0 and needle in r.output.strip().splitlines()[-1], r.output
    assert "Traceback" not in r.output
    assert sorted(p.name for p in path.parent.iterdir()) == before


def test_unpose_errors_and_warnings_name_the_input_not_the_output(tmp_path, caplog):
    """A refused result and the rest-fit warning named the output file (and advised `garment unpose`)."""
    g = read_obj(EXAMPLES / "skirt.obj")
    zup = tmp_path / "zup.obj"
    v = g.vertices
    write_obj(zup, np.stack([v[:, 0], -v[:, 2], v[:, 1]], axis=1), g.faces)  # Y-up to Z-up
    r = invoke(["unpose", zup, "--pose", "apose", "--out", tmp_path / "result.obj"])
    last = r.output.strip().splitlines()[-1]
    assert r.exit_code != 0 and "zup.obj" in last and "result.obj" not in r.output, r.output
    assert not (tmp_path / "result.obj").exists()

    with caplog.at_level(logging.WARNING):
        r = invoke(["unpose", EXAMPLES / "skirt.obj", "--pose", "tpose", "--betas", "-20", "--out",
                    tmp_path / "wide.obj"])
    assert r.exit_code == 0, r.output
    warnings = [m for m in (rec.getMessage() for rec in caplog.records) if "inside the body's rest surface" in m]
    assert len(warnings) == 1, warnings  # the check of the file written back said it again, of 'wide'
    warning = warnings[0]
    assert "skirt.obj" in warning and "wide" not in warning and "`garment unpose`" not in warning, warning
    assert "--betas" in warning


def test_unpose_a_motion_given_as_garment_is_named_for_what_it_is(tmp_path):
    motion = tmp_path / "walk.npz"
    write_motion(motion, n_frames=3, fps=30.0)
    for pose in ("apose", "tpose"):  # tpose alone: said before what --pose tpose lacks
        r = invoke(["unpose", motion, "--pose", pose, "--out", tmp_path / "out.obj"])
        assert r.exit_code != 0 and "expected an OBJ or USD garment, got a NumPy .npz archive (a motion?)" in r.output
    assert not (tmp_path / "out.obj").exists()


def test_unpose_counts_the_vertices_of_the_file_it_writes(tmp_path):
    """A t-shirt exported as two panels (the seam's vertices written twice, welded as read): the count printed is
    of the file written, which keeps the file's points, not of the welded mesh."""
    g = read_obj(EXAMPLES / "tshirt.obj")
    faces = g.faces.copy()
    half = len(faces) // 2
    faces[:half] += len(g.vertices)  # the first panel's own copies of its vertices
    panels = tmp_path / "panels.obj"
    write_obj(panels, np.concatenate([g.vertices, g.vertices]) + np.float32([0.0, 0.3, 0.0]), faces)
    r = invoke(["unpose", panels, "--pose", "tpose", "--move", "0,-0.3,0"])
    assert r.exit_code == 0, r.output
    lines = sum(line.startswith("v ") for line in (tmp_path / "panels_rest.obj").read_text().splitlines())
    assert lines == 2 * len(g.vertices) and f"{lines} vertices moved by 0,-0.3,0 m" in r.output, r.output


def test_turn_given_twice_turns_twice(tmp_path):
    """The example trousers upside down (180 degrees about X): `--turn z-up --turn z-up` turns them back (a fix
    named on a file already turned joins the turns so), and `--scale` scales first."""
    from core.skinning import TURNS

    g = read_obj(EXAMPLES / "trousers.obj")
    upside = tmp_path / "upside.obj"
    flipped = g.vertices.astype(np.float64) @ TURNS["x+90"].T @ TURNS["x+90"].T / 0.01
    write_obj(upside, flipped.astype(np.float32), g.faces)
    r = invoke(["unpose", upside, "--pose", "tpose", "--scale", "0.01", "--turn", "z-up", "--turn", "z-up"])
    assert r.exit_code == 0 and "scaled by 0.01, turned z-up, turned z-up" in r.output, r.output
    assert np.abs(read_obj(tmp_path / "upside_rest.obj").vertices - g.vertices).max() < 1e-5


def test_a_pose_files_betas_are_not_taken_as_the_embedded_bodys_own(tmp_path):
    """A motion file's betas were fitted to SMPL's shape basis (AMASS's are): taken off the embedded body they shaped
    it as nobody in particular, without a word, where bake bakes such a motion on the mean shape, warned. Now the
    mean shape, warned, as a pose file without betas; --betas still takes off the coefficients given."""
    walk = dict(np.load(EXAMPLES / "walk.npz"))
    np.savez(tmp_path / "fitted.npz", **{**walk, "betas": np.array([2.0, 1.5] + [0.0] * 8, np.float32)})
    np.savez(tmp_path / "plain.npz", **{**walk, "betas": np.zeros(10, np.float32)})
    outs = {}
    for name in ("fitted", "plain"):
        r = invoke(["unpose", EXAMPLES / "skirt.obj", "--pose", tmp_path / f"{name}.npz", "--out",
                    tmp_path / f"{name}.obj"])
        assert r.exit_code == 0, r.output
        assert ("its betas were fitted to another body model" in r.output) == (name == "fitted")
        # no shape taken off either way (zero betas were said to be: "and mean shape")
        assert "moved to the rest pose from frame 0" in r.output and "mean shape from" not in r.output, r.output
        outs[name] = read_obj(tmp_path / f"{name}.obj").vertices
    np.testing.assert_array_equal(outs["fitted"], outs["plain"])
    r = invoke(["unpose", EXAMPLES / "skirt.obj", "--pose", tmp_path / "fitted.npz", "--betas", "2,1.5", "--out",
                tmp_path / "given.obj"])
    assert r.exit_code == 0 and "fitted to another body model" not in r.output, r.output
    assert "moved to the rest pose and mean shape from frame 0" in r.output
    assert np.abs(read_obj(tmp_path / "given.obj").vertices - outs["plain"]).max() > 1e-3


def test_a_torn_result_is_warned_of(tmp_path, monkeypatch):
    """The t-shirt on arms lowered 75 degrees unposed as before its vertices took the faces facing their way (the
    nearest face alone): its sleeves tore from the arms (edges to 8.5x their length) and the command said only
    that it went well. Such a result is warned of, naming the worst edge and how to look at it; the file is
    written (the user decides)."""
    from tests.core.test_unpose import _posed

    import core.unpose
    from core.body import default_body
    from core.unpose import a_pose

    body = default_body()
    g = read_obj(EXAMPLES / "tshirt.obj")
    posed = _posed(g, body, a_pose(body, 75.0))
    path = tmp_path / "shirt75.obj"
    write_obj(path, posed.vertices, posed.faces, posed.uvs, posed.face_uvs)
    args = ["unpose", path, "--pose", "apose", "--arm-angle", "75", "--out"]
    r = invoke([*args, tmp_path / "now.obj"])
    assert r.exit_code == 0 and "warning" not in r.output and "tore" not in r.output, r.output
    monkeypatch.setattr(core.unpose, "UNPOSE_FACING_REACH_M", 0.0)
    r = invoke([*args, tmp_path / "nearest.obj"])
    warned = [line for line in r.output.splitlines() if line.startswith("warning")]
    assert r.exit_code == 0 and len(warned) == 1 and (tmp_path / "nearest.obj").is_file(), r.output
    assert warned[0].startswith(f"warning: garment '{path}': ") and " of its edges came out over 3x their length " \
        "as authored, plus 1 cm (the worst 8." in warned[0] and warned[0].endswith(
            f"look at it before baking it (garment render {tmp_path / 'nearest.obj'})"), warned[0]
