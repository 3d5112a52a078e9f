import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tests.garmentcli.cli import invoke
from tests.formats.test_usd import usd_problems
from tests.garmentcli.conftest import write_motion, write_shell_obj


def run(args):
    return invoke(args)


def assert_one_line_error(result, *needles):
    assert result.exit_code != 0, result.output
    assert "Traceback" not in result.output
    err = result.output.strip().splitlines()
    assert len(err) >= 1
    line = err[-1]
    for n in needles:
        assert n in line, (n, line)


def test_bake_writes_usd_obj_and_summary(scene):
    from pxr import Usd, UsdGeom

    r = run(["bake", scene["garment"], scene["motion"], scene["motion2"], "--body", scene["body"],
             "--out", scene["out"], "--settle", 3])
    assert r.exit_code == 0, r.output
    walk = scene["out"] / "shell_walk"
    # 12 frames at 60 fps -> 6 frames at 30 fps, plus 3 settle frames
    summary = json.loads((walk / "summary.json").read_text())
    assert summary["frames"] == 9 and summary["fps"] == 30 and summary["settle_frames"] == 3
    assert summary["method"] == "lbs" and summary["source_fps"] == 60
    assert 0 <= summary["penetration"]["mean_percent"] <= 100
    assert summary["seconds_per_frame"] > 0
    stage = Usd.Stage.Open(str(walk / "shell_walk.usd"))
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    assert stage.GetTimeCodesPerSecond() == 30
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (0, 8)
    garment = UsdGeom.Mesh(stage.GetPrimAtPath("/Root/garment"))
    body = UsdGeom.Mesh(stage.GetPrimAtPath("/Root/body"))
    p0 = np.array(garment.GetPointsAttr().Get(0))
    p8 = np.array(garment.GetPointsAttr().Get(8))
    assert p0.shape == (scene["tiny"].n_vertices, 3) and not np.allclose(p0, p8)
    assert len(body.GetPointsAttr().Get(4)) == scene["tiny"].n_vertices
    objs = sorted((walk / "obj").glob("*.obj"))
    assert len(objs) == 9
    # 7 frames at 120 fps -> 2 frames at 30 fps (+3 settle); SMPL+H poses drive the SMPL body
    jump = json.loads((scene["out"] / "shell_jump" / "summary.json").read_text())
    assert jump["frames"] == 5


def test_lbs_smooth_auto_spreads_the_legs_weights_and_a_number_of_passes_does_not(scene):
    from core.skinning import LEG_SPREAD_M
    from formats.sequence import read_sequence

    baked = {}
    for value in (None, "AUTO", "10"):
        extra = [] if value is None else ["--lbs-smooth", value]
        out = scene["out"] / f"smooth_{value}"
        r = run(["bake", scene["garment"], scene["motion"], "--body", scene["body"], "--method", "lbs", "--frames",
                 "0:4", "--no-obj", "--out", out, *extra])
        assert r.exit_code == 0, r.output
        summary = json.loads((out / "shell_walk" / "summary.json").read_text())
        baked[value] = summary["deformer"], read_sequence(out / "shell_walk" / "shell_walk.usd").points
    (auto, auto_points), (named, named_points), (ten, ten_points) = baked.values()
    assert auto["options"]["leg_spread_m"] == named["options"]["leg_spread_m"] == LEG_SPREAD_M
    assert auto["leg_spread_passes"] > 0 and auto["options"]["smooth_iterations"] == 10
    np.testing.assert_array_equal(auto_points, named_points)
    assert ten["options"]["leg_spread_m"] is None and ten["leg_spread_passes"] == 0
    assert np.abs(auto_points - ten_points).max() > 1e-4


def test_bake_matches_between_obj_and_usd(scene):
    from formats.sequence import read_sequence

    r = run(["bake", scene["garment"], scene["motion"], "--body", scene["body"], "--out", scene["out"]])
    assert r.exit_code == 0, r.output
    d = scene["out"] / "shell_walk"
    usd = read_sequence(d / "shell_walk.usd")
    obj = read_sequence(d / "obj")
    np.testing.assert_allclose(usd.points, obj.points, atol=2e-6)
    assert usd.body_points is not None and usd.body_points.shape[0] == usd.points.shape[0]


def test_bake_refuses_to_overwrite_then_overwrites(scene):
    args = ["bake", scene["garment"], scene["motion"], "--body", scene["body"], "--out", scene["out"]]
    assert run(args).exit_code == 0
    before = (scene["out"] / "shell_walk" / "summary.json").read_text()
    r = run(args)
    assert_one_line_error(r, "exists", "--overwrite")
    assert (scene["out"] / "shell_walk" / "summary.json").read_text() == before
    r = run(args + ["--overwrite", "--frames", "0:4"])
    assert r.exit_code == 0, r.output
    assert json.loads((scene["out"] / "shell_walk" / "summary.json").read_text())["frames"] == 2
    assert not list(scene["out"].glob(".*partial"))


def test_bake_frames_fps_and_no_outputs(scene):
    r = run(["bake", scene["garment"], scene["motion"], "--body", scene["body"], "--out", scene["out"],
             "--fps", 24, "--frames", "2:", "--no-obj", "--no-body"])
    assert r.exit_code == 0, r.output
    d = scene["out"] / "shell_walk"
    s = json.loads((d / "summary.json").read_text())
    # source frames 2..11 at 60 fps span 0.15 s -> 24 fps frames at 0, 1/24, .., 0.125 s
    assert s["frames"] == 4 and s["fps"] == 24
    assert not (d / "obj").exists()
    from pxr import Usd

    assert not Usd.Stage.Open(str(d / "shell_walk.usd")).GetPrimAtPath("/Root/body")


def test_a_motion_shorter_than_one_output_frame_is_baked_as_one_frame_with_a_warning(scene, caplog):
    """Two source frames at 60 fps (1/60 s) fall within one frame at 30 fps: the second pose was dropped without
    a word (0.84 m of travel in the audit's case); it is said, naming --fps."""
    r = run(["bake", scene["garment"], scene["motion"], "--body", scene["body"], "--out", scene["out"],
             "--frames", "0:2", "--no-obj", "--method", "lbs"])
    assert r.exit_code == 0, r.output
    assert json.loads((scene["out"] / "shell_walk" / "summary.json").read_text())["frames"] == 1
    assert f"motion '{scene['motion']}': its 2 frames at 60 fps span 0.0167 s, less than one frame at --fps 30: " \
           "baked as one frame, its first (--fps 60 keeps every frame)" in caplog.text
    caplog.clear()
    r = run(["bake", scene["garment"], scene["motion"], "--body", scene["body"], "--out", scene["out"],
             "--frames", "0:3", "--no-obj", "--method", "lbs", "--overwrite"])
    assert r.exit_code == 0 and "less than one frame" not in caplog.text  # 1/30 s: two frames


def bad_obj(tmp_path, text, name="bad.obj"):
    p = tmp_path / name
    p.write_text(text)
    return p


BAD_CASES = {
    "missing garment": (lambda s: ["bake", s["dir"] / "nope.obj", s["motion"]], ["nope.obj"]),
    "missing motion": (lambda s: ["bake", s["garment"], s["dir"] / "gone.npz"], ["gone.npz"]),
    "missing body": (lambda s: ["bake", s["garment"], s["motion"], "--body", s["dir"] / "nobody.npz"], ["nobody.npz"]),
    "7-gon face": (lambda s: ["bake", bad_obj(s["dir"], "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 2 0\nv 1 2 0\nv 2 2 0\n"
                                                  "f 1 2 3 4 5 6 7\n"), s["motion"]], ["bad.obj", "cannot split the face with 7 vertices"]),
    "obj no faces": (lambda s: ["bake", bad_obj(s["dir"], "v 0 0 0\nv 1 0 0\n"), s["motion"]], ["bad.obj", "faces"]),
    "obj nan": (lambda s: ["bake", bad_obj(s["dir"], "v 0 0 nan\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"), s["motion"]],
                ["bad.obj"]),
    "obj garbage": (lambda s: ["bake", bad_obj(s["dir"], "v 0 zero 0\nf 1 2 3\n"), s["motion"]], ["bad.obj"]),
    "bad method": (lambda s: ["bake", s["garment"], s["motion"], "--method", "magic"], ["--method", "magic"]),
    "zero fps": (lambda s: ["bake", s["garment"], s["motion"], "--fps", 0], ["--fps"]),
    "bad frames": (lambda s: ["bake", s["garment"], s["motion"], "--frames", "a:b"], ["--frames"]),
    "empty frames": (lambda s: ["bake", s["garment"], s["motion"], "--frames", "50:60"], ["--frames", "no frame"]),
    "negative settle": (lambda s: ["bake", s["garment"], s["motion"], "--settle", -2], ["--settle"]),
    "preroll without frames": (lambda s: ["bake", s["garment"], s["motion"], "--preroll", 3],
                               ["--preroll", "--frames START:STOP"]),
    "preroll and settle": (lambda s: ["bake", s["garment"], s["motion"], "--frames", "4:", "--preroll", 3,
                                      "--settle", 2], ["--settle and --preroll"]),
    # 1,000,000 passes (a typo) took minutes; --lbs-smooth with another method did nothing
    "lbs-smooth typo": (lambda s: ["bake", s["garment"], s["motion"], "--method", "lbs", "--lbs-smooth", 1_000_000],
                        ["--lbs-smooth", "expected 'auto' or passes from 0 to 1000, got '1000000'"]),
    "lbs-smooth for the simulator": (lambda s: ["bake", s["garment"], s["motion"], "--method", "sim", "--lbs-smooth",
                                                20], ["--lbs-smooth applies to --method lbs only (got --method sim)"]),
    # accepted before (fuzz audit): 1e-9 fps wrote one frame; 1e300 Hz put the motion within one frame; a billion
    # substeps ran for ever; a start frame of 1e20 merged the frames into one USD time code
    "tiny output fps": (lambda s: ["bake", s["garment"], s["motion"], "--fps", "1e-9"], ["--fps", "1.0<=x<=1000.0"]),
    "huge source fps": (lambda s: ["bake", s["garment"], s["motion"], "--source-fps", "1e300"],
                        ["--source-fps", "expected a frame rate of at most 10,000 Hz, got 1e+300"]),
    "billion substeps": (lambda s: ["bake", s["garment"], s["motion"], "--method", "sim", "--substeps", 10**9],
                         ["--substeps", "1<=x<=1000"]),
    "start frame beyond doubles": (lambda s: ["bake", s["garment"], s["motion"], "--start-frame", 10**20],
                                   ["--start-frame", "0<=x<=1000000000"]),
    # the memory refusal advised --frames parts larger than the motion
    "settle beyond memory": (lambda s: ["bake", s["garment"], s["motion"], "--method", "lbs", "--settle", 10**10],
                             ["--settle 10000000000: 10000000000 frames", "lower --settle"]),
}


