"""`garment tradeoff` on a tiny scene: every configuration measured against the finest simulation."""

import csv
import importlib.util
import json
import sys
import types
from pathlib import Path

import numpy as np
import pytest
import torch

from core.tradeoff import configurations, make_deformer, pareto_front, scene_summary
from tests.core.model_fixtures import TINY_CONFIG, perturbed_model
from tests.garmentcli.cli import invoke


def test_configurations_cover_methods_precisions_push_out_and_sim_settings():
    rows = configurations({"m": "m.pt"})
    assert [r.name for r in rows][:6] == ["lbs", "lbs +strain-limit 1.5", "m float32", "m float32 +push-out",
                                          "m bfloat16", "m bfloat16 +push-out"]
    assert rows[1].options == {"strain_limit": 1.5} and not rows[0].options
    assert make_deformer(rows[1]).options.strain_limit == 1.5 and make_deformer(rows[0]).options.strain_limit is None
    sims = [r for r in rows if r.method == "sim"]
    assert {(r.options["substeps"], r.options["self_contact"]) for r in sims} == {(10, False), (10, True), (20, False),
                                                                                 (20, True)}
    assert [r.name for r in rows if r.reference] == ["sim 20 substeps +self-contact"]
    assert not any(r.spread for r in rows)
    # --spread: the reference once more, from jittered starting positions; not itself the reference
    spread = configurations({"m": "m.pt"}, spread=True)
    assert spread[:-1] == rows and spread[-1].spread and not spread[-1].reference
    assert spread[-1].options == {"substeps": 20, "self_contact": True, "jitter_m": 1e-6}
    assert not any(r.spread for r in configurations({"m": "m.pt"}, with_sim=False, spread=True))


def test_the_simulator_rows_warm_up_on_two_frames_before_they_are_timed(monkeypatch):
    import core.tradeoff
    from core.motion import Motion
    from core.tradeoff import Config, measure

    runs = []

    class Recording:
        report: dict = {}

        def prepare(self, garment, body):
            pass

        def deform(self, garment, body, motion):
            runs.append(motion.n_frames)
            return np.zeros((motion.n_frames, 3, 3), dtype=np.float32)

    warm = []  # make_deformer's warm_up of each deformer made
    monkeypatch.setattr(core.tradeoff, "make_deformer", lambda *a, warm_up=False, **k: warm.append(warm_up) or Recording())
    motion = Motion(np.zeros((7, 24, 3), np.float32), np.zeros((7, 3), np.float32), 30.0)
    sim = Config("sim", "sim", {"substeps": 10, "self_contact": False, "jitter_m": 1e-6})
    m = measure(sim, None, None, motion, repeats=3)
    assert runs == [2, 7] and m.runs == 1 and m.points.shape == (7, 3, 3)
    assert warm == [False, True]  # the warm-up's own simulator: without settling and blending in (25 frames)
    monkeypatch.undo()
    warmed = core.tradeoff.make_deformer(sim, warm_up=True)
    assert (warmed.options.settle_s, warmed.options.blend_frames, warmed.options.substeps) == (0.0, 0, 10)
    assert warmed.jitter_m == 1e-6 and core.tradeoff.make_deformer(sim).options.settle_s > 0
    monkeypatch.setattr(core.tradeoff, "make_deformer", lambda *a, **k: Recording())
    runs.clear()
    measure(Config("lbs", "lbs"), None, None, motion, repeats=3)
    assert runs == [7, 7, 7, 7]
    assert not m.self_contact_skipped  # (no self-contact asked)
    # a self-contact row the scene analysis ran without it (its report: no self-contact) is said to be one
    contact = Config("sim +self-contact", "sim", {"substeps": 10, "self_contact": True})
    Recording.report = {"self_contact": None}
    assert measure(contact, None, None, motion).self_contact_skipped
    Recording.report = {"self_contact": {"detection_gap_m": 0.005}}
    assert not measure(contact, None, None, motion).self_contact_skipped


def test_pareto_front_naive():
    pts = [(1.0, 5.0), (2.0, 3.0), (3.0, 4.0), (4.0, 0.0), (2.0, 3.0)]
    # (3, 4) is beaten by (2, 3); the two equal (2, 3) do not beat each other.
    assert pareto_front(pts) == [True, True, False, True, True]
    # 3x the time for 0.00004 mm less is no gain (errors within PARETO_TOLERANCE_MM are one); 0.02 mm less is
    assert pareto_front([(1.0, 30.5619), (3.0, 30.5618)]) == [True, False]
    assert pareto_front([(1.0, 30.5619), (3.0, 30.5419)]) == [True, True]


