"""CLI tests of `garment metrics PRED GT`: happy paths and each bad input."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from garmentcli.main import cli
from tests.meshes import grid, icosphere


def save_seq(path, points, faces, **extra):
    np.savez(path, points=np.asarray(points, dtype=np.float32), faces=np.asarray(faces, dtype=np.int64),
             fps=30.0, **extra)
    return path


@pytest.fixture
def seq(tmp_path):
    """A 3-frame 6x6 grid waving in z: (points (3, 49, 3), faces)."""
    v, f = grid(6, 6, size=0.5)
    pts = np.stack([v + [0, 0, 0.01 * t] for t in range(3)])
    pts[:, :, 2] += 0.02 * np.sin(7 * pts[:, :, 0])
    return pts, f


def run(args):
    result = CliRunner().invoke(cli, ["metrics", *map(str, args)])
    return result


def error_line(result):
    lines = [line for line in result.output.splitlines() if line.startswith("Error:")]
    assert len(lines) == 1, result.output
    return lines[0]


def assert_clean_failure(result, *names):
    assert result.exit_code != 0, result.output
    assert "Traceback" not in result.output
    assert not isinstance(result.exception, Exception) or isinstance(result.exception, SystemExit)
    line = error_line(result)
    for name in names:
        assert name in line, line
    return line


def test_identical_sequences_give_zeros(tmp_path, seq):
    pts, f = seq
    a = save_seq(tmp_path / "a.npz", pts, f)
    b = save_seq(tmp_path / "b.npz", pts, f)
    res = run([a, b])
    assert res.exit_code == 0, res.output
    lines = res.output.splitlines()
    assert lines[0].split("|")[1:-1] == [" E_verts (mm) ", " E_vnorm (deg) ", " E_fnorm (deg) ", " E_edge (%) ",
                                        " E_curv (1/m^2) "]
    assert [float(x) for x in lines[2].split("|")[1:-1]] == [0.0] * 5
    assert not list(tmp_path.glob("metrics.*"))  # no --out: print only


def test_out_writes_requested_formats(tmp_path, seq):
    pts, f = seq
    a = save_seq(tmp_path / "a.npz", pts + [0.0, 0.0, 0.005], f)
    b = save_seq(tmp_path / "b.npz", pts, f)
    out = tmp_path / "report"
    res = run([a, b, "--out", out])
    assert res.exit_code == 0, res.output
    assert sorted(p.name for p in out.iterdir()) == ["metrics.csv", "metrics.json", "metrics.md"]
    doc = json.loads((out / "metrics.json").read_text())
    assert doc["overall"]["e_verts"] == pytest.approx(5.0, rel=1e-4)
    assert doc["metadata"]["pred"] == str(a) and doc["metadata"]["gt"] == str(b)
    assert len((out / "metrics.csv").read_text().splitlines()) == 1 + 3

    # Existing files are kept unless --overwrite; --format picks one file.
    res = run([a, b, "--out", out, "--format", "json"])
    assert_clean_failure(res, "--out", "metrics.json", "--overwrite")
    out2 = tmp_path / "only_md"
    res = run([a, b, "--out", out2, "--format", "md"])
    assert res.exit_code == 0, res.output
    assert [p.name for p in out2.iterdir()] == ["metrics.md"]
    assert run([a, b, "--out", out, "--overwrite"]).exit_code == 0


def test_body_in_pred_gives_penetration(tmp_path):
    v, f = icosphere(2, 0.2)
    body, body_f = icosphere(1, 0.15)
    gt = np.stack([v, v])
    pred = gt.copy()
    pred[0] *= 0.5  # frame 0: every garment vertex inside the body sphere
    T = 2
    a = save_seq(tmp_path / "a.npz", pred, f, body_points=np.repeat(body[None], T, 0).astype(np.float32),
                 body_faces=body_f)
    b = save_seq(tmp_path / "b.npz", gt, f)
    out = tmp_path / "out"
    res = run([a, b, "--out", out, "--format", "json"])
    assert res.exit_code == 0, res.output
    assert "penetration (%)" in res.output
    doc = json.loads((out / "metrics.json").read_text())
    assert doc["per_frame"]["penetration_pct"] == [100.0, 0.0]
    assert doc["per_frame"]["gt_penetration_pct"] == [0.0, 0.0]
    assert doc["metadata"]["body_from"] == str(a)
    assert doc["metadata"]["penetration_depth_mm"] == pytest.approx(2.0)

    # Vertices 4-5 cm inside do not count when the depth threshold is 10 cm; a body in GT is used too.
    a2 = save_seq(tmp_path / "a2.npz", pred, f)
    b2 = save_seq(tmp_path / "b2.npz", gt, f, body_points=np.repeat(body[None], T, 0).astype(np.float32),
                  body_faces=body_f)
    res = run([a2, b2, "--out", tmp_path / "deep", "--format", "json", "--depth-mm", "100"])
    assert res.exit_code == 0, res.output
    doc = json.loads((tmp_path / "deep" / "metrics.json").read_text())
    assert doc["per_frame"]["penetration_pct"] == [0.0, 0.0]
    assert doc["metadata"]["body_from"] == str(b2)


def test_missing_file(tmp_path, seq):
    pts, f = seq
    a = save_seq(tmp_path / "a.npz", pts, f)
    assert_clean_failure(run([a, tmp_path / "nope.npz"]), "nope.npz")


def test_different_vertex_counts(tmp_path, seq):
    pts, f = seq
    v2, f2 = grid(5, 6, size=0.5)
    a = save_seq(tmp_path / "a.npz", pts, f)
    b = save_seq(tmp_path / "b.npz", np.stack([v2] * 3), f2)
    assert_clean_failure(run([a, b]), "a.npz", "b.npz", "49 vertices", "42")


def test_different_faces(tmp_path, seq):
    pts, f = seq
    a = save_seq(tmp_path / "a.npz", pts, f)
    other = f.copy()
    other[0] = [0, 48, 24]  # a triangle across the grid: another surface
    b = save_seq(tmp_path / "b.npz", pts, other)
    assert_clean_failure(run([a, b]), "a.npz", "b.npz", "different faces")
    c = save_seq(tmp_path / "c.npz", pts, f[::-1, ::-1])  # the same triangles, reversed order and winding
    r = run([a, c])
    assert r.exit_code == 0 and "E_verts" in r.output


def test_different_frame_counts(tmp_path, seq):
    pts, f = seq
    a = save_seq(tmp_path / "a.npz", pts, f)
    b = save_seq(tmp_path / "b.npz", pts[:2], f)
    assert_clean_failure(run([a, b]), "a.npz", "3 frames", "b.npz", "2")


def test_nan_in_input(tmp_path, seq):
    pts, f = seq
    bad = pts.copy()
    bad[1, 4, 2] = np.nan
    a = save_seq(tmp_path / "a.npz", bad, f)
    b = save_seq(tmp_path / "b.npz", pts, f)
    assert_clean_failure(run([a, b]), "a.npz")
    frames = tmp_path / "frames"
    frames.mkdir()
    from formats.obj import write_obj

    for t, p in enumerate(bad):
        write_obj(frames / f"frame_{1001 + t:04d}.obj", p, f)
    line = assert_clean_failure(run([frames, b]), "frame_1002.obj")
    lines = (frames / "frame_1002.obj").read_text().splitlines()
    at = next(n for n, text in enumerate(lines, 1) if text.split()[:1] == ["v"] and "nan" in text.lower())
    assert line.endswith(f"expected finite coordinates, got NaN at vertex 5 on line {at}"), line


def test_duplicate_faces_are_left_out_with_a_warning(tmp_path, seq, caplog):
    pts, f = seq
    bumpy = pts + np.random.default_rng(0).normal(0.0, 0.003, pts.shape)
    once = [run([save_seq(tmp_path / "p.npz", bumpy, f), save_seq(tmp_path / "g.npz", pts, f), "--out",
                 tmp_path / "once", "--format", "json"])]
    twice_f = np.concatenate([f, f[:1, ::-1]])  # the first face again, wound the other way
    once.append(run([save_seq(tmp_path / "p2.npz", bumpy, twice_f), save_seq(tmp_path / "g2.npz", pts, twice_f),
                     "--out", tmp_path / "twice", "--format", "json"]))
    assert all(r.exit_code == 0 for r in once), once[1].output
    assert "1 duplicate faces (on the same vertices as an earlier face) left out of the metrics" in caplog.text
    a, b = (json.loads((tmp_path / d / "metrics.json").read_text())["overall"] for d in ("once", "twice"))
    assert a == pytest.approx(b, rel=1e-9)


def test_bad_format(tmp_path, seq):
    pts, f = seq
    a = save_seq(tmp_path / "a.npz", pts, f)
    assert_clean_failure(run([a, a, "--format", "xml"]), "--format", "xml")
    assert_clean_failure(run([a, a, "--format", "csv"]), "--format", "needs --out")  # it wrote nothing, silently


def test_body_from_motion_matches_bake_penetration(scene):
    """--body/--motion pose the body like the bake did: same penetration share as a USD that carries it."""
    args = ["bake", scene["garment"], scene["motion"], "--body", scene["body"], "--out", scene["out"], "--settle", 2,
            "--method", "lbs"]
    assert CliRunner().invoke(cli, [str(x) for x in args]).exit_code == 0
    d = scene["out"] / "shell_walk"
    with_body = run([d / "shell_walk.usd", d / "obj", "--out", scene["dir"] / "m1", "--format", "json"])
    from_motion = run([d / "obj", d / "obj", "--body", scene["body"], "--motion", scene["motion"], "--settle", 2,
                       "--out", scene["dir"] / "m2", "--format", "json"])
    assert with_body.exit_code == 0 and from_motion.exit_code == 0, (with_body.output, from_motion.output)
    m1 = json.loads((scene["dir"] / "m1" / "metrics.json").read_text())
    m2 = json.loads((scene["dir"] / "m2" / "metrics.json").read_text())
    assert m1["overall"]["penetration_pct"] == pytest.approx(m2["overall"]["penetration_pct"], abs=1e-6)
    # the record names where the body came from: the stage, or the motion (not GT, which carries none)
    assert m1["metadata"]["body_from"] == str(d / "shell_walk.usd")
    assert m2["metadata"]["body_from"] == str(scene["motion"])
    # a motion prepared differently (no settle) has another frame count: a clear error
    bad = run([d / "obj", d / "obj", "--body", scene["body"], "--motion", scene["motion"]])
    assert_clean_failure(bad, "--motion", "frames")
    assert_clean_failure(run([d / "obj", d / "obj", "--body", scene["body"]]), "--body", "--motion")



def test_a_ground_truth_in_another_frame_is_pointed_out(tmp_path, seq):
    """GT written Y-up (or in centimetres) by another tool: the metrics are printed as they are, with one warning
    naming the likely mix-up; a GT in this tool's world gets none."""
    pts, f = seq
    pts = pts + [0.0, 0.0, 1.0]  # a garment at waist height
    a = save_seq(tmp_path / "a.npz", pts, f)
    to_y_up = np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]], dtype=np.float64)  # (x, y, z) -> (x, z, -y)
    # what to do fits the mix-up (it told every one "convert it to this tool's world (metres, Z-up)": OBJ frames
    # and point caches, read Y-up, were broken so rewritten)
    for name, gt, needle, advice in (
            ("yup.npz", pts @ to_y_up, "looks as if it is Y-up", "read it Y-up (OBJ frames: --up y, or 'up': 'y' "
             "in their sequence.json; a USD: its upAxis Y) or turn it to Z-up"),
            ("cm.npz", pts * 100, "looks as if it is in centimetres", "scale it to metres (x 0.01)"),
            ("mm.npz", pts * 1000, "looks as if it is in millimetres", "scale it to metres (x 0.001)"),
            ("inch.npz", pts / 0.0254, "looks as if it is in inches", "scale it to metres (x 0.0254)"),
            ("yup_mm.npz", pts @ to_y_up * 1000, "looks as if it is Y-up and in millimetres",
             "scale it to metres (x 0.001) and read it Y-up")):
        b = save_seq(tmp_path / name, gt + 0.001, f)
        r = run([a, b, "--out", tmp_path / name.replace(".npz", "")])
        assert r.exit_code == 0 and "E_verts" in r.output
        assert f"warning: '{b}' {needle}" in r.output and f"(the metrics compare it as it is): {advice}" in \
            " ".join(r.output.split()), r.output
        meta = json.loads((tmp_path / name.replace(".npz", "") / "metrics.json").read_text())["metadata"]
        assert needle in meta["frame_hint"]
    r = run([a, save_seq(tmp_path / "same.npz", pts + 0.001, f)])
    assert r.exit_code == 0 and "warning" not in r.output