@pytest.mark.parametrize("case", sorted(BAD_CASES))
def test_bake_bad_input_one_line_no_output(scene, case):
    make_args, needles = BAD_CASES[case]
    args = make_args(scene) + ["--out", scene["out"]]
    if "--body" not in args:
        args += ["--body", scene["body"]]
    r = run(args)
    assert_one_line_error(r, *needles)
    if r.exit_code == 2:  # a usage error: one line, not click's usage, hint and blank line before it
        assert r.output.strip().splitlines() == [r.output.strip()], r.output
        assert r.output.startswith("Error: ") and r.output.strip().endswith(" bake --help')"), r.output
    assert not scene["out"].exists() or not any(scene["out"].iterdir())


def test_bake_bad_motion_files(scene):
    d = scene["dir"]
    cases = {
        "nan.npz": ({"poses": np.full((5, 72), np.nan, np.float32)}, ["nan.npz", "NaN"]),
        "shape.npz": ({"poses": np.zeros((5, 50), np.float32)}, ["shape.npz", "72"]),
        "trans.npz": ({"trans": np.zeros((3, 3), np.float32)}, ["trans.npz", "expected trans of shape (5, 3), one row",
                                                                "got (3, 3)"]),
    }
    for name, (over, needles) in cases.items():
        write_motion(d / name, n_frames=5, **over)
        r = run(["bake", scene["garment"], d / name, "--body", scene["body"], "--out", scene["out"]])
        assert_one_line_error(r, *needles)
    (d / "notnpz.npz").write_text("hello")
    assert_one_line_error(run(["bake", scene["garment"], d / "notnpz.npz", "--body", scene["body"],
                               "--out", scene["out"]]), "notnpz.npz")
    assert not scene["out"].exists() or not any(scene["out"].iterdir())


def test_bake_garment_in_centimetres_or_far_away(scene):
    d = scene["dir"]
    write_shell_obj(d / "cm.obj", scene["tiny"], scale=100.0)
    assert_one_line_error(run(["bake", d / "cm.obj", scene["motion"], "--body", scene["body"], "--out", scene["out"]]),
                          "cm.obj", "centimetres")
    far = (d / "shell.obj").read_text().splitlines()
    far = [f"v {float(l.split()[1]) + 2.0} {l.split()[2]} {l.split()[3]}" if l.startswith("v ") else l for l in far]
    (d / "far.obj").write_text("\n".join(far))
    assert_one_line_error(run(["bake", d / "far.obj", scene["motion"], "--body", scene["body"], "--out", scene["out"]]),
                          "far.obj", "rest pose")


def test_bake_garment_written_z_up_is_refused_naming_the_rotation(scene):
    """The example trousers on the default body, their file written Z-up: one line naming the fix, nothing written."""
    from pathlib import Path

    src = Path(__file__).resolve().parents[2] / "examples" / "trousers.obj"
    lines = [f"v {x} {-float(z)} {y}" if tag == "v" else line
             for line in src.read_text().splitlines()
             for tag, x, y, z in [(line.split() + ["", "", "", ""])[:4]]]
    (scene["dir"] / "zup.obj").write_text("\n".join(lines) + "\n")
    r = run(["bake", scene["dir"] / "zup.obj", scene["motion"], "--method", "lbs", "--out", scene["out"]])
    assert_one_line_error(r, "zup.obj", "inside the body", "it fits when rotated -90 degrees about X (Z-up to Y-up)")
    assert not scene["out"].exists() or not any(scene["out"].iterdir())


@pytest.mark.parametrize("per_metre, turned, told", [
    (100.0, "z-up", "in centimetres (scaled by 0.01) it fits when rotated -90 degrees about X (Z-up to Y-up): "
                    "`garment unpose {path} --pose tpose --scale 0.01 --turn z-up`"),
    (1 / 0.0254, None, "in inches (scaled by 0.0254) it rests on the body: `garment unpose {path} --pose tpose "
                       "--scale 0.0254`"),
    (100.0, "yaw", "in centimetres (scaled by 0.01) it fits when rotated -30 degrees about Y (the up axis): "
                   "`garment unpose {path} --pose tpose --scale 0.01 --turn y-30`"),
    (100.0, "up", "in centimetres (scaled by 0.01) it fits better when moved down by 0.25 m (authored on a body "
                  "whose origin stands elsewhere): pass the body it was authored on with --body, or move it: "
                  "`garment unpose {path} --pose tpose --scale 0.01 --move 0,-0.25,0`")])
def test_a_garment_in_other_units_is_refused_naming_the_units_the_body_tells(scene, per_metre, turned, told):
    """A 3ds Max export of the example trousers (centimetres, Z-up) was told "centimetres or inches?" and, once
    scaled, refused again naming the turn: now the body tells the units, and the one command names both; run,
    its result bakes. In inches, Y-up: the inches alone. In centimetres, turned 30 degrees about the up axis: the
    turn back in centimetres, not inches, where the trousers, 2.54 times too large, rest on the body too (0.32 m
    from it, median, baked without a word); the jumpsuit moved up 0.25 m (authored on SMPL's rest body): the move
    besides."""
    from core.skinning import turn_matrix

    src = Path(__file__).resolve().parents[2] / "examples" / ("jumpsuit.obj" if turned == "up" else "trousers.obj")
    lines = []
    for line in src.read_text().splitlines():
        if line.startswith("v "):
            x, y, z = (float(c) * per_metre for c in line.split()[1:4])
            if turned == "yaw":
                x, y, z = turn_matrix("y+30") @ [x, y, z]
            y += 25.0 if turned == "up" else 0.0
            line = f"v {x:.5f} {-z:.5f} {y:.5f}" if turned == "z-up" else f"v {x:.5f} {y:.5f} {z:.5f}"
        lines.append(line)
    path = scene["dir"] / "max.obj"
    path.write_text("\n".join(lines) + "\n")
    r = run(["bake", path, scene["motion"], "--method", "lbs", "--out", scene["out"]])
    assert_one_line_error(r, f"'{path}': expected metres (a garment spans under 3 m), got an extent of ",
                          "units; " + told.format(path=path))
    assert not scene["out"].exists() or not any(scene["out"].iterdir())
    if turned == "z-up":
        fixed = scene["dir"] / "fixed.obj"
        r = run(["unpose", path, "--pose", "tpose", "--scale", "0.01", "--turn", "z-up", "--out", fixed])
        assert r.exit_code == 0, r.output
        r = run(["bake", fixed, scene["motion"], "--method", "lbs", "--out", scene["out"], "--no-obj"])
        assert r.exit_code == 0, r.output


def test_bad_body_file(scene):
    d = scene["dir"]
    np.savez(d / "broken_body.npz", v_template=np.zeros((10, 3)))
    r = run(["bake", scene["garment"], scene["motion"], "--body", d / "broken_body.npz", "--out", scene["out"]])
    assert_one_line_error(r, "broken_body.npz")


def test_body_in_centimetres_or_with_weights_not_summing_to_one_is_refused(scene):
    """The body's own faults are blamed on the body file, not on the garment ('far from the body'), and nothing
    is written."""
    d, tiny = scene["dir"], scene["tiny"]
    kintree = np.stack([tiny.parents, np.arange(tiny.n_joints)])
    arrays = dict(v_template=tiny.v_template, shapedirs=tiny.shapedirs, J_regressor=tiny.J_regressor,
                  weights=tiny.weights, kintree_table=kintree, f=tiny.faces)
    np.savez(d / "body_cm.npz", **{**arrays, "v_template": tiny.v_template * 100, "shapedirs": tiny.shapedirs * 100})
    np.savez(d / "weights_half.npz", **{**arrays, "weights": tiny.weights * 0.5})
    for name, needles in (("body_cm.npz", ("expected metres", "is it in centimetres? scale it by 0.01")),
                          ("weights_half.npz", ("rows sum to 1", "the worst sums to 0.5"))):
        r = run(["bake", scene["garment"], scene["motion"], "--body", d / name, "--out", scene["out"]])
        assert_one_line_error(r, f"body '{d / name}'", *needles)
        assert "garment mesh" not in r.output
    assert not scene["out"].exists() or not any(scene["out"].iterdir())


