"""`garment fit` and `bake --method psd` through click's CliRunner, on the tiny dataset of model_fixtures."""

import json
from pathlib import Path

import numpy as np
import pytest

from formats.psd import load_fit
from tests.core.model_fixtures import copy_recording_body, make_dataset, tube, write_obj
from tests.garmentcli.cli import invoke
from tests.garmentcli.conftest import write_motion, write_tiny_body


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    root = tmp_path_factory.mktemp("fit")
    data = make_dataset(root / "ds")
    body = root / "tiny_body.npz"
    write_tiny_body(body)
    garment = root / "a.obj"
    garment.write_bytes((data / "garments" / "a.obj").read_bytes())
    return root, data, body, garment


@pytest.fixture(scope="module")
def fitted(setup):
    """`garment fit` of the garment, once: (its result, the fit written beside the garment). Each test that uses
    the fit asks for it (one read a fit another test wrote, and failed where xdist ran it first or elsewhere)."""
    root, data, body, garment = setup
    return invoke(["fit", garment, "--data", data, "--body", body, "--rank", "8"]), root / "a.psd.npz"


def test_fit_then_bake_with_it(setup, fitted):
    """The garment's two training sequences give a fit (written beside it by default) that `bake --method psd`
    uses; the summary names it; the baked frames are finite and near LBS's (the fixture's offsets are small)."""
    root, data, body, garment = setup
    r, fit_path = fitted
    assert r.exit_code == 0, r.output
    assert "8 blend shapes of 'a.obj' fitted to 2 sequences (24 frames)" in r.output
    assert "no validation sequences yet" in r.output  # the fixture's val split is another garment's
    fit = load_fit(fit_path)
    assert fit.rank == 8 and fit.meta["garment"] == "a"
    write_motion(root / "walk.npz", n_frames=6, fps=30.0)
    r = invoke(["bake", garment, root / "walk.npz", "--method", "psd", "--fit", fit_path, "--body", body,
                "--out", root / "out"])
    assert r.exit_code == 0, r.output
    summary = json.loads((root / "out" / "a_walk" / "summary.json").read_text())
    assert summary["method"] == "psd"
    import hashlib  # the fit is an input, recorded as such (it was a relative path inside a sentence)

    assert summary["inputs"]["fit"] == str(Path(fit_path).resolve())
    assert summary["inputs"]["fit_sha256"] == hashlib.sha256(Path(fit_path).read_bytes()).hexdigest()
    r = invoke(["bake", garment, root / "walk.npz", "--method", "lbs", "--body", body, "--out", root / "lbs"])
    assert r.exit_code == 0, r.output
    from formats.sequence import read_sequence

    psd, lbs = (read_sequence(root / d / "a_walk").points for d in ("out", "lbs"))
    gap = np.linalg.norm(psd - lbs, axis=-1)
    assert np.isfinite(psd).all() and 0 < gap.mean() < 0.03


def test_a_motion_beyond_what_the_fit_saw_is_warned_about(setup, fitted):
    """psd said nothing where a motion lay beyond its training sequences (a run at six times its speed on betas
    +5: 22 mm against LBS's 15): the fit records its motions' joint speeds and largest beta, and a motion far
    faster, or of a body shape far larger, is warned about in its own summary."""
    root, data, body, garment = setup
    _, fit_path = fitted
    meta = load_fit(fit_path).meta
    lo, hi = meta["speed_m_s"]
    assert 0 < lo <= hi and meta["betas_abs_max"] >= 0
    write_motion(root / "fast.npz", n_frames=12, fps=300.0)  # the fixture's poses ten times faster
    write_motion(root / "shaped.npz", n_frames=12, fps=30.0, betas=np.full(16, 4.0, np.float32))
    for name, extra, needle in (("fast", ["--fps", "300"], "its joints move at"), ("shaped", ["--betas", "motion"],
                                                                                     "a beta of 4")):
        r = invoke(["bake", garment, root / f"{name}.npz", "--method", "psd", "--fit", fit_path, "--body", body,
                    "--out", root / f"beyond_{name}", *extra])
        assert r.exit_code == 0, r.output
        warnings = json.loads((root / f"beyond_{name}" / f"a_{name}" / "summary.json").read_text())["warnings"]
        beyond = [w for w in warnings if "beyond the sequences the fit" in w]
        assert len(beyond) == 1 and needle in beyond[0] and "psd can do worse than lbs there" in beyond[0], warnings
    r = invoke(["fit", garment, "--data", data, "--body", body])
    assert r.exit_code != 0 and "exists: pass --overwrite" in r.output