def test_sides_of_no_garment_size_that_no_fix_explains_are_pointed_out(tmp_path, seq):
    """Both sides in millimetres (E_verts then in micrometres' worth of the unit), or one side at 1e30 (an absurd
    unit no fix matches): the metrics are printed, with one warning naming the sizes; the same sides in metres
    get none."""
    pts, f = seq
    pts = pts - pts[0].mean(axis=0) * [1, 1, 0] + [0.0, 0.0, 1.0]
    assert 0.1 <= np.ptp(pts[0], axis=0).max() <= 3.0
    for name, pred, gt, needle in (
            ("mm", pts * 1000, pts * 1000 + 1.0, "warning: PRED and GT are "),
            ("huge", pts, pts * 1e30, "warning: GT is 5e+29 m across, 1e+30 times PRED (expected a garment 0.1-3 m "
                                      "across in metres): scale it to metres")):
        p, g = save_seq(tmp_path / f"{name}_p.npz", pred, f), save_seq(tmp_path / f"{name}_g.npz", gt, f)
        r = run([p, g, "--out", tmp_path / name])
        assert r.exit_code == 0 and "E_verts" in r.output, r.output
        warnings = [line for line in r.output.splitlines() if line.startswith("warning")]
        assert len(warnings) == 1 and warnings[0].startswith(needle), r.output
        meta = json.loads((tmp_path / name / "metrics.json").read_text())["metadata"]
        assert meta["frame_hint"] == warnings[0].removeprefix("warning: ")
    assert "in another unit, both?" in run([tmp_path / "mm_p.npz", tmp_path / "mm_g.npz"]).output
    r = run([save_seq(tmp_path / "m_p.npz", pts, f), save_seq(tmp_path / "m_g.npz", pts + 0.001, f)])
    assert r.exit_code == 0 and "warning" not in r.output, r.output