def test_bake_reports_scene_skips_and_no_skip_overrides_them(scene):
    r = run(["bake", scene["garment"], scene["motion"], "--body", scene["body"], "--out", scene["out"], "--no-obj"])
    assert r.exit_code == 0, r.output
    joints = json.loads((scene["out"] / "shell_walk" / "summary.json").read_text())["scene"]["joints"]
    assert not joints["overridden"] and joints["skipped_work"] == (joints["used"] < joints["joints"])
    r = run(["bake", scene["garment"], scene["motion"], "--body", scene["body"], "--out", scene["out"], "--no-obj",
             "--overwrite", "--no-skip", "joints"])
    assert r.exit_code == 0, r.output
    summary = json.loads((scene["out"] / "shell_walk" / "summary.json").read_text())
    assert summary["scene"]["joints"]["overridden"] and not summary["scene"]["joints"]["skipped_work"]
    assert summary["options"]["no_skip"] == ["joints"]  # as asked, beside what it changed
    r = run(["bake", scene["garment"], scene["motion"], "--body", scene["body"], "--out", scene["out"],
             "--no-skip", "faces"])
    assert_one_line_error(r, "--no-skip", "faces")
    # a skip the method does not have would change nothing: refused, as --pin is for another method than sim
    for name, needle in (("floor", "--no-skip floor applies to --method sim only (got --method lbs)"),
                         ("body-faces", "--no-skip body-faces applies to --method sim only")):
        r = run(["bake", scene["garment"], scene["motion"], "--body", scene["body"], "--out", scene["out"] / "x",
                 "--no-skip", name])
        assert_one_line_error(r, needle)
        assert not (scene["out"] / "x").exists()


def test_bake_workers_equal_one_process_and_report_throughput(scene):
    from formats.sequence import read_sequence

    outs = {}
    for n in (1, 2):
        out = scene["out"] / f"w{n}"
        r = run(["bake", scene["garment"], scene["motion"], scene["motion2"], "--body", scene["body"], "--out", out,
                 "--workers", n, "--no-body"])
        assert r.exit_code == 0, r.output
        assert "frames/s" in r.output.splitlines()[-1] and "of 2 motions" in r.output
        outs[n] = {d.name: read_sequence(d / "obj").points for d in sorted(out.iterdir())}
    assert sorted(outs[1]) == sorted(outs[2]) == ["shell_jump", "shell_walk"]
    for name in outs[1]:
        np.testing.assert_allclose(outs[2][name], outs[1][name], atol=1e-6)
    r = run(["bake", scene["garment"], scene["motion"], "--body", scene["body"], "--out", scene["out"], "--workers", 0])
    assert_one_line_error(r, "--workers")
    r = run(["bake", scene["garment"], scene["motion"], "--body", scene["body"], "--out", scene["out"], "--workers",
             257])  # (processes, each with torch loaded)
    assert_one_line_error(r, "Invalid value for '--workers': 257 is not in the range 1<=x<=256.")
    # one motion: baked here, said (the option was quietly ignored)
    r = run(["bake", scene["garment"], scene["motion"], "--body", scene["body"], "--out", scene["out"] / "one",
             "--workers", 2, "--no-body", "--no-obj"])
    assert r.exit_code == 0 and "note: --workers 2: one motion, baked in this process" in r.output, r.output


def test_one_process_goes_on_past_a_failed_motion_and_counts_the_frames_written(scene, monkeypatch):
    """A motion that fails while baked stopped a one-process batch there (the later motions never tried), where
    --workers and a cluster go on: now each engine bakes the others and ends with one line naming the first that
    failed. The throughput line counts the frames written (it counted --preroll's)."""
    import garmentcli.bake as bake_cli
    from core.errors import InputError

    real = bake_cli.bake_item

    def failing(garment, body, motion, *args, **kw):
        if motion.name == "walk":
            raise InputError("the simulator diverged (injected)")
        return real(garment, body, motion, *args, **kw)

    monkeypatch.setattr(bake_cli, "bake_item", failing)
    out = scene["out"] / "f"
    args = ["bake", scene["garment"], scene["motion"], scene["motion2"], "--body", scene["body"], "--no-obj",
            "--frames", "3:", "--preroll", "3"]
    r = run([*args, "--out", out])
    assert_one_line_error(r, f"bake: 1 of 2 motions failed, the others are written; '{scene['motion']}': the "
                             "simulator diverged (injected); rerun with --skip-existing")
    assert f"error: bake of '{scene['motion']}': the simulator diverged (injected)" in r.output
    assert sorted(p.name for p in out.iterdir()) == ["shell_jump"]  # the motion after it baked
    monkeypatch.setattr(bake_cli, "bake_item", real)
    r = run([*args, "--out", out, "--skip-existing"])
    assert r.exit_code == 0, r.output
    written = sum(json.loads((out / d / "summary.json").read_text())["frames"] for d in ("shell_walk", "shell_jump"))
    assert f"baked {written} frames of 1 motions" not in r.output  # (one motion left: no batch line)
    r = run([*args, "--out", scene["out"] / "g"])
    assert r.exit_code == 0 and f"baked {written} frames of 2 motions in" in r.output, r.output


def test_bake_suggests_push_out_where_much_of_the_garment_is_inside_the_body(scene):
    d = scene["dir"]
    write_shell_obj(d / "tight.obj", scene["tiny"], offset=-0.01)  # authored 1 cm inside the body
    for extra, hinted in (([], True), (["--push-out"], False)):
        r = run(["bake", d / "tight.obj", scene["motion"], "--body", scene["body"], "--out", scene["out"],
                 "--method", "lbs", "--overwrite", *extra])
        assert r.exit_code == 0, r.output
        line = [ln for ln in r.output.splitlines() if "penetration mean" in ln][0]
        assert ("--push-out moves them outside" in line) == hinted, line


def test_the_command_gives_numpy_one_blas_thread_unless_told_otherwise():
    """More OpenBLAS threads than free cores made numpy products 14-400x slower under --workers."""
    import os
    import subprocess
    import sys

    code = "import garmentcli, os, numpy; print(os.environ['OPENBLAS_NUM_THREADS'])"
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    assert subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True).stdout.strip() == "1"
    env["OPENBLAS_NUM_THREADS"] = "3"
    assert subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True).stdout.strip() == "3"


@pytest.mark.parametrize("workers", [1, 2])
def test_summary_records_the_warnings_of_its_own_inputs(scene, workers, monkeypatch):
    """A Y-up motion's warning lands in its own summary.json, not in that of the other motion of the batch
    (baked here or in worker processes); the inputs are recorded as absolute paths either way (on workers the
    garment was, the motion not)."""
    d = scene["dir"]
    poses = np.zeros((12, 72), np.float32)  # root unturned: the body stands along world +Y
    write_motion(d / "yup.npz", poses=poses)
    monkeypatch.chdir(d)
    rel = [os.path.relpath(p, d) for p in (scene["garment"], scene["motion"], d / "yup.npz", scene["body"])]
    r = run(["bake", *rel[:3], "--body", rel[3], "--method", "lbs", "--out", scene["out"], "--no-obj",
             "--workers", workers])
    assert r.exit_code == 0, r.output
    yup = json.loads((scene["out"] / "shell_yup" / "summary.json").read_text())
    walk = json.loads((scene["out"] / "shell_walk" / "summary.json").read_text())["warnings"]
    assert len(yup["warnings"]) == 1 and "yup.npz" in yup["warnings"][0] and "looks Y-up" in yup["warnings"][0]
    assert walk == []
    assert yup["inputs"] == {"garment": str(Path(scene["garment"]).resolve()), "motion": str((d / "yup.npz").resolve()),
                             "body": str(Path(scene["body"]).resolve())}


def test_betas_option_sets_the_body_shape_and_rejects_garbage(scene):
    """--betas mean bakes the mean body whatever the motion says; a list sets the coefficients (padded);
    'motion' keeps the motion's, and so does 'auto' (default) on a --body; summary.json records the option and the
    betas baked."""
    d = scene["dir"]
    write_motion(d / "shaped.npz", betas=np.full(16, 1.5, np.float32))
    outs = {}
    for option in ("auto", "motion", "mean", "0.5,-0.5"):
        out = d / f"out_{option}"
        r = run(["bake", scene["garment"], d / "shaped.npz", "--body", scene["body"], "--out", out, "--no-obj",
                 "--betas", option])
        assert r.exit_code == 0, r.output
        summary = json.loads((out / "shell_shaped" / "summary.json").read_text())
        assert summary["options"]["betas"] == option
        outs[option] = summary["body"]["betas"]
    n = len(outs["mean"])
    assert outs["mean"] == [0.0] * n and outs["motion"] == outs["auto"] == [1.5] * n
    assert outs["0.5,-0.5"] == [0.5, -0.5] + [0.0] * (n - 2)
    for bad in ("tall", "1,nan"):
        r = run(["bake", scene["garment"], d / "shaped.npz", "--body", scene["body"], "--out", d / "x", "--betas", bad])
        assert_one_line_error(r, "--betas")
        assert not (d / "x").exists()
    assert "expected 'auto', 'motion', 'mean' or comma-separated numbers, got 'tall'" in run(
        ["bake", scene["garment"], d / "shaped.npz", "--out", d / "x", "--betas", "tall"]).output