def _row(config, method, s, mm, reference=False, failed=""):
    return {"config": config, "method": method, "seconds_per_frame": s, "e_verts": mm, "reference": reference,
            "failed": failed}


def test_scene_summary_shares_and_time_order():
    result = {"garment": "g.obj", "vertices": 10, "frames": 3, "rows": [
        _row("lbs", "lbs", 1e-4, 40.0), _row("m float32", "model", 0.02, 10.0), _row("m bfloat16", "model", 0.03, 11.0),
        _row("sim 10 substeps", "sim", 1.0, 8.0), _row("sim 20 substeps", "sim", 2.0, 5.0),
        _row("sim 20 substeps +self-contact", "sim", 4.0, 0.0, reference=True)]}
    s = scene_summary(result, "m")
    assert (s["lbs_mm"], s["model_mm"], s["model_share_of_lbs"]) == (40.0, 10.0, 0.25)
    assert (s["closest_sim"], s["closest_sim_mm"], s["sim_s"]) == ("sim 20 substeps", 5.0, 1.0)
    assert s["reference"] == "sim 20 substeps +self-contact" and s["time_ordered"]
    # a model row slower than the fastest simulator breaks the order; a failed row does not count
    result["rows"].append(_row("slow float32", "model", 1.5, 9.0))
    assert not scene_summary(result, "m")["time_ordered"]
    result["rows"][-1]["failed"] = "out of range"
    assert scene_summary(result, "m")["time_ordered"]
    with pytest.raises(KeyError, match="no row 'x float32'"):
        scene_summary(result, "x")
    assert np.isnan(s["spread_mm"]) and np.isnan(s["gap_closed"])
    # The reference's spread: the floor under the errors; LBS is 40 - 4 = 36 mm above it, the model removes 30 of
    # them. The spread row (as slow as the reference) is neither the closest simulator row nor the fastest.
    result["rows"].append({**_row("reference +1 um jitter", "sim", 0.5, 4.0), "spread": True})
    s = scene_summary(result, "m")
    assert s["spread_mm"] == 4.0 and s["gap_closed"] == pytest.approx(30.0 / 36.0)
    assert (s["closest_sim"], s["sim_s"]) == ("sim 20 substeps", 1.0)


@pytest.fixture
def model_file(tmp_path):
    from formats.checkpoint import save_checkpoint

    return save_checkpoint(tmp_path / "tiny.pt", TINY_CONFIG, perturbed_model(TINY_CONFIG, 0.05).state_dict())