def test_reports_onto_a_full_disk_are_one_line_naming_the_file(tmp_path, seq, monkeypatch):
    """ENOSPC while the last report is written (it was a traceback, the first two left in place): one line naming
    it and the space left; the reports are written together, so none is left, and over earlier ones (--overwrite)
    those stay as they were."""
    import pathlib

    pts, f = seq
    a = save_seq(tmp_path / "a.npz", pts, f)
    write_text = pathlib.Path.write_text

    def disk_full_at_md(self, *args, **kwargs):
        if self.suffix == ".md":
            raise OSError(28, "No space left on device")
        return write_text(self, *args, **kwargs)

    monkeypatch.setattr(pathlib.Path, "write_text", disk_full_at_md)
    r = run([a, a, "--out", tmp_path / "m"])
    assert r.exit_code == 1 and "Traceback" not in r.output, r.output
    line = r.output.strip().splitlines()[-1]
    assert line.startswith(f"Error: output '{tmp_path / 'm' / 'metrics.md'}': could not be written (No space left "
                           "on device; ") and line.endswith(" free on its file system)")
    assert not (tmp_path / "m").exists()  # nothing, not even the --out folder it made
    monkeypatch.setattr(pathlib.Path, "write_text", write_text)
    assert run([a, a, "--out", tmp_path / "m"]).exit_code == 0
    before = {p.name: p.read_bytes() for p in (tmp_path / "m").iterdir()}
    monkeypatch.setattr(pathlib.Path, "write_text", disk_full_at_md)
    b = save_seq(tmp_path / "b.npz", pts + 0.01, f)
    assert run([a, b, "--out", tmp_path / "m", "--overwrite"]).exit_code == 1
    assert {p.name: p.read_bytes() for p in (tmp_path / "m").iterdir()} == before


