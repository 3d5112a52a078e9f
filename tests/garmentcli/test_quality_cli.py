"""`bake --quality auto`: LBS for a tight garment on a slow motion, the model for a loose one on a fast motion."""

import json
import logging

import numpy as np
import pytest

from tests.core.model_fixtures import TINY_CONFIG, perturbed_model
from tests.core.test_quality import synthetic_calibration
from tests.garmentcli.cli import invoke
from tests.garmentcli.conftest import write_motion, write_shell_obj


@pytest.fixture
def auto_scene(scene):
    from formats.checkpoint import save_checkpoint

    d = scene["dir"]
    model = save_checkpoint(d / "tiny.pt", TINY_CONFIG, perturbed_model(TINY_CONFIG, 0.05).state_dict())
    synthetic_calibration().save(d / "tiny.calibration.json")
    write_shell_obj(d / "loose.obj", scene["tiny"], offset=0.09)
    write_shell_obj(d / "tight.obj", scene["tiny"], offset=0.006)
    poses = np.zeros((8, 72), np.float32)
    poses[:, :3] = [np.pi / 2, 0, 0]
    slow = np.zeros((8, 3), np.float32)
    slow[:, 0] = np.arange(8) * 0.01  # 0.3 m/s at 30 fps
    fast = np.zeros((8, 3), np.float32)
    fast[:, 0] = np.arange(8) * 0.17  # 5.1 m/s
    write_motion(d / "slow.npz", n_frames=8, fps=30.0, poses=poses, trans=slow)
    write_motion(d / "fast.npz", n_frames=8, fps=30.0, poses=poses, trans=fast)
    write_motion(d / "still.npz", n_frames=8, fps=30.0, poses=poses, trans=np.zeros((8, 3), np.float32))
    return {**scene, "model": model}


def _auto(s, garment, motion, *extra):
    return invoke(["bake", s["dir"] / garment, s["dir"] / motion, "--body", s["body"], "--model", s["model"],
                   "--quality", "auto", "--out", s["out"], "--no-obj", *extra])


def test_auto_picks_lbs_for_tight_and_slow_and_model_for_loose_and_fast(auto_scene):
    s = auto_scene
    r = _auto(s, "tight.obj", "slow.npz")
    assert r.exit_code == 0, r.output
    summary = json.loads((s["out"] / "tight_slow" / "summary.json").read_text())
    assert summary["method"] == "lbs" and summary["quality"]["config"] == "lbs"
    assert summary["quality"]["expected_mm"] <= summary["quality"]["budget_mm"] == 40.0
    assert "quality auto: lbs" in r.output
    r = _auto(s, "loose.obj", "fast.npz", "--budget-mm", 250)
    assert r.exit_code == 0, r.output
    summary = json.loads((s["out"] / "loose_fast" / "summary.json").read_text())
    assert summary["method"] == "model" and summary["quality"]["config"] == "model float32"
    assert summary["quality"]["features"]["speed_m_s"] == pytest.approx(5.1, rel=1e-3)
    assert "'lbs' is cheaper but expected" in summary["quality"]["reason"]


def test_auto_can_choose_lbs_with_its_strain_limit(auto_scene):
    """A calibration with `garment tradeoff`'s "lbs +strain-limit" row: where plain LBS is expected over the budget
    and the limited one within it, the bake runs LBS with the limit, and says so."""
    s = auto_scene
    synthetic_calibration(lbs_limited=True).save(s["dir"] / "limited.json")
    r = _auto(s, "tight.obj", "slow.npz", "--calibration", s["dir"] / "limited.json")
    assert r.exit_code == 0, r.output
    summary = json.loads((s["out"] / "tight_slow" / "summary.json").read_text())
    assert summary["quality"]["config"] == "lbs" and summary["options"]["strain_limit"] is None
    expected = {c["config"]: c["expected_mm"] for c in summary["quality"]["candidates"]}
    budget = (expected["lbs"] + expected["lbs +strain-limit 1.5"]) / 2
    r = _auto(s, "tight.obj", "slow.npz", "--calibration", s["dir"] / "limited.json", "--budget-mm", budget,
              "--overwrite")
    assert r.exit_code == 0, r.output
    summary = json.loads((s["out"] / "tight_slow" / "summary.json").read_text())
    assert summary["method"] == "lbs" and summary["quality"]["config"] == "lbs +strain-limit 1.5"
    assert summary["options"]["strain_limit"] == summary["deformer"]["strain_limit"]["limit"] == 1.5