def test_a_motion_without_a_frame_rate_bakes_with_source_fps(scene):
    d = scene["dir"]
    poses = np.zeros((12, 72), np.float32)
    poses[:, 0] = np.pi / 2
    np.savez(d / "norate.npz", poses=poses, trans=np.zeros((12, 3), np.float32))
    r = run(["bake", scene["garment"], d / "norate.npz", "--body", scene["body"], "--out", scene["out"]])
    assert_one_line_error(r, "norate.npz", "found none: pass the motion's frame rate with --source-fps")
    r = run(["bake", scene["garment"], d / "norate.npz", "--body", scene["body"], "--out", scene["out"], "--no-obj",
             "--source-fps", 60])
    assert r.exit_code == 0, r.output
    summary = json.loads((scene["out"] / "shell_norate" / "summary.json").read_text())
    assert summary["source_fps"] == 60.0 and summary["frames"] == 6  # 12 frames at 60 fps baked at 30
    r = run(["bake", scene["garment"], d / "norate.npz", "--out", scene["out"], "--source-fps", 0])
    assert_one_line_error(r, "--source-fps")


def test_a_bake_too_big_for_the_free_memory_is_refused_before_any_work(scene, monkeypatch):
    """With room for 2 frames free (psutil reports it), the 12-frame walk (60 fps, baked at 30: 6 frames) is
    refused naming the motion, the memory and the --frames parts that fit (4 source frames); nothing is written.
    With the real free memory it bakes."""
    import types

    import psutil

    from formats.body import load_body
    from formats.obj import read_obj
    from garmentcli.bake import BAKE_COPIES

    per_frame = (read_obj(scene["garment"]).n_vertices + load_body(scene["body"]).n_vertices) * 12 * BAKE_COPIES["lbs"]
    monkeypatch.setattr(psutil, "virtual_memory", lambda: types.SimpleNamespace(available=int(2 * per_frame)))
    r = run(["bake", scene["garment"], scene["motion"], "--body", scene["body"], "--out", scene["out"]])
    assert_one_line_error(r, "walk.npz", "6 frames", "is free: bake it in parts of at most 4 source frames",
                          "--frames START:STOP")
    assert not scene["out"].exists()
    # --no-body: the body is posed at the frames checked for penetration only, and not counted (a --no-body bake
    # of 50,000 frames was let through counting it and peaked beyond twice that, the body posed at every frame)
    garment_frame = read_obj(scene["garment"]).n_vertices * 12 * BAKE_COPIES["lbs"]
    monkeypatch.setattr(psutil, "virtual_memory", lambda: types.SimpleNamespace(available=int(6.5 * garment_frame)))
    assert 6.5 * garment_frame < 6 * per_frame
    r = run(["bake", scene["garment"], scene["motion"], "--body", scene["body"], "--out", scene["out"]])
    assert_one_line_error(r, "walk.npz", "6 frames")
    r = run(["bake", scene["garment"], scene["motion"], "--body", scene["body"], "--out", scene["out"], "--no-body"])
    assert r.exit_code == 0, r.output
    monkeypatch.undo()
    r = run(["bake", scene["garment"], scene["motion"], "--body", scene["body"], "--out", scene["out"], "--overwrite"])
    assert r.exit_code == 0, r.output


def test_skip_existing_takes_the_embedded_body_named(scene, tmp_path):
    """`--body` naming the embedded default body's file is what a bake without --body uses: --skip-existing took it
    for another body; `--frames 00:2` is `--frames 0:2`."""
    from importlib import resources

    args = ["bake", scene["garment"], scene["motion"], "--out", tmp_path, "--no-obj", "--frames", "0:2"]
    assert run(args).exit_code == 0
    with resources.as_file(resources.files("core.assets").joinpath("default_body.npz")) as embedded:
        r = run([*args[:-1], "00:2", "--skip-existing", "--body", embedded])
    assert r.exit_code == 0 and "1 of 1 motions already baked, skipped" in r.output, r.output
    r = run([*args, "--skip-existing", "--body", scene["body"]])
    assert_one_line_error(r, "was baked with --body a file of sha256 ")


def test_skip_existing_with_every_motion_baked_does_nothing(scene):
    args = ["bake", scene["garment"], scene["motion"], "--body", scene["body"], "--out", scene["out"], "--no-obj"]
    assert run(args).exit_code == 0
    summary = scene["out"] / "shell_walk" / "summary.json"
    before = summary.stat().st_mtime_ns
    r = run([*args, "--skip-existing"])
    assert r.exit_code == 0 and "1 of 1 motions already baked, skipped" in r.output, r.output
    assert summary.stat().st_mtime_ns == before
    # a bake of other settings is not this run's to skip (it said "already baked" of a bake at another --fps)
    for extra, said in ((["--frames", "0:3"], "--frames left out (this run: 0:3)"),
                        (["--fps", "24"], "--fps 30 (this run: 24)"),
                        (["--method", "model"], "--method lbs (this run: --method model)"),
                        (["--quality", "auto"], "--method lbs (this run: --quality auto)"),
                        # the method's own options and the outputs asked for (it took them for the bake's)
                        (["--push-out"], "--push-out off (this run: on)"),
                        (["--lbs-smooth", "0"], "--lbs-smooth auto (this run: 0)"),
                        (["--strain-limit", "off"], "--strain-limit left out (this run: off)"),
                        (["--point-cache", "pc2"], "--point-cache left out (this run: pc2)")):
        r = run([*args, "--skip-existing", *extra])
        assert_one_line_error(r, f"output '{scene['out'] / 'shell_walk'}' was baked with {said}: pass --overwrite")
    r = run([*args[:-1], "--skip-existing"])
    assert_one_line_error(r, "was baked with --no-obj on (this run: off)")
    for same in (["--frames", "0:"], ["--frames", ":"]):  # the whole motion spelled otherwise
        assert "1 of 1 motions already baked" in run([*args, "--skip-existing", *same]).output
    # an input file of other content by the same name (a body, a model or a fit remade in place)
    with np.load(scene["body"]) as z:
        arrays = dict(z)
    np.savez(scene["body"], **{**arrays, "v_template": arrays["v_template"] * 1.01})
    r = run([*args, "--skip-existing"])
    assert_one_line_error(r, "was baked with --body a file of sha256 ", " (this run: a file of sha256 ")
    assert summary.stat().st_mtime_ns == before
    # an earlier version's bake, no "settings" recorded: compared by what its summary records
    record = json.loads(summary.read_text())
    del record["settings"]
    summary.write_text(json.dumps(record))
    assert_one_line_error(run([*args, "--skip-existing", "--fps", "24"]), "was baked with --fps 30 (this run: 24)")
    assert "1 of 1 motions already baked" in run([*args, "--skip-existing", "--push-out"]).output
    other = scene["dir"] / "other"
    (other / "shell_walk").mkdir(parents=True)  # an empty folder (or a file) by the bake's name: no finished bake
    r = run([*args[:-3], "--out", other, "--skip-existing"])
    assert_one_line_error(r, f"output '{other / 'shell_walk'}' exists and is no finished bake (no summary.json")
    assert list((other / "shell_walk").iterdir()) == []