def test_tradeoff_writes_table_plot_and_json(scene, model_file):
    r = invoke(["tradeoff", scene["garment"], scene["motion"], "--body", scene["body"], "--model", f"tiny={model_file}",
                "--repeats", 1, "--frames", "0:4", "--out", scene["out"], "--spread", "--device", "cpu"])
    assert r.exit_code == 0, r.output
    d = scene["out"] / "shell_walk"
    rows = list(csv.DictReader(open(d / "tradeoff.csv")))
    assert [row["config"] for row in rows] == [c.name for c in configurations({"tiny": str(model_file)}, spread=True)]
    by = {row["config"]: row for row in rows}
    ref = by["sim 20 substeps +self-contact"]
    assert float(ref["e_verts"]) == 0.0 and ref["reference"] == "True"
    # The reference has no error; it, or the faster of the configurations that equal it, is on the front (the scene
    # analysis may switch self-contact off on this small scene: the two 20-substep rows are then one simulation
    # and either may time faster).
    exact = [row for row in rows if float(row["e_verts"]) == 0.0 and row["spread"] == "False"]
    assert min(exact, key=lambda row: float(row["seconds_per_frame"]))["pareto"] == "True"
    assert float(by["lbs"]["e_verts"]) > 0 and float(by["sim 10 substeps"]["e_verts"]) > 0
    # The jittered rerun of the reference lands near it but not on it.
    assert 0 < float(by["reference +1 um jitter"]["e_verts"]) < float(by["lbs"]["e_verts"])
    for row in rows:
        assert float(row["seconds_per_frame"]) > 0 and np.isfinite(float(row["e_verts"]))
        assert float(row["peak_memory_mb"]) >= 0 and row["gpu_peak_memory_mb"] == ""  # nothing ran on a GPU
    # The fastest row is on the Pareto front; the push-out leaves no vertex > 2 mm inside the body.
    fastest = min(rows, key=lambda row: float(row["seconds_per_frame"]))
    assert fastest["pareto"] == "True"
    assert float(by["tiny float32 +push-out"]["penetration_pct"]) == 0.0
    meta = json.loads((d / "tradeoff.json").read_text())
    assert meta["frames"] > 0 and len(meta["rows"]) == len(rows) and meta["model_device"] == "cpu"
    assert (d / "tradeoff.png").stat().st_size > 1000 and "| lbs " in (d / "tradeoff.md").read_text()
    assert "GPU peak" not in (d / "tradeoff.md").read_text()
    assert "shell_walk" in r.output
    # Existing output: refused without --overwrite.
    r = invoke(["tradeoff", scene["garment"], scene["motion"], "--body", scene["body"], "--model",
                f"tiny={model_file}", "--out", scene["out"]])
    assert r.exit_code != 0 and "--overwrite" in r.output


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device")
def test_tradeoff_model_rows_on_a_gpu_report_its_memory(scene, model_file, monkeypatch):
    """`--device cuda`: the model rows' GPU memory is a column of its own; the other rows have none. The
    simulator's rows are stood in for (Newton is not on every GPU machine; they run on the CPU anyway)."""
    import garmentcli.tradeoff

    real, fake = garmentcli.tradeoff.measure, _fake_measure(lambda c: False)
    monkeypatch.setattr(garmentcli.tradeoff, "measure",
                        lambda config, *a, **k: (fake if config.method == "sim" else real)(config, *a, **k))
    if importlib.util.find_spec("newton") is None:
        monkeypatch.setitem(sys.modules, "newton", types.ModuleType("newton"))  # passes tradeoff's import check
    r = invoke(["tradeoff", scene["garment"], scene["motion"], "--body", scene["body"], "--model", f"tiny={model_file}",
                "--repeats", 1, "--frames", "0:4", "--out", scene["out"], "--device", "cuda"])
    assert r.exit_code == 0, r.output
    d = scene["out"] / "shell_walk"
    for row in csv.DictReader(open(d / "tradeoff.csv")):
        assert (float(row["gpu_peak_memory_mb"]) > 0) if row["method"] == "model" else row["gpu_peak_memory_mb"] == ""
    assert json.loads((d / "tradeoff.json").read_text())["model_device"].startswith("cuda")
    assert "GPU peak MB" in (d / "tradeoff.md").read_text()


@pytest.mark.parametrize("extra, needle", [(["--model", "nopath"], "NAME=PATH"),
                                           (["--model", "x=missing.pt"], "missing.pt"),
                                           (["--repeats", "0"], "--repeats"),
                                           (["--device", "tpu"], "expected auto, cpu, cuda or cuda:N, got 'tpu'"),
                                           (["--fit", "f=GARMENT"], "psd fit"),  # no fit: a failed row, exit 0
                                           ])
def test_tradeoff_bad_options(scene, extra, needle):
    extra = [a.replace("GARMENT", str(scene["garment"])) for a in extra]
    r = invoke(["tradeoff", scene["garment"], scene["motion"], "--out", scene["out"], *extra])
    assert r.exit_code != 0 and needle in r.output and "Traceback" not in r.output
    assert not scene["out"].exists()


def test_a_model_that_cannot_be_loaded_is_refused_before_any_row(scene, model_file, monkeypatch):
    """A checkpoint read fine by its header but whose weights are not its config's failed row by row, and the
    simulator rows ran on (hours): the network is loaded before the first row."""
    import torch

    import garmentcli.tradeoff

    ck = torch.load(model_file, weights_only=True)
    name = next(iter(ck["model"]))
    del ck["model"][name]
    broken = scene["dir"] / "broken.pt"
    torch.save(ck, broken)
    measured = []
    monkeypatch.setattr(garmentcli.tradeoff, "measure", _counting_measure(measured))
    r = invoke(["tradeoff", scene["garment"], scene["motion"], "--body", scene["body"], "--model", f"b={broken}",
                "--frames", "0:4", "--out", scene["out"]])
    assert r.exit_code == 1 and f"model '{broken}': weights do not match its config (missing ['{name}'])" in \
        r.output.strip().splitlines()[-1], r.output
    assert measured == [] and not scene["out"].exists()


def test_tradeoff_missing_garment(scene):
    r = invoke(["tradeoff", scene["dir"] / "gone.obj", scene["motion"], "--out", scene["out"]])
    assert r.exit_code != 0 and "gone.obj" in r.output and not scene["out"].exists()