def test_an_out_of_room_error_outside_the_atomic_writers_names_the_output(tmp_path):
    """A command's OSError of a full disk or quota that no atomic writer caught: one line naming the command's
    --out (or the file the error names); any other OSError is left as it is."""
    import click

    from garmentcli.common import input_errors_as_click

    @input_errors_as_click
    def command(out_dir=None, errno_=28, filename=None):
        raise OSError(errno_, os.strerror(errno_), filename)

    with pytest.raises(click.ClickException) as err:
        command(out_dir=str(tmp_path / "o"), errno_=122)  # EDQUOT: the user's quota
    assert err.value.message.startswith(f"output '{tmp_path / 'o'}': could not be written (Disk quota exceeded; ")
    with pytest.raises(click.ClickException) as err:
        command(filename=str(tmp_path / "log.csv"))
    assert err.value.message.startswith(f"output '{tmp_path / 'log.csv'}': could not be written (No space left")
    with pytest.raises(click.ClickException, match=r"^the outputs: could not be written \(No space left on device\)$"):
        command()
    with pytest.raises(PermissionError):
        command(out_dir="x", errno_=13)


def _bake_dir(root, name, points, faces):
    """A `garment bake` output directory root/name/ holding its stage (the garment only) and a summary."""
    from formats.usd import MeshTrack, write_usd_stage

    d = root / name
    write_usd_stage(d / f"{name}.usd", [MeshTrack("garment", points, faces)], fps=30)
    (d / "summary.json").write_text("{}")
    return d