def test_auto_over_motions_takes_the_costliest_choice_and_names_a_motion_beyond_the_calibration(auto_scene,
                                                                                              caplog):
    """A still motion lies below the calibration's slowest scene: there the model is expected no better than
    lbs (the calibration alone expects it at 40 % of lbs's error), so alone it is baked with lbs, warned about;
    baked with the fast motion, every motion takes the model the fast one needs, and the summaries say which
    motion chose it and which lies beyond the calibration."""
    import logging

    s = auto_scene
    with caplog.at_level(logging.WARNING):
        r = _auto(s, "loose.obj", "still.npz", "--budget-mm", 250)
    assert r.exit_code == 0, r.output
    q = json.loads((s["out"] / "loose_still" / "summary.json").read_text())["quality"]
    assert q["config"] == "lbs" and q["motion"] == "still.npz" and q["outside_motions"] == ["still.npz"]
    assert [o["feature"] for o in q["outside_calibration"]] == ["speed_m_s"]
    model = next(c for c in q["candidates"] if c["config"] == "model float32")
    assert model["expected_mm"] == q["expected_mm"] > model["expected_mm_calibration"]
    warned = [rec.getMessage() for rec in caplog.records if "beyond the calibration" in rec.getMessage()]
    assert len(warned) == 1 and f"'{s['dir'] / 'still.npz'}'" in warned[0]  # as given
    r = _auto(s, "loose.obj", "still.npz", s["dir"] / "fast.npz", "--budget-mm", 250, "--overwrite")
    assert r.exit_code == 0, r.output
    for name in ("loose_still", "loose_fast"):
        summary = json.loads((s["out"] / name / "summary.json").read_text())
        q = summary["quality"]
        assert q["config"] == "model float32" and q["motion"] == "fast.npz" and q["outside_motions"] == ["still.npz"]
        # the warning naming the still motion in its own summary only (it named the file, the filter its path)
        assert any("beyond the calibration" in w for w in summary["warnings"]) == (name == "loose_still")
        assert q["features"]["speed_m_s"] == pytest.approx(5.1, rel=1e-3)


def test_the_model_on_a_motion_beyond_its_calibration_is_warned_about_in_that_motions_summary(auto_scene, caplog):
    """Baked with the model (the default method), a motion beyond the scenes of the model's calibration (the still
    one, slower than any) is warned about, naming it, in its own summary.json only; one within them is not."""
    import logging

    s = auto_scene
    with caplog.at_level(logging.WARNING):
        r = invoke(["bake", s["dir"] / "loose.obj", s["dir"] / "still.npz", s["dir"] / "fast.npz", "--body", s["body"],
                    "--model", s["model"], "--method", "model", "--out", s["out"], "--no-obj"])
    assert r.exit_code == 0, r.output
    warned = [rec.getMessage() for rec in caplog.records if "beyond the scenes the model's calibration" in
              rec.getMessage()]
    assert len(warned) == 1 and "still.npz" in warned[0] and "speed 0 m/s, under the smallest calibrated" in warned[0]
    for name, expected in (("loose_still", 1), ("loose_fast", 0)):
        summary = json.loads((s["out"] / name / "summary.json").read_text())
        assert summary["method"] == "model"
        assert sum("beyond the scenes the model's calibration" in w for w in summary["warnings"]) == expected


@pytest.mark.parametrize("extra, needle", [(["--method", "lbs"], "leave out --method"),
                                           (["--precision", "bfloat16"], "leave out --method and --precision"),
                                           (["--calibration", "nope.json"], "nope.json"),
                                           (["--budget-mm", "nan"], "expected a finite number > 0, got 'nan'"),
                                           (["--budget-mm", "inf"], "expected a finite number > 0, got 'inf'")])
def test_auto_bad_combinations(auto_scene, extra, needle):
    r = _auto(auto_scene, "tight.obj", "slow.npz", *extra)
    assert r.exit_code != 0 and needle in r.output and "Traceback" not in r.output
    assert not auto_scene["out"].exists()


def test_auto_with_push_out_pushes_the_chosen_methods_output_out(auto_scene):
    """--quality auto with --push-out was refused, while the bake it chose (lbs on the tight garment) then
    suggested --push-out: the push-out now follows the chosen method, said and recorded."""
    s = auto_scene
    r = _auto(s, "tight.obj", "slow.npz", "--push-out")
    assert r.exit_code == 0, r.output
    assert "quality auto: lbs +push-out (--push-out) (" in r.output
    summary = json.loads((s["out"] / "tight_slow" / "summary.json").read_text())
    assert summary["method"] == "lbs" and summary["push_out"] is True and "push_out" in summary["deformer"]