def _fake_measure(fail, error=None):
    """A stand-in for core.tradeoff.measure: LBS points for every row (shifted 1 cm but for the reference);
    rows for which `fail(config)` holds raise `error` (default: the simulator's error)."""
    from core.deform import LBSDeformer
    from core.sim import SimulationError
    from core.tradeoff import Measurement

    def measure(config, garment, body, motion, repeats=3, cache_dir=None, device=None):
        if fail(config):
            raise error or SimulationError(f"sim: frame 3 of motion '{motion.name}' failed after 3 tries")
        pts = LBSDeformer().deform(garment, body, motion)[motion.n_lead:motion.n_lead + motion.n_written]
        pts = pts + (0.0 if config.reference else 0.01)
        retries = [{"frame": 1, "tries": 2, "kept_substeps": 20}] if config.name == "sim 10 substeps" else []
        return Measurement(config, pts, 1.0 if config.method == "sim" else 0.01, 0.0, 0.0, 1, retries=retries,
                           self_contact_skipped=config.name == "sim 10 substeps +self-contact")

    return measure


def _counting_measure(measured: list):
    """`_fake_measure` (nothing fails) that appends each measured configuration's name to `measured`."""
    fake = _fake_measure(lambda c: False)

    def measure(config, *args, **kwargs):
        measured.append(config.name)
        return fake(config, *args, **kwargs)

    return measure


def test_a_failing_configuration_is_a_row_that_says_so(scene, monkeypatch):
    import garmentcli.tradeoff

    monkeypatch.setattr(garmentcli.tradeoff, "measure", _fake_measure(lambda c: c.name == "sim 10 substeps"))
    r = invoke(["tradeoff", scene["garment"], scene["motion"], "--body", scene["body"], "--frames", "0:4",
                "--out", scene["out"]])
    assert r.exit_code == 0, r.output
    assert "sim 10 substeps: failed (sim: frame 3" in r.output
    d = scene["out"] / "shell_walk"
    rows = {row["config"]: row for row in csv.DictReader(open(d / "tradeoff.csv"))}
    assert rows["sim 10 substeps"]["failed"].startswith("sim: frame 3") and rows["sim 10 substeps"]["e_verts"] == ""
    assert rows["lbs"]["failed"] == "" and np.isclose(float(rows["lbs"]["e_verts"]), 10 * np.sqrt(3), atol=0.01)
    assert "`sim 10 substeps` failed: sim: frame 3" in (d / "tradeoff.md").read_text()
    # The reference failing leaves nothing to compare with: one clear line, nothing written.
    monkeypatch.setattr(garmentcli.tradeoff, "measure", _fake_measure(lambda c: c.reference))
    r = invoke(["tradeoff", scene["garment"], scene["motion"], "--body", scene["body"], "--frames", "0:4",
                "--out", scene["out"] / "second"])
    assert r.exit_code != 0 and "reference configuration 'sim 20 substeps +self-contact' failed" in r.output
    assert "Traceback" not in r.output and not (scene["out"] / "second" / "shell_walk").exists()
    assert "finished simulator rows are kept in" in r.output  # hidden, for --reuse-sim


def test_a_row_failing_otherwise_is_a_failed_row_too(scene, monkeypatch):
    """Out of memory or a device error in one row (LBS here) does not throw away the simulations of the others."""
    import garmentcli.tradeoff

    monkeypatch.setattr(garmentcli.tradeoff, "measure",
                        _fake_measure(lambda c: c.method == "lbs", RuntimeError("CUDA error: out of memory")))
    r = invoke(["tradeoff", scene["garment"], scene["motion"], "--body", scene["body"], "--frames", "0:4",
                "--out", scene["out"]])
    assert r.exit_code == 0, r.output
    assert "lbs: failed (RuntimeError: CUDA error: out of memory)" in r.output and "; lbs failed" in r.output
    rows = {row["config"]: row for row in csv.DictReader(open(scene["out"] / "shell_walk" / "tradeoff.csv"))}
    assert rows["lbs"]["failed"] == "RuntimeError: CUDA error: out of memory" and rows["lbs"]["e_verts"] == ""
    assert float(rows["sim 10 substeps"]["e_verts"]) > 0
    # the cross-garment summary names the failed row instead of a KeyError on its missing error
    result = json.loads((scene["out"] / "shell_walk" / "tradeoff.json").read_text())
    with pytest.raises(KeyError, match="row 'lbs' failed"):
        scene_summary(result, "model")