def test_two_bake_output_directories_are_compared_bake_by_bake(tmp_path, seq):
    """`garment metrics pred/ gt/` with the --out directories of two bakes: each bake of the same name compared,
    a bake in one only warned about and left out, one table with a row per bake and the mean over every frame
    (each bake weighted by its frames); with --out each bake's reports in its own folder and the table beside."""
    pts, f = seq
    run_pts = np.concatenate([pts, pts])  # 6 frames
    for root, walk_mm, run_mm in ((tmp_path / "pred", 1.0, 3.0), (tmp_path / "gt", 0.0, 0.0)):
        _bake_dir(root, "shirt_walk", pts + [0, 0, walk_mm * 1e-3], f)
        _bake_dir(root, "shirt_run", run_pts + [0, 0, run_mm * 1e-3], f)
    _bake_dir(tmp_path / "gt", "shirt_jump", pts, f)
    r = run([tmp_path / "pred", tmp_path / "gt", "--out", tmp_path / "m", "--format", "json"])
    assert r.exit_code == 0, r.output
    assert "warning: 'shirt_jump' is in GT only: left out" in r.output
    doc = json.loads((tmp_path / "m" / "metrics_batch.json").read_text())
    bakes = doc["bakes"]
    assert list(bakes) == ["shirt_run", "shirt_walk", "all (mean over every frame)"]
    assert bakes["shirt_walk"]["e_verts"] == pytest.approx(1.0, abs=1e-3) and bakes["shirt_walk"]["frames"] == 3
    assert bakes["shirt_run"]["e_verts"] == pytest.approx(3.0, abs=1e-3) and bakes["shirt_run"]["frames"] == 6
    assert bakes["all (mean over every frame)"]["e_verts"] == pytest.approx((3 * 1.0 + 6 * 3.0) / 9, abs=1e-3)
    assert json.loads((tmp_path / "m" / "shirt_walk" / "metrics.json").read_text())["n_frames"] == 3
    assert "| shirt_run " in r.output
    # Again into the same --out: refused, naming the first file it would overwrite.
    r = run([tmp_path / "pred", tmp_path / "gt", "--out", tmp_path / "m", "--format", "json"])
    assert r.exit_code != 0 and "metrics_batch.json' exists; pass --overwrite" in error_line(r)


def test_bakes_against_another_tools_folders_of_obj_frames_named_as_them(tmp_path, seq):
    """GT exported by another tool, each motion into a folder of OBJ frames of the bake's name (Blender's
    shirt_000001.obj, Y-up): it was "one sequence", refused; compared bake by bake."""
    from core.geometry import Y_UP_TO_Z_UP_MATRIX
    from formats.obj import write_obj

    pts, f = seq
    for name, shift in (("shirt_walk", 1.0), ("shirt_run", 2.0)):
        _bake_dir(tmp_path / "pred", name, pts + [0, 0, shift * 1e-3], f)
        (tmp_path / "gt" / name).mkdir(parents=True)
        for t, frame in enumerate(pts @ Y_UP_TO_Z_UP_MATRIX):
            write_obj(tmp_path / "gt" / name / f"shirt_{t + 1:06d}.obj", frame, f)
    r = run([tmp_path / "pred", tmp_path / "gt", "--out", tmp_path / "m", "--format", "json"])
    assert r.exit_code == 0, r.output
    bakes = json.loads((tmp_path / "m" / "metrics_batch.json").read_text())["bakes"]
    assert bakes["shirt_walk"]["e_verts"] == pytest.approx(1.0, abs=1e-3)
    assert bakes["shirt_run"]["e_verts"] == pytest.approx(2.0, abs=1e-3)


def test_bake_directories_bad_pairs(tmp_path, seq):
    pts, f = seq
    _bake_dir(tmp_path / "pred", "shirt_walk", pts, f)
    _bake_dir(tmp_path / "gt", "shirt_run", pts, f)
    assert "hold no bake of the same name: PRED has shirt_walk, GT has shirt_run" in error_line(
        run([tmp_path / "pred", tmp_path / "gt"]))
    one = save_seq(tmp_path / "one.npz", pts, f)
    assert "holds bakes (shirt_walk) but" in error_line(run([tmp_path / "pred", one]))
    # One bake's own directory against a sequence: read as its stage.
    r = run([tmp_path / "pred" / "shirt_walk", one])
    assert r.exit_code == 0, r.output
    motion = tmp_path / "m.npz"
    np.savez(motion, poses=np.zeros((3, 72)), trans=np.zeros((3, 3)), mocap_framerate=30.0)
    _bake_dir(tmp_path / "gt", "shirt_walk", pts, f)
    assert "--motion" in error_line(run([tmp_path / "pred", tmp_path / "gt", "--motion", motion]))