def test_a_motion_turning_a_joint_beyond_the_fitted_frames_is_warned_about(setup, fitted):
    """The fit records the largest rotation of each joint that moves the garment (the fixture's sequences swing the
    hips 0.5 rad): a motion turning a hip 1.5 rad is warned about, naming the joint; one within is not (the arms
    raised on a fit of walks came 7.2 mm off without a word)."""
    root, data, body, garment = setup
    _, fit_path = fitted
    angles = load_fit(fit_path).meta["joint_angle_max_deg"]
    assert angles["left_hip"] == pytest.approx(np.degrees(0.5), abs=0.5) and "pelvis" not in angles
    for name, hip, warned in (("wide", 1.5, True), ("narrow", 0.4, False)):
        poses = np.zeros((12, 72), np.float32)
        poses[:, :3] = [np.pi / 2, 0, 0]
        poses[:, 3] = hip * np.sin(np.linspace(0, np.pi, 12))  # left hip about X
        write_motion(root / f"{name}.npz", n_frames=12, fps=30.0, poses=poses)
        r = invoke(["bake", garment, root / f"{name}.npz", "--method", "psd", "--fit", fit_path, "--body", body,
                    "--out", root / f"turn_{name}"])
        assert r.exit_code == 0, r.output
        warnings = json.loads((root / f"turn_{name}" / f"a_{name}" / "summary.json").read_text())["warnings"]
        beyond = [w for w in warnings if "beyond the sequences the fit" in w]
        assert bool(beyond) == warned, warnings
        if warned:
            assert "its left_hip turns 85 degrees, the most fitted 29" in beyond[0]  # 1.5 rad at its 12 samples


def test_fit_and_psd_bad_inputs(setup, fitted, tmp_path):
    root, data, body, garment = setup
    fit_path = fitted[1]
    other = tmp_path / "other.obj"
    write_obj(other, *tube(9, 4))
    r = invoke(["fit", other, "--data", data, "--body", body, "--out", tmp_path / "o.npz"])
    assert r.exit_code != 0 and "did not simulate 'other.obj' (its garments: a, b" in r.output
    assert not (tmp_path / "o.npz").exists()
    r = invoke(["fit", garment, "--data", tmp_path, "--body", body, "--out", tmp_path / "o.npz"])
    assert r.exit_code != 0 and "expected a `garment dataset` directory" in r.output
    write_motion(tmp_path / "walk.npz", n_frames=4, fps=30.0)
    common = [garment, tmp_path / "walk.npz", "--body", body, "--out", tmp_path / "out"]
    r = invoke(["bake", *common, "--method", "psd"])
    assert r.exit_code != 0 and "--method psd needs --fit FILE" in r.output
    r = invoke(["bake", *common, "--method", "lbs", "--fit", fit_path])
    assert r.exit_code != 0 and "--fit applies to --method psd only" in r.output
    r = invoke(["bake", other, tmp_path / "walk.npz", "--body", body, "--out", tmp_path / "out", "--method", "psd",
                "--fit", fit_path])
    assert r.exit_code != 0 and "fitted to another garment" in r.output
    (tmp_path / "junk.npz").write_bytes(b"junk")
    r = invoke(["bake", *common, "--method", "psd", "--fit", tmp_path / "junk.npz"])
    assert r.exit_code != 0 and "junk.npz': cannot be read" in r.output
    assert not (tmp_path / "out").exists()


def test_fit_takes_the_garment_through_a_round_trip_as_bake_takes_its_fit(setup, tmp_path):
    """The simulated garment with each face starting at another corner and its vertices moved by 3 um (an export,
    a unit round trip): `bake --method psd` took it with the garment's fit, `fit` refused it as not simulated."""
    from formats.obj import read_obj

    root, data, body, garment = setup
    g = read_obj(garment)
    same = tmp_path / "same.obj"
    write_obj(same, g.vertices + 3e-6, np.roll(g.faces, 1, axis=1))
    r = invoke(["fit", same, "--data", data, "--body", body, "--rank", "4", "--out", tmp_path / "s.npz"])
    assert r.exit_code == 0, r.output
    assert "4 blend shapes of 'same.obj' fitted to 2 sequences" in r.output
    moved = tmp_path / "moved.obj"
    write_obj(moved, g.vertices + 1e-4, g.faces)  # 0.1 mm: another garment
    r = invoke(["fit", moved, "--data", data, "--body", body, "--out", tmp_path / "m.npz"])
    assert r.exit_code != 0 and "did not simulate 'moved.obj'" in r.output