def test_a_run_beyond_memory_stops_before_its_first_row(scene, monkeypatch):
    import garmentcli.tradeoff
    import psutil

    measured = []
    monkeypatch.setattr(garmentcli.tradeoff, "measure", _counting_measure(measured))
    # a frame needs a third of the memory free: 3 of the scene's frames fit, 6 of its 60 fps source
    monkeypatch.setattr(garmentcli.tradeoff, "memory_needed",
                        lambda rows, g, b, n: n * psutil.virtual_memory().available / 3)
    r = invoke(["tradeoff", scene["garment"], scene["motion"], "--body", scene["body"], "--out", scene["out"]])
    assert r.exit_code != 0 and "Traceback" not in r.output and not measured
    assert "GB is free: measure a part of at most 6 source frames with --frames START:STOP" in r.output, r.output
    assert not scene["out"].exists()


def test_reuse_sim_takes_the_simulator_rows_of_the_same_scene_only(scene, monkeypatch):
    import garmentcli.tradeoff

    base = ["tradeoff", scene["garment"], scene["motion"], "--body", scene["body"], "--out", scene["out"]]
    r = invoke([*base, "--reuse-sim", "--frames", "0:4"])
    assert r.exit_code != 0 and "no earlier run to reuse" in r.output and not (scene["out"] / "shell_walk").exists()
    monkeypatch.setattr(garmentcli.tradeoff, "measure", _fake_measure(lambda c: False))
    assert invoke([*base, "--frames", "0:4"]).exit_code == 0
    d = scene["out"] / "shell_walk"
    first = {row["config"]: row for row in csv.DictReader(open(d / "tradeoff.csv"))}
    assert len(list((d / "simulations").glob("*.npz"))) == 4
    # a stored simulation is a sequence `metrics` and `render` read (it held no faces), a retried frame is said
    from formats.obj import read_obj
    from formats.sequence import read_sequence

    stored = read_sequence(d / "simulations" / "sim_20_substeps_self-contact.npz")
    np.testing.assert_array_equal(stored.faces, read_obj(scene["garment"]).faces)
    assert stored.n_frames == 2 and stored.fps == 30.0
    retried = "`sim 10 substeps`: frame 1 run again at 20 substeps (try 2)"
    assert retried in (d / "tradeoff.md").read_text()
    assert first["sim 10 substeps"]["retries"] == "frame 1 run again at 20 substeps (try 2)"
    # a self-contact row run without it (the scene analysis) is said so: it was the row without it, unsaid
    skipped = "`sim 10 substeps +self-contact`: self-contact skipped by the scene analysis"
    assert skipped in (d / "tradeoff.md").read_text()
    rows = {r["config"]: r for r in json.loads((d / "tradeoff.json").read_text())["rows"]}
    assert rows["sim 10 substeps +self-contact"]["self_contact_skipped"] and \
        not rows["sim 20 substeps +self-contact"]["self_contact_skipped"]
    meta = json.loads((d / "tradeoff.json").read_text())
    assert meta["options"]["frames"] == "0:4" and meta["options"]["repeats"] == 3 and meta["simulator_version"] >= 1
    assert "torch" in meta["software"]
    measured = []
    monkeypatch.setattr(garmentcli.tradeoff, "measure", _counting_measure(measured))
    r = invoke([*base, "--reuse-sim", "--frames", "0:4"])
    assert r.exit_code == 0, r.output
    assert "4 of 4 simulator rows taken from the earlier run" in r.output
    # without a terminal, one line per measured configuration (a log shows how far a long run is)
    assert "tradeoff: 1/10 lbs: " in r.output and "tradeoff: 7/10 sim" not in r.output
    assert measured and not any(name.startswith("sim") for name in measured)
    again = {row["config"]: row for row in csv.DictReader(open(d / "tradeoff.csv"))}
    assert retried in (d / "tradeoff.md").read_text() and skipped in (d / "tradeoff.md").read_text()  # stored too
    for name in ("sim 10 substeps", "lbs"):
        assert float(again[name]["e_verts"]) == pytest.approx(float(first[name]["e_verts"]), abs=1e-6)
    assert again["sim 10 substeps"]["seconds_per_frame"] == first["sim 10 substeps"]["seconds_per_frame"]
    # Other frames (the 60 fps source is baked at 30 fps: 0:6 is three frames, 0:4 two): every simulator row runs again.
    measured.clear()
    r = invoke([*base, "--reuse-sim", "--frames", "0:6"])
    assert r.exit_code == 0, r.output
    assert "0 of 4 simulator rows" in r.output and sum(name.startswith("sim") for name in measured) == 4