@pytest.mark.parametrize("old", ["metrics_per_frame.png", "metrics_heatmap.png", "metrics_report.html"])
def test_plots_refuse_to_overwrite_any_file_they_would_write(tmp_path, seq, old):
    """--plots --format json writes metrics.json and the plot report: every one is checked, not only metrics.json."""
    pts, f = seq
    a, b = save_seq(tmp_path / "a.npz", pts, f), save_seq(tmp_path / "b.npz", pts, f)
    out = tmp_path / "out"
    out.mkdir()
    (out / old).write_bytes(b"older report")
    r = run([a, b, "--out", out, "--format", "json", "--plots"])
    assert_clean_failure(r, "--out", old, "--overwrite")
    assert sorted(p.name for p in out.iterdir()) == [old]  # nothing written
    assert (out / old).read_bytes() == b"older report"


def test_plots_that_fail_part_way_leave_no_report_nor_half_a_picture(tmp_path, seq, monkeypatch):
    """A full disk while the pictures were written left metrics.json, .csv, .md and half a heatmap in --out (each
    report said 'wrote'): the pictures are made first, beside, and nothing is left when one fails; then the whole
    set, pictures linked in the report."""
    import errno

    import formats.plots as P

    pts, f = seq
    a, b = save_seq(tmp_path / "a.npz", pts, f), save_seq(tmp_path / "b.npz", pts, f)
    out = tmp_path / "out"

    def full(result, path, *args, **kwargs):
        Path(path).write_bytes(b"\x89PNG half")
        raise OSError(errno.ENOSPC, "No space left on device", str(path))

    with monkeypatch.context() as m:
        m.setattr(P, "plot_error_histograms", full)
        r = run([a, b, "--out", out, "--plots"])
    assert r.exit_code != 0 and "No space left on device" in r.output and "wrote" not in r.output, r.output
    assert not out.exists() or not list(out.iterdir())
    r = run([a, b, "--out", out, "--plots"])
    assert r.exit_code == 0, r.output
    names = {p.name for p in out.iterdir()}
    assert {"metrics.json", "metrics.csv", "metrics.md", "metrics_per_frame.png", "metrics_report.html"} <= names
    assert not any(n.startswith(".") for n in names)
    assert "metrics_per_frame.png" in (out / "metrics_report.html").read_text()


def test_gt_penetration_is_taken_against_gts_own_body(tmp_path):
    """Two bakes of different motions: GT's garment sits inside PRED's body but outside its own."""
    v, f = icosphere(2, 0.2)
    body, body_f = icosphere(1, 0.15)
    T = 2
    pred_body = np.repeat(body[None], T, 0).astype(np.float32)
    gt_body = pred_body + np.float32([1.0, 0.0, 0.0])
    a = save_seq(tmp_path / "a.npz", np.stack([v, v]), f, body_points=pred_body, body_faces=body_f)
    b = save_seq(tmp_path / "b.npz", np.stack([v, v]) * 0.5, f, body_points=gt_body, body_faces=body_f)
    res = run([a, b, "--out", tmp_path / "out", "--format", "json"])
    assert res.exit_code == 0, res.output
    doc = json.loads((tmp_path / "out" / "metrics.json").read_text())
    assert doc["overall"]["penetration_pct"] == 0.0 and doc["overall"]["gt_penetration_pct"] == 0.0
    warnings = [line for line in res.output.splitlines() if "different bodies" in line]
    assert warnings == ["warning: PRED and GT carry different bodies (up to 1,000 mm apart at frame 0): each side's "
                        "penetration is taken against its own body"]
    # The same body on both sides: no warning.
    c = save_seq(tmp_path / "c.npz", np.stack([v, v]), f, body_points=pred_body, body_faces=body_f)
    res = run([a, c])
    assert res.exit_code == 0 and "different bodies" not in res.output, res.output


def test_different_frame_rates_are_refused(tmp_path, seq):
    pts, f = seq
    a = tmp_path / "a60.npz"
    np.savez(a, points=pts.astype(np.float32), faces=f.astype(np.int64), fps=60.0)
    b = save_seq(tmp_path / "b.npz", pts, f)  # 30 fps, the same frame count
    line = assert_clean_failure(run([a, b]), "a60.npz", "60 fps", "b.npz", "30 fps")
    assert "expected the same frame rate" in line
    c = tmp_path / "no_fps.npz"
    np.savez(c, points=pts.astype(np.float32), faces=f.astype(np.int64))
    assert run([a, c]).exit_code == 0  # one side does not say: nothing to compare