@pytest.mark.parametrize("args, option, word", [(["--ridge", "nan"], "--ridge", "finite"),
                                                (["--ridge", "inf"], "--ridge", "finite"),
                                                (["--out", "fit5.obj"], "--out", ".npz")])
def test_fit_refuses_a_non_finite_ridge_and_an_out_that_is_no_npz(setup, tmp_path, args, option, word):
    """--ridge nan/inf wrote a fit whose error was 'nan mm'; --out x.obj got npz data."""
    root, data, body, garment = setup
    args = [str(tmp_path / a) if a.endswith(".obj") else a for a in args]
    out = ["--out", str(tmp_path / "f.npz")] if "--out" not in args else []
    r = invoke(["fit", garment, "--data", data, "--body", body, *out, *args])
    assert r.exit_code == 2 and option in r.output and word in r.output and "Traceback" not in r.output, r.output
    assert not list(tmp_path.iterdir())


def test_fit_refuses_a_body_other_than_the_datasets(setup, tmp_path):
    """The body the dataset records (`inputs.body`) must be the one given: --body forgotten is refused, naming
    the dataset's body; nothing is written."""
    root, data, body, garment = setup
    ds = copy_recording_body(data, body, tmp_path / "ds")
    r = invoke(["fit", garment, "--data", ds, "--rank", "4", "--out", tmp_path / "a.npz"])
    assert r.exit_code != 0 and "Traceback" not in r.output
    assert f"was simulated on body '{body}' (file sha256 " in r.output and "got the embedded default" in r.output
    assert not (tmp_path / "a.npz").exists()
    r = invoke(["fit", garment, "--data", ds, "--body", body, "--rank", "4", "--out", tmp_path / "a.npz"])
    assert r.exit_code == 0, r.output


def test_fit_with_no_ridge_on_too_few_frames_is_one_line(setup, tmp_path):
    """--ridge 0 (allowed: a plain least-squares fit) on 24 frames, fewer than the regressors: the system is
    singular; one line naming --ridge, not numpy's traceback, and nothing written."""
    root, data, body, garment = setup
    r = invoke(["fit", garment, "--data", data, "--body", body, "--ridge", "0", "--out", tmp_path / "r0.npz"])
    assert r.exit_code != 0 and "Traceback" not in r.output and not isinstance(r.exception, np.linalg.LinAlgError)
    assert "--ridge" in r.output and "24 training frames" in r.output
    assert not (tmp_path / "r0.npz").exists()


def test_psd_frames_of_a_range_and_of_parts_are_the_whole_motions(setup, fitted):
    """psd's blend shapes read each frame's joint rates and root acceleration from the frames around it: a
    --frames range deforms FEATURE_CONTEXT_FRAMES source frames either side (not written), so its frames are the
    whole motion's (at the range's ends they were one-sided differences, up to 3 cm off), and a motion baked in
    two parts has no seam; where the range reaches the motion's ends there is nothing to add. The context is
    counted in output frames: at --fps 30 from 60, twice as many source frames."""
    from core.psd import FEATURE_CONTEXT_FRAMES
    from formats.sequence import read_sequence

    root, data, body, garment = setup
    _, fit_path = fitted
    write_motion(root / "parts.npz", n_frames=32, fps=60.0, seed=3)  # 16 frames at --fps 30
    common = [garment, root / "parts.npz", "--method", "psd", "--fit", fit_path, "--body", body, "--fps", "30"]

    def bake(name, *extra):
        r = invoke(["bake", *common, *extra, "--out", root / "parts" / name])
        assert r.exit_code == 0, r.output
        summary = json.loads((root / "parts" / name / "a_parts" / "summary.json").read_text())
        summary["said"] = r.output
        return read_sequence(root / "parts" / name / "a_parts" / "a_parts.usd").points, summary

    whole, _ = bake("whole")
    first, s_first = bake("first", "--frames", "0:14")
    second, s_second = bake("second", "--frames", "14:")
    middle, s_middle = bake("middle", "--frames", "10:18")
    np.testing.assert_allclose(np.concatenate([first, second]), whole, atol=1e-5)
    np.testing.assert_allclose(middle, whole[5:9], atol=1e-5)
    single, s_single = bake("single", "--frames", "10:12")
    np.testing.assert_allclose(single, whole[5:6], atol=1e-5)
    assert "a_parts: 1 frame at 30 fps" in s_single["said"]  # (was "1 frames")
    assert (s_first["preroll_frames"], s_first["tail_frames"]) == (0, FEATURE_CONTEXT_FRAMES)  # output frames
    assert (s_second["preroll_frames"], s_second["tail_frames"]) == (FEATURE_CONTEXT_FRAMES, 0)
    assert s_middle["frames"] == 4 and s_middle["tail_frames"] == FEATURE_CONTEXT_FRAMES
    # the context is what makes them agree: the one-sided ends of a range without it moved the cloth
    from core.motion import preroll
    from formats.motion import load_motion

    motion = load_motion(str(root / "parts.npz"))
    bare, ctx = preroll(motion, 5, 9, 0), preroll(motion, 5, 9, 0, context=(2, 2))
    assert (bare.n_frames, ctx.n_frames, ctx.n_lead, ctx.n_tail, ctx.n_written) == (4, 8, 2, 2, 4)