def test_an_interrupted_run_keeps_its_finished_simulator_rows_for_reuse_sim(scene, monkeypatch):
    import garmentcli.tradeoff

    base = ["tradeoff", scene["garment"], scene["motion"], "--body", scene["body"], "--out", scene["out"],
            "--frames", "0:4"]
    monkeypatch.setattr(garmentcli.tradeoff, "measure", _fake_measure(lambda c: c.reference))
    r = invoke(base)
    assert r.exit_code != 0 and not (scene["out"] / "shell_walk").exists()
    staged = scene["out"] / ".shell_walk.simulations"
    assert len(list(staged.glob("*.npz"))) == 3  # every simulator row but the failed reference
    measured = []
    monkeypatch.setattr(garmentcli.tradeoff, "measure", _counting_measure(measured))
    r = invoke([*base, "--reuse-sim"])
    assert r.exit_code == 0, r.output
    assert "3 of 4 simulator rows taken from the earlier run" in r.output
    assert [n for n in measured if n.startswith("sim")] == ["sim 20 substeps +self-contact"]
    assert len(list((scene["out"] / "shell_walk" / "simulations").glob("*.npz"))) == 4 and not staged.exists()
    # a fresh run (no --reuse-sim) says it discards what an interrupted run left
    monkeypatch.setattr(garmentcli.tradeoff, "measure", _fake_measure(lambda c: c.reference))
    assert invoke([*base, "--overwrite"]).exit_code != 0 and staged.is_dir()
    monkeypatch.setattr(garmentcli.tradeoff, "measure", _fake_measure(lambda c: False))
    r = invoke([*base, "--overwrite"])
    assert r.exit_code == 0 and "discarding the simulator rows an interrupted run left" in r.output
    assert not staged.exists()


def test_spread_is_a_row_a_line_and_no_choice(scene, monkeypatch, tmp_path):
    import garmentcli.tradeoff

    monkeypatch.setattr(garmentcli.tradeoff, "measure", _fake_measure(lambda c: False))
    cal = tmp_path / "cal.json"
    r = invoke(["tradeoff", scene["garment"], scene["motion"], "--body", scene["body"], "--frames", "0:4",
                "--out", scene["out"], "--spread", "--calibrate", cal])
    assert r.exit_code == 0, r.output
    d = scene["out"] / "shell_walk"
    rows = {row["config"]: row for row in csv.DictReader(open(d / "tradeoff.csv"))}
    row = rows["reference +1 um jitter"]
    assert row["spread"] == "True" and row["reference"] == "False" and row["pareto"] == "False"
    assert float(row["e_verts"]) == pytest.approx(10 * np.sqrt(3), abs=0.01)  # the fake's 1 cm shift
    assert "the reference's spread 17.3 mm" in r.output
    assert "floor under every row's error" in (d / "tradeoff.md").read_text()
    assert len(list((d / "simulations").glob("*.npz"))) == 5
    # the calibration --quality auto chooses from holds every configuration but the spread
    configs = json.loads(cal.read_text())["configs"]
    assert "sim 20 substeps" in configs and "reference +1 um jitter" not in configs