def test_the_frame_hint_names_the_side_out_of_line_and_skips_a_degenerate_one(tmp_path, seq):
    pts, f = seq
    pts = pts - pts[0].mean(axis=0) * [1, 1, 0] + [0.0, 0.0, 1.0]  # a garment around the body, at waist height
    gt = save_seq(tmp_path / "gt.npz", pts, f)
    turned = pts @ np.array([[1, 0, 0], [0, 0, 1], [0, -1, 0]], dtype=np.float64)  # a Z-up garment turned again
    for name, pred, needle in (("cm.npz", pts * 100, "looks as if it is in centimetres"),
                               ("turned.npz", turned, "looks as if it was turned from Y-up to Z-up but was Z-up")):
        p = save_seq(tmp_path / name, pred + 0.001, f)
        r = run([p, gt])
        assert r.exit_code == 0, r.output
        warnings = [line for line in r.output.splitlines() if line.startswith("warning")]
        assert len(warnings) == 1 and warnings[0].startswith(f"warning: '{p}' {needle}"), r.output
        assert "from GT's" in warnings[0]
    zero = save_seq(tmp_path / "zero.npz", np.zeros_like(pts), f)  # a PRED collapsed to one point
    r = run([zero, gt])
    assert r.exit_code == 0 and "looks as if" not in r.output, r.output


@pytest.mark.parametrize("option, value", [("--fps", "60"), ("--frames", "0:3"), ("--settle", "2"),
                                           ("--betas", "mean"), ("--source-fps", "120"), ("--motion-up", "y"),
                                           ("--fps", "30")])  # the default value, given: refused too
def test_motion_options_without_motion_are_refused(tmp_path, seq, option, value):
    pts, f = seq
    a, b = save_seq(tmp_path / "a.npz", pts, f), save_seq(tmp_path / "b.npz", pts, f)
    line = assert_clean_failure(run([a, b, option, value]), option, "--motion")
    assert "E_verts" not in run([a, b, option, value]).output
    assert line.count("\n") == 0


def test_a_mismatched_pair_in_a_batch_does_not_stop_the_others(tmp_path, seq):
    pts, f = seq
    for root in (tmp_path / "pred", tmp_path / "gt"):
        _bake_dir(root, "shirt_walk", pts, f)
        _bake_dir(root, "shirt_run", pts if root.name == "gt" else np.concatenate([pts, pts]), f)  # 6 vs 3 frames
    r = run([tmp_path / "pred", tmp_path / "gt", "--out", tmp_path / "m", "--format", "json"])
    assert r.exit_code != 0
    assert "1 of 2 bakes could not be compared: shirt_run" in error_line(r)
    failed = [line for line in r.output.splitlines() if line.startswith("failed:")]
    assert len(failed) == 1 and failed[0].startswith("failed: 'shirt_run': ") and "6 frames" in failed[0]
    assert "| shirt_walk " in r.output
    doc = json.loads((tmp_path / "m" / "metrics_batch.json").read_text())
    assert list(doc["bakes"]) == ["shirt_walk", "all (mean over every frame)"]
    assert doc["metadata"]["not compared"] == "shirt_run"
    assert not (tmp_path / "m" / "shirt_run").exists()
    r = run([tmp_path / "pred", tmp_path / "gt", "--out", tmp_path / "c", "--format", "csv"])
    rows = (tmp_path / "c" / "metrics_batch.csv").read_text().splitlines()
    assert rows[-1].startswith("shirt_run,not compared,") and rows[-2].startswith("all (mean over every frame),")


@pytest.mark.parametrize("value", ["nan", "inf", "1e300"])
def test_a_non_finite_depth_is_refused_when_read(tmp_path, seq, value):
    """--depth-mm nan / inf (FloatRange let them through; writing metrics.json raised ValueError), or beyond a
    metre (1e300 counted nothing as inside, without a word)."""
    pts, f = seq
    a = save_seq(tmp_path / "a.npz", pts, f)
    r = run([a, a, "--depth-mm", value, "--out", tmp_path / "m"])
    line = assert_clean_failure(r, "--depth-mm")
    assert ("finite" in line or "1000" in line) and not (tmp_path / "m").exists()


def test_a_depth_with_no_body_to_measure_it_against_is_said(tmp_path, seq):
    """--depth-mm where neither side carries a body (nor --motion poses one) measured nothing without a word."""
    pts, f = seq
    a = save_seq(tmp_path / "a.npz", pts, f)
    r = run([a, a, "--depth-mm", "5"])
    assert r.exit_code == 0 and "warning: --depth-mm 5: neither" in r.output and "no penetration to measure" in r.output
    assert "--depth-mm" not in run([a, a]).output


def test_up_where_no_input_is_obj_frames_is_said(tmp_path, seq):
    """--up names the frame of OBJ input: given with two npz sequences it did nothing, without a word."""
    pts, f = seq
    a = save_seq(tmp_path / "a.npz", pts, f)
    r = run([a, a, "--up", "y"])
    assert r.exit_code == 0 and f"warning: --up y: neither '{a}' nor '{a}' is OBJ frames" in r.output, r.output
    assert "--up" not in run([a, a]).output


