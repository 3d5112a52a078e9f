"""`garment attribute`: outputs on a tiny scene, and every bad input refused with one clear line."""

import dataclasses
import json

import numpy as np
import pytest
from click.testing import CliRunner

from formats.checkpoint import save_checkpoint
from garmentcli.main import cli
from tests.core.model_fixtures import TINY_CONFIG, perturbed_model


def run(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


@pytest.fixture
def model_path(tmp_path):
    model = perturbed_model(TINY_CONFIG, 0.2)
    return save_checkpoint(tmp_path / "m.pt", TINY_CONFIG, model.state_dict())


def test_attribute_writes_table_arrays_and_heatmaps(scene, model_path, monkeypatch, tmp_path):
    monkeypatch.setenv("GARMENT_CACHE_DIR", str(tmp_path / "cache"))
    out = scene["out"] / "att"
    r = run("attribute", model_path, scene["garment"], scene["motion"], "--frame", 3, "--steps", 6,
            "--body", scene["body"], "--out", out)
    assert r.exit_code == 0, r.output
    summary = json.loads((out / "summary.json").read_text())
    assert summary["steps"] == 6 and len(summary["top"]) == 15
    with np.load(out / "attributions.npz") as z:
        n = len(z["deformation_m"])
        assert n == 642 and z["garment_feature_attribution"].shape == (n,)
        total = sum(float(z[f"phi_{k}"].sum()) for k in ("pose", "velocity", "body", "garment"))
    assert np.isclose(total, summary["sum_m"])
    table = (out / "attributions.md").read_text()
    assert "| body shape |" in table and "| garment features |" in table
    for name in ("heatmap_deformation.png", "heatmap_garment_features.png"):
        assert (out / name).stat().st_size > 1000
    # A region: the first 10 vertices.
    (tmp_path / "v.txt").write_text(" ".join(str(i) for i in range(10)))
    r = run("attribute", model_path, scene["garment"], scene["motion"], "--frame", 3, "--steps", 2, "--no-render",
            "--body", scene["body"], "--vertices", tmp_path / "v.txt", "--out", out, "--overwrite")
    assert r.exit_code == 0, r.output
    assert "over 10 vertices" in (out / "attributions.md").read_text()
    assert "f(input) = " in r.output and "completeness error" in r.output  # the check is shown, not only written
    # An index given again counts once (it weighed the mean: "0 0 0 1" is vertices 0 and 1).
    (tmp_path / "twice.txt").write_text("0 0 0 1")
    r = run("attribute", model_path, scene["garment"], scene["motion"], "--frame", 3, "--steps", 2, "--no-render",
            "--body", scene["body"], "--vertices", tmp_path / "twice.txt", "--out", out, "--overwrite")
    assert r.exit_code == 0 and "over 2 vertices" in (out / "attributions.md").read_text()


def test_attribute_warns_where_the_attributions_do_not_add_up(scene, model_path, monkeypatch, caplog):
    import garmentcli.attribute as A

    out = scene["out"] / "few"
    base = ["attribute", model_path, scene["garment"], scene["motion"], "--frame", 3, "--steps", 2, "--no-render",
            "--body", scene["body"], "--out", out, "--overwrite"]
    summary = lambda: json.loads((out / "summary.json").read_text())  # noqa: E731
    assert run(*base).exit_code == 0
    s = summary()
    gap = s["f_input_m"] - s["f_baseline_m"]
    assert ("the attributions sum to" in caplog.text) == (abs(s["completeness_error_m"]) > 0.05 * abs(gap) + 1e-5)
    monkeypatch.setattr(A, "COMPLETENESS_WARN_M", 0.0)
    monkeypatch.setattr(A, "COMPLETENESS_WARN_SHARE", 0.0)  # any error at all
    caplog.clear()
    assert run(*base).exit_code == 0
    assert "the attributions sum to" in caplog.text and "pass more --steps (now 2)" in caplog.text


def test_attribute_takes_betas_as_bake_does(scene, model_path, monkeypatch, tmp_path):
    """A motion's betas warned about on the embedded body suggested `--betas motion`, which `attribute` did not
    have: the body shape's row was 0 whatever the user wanted. `--betas` is bake's: the mean shape attributes
    nothing to the body's shape, coefficients something."""
    monkeypatch.setenv("GARMENT_CACHE_DIR", str(tmp_path / "cache"))
    phi = {}
    for betas in ("mean", "1.5,-1,0.5"):
        out = scene["out"] / f"att_{betas}"
        r = run("attribute", model_path, scene["garment"], scene["motion"], "--frame", 2, "--steps", 2, "--no-render",
                "--body", scene["body"], "--betas", betas, "--out", out)
        assert r.exit_code == 0, r.output
        with np.load(out / "attributions.npz") as z:
            phi[betas] = float(np.abs(z["phi_body"]).sum())
    assert phi["mean"] == 0.0 and phi["1.5,-1,0.5"] > 0.0


def test_attribute_explains_the_shipped_model_named_default(scene, monkeypatch, tmp_path):
    """MODEL `default`: the model shipped inside the installed package, which a user has no path to."""
    from core.model_deform import DEFAULT_MODEL

    monkeypatch.setenv("GARMENT_CACHE_DIR", str(tmp_path / "cache"))
    out = scene["out"] / "att_default"
    r = run("attribute", "default", scene["garment"], scene["motion"], "--frame", 1, "--steps", 2,
            "--body", scene["body"], "--out", out, "--no-render")
    assert r.exit_code == 0, r.output
    assert json.loads((out / "summary.json").read_text())["model"] == str(DEFAULT_MODEL)


def test_attribute_reads_an_smplh_body_on_the_models_joints(scene, model_path):
    """A model of SMPL's 24 joints attributes on an SMPL+H body (the tiny body with MANO's finger joints) as on
    the body it was made from: the body read on SMPL's joints (`Body.smpl_view`); it was refused."""
    from tests.meshes import with_fingers

    np.savez(scene["dir"] / "hands.npz", **with_fingers(scene["tiny"], "smplh", seed=None))
    found = {}
    for name, body in (("tiny", scene["body"]), ("hands", scene["dir"] / "hands.npz")):
        r = run("attribute", model_path, scene["garment"], scene["motion"], "--frame", 3, "--steps", 2,
                "--no-render", "--body", body, "--out", scene["out"] / name)
        assert r.exit_code == 0, r.output
        with np.load(scene["out"] / name / "attributions.npz") as z:
            found[name] = {k: z[k] for k in z.files}
    assert found["tiny"].keys() == found["hands"].keys()
    for k, v in found["tiny"].items():
        np.testing.assert_allclose(found["hands"][k], v, atol=1e-6, err_msg=k)


def test_attribute_bad_inputs(scene, model_path, tmp_path):
    base = [model_path, scene["garment"], scene["motion"], "--body", scene["body"], "--no-render"]
    r = run("attribute", *base, "--frame", 999, "--out", tmp_path / "a")
    assert r.exit_code != 0 and "--frame" in r.output and not (tmp_path / "a").exists()
    (tmp_path / "bad.txt").write_text("1 2 x")
    r = run("attribute", *base, "--frame", 1, "--vertices", tmp_path / "bad.txt", "--out", tmp_path / "a")
    assert r.exit_code != 0 and "--vertices" in r.output and not (tmp_path / "a").exists()
    (tmp_path / "binary.txt").write_bytes(b"\x80\xff\x00")  # raised UnicodeDecodeError
    r = run("attribute", *base, "--frame", 1, "--vertices", tmp_path / "binary.txt", "--out", tmp_path / "a")
    assert r.exit_code != 0 and isinstance(r.exception, SystemExit) and "--vertices" in r.output, r.output
    assert "binary" in r.output and not (tmp_path / "a").exists()
    r = run("attribute", *base, "--frame", 1, "--steps", 2**31, "--out", tmp_path / "a")  # ran out of memory
    assert r.exit_code == 2 and "--steps" in r.output and not (tmp_path / "a").exists()
    (tmp_path / "far.txt").write_text("5000")
    r = run("attribute", *base, "--frame", 1, "--vertices", tmp_path / "far.txt", "--out", tmp_path / "a")
    assert r.exit_code != 0 and "0..641" in r.output and "far.txt" in r.output
    (tmp_path / "none.txt").write_text(" \n")
    r = run("attribute", *base, "--frame", 1, "--vertices", tmp_path / "none.txt", "--out", tmp_path / "a")
    assert r.exit_code != 0 and "none.txt': expected vertex indices, got none" in r.output
    (tmp_path / "notamodel.pt").write_text("hello")
    r = run("attribute", tmp_path / "notamodel.pt", *base[1:], "--frame", 1, "--out", tmp_path / "a")
    assert r.exit_code != 0 and "notamodel.pt" in r.output
    r = run("attribute", *base, "--out", tmp_path / "a")
    assert r.exit_code != 0 and "--frame" in r.output
    # a model of another skeleton than the body's: one line naming both, before the progress bar
    config52 = dataclasses.replace(TINY_CONFIG, n_joints=52)
    other = save_checkpoint(tmp_path / "m52.pt", config52, perturbed_model(config52, 0.2).state_dict())
    r = run("attribute", other, *base[1:], "--frame", 1, "--out", tmp_path / "a")
    assert r.exit_code != 0 and "attribute (" not in r.output and not (tmp_path / "a").exists()
    assert r.output.strip().splitlines()[-1].endswith(
        f"model '{other}' was trained for a body of 52 joints, got body 'tiny_body' with 24: pass the --body it "
        "was made for")