def _two_panel_quad_tube(path, n_theta=16, n_rows=5, materials=("", "")):
    """A tube of quads around the tiny body's torso, cut at its sides into two panels that each repeat the seam's
    vertices, with per-panel UVs (as a pattern tool exports a garment) and each panel's `usemtl` (none for "").
    Returns (vertices, quads) as written."""
    half = n_theta // 2
    verts, uvs, quads = [], [], []
    for panel in range(2):
        first = len(verts)
        for r, y in enumerate(np.linspace(-0.3, 0.1, n_rows)):
            for c in range(half + 1):
                t = 2 * np.pi * (panel * half + c) / n_theta
                verts.append([0.3 * np.cos(t), y, 0.2 * np.sin(t)])
                uvs.append([c / half, r / (n_rows - 1)])
        for r in range(n_rows - 1):
            for c in range(half):
                a = first + r * (half + 1) + c
                quads.append([a, a + half + 1, a + half + 2, a + 1])
    lines = [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in verts] + [f"vt {u:.6f} {v:.6f}" for u, v in uvs]
    per_panel = len(quads) // 2
    for k, q in enumerate(quads):
        if k % per_panel == 0 and materials[k // per_panel]:
            lines.append(f"usemtl {materials[k // per_panel]}")
        lines.append("f " + " ".join(f"{i + 1}/{i + 1}" for i in q))
    path.write_text("\n".join(lines) + "\n")
    return np.array(verts), np.array(quads)


def test_outputs_carry_the_files_material_library(scene):
    """A garment whose materials come from an .mtl with a texture: the OBJ frames name a copy of the library in
    obj/ whose texture path leads to the texture; the USD garment's subsets are bound to preview materials of
    the library's colours, the textured one reading the texture (by a path relative to the stage) through st."""
    from pxr import Usd, UsdShade

    asset = scene["dir"] / "asset"
    (asset / "tex").mkdir(parents=True)
    (asset / "tex" / "weave.png").write_bytes(b"png")
    (asset / "panels.mtl").write_text("newmtl front\nKd 0.2 0.4 0.6\nmap_Kd tex/weave.png\n"
                                      "newmtl back\nKd 1 0 0\nd 0.5\n")
    path = asset / "panels.obj"
    _two_panel_quad_tube(path, materials=("front", "back"))
    path.write_text("mtllib panels.mtl\n" + path.read_text())
    r = run(["bake", str(path), scene["motion"], "--body", scene["body"], "--out", scene["out"]])
    assert r.exit_code == 0, r.output
    d = scene["out"] / "panels_walk"
    assert (d / "obj" / "frame_0000.obj").read_text().splitlines()[1] == "mtllib panels.mtl"
    copy = (d / "obj" / "panels.mtl").read_text().splitlines()
    texture_line = next(line for line in copy if line.startswith("map_Kd"))
    assert (d / "obj" / texture_line.split()[1]).resolve() == (asset / "tex" / "weave.png").resolve()
    stage = Usd.Stage.Open(str(d / "panels_walk.usd"))
    looks = {}
    for name in ("front", "back"):
        subset = stage.GetPrimAtPath(f"/Root/garment/{name}")
        material = UsdShade.MaterialBindingAPI(subset).GetDirectBinding().GetMaterial()
        looks[name] = UsdShade.Shader(stage.GetPrimAtPath(f"{material.GetPath()}/PreviewSurface"))
    back = looks["back"]
    assert tuple(back.GetInput("diffuseColor").Get()) == (1, 0, 0) and back.GetInput("opacity").Get() == 0.5
    source = looks["front"].GetInput("diffuseColor").GetConnectedSources()[0][0].source
    texture = UsdShade.Shader(source.GetPrim())
    assert texture.GetIdAttr().Get() == "UsdUVTexture"
    assert (d / texture.GetInput("file").Get().path).resolve() == (asset / "tex" / "weave.png").resolve()
    reader = UsdShade.Shader(texture.GetInput("st").GetConnectedSources()[0][0].source.GetPrim())
    assert reader.GetInput("varname").Get() == "st"
    assert usd_problems(d / "panels_walk.usd") == []  # as usdchecker sees it
    # That stage as the garment (a USD garment with preview materials): its looks kept, the OBJ frames naming a
    # library written of them (they were named by `usemtl` alone, their colours lost), the stage binding them again
    r = run(["bake", str(d / "panels_walk.usd"), scene["motion"], "--body", scene["body"], "--out",
             scene["out"] / "again"])
    assert r.exit_code == 0, r.output
    again = scene["out"] / "again" / "panels_walk_walk"
    assert (again / "obj" / "frame_0000.obj").read_text().splitlines()[1] == "mtllib panels_walk_walk.mtl"
    from formats.mtl import read_mtl

    written = read_mtl(again / "obj" / "panels_walk_walk.mtl")
    assert written["back"].diffuse == (1.0, 0.0, 0.0) and written["back"].opacity == 0.5
    assert written["front"].diffuse is None and written["front"].diffuse_texture == (asset / "tex" / "weave.png").resolve()
    stage = Usd.Stage.Open(str(again / "panels_walk_walk.usd"))
    material = UsdShade.MaterialBindingAPI(stage.GetPrimAtPath("/Root/garment/back")).GetDirectBinding().GetMaterial()
    assert tuple(UsdShade.Shader(stage.GetPrimAtPath(f"{material.GetPath()}/PreviewSurface")).GetInput(
        "diffuseColor").Get()) == (1, 0, 0)


def test_outputs_keep_the_files_ngons(scene):
    """Faces of more than 4 corners are simulated as triangles but written whole: the two-panel tube with each
    pair of neighbouring quads as one hexagon comes back as those hexagons in the OBJ frames and the USD stage,
    each corner with its UV."""
    from pxr import Usd, UsdGeom

    path = scene["dir"] / "hexes.obj"
    _, quads = _two_panel_quad_tube(path)
    hexes = [[a[0], a[1], a[2], b[2], b[3], a[3]] for a, b in zip(quads[0::2].tolist(), quads[1::2].tolist())]
    lines = [line for line in path.read_text().splitlines() if not line.startswith("f ")]
    path.write_text("\n".join(lines + ["f " + " ".join(f"{i + 1}/{i + 1}" for i in h) for h in hexes]) + "\n")
    r = run(["bake", str(path), scene["motion"], "--body", scene["body"], "--out", scene["out"]])
    assert r.exit_code == 0, r.output
    d = scene["out"] / "hexes_walk"
    assert json.loads((d / "summary.json").read_text())["garment"]["written_as_file"] == {"vertices": 90,
                                                                                         "polygons": 32}
    frame = (d / "obj" / "frame_0002.obj").read_text().splitlines()
    faces = [[[int(i) - 1 for i in c.split("/")] for c in line.split()[1:]] for line in frame if line.startswith("f ")]
    assert [[c[0] for c in f] for f in faces] == hexes and all(c[0] == c[1] for f in faces for c in f)
    stage = Usd.Stage.Open(str(d / "hexes_walk.usd"))  # kept: a prim outlives no stage
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/Root/garment"))
    assert list(mesh.GetFaceVertexCountsAttr().Get()) == [6] * 32
    assert list(mesh.GetFaceVertexIndicesAttr().Get()) == np.ravel(hexes).tolist()
    assert len(UsdGeom.PrimvarsAPI(mesh).GetPrimvar("st").Get()) == 192


def test_outputs_keep_the_files_points_quads_and_uv_seams(scene):
    """A garment of quads in two panels (its seam's vertices repeated) is deformed welded and triangulated, but
    written as its file has it: the same points in the same order (a seam's two copies at one position), its
    quads, its UVs, in the OBJ sequence and the USD stage alike; the summary says so."""
    from pxr import Usd, UsdGeom

    from core.geometry import Y_UP_TO_Z_UP_MATRIX

    path = scene["dir"] / "panels.obj"
    verts, quads = _two_panel_quad_tube(path, materials=("front cotton", "back_lining"))
    r = run(["bake", str(path), scene["motion"], "--body", scene["body"], "--out", scene["out"]])
    assert r.exit_code == 0, r.output
    d = scene["out"] / "panels_walk"
    summary = json.loads((d / "summary.json").read_text())
    assert summary["garment"]["vertices"] == 80  # 16 x 5 after the seams' 10 repeats are welded
    assert summary["garment"]["written_as_file"] == {"vertices": 90, "polygons": 64}
    frame = (d / "obj" / "frame_0000.obj").read_text().splitlines()
    faces = [line.split()[1:] for line in frame if line.startswith("f ")]
    assert len([line for line in frame if line.startswith("v ")]) == 90 and len(faces) == 64
    assert [[int(c.split("/")[0]) - 1 for c in f] for f in faces] == quads.tolist()
    assert all(c.split("/")[0] == c.split("/")[1] for f in faces for c in f)  # each corner its own vt, as written
    # Each panel's material: a usemtl line before its first face, a GeomSubset of its faces for binding shaders.
    body = [line for line in frame if line.startswith(("f ", "usemtl"))]
    assert body[0] == "usemtl front cotton" and body[33] == "usemtl back_lining" and body.count("usemtl back_lining") == 1
    stage = Usd.Stage.Open(str(d / "panels_walk.usd"))
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/Root/garment"))
    assert list(mesh.GetFaceVertexCountsAttr().Get()) == [4] * 64
    assert list(mesh.GetFaceVertexIndicesAttr().Get()) == quads.ravel().tolist()
    subsets = {s.GetPrim().GetName(): list(s.GetIndicesAttr().Get())
               for s in UsdGeom.Subset.GetGeomSubsets(mesh, UsdGeom.Tokens.face, "materialBind")}
    assert subsets == {"front_cotton": list(range(32)), "back_lining": list(range(32, 64))}
    st = UsdGeom.PrimvarsAPI(mesh).GetPrimvar("st")
    assert st.GetInterpolation() == UsdGeom.Tokens.faceVarying and len(st.Get()) == 256
    written_uvs = np.array([[float(x) for x in line.split()[1:]] for line in frame if line.startswith("vt ")])
    np.testing.assert_allclose(np.array(st.Get()), written_uvs[quads.ravel()], atol=1e-6)
    points = np.array(mesh.GetPointsAttr().Get(3))
    obj_points = np.array([[float(x) for x in line.split()[1:]]
                           for line in (d / "obj" / "frame_0003.obj").read_text().splitlines() if line.startswith("v ")])
    assert points.shape == (90, 3)
    # The OBJ frames Y-up, as OBJ importers take them (the stage Z-up, as it says): the same points turned.
    np.testing.assert_allclose(points, obj_points @ Y_UP_TO_Z_UP_MATRIX.T, atol=2e-6)
    assert json.loads((d / "obj" / "sequence.json").read_text())["up"] == "y"
    # The seam's two copies: one at each end of each panel's rows, where the other panel's row starts or ends.
    cols = 9
    for r in range(5):
        a0, a8, b0, b8 = r * cols, r * cols + 8, 45 + r * cols, 45 + r * cols + 8
        np.testing.assert_array_equal(points[a8], points[b0])
        np.testing.assert_array_equal(points[a0], points[b8])
    assert not np.allclose(points, verts)  # it moved


def test_bake_motions_from_a_directory_tree_keep_one_output_each(scene):
    """A directory of motions bakes every motion under it (AMASS's shape.npz left out, and a Mac archive's
    metadata: `._walk.bvh`, `__MACOSX/`, and hidden folders); two motions of one file name get one output each,
    named by their folders (one overwrote the other before); a motion named again is baked once; a directory
    without motions is refused."""
    tree = scene["dir"] / "mocap"
    for subject in ("s1", "s2"):
        (tree / subject).mkdir(parents=True)
        (tree / subject / "walk.npz").write_bytes(Path(scene["motion"]).read_bytes())
        np.savez(tree / subject / "shape.npz", betas=np.zeros(10), gender="male")
    finder = b"\x00\x05\x16\x07\x00\x02\x00\x00Mac OS X        "  # AppleDouble metadata, no BVH
    (tree / "s1" / "._walk.bvh").write_bytes(finder)
    for hidden in ("__MACOSX/s1", ".ipynb_checkpoints"):
        (tree / hidden).mkdir(parents=True)
        (tree / hidden / "run.bvh").write_bytes(finder)
    r = run(["bake", scene["garment"], tree, tree / "s1" / "walk.npz", "--body", scene["body"], "--method", "lbs",
             "--out", scene["out"]])
    assert r.exit_code == 0, r.output
    assert sorted(p.name for p in scene["out"].iterdir()) == ["shell_s1_walk", "shell_s2_walk"]
    assert "of 2 motions" in r.output
    (scene["dir"] / "empty").mkdir()
    r = run(["bake", scene["garment"], scene["dir"] / "empty", "--body", scene["body"], "--out", scene["dir"] / "e"])
    assert_one_line_error(r, "expected motion files under it (.npz, .pkl or .npy")
    assert not (scene["dir"] / "e").exists()


def test_motion_names_tell_files_of_one_name_apart():
    from garmentcli.common import motion_names

    assert motion_names(["/m/a/walk.npz", "/m/b/run.npz"]) == ["walk", "run"]
    assert motion_names(["/m/a/walk.npz", "/m/b/walk.npz", "/m/run.npz"]) == ["a_walk", "b_walk", "run"]
    assert motion_names(["/x/s/walk.npz", "/y/s/walk.npz"]) == ["x_s_walk", "y_s_walk"]
    # files of one stem in one folder by their suffixes (they went to one output, the second silently not baked)
    assert motion_names(["/m/walk.npz", "/m/walk.bvh", "/n/walk.npz"]) == ["walk_npz", "walk_bvh", "walk"]
    # names that differ in case only meet on a case-insensitive file system (macOS, Windows, a share of theirs)
    assert motion_names(["/m/a/walk.npz", "/m/a/walk.NPZ"]) == ["walk", "walk_2"]
    assert motion_names(["/m/a/Walk.npz", "/m/a/walk.npz", "/m/run.npz"]) == ["Walk", "walk_2", "run"]
    assert motion_names(["/m/a/walk.npz", "/m/a/walk.NPZ", "/m/a/walk.bvh"]) == ["walk_npz", "walk_NPZ_2", "walk_bvh"]
    assert motion_names(["/m/a/Walk.npz", "/m/b/walk.npz"]) == ["a_Walk", "b_walk"]
    assert motion_names(["/m/A/walk.npz", "/m/a/walk.npz"]) == ["walk", "walk_2"]
    # a name widened by its folder meets another file's stem: widened further, the other file as it is
    assert motion_names(["/t/lib/a/walk.npz", "/t/lib/a_walk.npz", "/t/lib/b/walk.npz"]) == \
        ["lib_a_walk", "a_walk", "b_walk"]
    # no folder tells them apart (a/b_walk.npz and a_b/walk.npz): numbered
    assert motion_names(["/m/a/b_walk.npz", "/m/a_b/walk.npz", "/n/a_b/walk.npz"]) == \
        ["b_walk", "m_a_b_walk", "n_a_b_walk"]
    names = motion_names(["/m/a/b_walk.npz", "/m/x/a_b_walk.npz", "/m/a/b/walk.npz", "/m/c/b/walk.npz"])
    assert len(set(names)) == 4, names


def test_a_batch_refuses_two_motions_for_one_output_and_a_name_too_long_before_any_work(scene):
    """Two files of one stem in one folder were written to one output: with one process the second was skipped
    without a word (exit 0); a name longer than the file system takes beside the hidden temporary one failed with
    'File name too long' only after its motion had been baked."""
    import click

    from garmentcli.bake import _refuse_shared_targets

    lib = scene["dir"] / "lib"
    lib.mkdir()
    motion = Path(scene["motion"]).read_bytes()
    for name in ("walk.npz", "walk.NPZ"):
        (lib / name).write_bytes(motion)
    out = scene["out"] / "lib"
    r = run(["bake", scene["garment"], lib, "--body", scene["body"], "--out", out, "--no-obj", "--no-body"])
    assert r.exit_code == 0 and "of 2 motions" in r.output, r.output
    assert sorted(p.name for p in out.iterdir()) == ["shell_walk", "shell_walk_2"]  # (not of one name but case)
    t = out / "shell_walk"
    for other in (t, out / "Shell_Walk"):
        with pytest.raises(click.ClickException, match="motions 'a.npz' and 'b.npz' would both be written to"):
            _refuse_shared_targets([("a.npz", t, {}), ("b.npz", other, {})])
    _refuse_shared_targets([("a.npz", t, {}), ("b.npz", out / "other", {})])
    long = scene["dir"] / ("w" * 230 + ".npz")
    long.write_bytes(motion)
    r = run(["bake", scene["garment"], scene["motion"], long, "--body", scene["body"], "--out", scene["out"] / "l"])
    assert_one_line_error(r, "written under a longer hidden name first): shorten the file names")
    assert not (scene["out"] / "l").exists()


def test_start_frame_numbers_the_usd_time_codes_and_obj_frames(scene):
    """--start-frame 1001: the stage's time codes and the OBJ files start at 1001 (settle frames included), the
    summary records it, and `metrics` pairs it frame by frame with a bake numbered from 0."""
    from pxr import Usd

    common = [scene["garment"], scene["motion"], "--body", scene["body"], "--method", "lbs", "--settle", "2"]
    r = run(["bake", *common, "--start-frame", "1001", "--out", scene["out"] / "shot"])
    assert r.exit_code == 0, r.output
    d = scene["out"] / "shot" / "shell_walk"
    summary = json.loads((d / "summary.json").read_text())
    n = summary["frames"]
    assert summary["options"]["start_frame"] == 1001
    names = sorted(p.name for p in (d / "obj").glob("*.obj"))
    assert names[0] == "frame_1001.obj" and names[-1] == f"frame_{1000 + n}.obj" and len(names) == n
    assert json.loads((d / "obj" / "sequence.json").read_text())["start"] == 1001
    stage = Usd.Stage.Open(str(d / "shell_walk.usd"))
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (1001, 1000 + n)
    assert list(stage.GetPrimAtPath("/Root/garment").GetAttribute("points").GetTimeSamples()) == list(
        range(1001, 1001 + n))
    r = run(["bake", *common, "--out", scene["out"] / "zero"])
    assert r.exit_code == 0, r.output
    r = run(["metrics", d, scene["out"] / "zero" / "shell_walk"])
    assert r.exit_code == 0, r.output
    values = r.output.strip().splitlines()[-1].strip("|").split("|")
    assert [float(v) for v in values[:5]] == [0.0] * 5  # E_verts ... E_curv: the same frames, paired by index
    assert_one_line_error(run(["bake", *common, "--start-frame", "-1", "--out", scene["out"] / "neg"]),
                          "--start-frame")


def test_point_caches_hold_the_obj_frames_in_the_garment_files_frame(scene):
    """--point-cache pc2 --point-cache mdd: <garment>_<motion>.pc2 and .mdd beside the stage hold every OBJ frame's
    points in their order, turned back to the garment file's Y-up frame, numbered from --start-frame (MDD: its
    times in seconds), which `metrics` reads against the bake (the same points: zero error; at frame 1001 of 24
    fps the MDD's float32 times read as 23.9993 fps, refused against the bake's 24); an unknown format is refused
    before any work."""
    from core.geometry import Y_UP_TO_Z_UP_MATRIX
    from formats.pointcache import read_point_cache
    from formats.sequence import read_sequence

    common = [scene["garment"], scene["motion"], "--body", scene["body"], "--method", "lbs"]
    r = run(["bake", *common, "--point-cache", "pc2", "--point-cache", "mdd", "--point-cache", "pc2",
             "--start-frame", "1001", "--fps", "24", "--out", scene["out"] / "caches"])
    assert r.exit_code == 0, r.output
    d = scene["out"] / "caches" / "shell_walk"
    frames = read_sequence(d / "obj").points
    summary = json.loads((d / "summary.json").read_text())
    fps = summary["fps"]
    assert summary["options"]["point_caches"] == ["pc2", "mdd"]
    assert fps == 24
    for kind, stamps in (("pc2", 1001 + np.arange(len(frames))), ("mdd", (1001 + np.arange(len(frames))) / fps)):
        points, read_stamps = read_point_cache(d / f"shell_walk.{kind}")
        np.testing.assert_allclose(points @ Y_UP_TO_Z_UP_MATRIX.T, frames, atol=1e-6)
        np.testing.assert_allclose(read_stamps, stamps, rtol=1e-6)
    assert sorted(p.name for p in d.glob("shell_walk.*")) == ["shell_walk.mdd", "shell_walk.pc2", "shell_walk.usd"]
    for cache in ("shell_walk.pc2", "shell_walk.mdd"):  # metrics reads a cache as GT, the bake's faces taken
        r = run(["metrics", d, d / cache])
        assert r.exit_code == 0, r.output
        assert [float(v) for v in r.output.strip().splitlines()[-1].strip("|").split("|")[:5]] == [0.0] * 5
    assert_one_line_error(run(["metrics", d / "shell_walk.pc2", d / "shell_walk.mdd"]), "are point caches: expected "
                          "one of them with its mesh")
    # a PC2 sampled every 2nd frame (its header's sample rate 2, as Max and Houdini write one) is not compared
    # frame by frame with a bake of every frame
    every_other = bytearray((d / "shell_walk.pc2").read_bytes())
    every_other[24:28] = np.float32(2.0).tobytes()
    (d / "every_other.pc2").write_bytes(bytes(every_other))
    assert_one_line_error(run(["metrics", d, d / "every_other.pc2"]), "every_other.pc2': expected a sample every "
                          "frame (sample rate 1), got a sample every 2 frames")
    assert_one_line_error(run(["bake", *common, "--point-cache", "abc", "--out", scene["out"] / "bad"]),
                          "--point-cache", "'abc' is not one of 'pc2', 'mdd'")
    assert not (scene["out"] / "bad").exists()


def test_preroll_frames_are_deformed_and_not_written(scene):
    """--frames 6:12 --preroll 4: the written frames are those of --frames 6:12 (LBS, which keeps no state, puts
    them at the same places), numbered as they are; the summary records the pre-roll."""
    common = [scene["garment"], scene["motion"], "--body", scene["body"], "--method", "lbs", "--frames", "6:12"]
    for name, extra in (("plain", []), ("led", ["--preroll", "4"])):
        r = run(["bake", *common, *extra, "--out", scene["out"] / name])
        assert r.exit_code == 0, r.output
        # LBS deforms each frame on its own: the pre-roll changes nothing, said (it was taken without a word)
        assert ("note: --preroll 4: lbs deforms each frame on its own" in r.output) == bool(extra), r.output
    from formats.sequence import read_sequence

    plain, led = (read_sequence(scene["out"] / n / "shell_walk" / "shell_walk.usd") for n in ("plain", "led"))
    assert led.points.shape == plain.points.shape == (3, plain.points.shape[1], 3)  # 6 source frames at 60 -> 30 fps
    np.testing.assert_allclose(led.points, plain.points, atol=1e-6)
    summary = json.loads((scene["out"] / "led" / "shell_walk" / "summary.json").read_text())
    assert summary["frames"] == 3 and summary["preroll_frames"] == 2 and summary["options"]["preroll"] == 4
    assert json.loads((scene["out"] / "plain" / "shell_walk" / "summary.json").read_text())["preroll_frames"] == 0


def test_an_output_that_cannot_be_written_stops_before_any_work(scene, tmp_path, monkeypatch):
    """--out under a file, a link to nothing, or in a folder where nothing can be made (a read-only or virtual file
    system: root passes every permission check, so it is tried): one line naming --out when the command line is
    read, nothing baked or left behind."""
    import garmentcli.bake

    afile = tmp_path / "afile"
    afile.write_text("")
    monkeypatch.setattr(garmentcli.bake, "bake_task", lambda *a, **k: pytest.fail("baked"))
    r = run(["bake", scene["garment"], scene["motion"], "--body", scene["body"], "--out", afile / "sub"])
    assert_one_line_error(r, "'--out'", "is a file, not a folder")
    dangling = tmp_path / "scratch"
    dangling.symlink_to(tmp_path / "not_mounted" / "bakes")  # a link to a disk not mounted: failed after the work
    r = run(["bake", scene["garment"], scene["motion"], "--body", scene["body"], "--out", dangling])
    assert_one_line_error(r, "'--out'", f"it is a link to '{tmp_path / 'not_mounted' / 'bakes'}', which is not there")
    readonly = tmp_path / "readonly"
    readonly.mkdir()

    def refused(*a, dir=None, **k):
        raise PermissionError(30, "Read-only file system")

    monkeypatch.setattr("garmentcli.common.tempfile.mkdtemp", refused)
    r = run(["bake", scene["garment"], scene["motion"], "--body", scene["body"], "--out", readonly / "new" / "out"])
    assert_one_line_error(r, "'--out'", f"cannot write in '{readonly}' (Read-only file system)")
    assert list(readonly.iterdir()) == []


def test_an_empty_or_too_long_name_is_one_line_naming_it(scene, tmp_path, monkeypatch):
    """An empty argument (a shell variable never set) anywhere: as MOTION it was the current folder (every motion
    under it baked), as --body the current folder, as --frames every frame; or a name longer than the file system
    takes (ENAMETOOLONG: pathlib raised it from exists()), as --out or as MOTION: one line, no traceback, nothing
    written."""
    base = ["bake", scene["garment"], scene["motion"], "--body", scene["body"]]
    long_name = "x" * 300
    monkeypatch.chdir(scene["dir"])  # a folder holding a motion
    for args, named in (([*base, "--out", ""], "after '--out'"), (["bake", scene["garment"], "", "--out", "o"],
                                                                  f"after '{scene['garment']}'"),
                        ([*base, "--frames", "", "--out", "o"], "after '--frames'"),
                        ([*base, "--frames=", "--out", "o"], "of '--frames'"),
                        (["info", ""], "after 'info'"), (["metrics", "o", ""], "after 'o'")):
        r = run(args)
        assert_one_line_error(r, f"an empty argument {named}: expected a path or a value, got '' (see '",
                              f" {args[0]} --help')")
        assert r.exit_code == 2 and not (scene["dir"] / "o").exists()
    # Shell completion parses what is typed so far, an empty word too; after '--' a name is taken as it is.
    from garmentcli.main import cli

    assert cli.make_context("garment", ["bake", "", "--fr"], resilient_parsing=True) is not None
    assert run(["info", scene["motion"], "--", "--x="]).output.count("an empty argument") == 0
    r = run([*base, "--out", tmp_path / long_name])
    assert_one_line_error(r, "'--out'", "File name too long")
    r = run(["bake", scene["garment"], tmp_path / long_name, "--body", scene["body"], "--out", tmp_path / "o"])
    assert_one_line_error(r, "x" * 20 + " (", " characters)': File name too long")
    assert not (tmp_path / "o").exists()


def test_an_error_repeats_a_huge_value_by_its_ends(scene, tmp_path):
    """A value of 100,000 characters (a file pasted as an option) in our message and in click's own: the error is
    one short line naming the option and the value's length; a value of ordinary length is repeated whole."""
    base = ["bake", scene["garment"], scene["motion"], "--body", scene["body"], "--out", tmp_path / "o"]
    for option, needle in (("--frames", "'--frames': expected START:STOP"), ("--lbs-smooth", "'--lbs-smooth'")):
        r = run([*base, option, "1" * 100_000])
        assert_one_line_error(r, needle, "...(100,00")
        assert len(r.output) < 1000, len(r.output)
    r = run([*base, "--frames", "1" * 250])
    assert_one_line_error(r, "1" * 250)
    assert not (tmp_path / "o").exists()


def test_a_npy_array_named_npz_in_a_motion_folder_is_refused_as_a_motion(scene, tmp_path):
    """A .npy array saved under an .npz name in a MOTION folder (np.load gives an array, not an archive: the
    folder scan raised TypeError): taken as a motion file and refused with the reason, in one line."""
    folder = tmp_path / "motions"
    folder.mkdir()
    with open(folder / "array.npz", "wb") as f:
        np.save(f, np.zeros(3))
    r = run(["bake", scene["garment"], folder, "--body", scene["body"], "--out", tmp_path / "o"])
    assert_one_line_error(r, "array.npz")
    assert not (tmp_path / "o").exists()


def test_every_output_option_is_checked_when_read():
    import click

    from garmentcli.common import OutputPath
    from garmentcli.main import all_commands

    outs = {name: p for name, c in all_commands().items() for p in c.params
            if isinstance(p, click.Option) and "--out" in p.opts}
    assert len(outs) >= 10 and all(isinstance(p.type, OutputPath) for p in outs.values()), \
        [n for n, p in outs.items() if not isinstance(p.type, OutputPath)]


def test_atomic_writers_turn_an_unwritable_place_into_one_line(tmp_path):
    from core.errors import InputError
    from formats.atomic import atomic_dir, atomic_file

    (tmp_path / "afile").write_text("")
    with pytest.raises(InputError, match=r"output '.*afile/d': cannot write in '.*afile'"):
        with atomic_dir(tmp_path / "afile" / "d", overwrite=False):
            pass
    with pytest.raises(InputError, match=r"output '.*afile/f.txt': cannot write in"):
        with atomic_file(tmp_path / "afile" / "f.txt"):
            pass


def test_bake_render_with_a_window_that_cannot_open_stops_before_any_work(scene, monkeypatch):
    """bake --render checks the off-screen window first: one line, nothing baked or written."""
    import formats.render as R
    import garmentcli.bake

    monkeypatch.setenv("VTK_DEFAULT_OPENGL_WINDOW", "vtkXOpenGLRenderWindow")
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.setattr(R, "_find_library", lambda name: f"lib{name}.so")
    monkeypatch.setattr(garmentcli.bake, "bake_task", lambda *a, **k: pytest.fail("baked"))
    r = run(["bake", scene["garment"], scene["motion"], "--body", scene["body"], "--out", scene["out"], "--render"])
    assert_one_line_error(r, "VTK_DEFAULT_OPENGL_WINDOW=vtkXOpenGLRenderWindow: expected an X display")
    assert not scene["out"].exists()


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="named pipes")
def test_a_pipe_a_device_or_a_link_loop_is_named_for_what_it_is(scene):
    """The shell's `<(...)` gives a pipe, read once where the readers seek and read again: said so, not 'no such
    file' (what it said for the garment and the motion); a device as --body, a symbolic link loop likewise."""
    d = scene["dir"]
    os.mkfifo(d / "pipe.obj")
    os.mkfifo(d / "pipe.npz")
    (d / "loop_a.obj").symlink_to(d / "loop_b.obj")
    (d / "loop_b.obj").symlink_to(d / "loop_a.obj")
    pipe = "a pipe (such as the shell's <(...)), expected a file: write it to a file first"
    base = ["--body", scene["body"], "--out", scene["out"]]
    assert_one_line_error(invoke(["bake", d / "pipe.obj", scene["motion"], *base]), "pipe.obj'", pipe)
    assert_one_line_error(invoke(["bake", scene["garment"], d / "pipe.npz", *base]), "pipe.npz'", pipe)
    assert_one_line_error(invoke(["bake", d / "loop_a.obj", scene["motion"], *base]), "loop_a.obj'",
                          "a symbolic link loop")
    assert_one_line_error(invoke(["metrics", d / "pipe.npz", scene["garment"]]), "pipe.npz'", pipe)
    # Every other command that reads a garment, a motion or a file option (info, preprocess and dataset waited for
    # the pipe's writer for ever; attribute, unpose and render called it missing).
    for args in (["info", d / "pipe.obj"], ["preprocess", d / "pipe.obj", "--no-cache", "--body", scene["body"]],
                 ["dataset", "--dry-run", "--garments", d / "pipe.obj", "--motions", scene["motion"], "--body",
                  scene["body"], "--out", scene["out"]],
                 ["attribute", "default", scene["garment"], d / "pipe.npz", "--frame", "0", "--no-render"],
                 ["unpose", scene["garment"], "--pose", d / "pipe.npz", "--body", scene["body"], "--out",
                  scene["out"] / "u.obj"],
                 ["tradeoff", scene["garment"], scene["motion"], "--fit", f"f={d / 'pipe.npz'}", "--out", scene["out"]],
                 ["bake", scene["garment"], scene["motion"], "--method", "model", "--model", d / "pipe.npz", *base]):
        r = invoke(args)
        assert r.exit_code != 0 and "pipe." in r.output and pipe in r.output, (args, r.output)
        assert len(r.output.strip().splitlines()) == 1 or args[0] == "info", (args, r.output)
    if Path("/dev/null").exists():
        assert_one_line_error(invoke(["bake", scene["garment"], scene["motion"], "--body", "/dev/null", "--out",
                                      scene["out"]]), "body file '/dev/null': a device, expected a file")
    assert not scene["out"].exists()