def test_one_frame_is_one_frame_in_messages(tmp_path, seq):
    pts, f = seq
    one = save_seq(tmp_path / "one.npz", pts[:1], f)
    line = assert_clean_failure(run([one, save_seq(tmp_path / "three.npz", pts, f)]), "one.npz", "three.npz")
    assert "has 1 frame," in line and "1 frames" not in line


def test_obj_frames_without_a_record_are_read_y_up_unless_up_says_z(tmp_path, seq):
    """OBJ frames without a sequence.json (another tool's) are read Y-up, as OBJ files are written; --up z reads
    those written Z-up (this tool's world) as they are: against the same points in an .npz, E_verts 0 then."""
    from formats.obj import write_obj

    pts, f = seq
    gt = save_seq(tmp_path / "gt.npz", pts, f)
    frames = tmp_path / "frames"
    frames.mkdir()
    for t, p in enumerate(pts):
        write_obj(frames / f"frame_{t:04d}.obj", p, f)
    r = run([frames, gt, "--out", tmp_path / "z", "--format", "json", "--up", "z"])
    assert r.exit_code == 0, r.output
    assert json.loads((tmp_path / "z" / "metrics.json").read_text())["overall"]["e_verts"] == pytest.approx(0.0,
                                                                                                           abs=1e-3)
    r = run([frames, gt, "--out", tmp_path / "y", "--format", "json"])
    assert r.exit_code == 0, r.output
    assert json.loads((tmp_path / "y" / "metrics.json").read_text())["overall"]["e_verts"] > 10.0


def test_z_up_obj_frames_read_y_up_are_told_to_pass_up_z(tmp_path):
    from formats.obj import write_obj

    v, f = grid(6, 6, size=0.5)
    v = v - v.mean(axis=0)  # about the body's axis, as a garment is
    pts = np.stack([v + [0.0, 0.0, 1.0 + 0.01 * t] for t in range(3)])  # a metre up, Z-up
    gt = save_seq(tmp_path / "gt.npz", pts, f)
    frames = tmp_path / "frames"
    frames.mkdir()
    for t, p in enumerate(pts):
        write_obj(frames / f"frame_{t:04d}.obj", p, f)
    r = run([frames, gt])
    assert r.exit_code == 0, r.output
    assert "OBJ frames without a sequence.json are read Y-up: --up z reads them as they are" in r.output


def test_frames_of_other_moments_are_pointed_out(tmp_path, seq):
    """Two bakes of other source frames (their summary.json), and frames numbered from other numbers, are compared
    frame by frame with a warning each (recorded in metrics.json)."""
    from formats.obj import write_obj

    pts, f = seq
    pred, gt = _bake_dir(tmp_path / "p", "shirt_walk", pts, f), _bake_dir(tmp_path / "g", "shirt_walk", pts, f)
    for d, frames in ((pred, "4:14"), (gt, None)):
        (d / "summary.json").write_text(json.dumps({"inputs": {"motion": "/x/walk.npz"},
                                                    "options": {"frames": frames, "fps": 30.0}}))
    r = run([pred, gt, "--out", tmp_path / "m", "--format", "json"])
    assert r.exit_code == 0, r.output
    told = (f"warning: '{pred}' was baked from frames 4:14 of 'walk.npz' at 30 fps, '{gt}' from frames all of "
            "'walk.npz' at 30 fps: compared frame by frame as they are")
    assert told in r.output
    meta = json.loads((tmp_path / "m" / "metrics.json").read_text())["metadata"]
    assert "baked from frames 4:14" in meta["alignment_hint"]
    frames = tmp_path / "frames"
    frames.mkdir()
    for t, p in enumerate(pts):
        write_obj(frames / f"frame_{1001 + t:04d}.obj", p, f)
    r = run([frames, save_seq(tmp_path / "gt.npz", pts, f), "--up", "z"])
    assert r.exit_code == 0, r.output
    assert "numbers its frames from 1001" in r.output and "PRED's frame 1001 against GT's 0" in r.output
    r = run([pred, pred])
    assert r.exit_code == 0 and "warning" not in r.output
    for d, frames in ((pred, "0:"), (gt, None)):  # every frame either way
        (d / "summary.json").write_text(json.dumps({"inputs": {"motion": "/x/walk.npz"},
                                                    "options": {"frames": frames, "fps": 30.0}}))
    r = run([pred, gt])
    assert r.exit_code == 0 and "warning" not in r.output, r.output