def test_a_fit_is_a_psd_row_left_out_of_the_calibration(scene, monkeypatch, tmp_path):
    """--fit NAME=PATH adds a `psd NAME` row after LBS, measured like the others; --calibrate leaves it out (a fit
    belongs to one garment); a fit file that is not there is refused."""
    import garmentcli.tradeoff
    from core.deform import LBSDeformer
    from core.motion import Motion
    from core.psd import fit_psd
    from formats.body import load_body
    from formats.obj import read_obj
    from formats.psd import save_fit

    assert [(c.name, c.method) for c in configurations({"m": None}, fits={"g": "g.npz"})[:3]] == [
        ("lbs", "lbs"), ("lbs +strain-limit 1.5", "lbs"), ("psd g", "psd")]
    garment, body = read_obj(scene["garment"]), load_body(scene["body"])
    motion = Motion(poses=np.zeros((3, 24, 3), np.float32), trans=np.zeros((3, 3), np.float32), fps=30.0)
    fit = tmp_path / "shell.psd.npz"
    save_fit(fit, fit_psd(garment, body, [(motion, LBSDeformer().deform(garment, body, motion))], rank=2))
    from core.tradeoff import Config

    psd = make_deformer(Config("psd mine", "psd", {"path": str(fit)}))
    np.testing.assert_allclose(psd.deform(garment, body, motion), LBSDeformer().deform(garment, body, motion),
                               atol=1e-5)
    fake, given = _fake_measure(lambda c: False), {}

    def measure(config, garment, body, motion, *args, **kwargs):  # the motion each row deforms
        given[config.method] = motion
        return fake(config, garment, body, motion, *args, **kwargs)

    monkeypatch.setattr(garmentcli.tradeoff, "measure", measure)
    base = ["tradeoff", scene["garment"], scene["motion"], "--body", scene["body"], "--frames", "0:4"]
    r = invoke([*base, "--fit", f"mine={fit}", "--out", scene["out"], "--calibrate", tmp_path / "cal.json"])
    assert r.exit_code == 0, r.output
    # the psd row's motion has its context frames after --frames (psd's rates, as bake's), the others' none; at
    # --fps 30 from 60 fps, 2 output frames of 4 source frames
    from core.psd import FEATURE_CONTEXT_FRAMES

    assert (given["psd"].n_tail, given["psd"].n_written) == (FEATURE_CONTEXT_FRAMES, given["lbs"].n_written)
    assert given["lbs"].n_tail == given["model"].n_tail == given["sim"].n_tail == 0
    rows = [row["config"] for row in csv.DictReader(open(scene["out"] / "shell_walk" / "tradeoff.csv"))]
    assert rows[:3] == ["lbs", "lbs +strain-limit 1.5", "psd mine"]
    cal = json.loads((tmp_path / "cal.json").read_text())
    assert "psd mine" not in cal["configs"]
    # which model the model rows measured, by content, and what made the file (the shipped calibration says neither)
    from core.model_deform import DEFAULT_MODEL
    from core.provenance import file_sha256

    models = [c["models"] for c in cal["configs"].values() if c["method"] == "model"]
    assert models and all(m == {file_sha256(DEFAULT_MODEL): 1} for m in models)
    assert "models" not in cal["configs"]["lbs"] and cal["provenance"]["software"]["garment"]
    r = invoke([*base, "--fit", f"x={tmp_path / 'gone.npz'}", "--out", tmp_path / "o"])
    assert r.exit_code != 0 and "fit '" in r.output and "gone.npz': no such file" in r.output


def test_preroll_frames_are_deformed_timed_and_left_out_of_the_comparison(scene, monkeypatch):
    """measure keeps the frames after the pre-roll (LBS: those of --frames alone) and times every frame deformed;
    the command compares those, records the pre-roll, and refuses --preroll without --frames."""
    import garmentcli.tradeoff
    from core.deform import LBSDeformer
    from core.motion import preroll, resample
    from core.tradeoff import Config, measure
    from formats.body import load_body
    from formats.motion import load_motion
    from formats.obj import read_garment

    garment, body = read_garment(scene["garment"]), load_body(scene["body"])
    source = load_motion(scene["motion"])
    led = resample(preroll(source, 6, 12, 4), 30.0)
    m = measure(Config("lbs", "lbs", {}), garment, body, led, repeats=1)
    plain = resample(preroll(source, 6, 12, 0), 30.0)
    assert led.n_lead == 2 and m.points.shape[0] == plain.n_frames == 3
    np.testing.assert_allclose(m.points, LBSDeformer().deform(garment, body, plain), atol=1e-6)
    monkeypatch.setattr(garmentcli.tradeoff, "measure", _fake_measure(lambda c: False))
    base = ["tradeoff", scene["garment"], scene["motion"], "--body", scene["body"], "--out", scene["out"]]
    r = invoke([*base, "--frames", "6:12", "--preroll", 4])
    assert r.exit_code == 0, r.output
    result = json.loads((scene["out"] / "shell_walk" / "tradeoff.json").read_text())
    assert (result["frames"], result["preroll_frames"]) == (3, 2)
    assert "3 frames at 30 fps after 2 pre-roll frames" in (scene["out"] / "shell_walk" / "tradeoff.md").read_text()
    lbs = next(row for row in result["rows"] if row["config"] == "lbs")
    assert lbs["e_verts"] == pytest.approx(10 * np.sqrt(3), abs=0.01)
    r = invoke([*base, "--preroll", 4, "--overwrite"])
    assert r.exit_code != 0 and "--preroll: expected --frames START:STOP" in r.output