def test_auto_leaves_out_the_options_of_other_methods_than_the_one_chosen_and_says_so(auto_scene):
    """An explicit --method refuses another method's options; --quality auto dropped them without a word
    (--lbs-smooth, --no-contact-guard, --strain-limit with the simulator chosen), or failed naming a --method never
    given (--material with the model chosen): they are left out, named."""
    s = auto_scene
    (s["dir"] / "mat.json").write_text("{}")
    r = _auto(s, "tight.obj", "slow.npz", "--no-contact-guard", "--material", s["dir"] / "mat.json",
              "--substeps", "20", "--lbs-smooth", "5")
    assert r.exit_code == 0, r.output
    assert "quality auto: lbs (" in r.output
    assert ("quality auto: --no-contact-guard, --material, --substeps left out: they apply to other methods than the "
            "lbs chosen") in r.output
    summary = json.loads((s["out"] / "tight_slow" / "summary.json").read_text())
    assert summary["method"] == "lbs" and summary["deformer"]["options"]["smooth_iterations"] == 5


def test_budget_without_auto_and_model_without_calibration(auto_scene):
    s = auto_scene
    r = invoke(["bake", s["dir"] / "tight.obj", s["dir"] / "slow.npz", "--body", s["body"], "--budget-mm", 5,
                "--out", s["out"]])
    assert r.exit_code != 0 and "--budget-mm applies to --quality auto only" in r.output
    (s["dir"] / "tiny.calibration.json").unlink()
    r = _auto(s, "tight.obj", "slow.npz")
    assert r.exit_code != 0 and "tiny.calibration.json" in r.output and not s["out"].exists()
    # a --model that is not there is named as such, not as a model without a calibration
    r = _auto(s, "tight.obj", "slow.npz", "--model", s["dir"] / "gone.pt")
    assert r.exit_code != 0 and f"Invalid value for --model: '{s['dir'] / 'gone.pt'}': no such file" in r.output
    assert "calibration" not in r.output and not s["out"].exists()


def test_auto_with_a_fit_picks_it_where_it_is_expected_within_the_budget(auto_scene, caplog):
    """--fit makes the garment's blend shapes a candidate, expected at LBS's expected error times the share the
    fit kept on its held-out motions, at about LBS's cost: on the loose garment's fast motion (LBS over the
    budget) a fit that kept 30 % is chosen before the model; one that kept 95 % is not; another garment's fit
    is refused."""
    from core.deform import LBSDeformer
    from core.motion import Motion
    from core.psd import fit_psd
    from formats.body import load_body
    from formats.obj import read_obj
    from formats.psd import save_fit

    s = auto_scene
    garment, body = read_obj(s["dir"] / "loose.obj"), load_body(s["body"])
    still = Motion(poses=np.zeros((3, 24, 3), np.float32), trans=np.zeros((3, 3), np.float32), fps=30.0)
    fit = fit_psd(garment, body, [(still, LBSDeformer().deform(garment, body, still))], rank=2)
    for share, name in ((0.3, "good"), (0.95, "poor")):
        fit.meta["errors"] = {"val": {"sequences": 4, "psd_mm": 100 * share, "lbs_mm": 100.0}}
        save_fit(s["dir"] / f"{name}.psd.npz", fit)
    r = _auto(s, "loose.obj", "fast.npz", "--budget-mm", 250, "--fit", s["dir"] / "good.psd.npz")
    assert r.exit_code == 0, r.output
    summary = json.loads((s["out"] / "loose_fast" / "summary.json").read_text())
    assert summary["method"] == "psd" and summary["quality"]["config"] == "psd"
    lbs = next(c for c in summary["quality"]["candidates"] if c["config"] == "lbs")
    assert summary["quality"]["expected_mm"] == pytest.approx(0.3 * lbs["expected_mm"]) and lbs["expected_mm"] > 250
    assert summary["deformer"]["fit"]["rank"] == 2
    # psd chosen for a --frames range: its context frames either side (`core.psd.FEATURE_CONTEXT_FRAMES`) as with
    # --method psd, the motion read again for them without saying its warnings twice
    with caplog.at_level(logging.WARNING):
        r = _auto(s, "loose.obj", "fast.npz", "--budget-mm", 250, "--fit", s["dir"] / "good.psd.npz", "--frames",
                  "2:5", "--betas", "6", "--overwrite")
    assert r.exit_code == 0, r.output
    assert sum("beta 0 is 6, beyond the" in m for m in caplog.messages) == 1, caplog.messages
    summary = json.loads((s["out"] / "loose_fast" / "summary.json").read_text())
    assert (summary["method"], summary["frames"], summary["preroll_frames"], summary["tail_frames"]) == ("psd", 3, 2, 2)
    r = _auto(s, "loose.obj", "fast.npz", "--budget-mm", 250, "--fit", s["dir"] / "poor.psd.npz", "--overwrite")
    assert r.exit_code == 0, r.output
    assert json.loads((s["out"] / "loose_fast" / "summary.json").read_text())["method"] == "model"
    r = _auto(s, "tight.obj", "fast.npz", "--fit", s["dir"] / "good.psd.npz")
    assert r.exit_code != 0 and "fitted to another garment" in r.output