def test_fit_says_a_rank_it_cut_records_its_data_absolute_and_names_motions_worse_than_lbs(setup, tmp_path,
                                                                                            monkeypatch):
    """--rank above the training frames is cut, said (it was cut without a word); the fit records its data
    folder resolved (a relative one meant nothing in a bake's summary.json elsewhere); the motions of a split worse
    than LBS are named, even where the split's mean is better (the mean hid them); a larger --ridge is advised
    only where it could change the fit."""
    from garmentcli.fit import RIDGE_ADVICE_MAX, _worse

    root, data, body, garment = setup
    monkeypatch.chdir(data.parent)
    r = invoke(["fit", garment, "--data", data.name, "--body", body, "--rank", "100", "--out", tmp_path / "f.npz"])
    assert r.exit_code == 0, r.output
    assert "23 blend shapes (--rank 100 asked: at most one fewer than the 24 training frames)" in r.output
    assert load_fit(tmp_path / "f.npz").meta["data"] == str(data.resolve())
    split = {"sequences": 3, "psd_mm": 10.0, "lbs_mm": 12.0,
             "worse_than_lbs": {"kick": {"psd_mm": 15.04, "lbs_mm": 14.0}}}
    said = (" (worse than LBS on 1 motion: 'kick' 15.0 against 14.0 mm: the fit does not carry over to these "
            "motions; fit on more of them")
    assert _worse(split, RIDGE_ADVICE_MAX * 10) == said + ")"  # at 1e12 a larger ridge was advised
    assert _worse(split, 10.0) == said + ", or a larger --ridge)"
    assert _worse({**split, "worse_than_lbs": {}}, 10.0) == ""


def test_workers_are_given_every_input_file_by_its_absolute_path(setup, fitted, monkeypatch):
    """A cluster's worker runs in its own folder: it opened a relative --fit there ("file not found", or another
    fit of that name, silently). Every input path of the task's spec is absolute, whatever the command was given."""
    import dataclasses

    import core.distributed

    root, data, body, garment = setup
    assert fitted[0].exit_code == 0, fitted[0].output
    write_motion(root / "walk.npz", n_frames=6, fps=30.0)
    write_motion(root / "jump.npz", n_frames=5, fps=30.0, seed=1)
    seen = []

    def run_items(task, calls, names, **kwargs):
        seen.extend(calls)
        return iter(())

    monkeypatch.setattr(core.distributed, "run_items", run_items)  # imported by the command when it runs
    monkeypatch.chdir(root)
    r = invoke(["bake", "a.obj", "walk.npz", "jump.npz", "--method", "psd", "--fit", "a.psd.npz", "--body",
                "tiny_body.npz", "--out", "rel", "--workers", 2])
    assert r.exit_code == 0, r.output
    spec = seen[0][0]
    paths = {f.name: getattr(spec, f.name) for f in dataclasses.fields(spec) if f.name.endswith("_path")}
    assert {"garment_path", "body_path", "fit_path", "model_path", "material_path"} <= set(paths)
    assert (paths["garment_path"], paths["body_path"], paths["fit_path"]) == \
        (str(root / "a.obj"), str(root / "tiny_body.npz"), str(root / "a.psd.npz"))
    assert all(p is None or Path(p).is_absolute() for p in paths.values()), paths
    assert [c[1] for c in seen] == [str(root / "walk.npz"), str(root / "jump.npz")]