def test_the_writing_of_the_obj_frames_has_a_bar_of_its_own(scene, monkeypatch):
    """After the bake bar's 100 % the OBJ frames are written (a 203k-vertex garment's 1.3 GB took a minute without a
    word): a "write" bar counts them, per motion; none with --no-obj."""
    import garmentcli.bake

    bars = []

    class Recorder:
        def __init__(self, total=None, desc=None, **kwargs):
            self.desc, self.total, self.n = desc, total, 0
            bars.append(self)

        def update(self, n=1):
            self.n += n

        def close(self):
            pass

        __enter__ = lambda self: self  # noqa: E731
        __exit__ = lambda self, *exc: None  # noqa: E731

    monkeypatch.setattr(garmentcli.bake, "tqdm", Recorder)
    common = [scene["garment"], scene["motion"], scene["motion2"], "--body", scene["body"], "--method", "lbs"]
    r = run(["bake", *common, "--out", scene["out"] / "a"])
    assert r.exit_code == 0, r.output
    written = [(b.total, b.n) for b in bars if b.desc == "write"]
    frames = [len(list((scene["out"] / "a" / f"shell_{m}" / "obj").glob("*.obj"))) for m in ("walk", "jump")]
    assert written == [(n, n) for n in frames] and min(frames) > 0
    bars.clear()
    assert run(["bake", *common, "--out", scene["out"] / "b", "--no-obj"]).exit_code == 0
    assert [b.desc for b in bars] == ["bake"]