def test_a_calibrate_file_that_cannot_take_the_scene_or_a_name_given_twice_stops_before_any_work(scene, monkeypatch):
    """--calibrate FILE that is no calibration (or cannot be written) and two --model rows of one NAME are refused
    in one line before any configuration is measured; the calibration used to be read only after the whole run."""
    import garmentcli.tradeoff

    measured = []
    monkeypatch.setattr(garmentcli.tradeoff, "measure", _counting_measure(measured))
    base = ["tradeoff", scene["garment"], scene["motion"], "--body", scene["body"], "--frames", "0:4",
            "--out", scene["out"]]
    notes = scene["dir"] / "notes.json"
    notes.write_text("my notes\n")
    r = invoke([*base, "--calibrate", notes])
    assert r.exit_code != 0 and f"quality calibration '{notes}': expected the JSON" in r.output
    r2 = invoke([*base, "--calibrate", notes / "cal.json"])
    assert r2.exit_code != 0 and "Invalid value for '--calibrate'" in r2.output and "is a file, not a folder" in r2.output
    r3 = invoke([*base, "--model", f"a={scene['garment']}", "--model", f"a={scene['body']}"])
    assert r3.exit_code != 0 and "--model" in r3.output and "expected distinct names, got 'a' twice" in r3.output
    assert not measured and not scene["out"].exists()
    assert not any("Traceback" in x.output for x in (r, r2, r3))
    # a file where the scene's result folder goes: --overwrite replaced folders only (a traceback after the run)
    scene["out"].mkdir()
    taken = scene["out"] / f"{Path(scene['garment']).stem}_{Path(scene['motion']).stem}"
    taken.write_text("not a folder\n")
    r4 = invoke([*base, "--overwrite"])
    assert r4.exit_code != 0 and f"output '{taken}' is a file: expected the scene's result folder" in r4.output
    assert not measured and taken.read_text() == "not a folder\n" and "Traceback" not in r4.output


def test_a_model_of_another_skeleton_leaves_its_rows_out_or_is_refused_by_name(scene, monkeypatch):
    """A model of SMPL+H's 52 joints on the scene's body of SMPL's 24: as the shipped model, its rows are left out
    with a line saying why (they stopped the run with the model's error); named with --model, it is refused
    before any row. A 52-joint body (SMPL+H-like: the tiny body with 28 more joints on its right hand) keeps the
    shipped model's rows: a model of SMPL's joints reads it on them (they were left out as well)."""
    import dataclasses

    import core.model_deform
    import garmentcli.tradeoff
    from formats.checkpoint import save_checkpoint
    from tests.meshes import tiny_body

    config52 = dataclasses.replace(TINY_CONFIG, n_joints=52)
    model52 = save_checkpoint(scene["dir"] / "m52.pt", config52, perturbed_model(config52, 0.2).state_dict())
    measured = []
    monkeypatch.setattr(garmentcli.tradeoff, "measure", _counting_measure(measured))
    base = ["tradeoff", scene["garment"], scene["motion"], "--body", scene["body"], "--frames", "0:4", "--out",
            scene["out"]]
    r = invoke([*base, "--model", f"mine={model52}"])
    assert r.exit_code != 0 and "Traceback" not in r.output and not measured
    assert "was trained for a body of 52 joints, got body 'tiny_body' with 24 (leave it out" in r.output
    monkeypatch.setattr(core.model_deform, "DEFAULT_MODEL", model52)
    r = invoke(base)
    assert r.exit_code == 0, r.output
    assert "got body 'tiny_body' with 24: its rows are left out" in r.output
    assert measured and not any("float32" in name or "bfloat16" in name for name in measured)
    assert "lbs" in measured and any(name.startswith("sim") for name in measured)
    monkeypatch.undo()
    monkeypatch.setattr(garmentcli.tradeoff, "measure", _counting_measure(measured))
    measured.clear()
    body = tiny_body()
    extra = 52 - body.n_joints
    parents = np.r_[body.parents, [body.n_joints - 1] * extra].astype(np.int64)
    kintree = np.stack([parents, np.arange(52)])
    kintree[0, 0] = 2**32 - 1
    path = scene["dir"] / "body52.npz"
    np.savez(path, v_template=body.v_template, shapedirs=body.shapedirs, f=body.faces.astype(np.uint32),
             J_regressor=np.r_[body.J_regressor, np.repeat(body.J_regressor[-1:], extra, axis=0)],
             weights=np.c_[body.weights, np.zeros((body.n_vertices, extra), np.float32)],
             kintree_table=kintree.astype(np.int64))
    r = invoke([*base[:4], path, *base[5:], "--overwrite"])
    assert r.exit_code == 0, r.output
    assert "rows are left out" not in r.output and any("float32" in name for name in measured)