@pytest.mark.parametrize("configs, needle", [({}, "expected configurations to choose from, got none"),
                                             ([1, 2], "'configs' must be an object"),
                                             ({"x": {"method": "magic", "ms_per_frame_per_kvert": 1,
                                                     "points": [[0.02, 0.3, 1.0]]}}, "'x': method must be one of"),
                                             ({"x": {"method": "lbs", "ms_per_frame_per_kvert": "nan",
                                                     "points": [[0.02, 0.3, 1.0]]}}, "finite number >= 0, not nan")])
def test_auto_with_a_calibration_of_the_wrong_form_is_one_line(auto_scene, configs, needle):
    """A hand-edited calibration (no configurations, a method bake does not have, a cost that is no number) is
    refused naming the file, before any work; it used to end in a traceback, or bake with a NaN cost."""
    path = auto_scene["dir"] / "edited.json"
    path.write_text(json.dumps({"configs": configs}))
    r = _auto(auto_scene, "tight.obj", "slow.npz", "--calibration", path)
    assert r.exit_code != 0 and f"quality calibration '{path}'" in r.output and needle in r.output
    assert "Traceback" not in r.output and not auto_scene["out"].exists()


def test_auto_choosing_the_simulator_says_it_replaced_the_users_substeps(auto_scene, monkeypatch):
    """The simulator's configuration chosen replaced --substeps 5 by its own without a word (the simulator itself
    is stood in for by lbs here: only what is said is tested)."""
    import garmentcli.bake as bake_cli

    choose, make = bake_cli._choose_quality, bake_cli.make_deformer

    def sim_chosen(*args, **kwargs):
        return {**choose(*args, **kwargs), "method": "sim", "options": {"substeps": 20}, "config": "sim 20 substeps"}

    monkeypatch.setattr(bake_cli, "_choose_quality", sim_chosen)
    monkeypatch.setattr(bake_cli, "make_deformer", lambda method, *a, **k: make("lbs", *a[:1]))
    r = _auto(auto_scene, "tight.obj", "slow.npz", "--substeps", "5")
    assert r.exit_code == 0, r.output
    assert "quality auto: --substeps 5 replaced by the configuration chosen (sim 20 substeps" in r.output


def test_auto_warns_where_the_calibration_measured_another_model(auto_scene, caplog):
    """A calibration records which model file its model configurations measured (`tradeoff --calibrate`): one of
    another model is warned about, naming both; one of this model, or one that records none, is not."""
    import logging

    from core.provenance import file_sha256
    from core.quality import Calibration

    s = auto_scene
    path = s["dir"] / "tiny.calibration.json"
    cal = Calibration.load(path)
    for sha, warned in (("f" * 64, True), (file_sha256(s["model"]), False)):
        for c in cal.configs.values():
            if c["method"] == "model":
                c["models"] = {sha: 3}
        cal.save(path)
        caplog.clear()
        with caplog.at_level(logging.WARNING):
            r = _auto(s, "tight.obj", "slow.npz", "--overwrite")
        assert r.exit_code == 0, r.output
        said = [rec.getMessage() for rec in caplog.records if "measured model" in rec.getMessage()]
        assert bool(said) == warned, said
        if warned:
            assert f"measured model ffffffff on its scenes, not '{s['model']}' (sha256 {file_sha256(s['model'])[:8]})" \
                in said[0]