def test_retries_without_a_scheduler_is_refused(scene):
    """--retries re-runs a Dask task; local workers do not retry: given without --scheduler it was ignored."""
    r = run(["bake", scene["garment"], scene["motion"], "--body", scene["body"], "--retries", "5", "--out",
             scene["out"] / "r"])
    assert_one_line_error(r, "--retries", "applies only with --scheduler")
    assert not (scene["out"] / "r").exists()


def test_a_bake_stopped_by_ctrl_c_exits_130_and_a_failed_one_leaves_no_out_folder_of_its_own(scene, monkeypatch):
    """Ctrl-C while the outputs are written: "Aborted!", the shell's exit code 130 (click's was 1), nothing left,
    not even the --out folder the bake made (an empty one was left after Ctrl-C, SIGTERM or a full disk); an --out
    that was there before stays."""
    import formats.usd

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(formats.usd, "write_usd_stage", interrupted)
    common = [scene["garment"], scene["motion"], "--body", scene["body"], "--method", "lbs", "--frames", "0:4"]
    r = run(["bake", *common, "--out", scene["out"] / "new"])
    assert r.exit_code == 130 and r.output.strip().splitlines()[-1] == "Aborted!", r.output
    assert not (scene["out"] / "new").exists()
    (scene["out"] / "there").mkdir(parents=True)
    r = run(["bake", *common, "--out", scene["out"] / "there"])
    assert r.exit_code == 130 and (scene["out"] / "there").is_dir() and not any((scene["out"] / "there").iterdir())


def test_the_simulator_not_installed_is_one_line_naming_the_extra(scene, monkeypatch):
    """Installed without the `sim` extra (newton, warp-lang), `--method sim`, `garment dataset` and `garment
    tradeoff` say so in one line before any work (`bake --method sim` and `dataset` ended in a traceback of
    `import warp` after reading their inputs)."""
    import sys

    monkeypatch.setitem(sys.modules, "warp", None)  # an import of it raises ImportError
    outs = scene["dir"] / "outs"
    common = [scene["garment"], scene["motion"], "--body", scene["body"]]
    for args in (["bake", *common, "--method", "sim", "--out", outs / "b"],
                 ["dataset", "--garments", scene["garment"], "--motions", scene["motion"], "--body", scene["body"],
                  "--out", outs / "d"],
                 ["tradeoff", *common, "--out", outs / "t"]):
        r = run(args)
        assert_one_line_error(r, "needs the reference simulator, whose packages are not installed (warp is missing): "
                                 "pip install 'garment[sim]'")
    assert not outs.exists()


def test_usage_errors_of_the_group_and_its_commands_are_one_line_and_garment_alone_shows_its_help():
    """`garment --bogus`, `garment bakee`, `garment bake` without arguments: one line each, exit 2, naming the help
    to read (click printed its usage, a hint and a blank line first); `garment` alone prints its help."""
    for args, needle, where in ((["--bogus"], "No such option '--bogus'", "--help"),
                                (["bakee"], "No such command 'bakee'", "--help"),
                                (["bake"], "Missing argument 'GARMENT'", "bake --help")):
        r = run(args)
        lines = r.output.strip().splitlines()
        assert r.exit_code == 2 and len(lines) == 1 and lines[0].startswith("Error: ") and needle in lines[0], r.output
        assert lines[0].endswith(f"{where}')"), r.output
    r = run([])
    assert "Usage:" in r.output and "Commands:" in r.output and "bake" in r.output


def test_the_group_lists_every_command_by_its_line_without_importing_any():
    """`garment --help` and `--version` import no command (each pulls in torch: 3.6-4.8 s); the list names every
    module of garmentcli that holds a click command, by the line COMMANDS gives it, each line within click's
    80-column help; each command, once asked for, has that line as its short help and its own help."""
    import importlib
    import pkgutil

    import click

    import garmentcli
    from garmentcli.main import COMMANDS, all_commands

    code = ("import sys; from garmentcli.main import main; sys.argv = ['garment', '{}']\ntry: main()\n"
            "except SystemExit: pass\nsys.exit(sorted(m for m in sys.modules if m.split('.')[0] in "
            "('torch', 'numpy', 'formats') or m.startswith('garmentcli.') and m != 'garmentcli.main') or 0)")
    for flag in ("--help", "--version"):
        done = subprocess.run([sys.executable, "-c", code.format(flag)], capture_output=True, text=True)
        assert done.returncode == 0, done.stderr  # (a list of the modules imported)
    r = run(["--help"])
    listed = r.output.split("Commands:")[1].splitlines()[1:]
    assert [line.split()[0] for line in listed if line.strip()] == sorted(COMMANDS)
    assert all(len(line) <= 80 and line.rstrip().endswith(".") for line in listed if line.strip()), listed
    holding = {name for _, name, _ in pkgutil.iter_modules(garmentcli.__path__)
               if isinstance(getattr(importlib.import_module(f"garmentcli.{name}"), name, None), click.Command)}
    assert holding == {module for module, _ in COMMANDS.values()}
    for name, command in all_commands().items():
        assert command.name == name and command.short_help == COMMANDS[name][1] and command.help
    assert run(["bake", "--help"]).output.startswith("Usage: cli bake [OPTIONS] GARMENT MOTION...")


@pytest.mark.parametrize("command", ["bake", "tradeoff"])
def test_a_bad_frames_value_is_a_usage_error_when_the_command_line_is_read(scene, command):
    """A malformed --frames exited 1 as a failure of the work ("Error: --frames: ..."), other bad values 2 with the
    command's help named: it is one of those now."""
    r = run([command, scene["garment"], scene["motion"], "--body", scene["body"], "--out", scene["out"] / "f",
             "--frames", "0:5:2"])
    assert r.exit_code == 2 and "Invalid value for '--frames': expected START:STOP" in r.output, r.output
    assert f"(see 'cli {command} --help')" in r.output and not (scene["out"] / "f").exists()
