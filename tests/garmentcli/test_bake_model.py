"""`bake` with its default method, the shipped model, on every example garment; its bad inputs."""

import json
from pathlib import Path

import numpy as np
import pytest

from click.testing import CliRunner

from core.model_deform import DEFAULT_MODEL
from formats.usd import read_usd
from garmentcli.main import cli
from tests.garmentcli.cli import invoke


def invoke_default(args):
    """The CLI as a user runs it (no --method added: the default method)."""
    return CliRunner().invoke(cli, [str(a) for a in args])

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = sorted((ROOT / "examples").glob("*.obj"))


def _bake(garment, out, *extra):
    r = invoke_default(["bake", garment, ROOT / "examples" / "run.npz", "--frames", "0:8", "--out", out, "--no-obj",
                "--no-body", *extra])
    assert r.exit_code == 0, r.output
    d = out / f"{garment.stem}_run"
    summary = json.loads((d / "summary.json").read_text())
    return read_usd(d / f"{garment.stem}_run.usd").tracks["garment"].points, summary, r.output


def _restricted_model(tmp_path, joints=("shoulder", "elbow", "wrist", "hand", "collar", "neck", "head")):
    """The shipped model as if no training garment had covered the arms, shoulders, neck and head."""
    from core.body import SMPL_JOINT_NAMES
    from formats.checkpoint import load_checkpoint, save_checkpoint

    data = load_checkpoint(DEFAULT_MODEL)
    meta = dict(data["meta"])
    meta["joint_coverage"] = [0.0 if any(j in name for j in joints) else c
                              for name, c in zip(SMPL_JOINT_NAMES, meta["joint_coverage"])]
    return save_checkpoint(tmp_path / "lower_body.pt", data["config"], data["model"], meta)


@pytest.mark.parametrize("garment", EXAMPLES, ids=lambda p: p.stem)
def test_model_on_every_example_garment_within_its_training_range(garment, tmp_path):
    assert len(EXAMPLES) == 5
    default, summary, out = _bake(garment, tmp_path / "default")
    lbs, lbs_summary, _ = _bake(garment, tmp_path / "lbs", "--method", "lbs")
    assert summary["method"] == "model" and Path(summary["deformer"]["model"]) == DEFAULT_MODEL
    from core.provenance import file_sha256  # the checkpoint an input, by path and content (it was the path given)

    assert (summary["inputs"]["model"], summary["inputs"]["model_sha256"]) == (str(DEFAULT_MODEL),
                                                                               file_sha256(DEFAULT_MODEL))
    assert "model" not in lbs_summary["inputs"]
    assert "method_fallback" not in summary and summary["deformer"]["training_range"]["within"]
    assert default.shape == lbs.shape and np.isfinite(default).all()
    gap = np.linalg.norm(default - lbs, axis=-1)
    extent = float(np.ptp(lbs[0], axis=0).max())
    # The network corrects LBS (it is not LBS: trained blend shapes and weights move vertices) and stays
    # bounded: on average within a tenth of the garment's size of the LBS garment, no vertex further than its
    # size. (Not half of it: on these frames the simulator itself takes a skirt vertex 0.37 m, 0.71 of the
    # skirt's size, from where LBS puts it; the model 0.28 m, 31 mm from the simulator on average, LBS 63 mm.)
    assert 1e-3 < gap.mean() < 0.1 * extent, (gap.mean(), extent)
    assert gap.max() < extent, (gap.max(), extent)


def test_garment_outside_the_training_range_is_baked_with_lbs_unless_the_model_is_asked_for(tmp_path):
    """A model whose training garments never covered the arms: a t-shirt is baked with lbs, with one line saying
    why; --method model runs the model anyway, with a warning; a skirt stays with the model."""
    model = _restricted_model(tmp_path)
    tshirt = ROOT / "examples" / "tshirt.obj"
    default, summary, out = _bake(tshirt, tmp_path / "default", "--model", model)
    lbs, _, _ = _bake(tshirt, tmp_path / "lbs", "--method", "lbs")
    assert summary["method"] == "lbs" and summary["method_fallback"]["to"] == "lbs"
    assert summary["method_fallback"]["uncovered_share"] > 0.05 and "baking with lbs instead" in out
    np.testing.assert_allclose(default, lbs, atol=1e-6)
    forced, summary, out = _bake(tshirt, tmp_path / "model", "--method", "model", "--model", model)
    assert "warning:" in out and "worse than lbs" in out
    assert summary["method"] == "model" and not summary["deformer"]["training_range"]["within"]
    assert np.abs(forced - lbs).max() > 1e-3
    _, summary, _ = _bake(ROOT / "examples" / "skirt.obj", tmp_path / "skirt", "--model", model)
    assert summary["method"] == "model" and "method_fallback" not in summary


def test_a_garment_far_coarser_or_finer_than_the_training_garments_is_warned_of(tmp_path):
    """A mesh far coarser or finer than the model's training garments (the shipped model's: median edges 11.0-18.5
    mm, its checkpoint's "garment_edge_m") baked with the model unwarned: a 120-vertex skirt 29 mm from its own
    bake, mean (LBS 12). Beyond EDGE_RANGE_FACTOR of that range it is warned of, and summary.json says so; the
    example skirt is not."""
    from core.garment import Garment
    from core.model_deform import EDGE_RANGE_FACTOR, edge_range_report, garment_edge_range, median_edge_m
    from formats.checkpoint import load_checkpoint
    from formats.obj import read_obj, write_obj
    from tests.core.model_fixtures import tube

    trained = load_checkpoint(DEFAULT_MODEL)["meta"]["garment_edge_m"]
    examples = [read_obj(p) for p in EXAMPLES]
    assert trained == garment_edge_range(examples) == pytest.approx([0.011027, 0.018496])
    v, f = tube(16, 5)  # a loose skirt of 80 vertices, edges about 10 cm
    coarse = tmp_path / "coarse.obj"
    write_obj(coarse, v, f)
    edge = median_edge_m(Garment(v, f))
    assert edge > EDGE_RANGE_FACTOR * trained[1]
    _, summary, out = _bake(coarse, tmp_path / "coarse", "--method", "model", "--frames", "0:2")
    assert (f"warning: garment '{coarse}' has edges of {edge * 1e3:.1f} mm (median), coarser than model "
            f"'{DEFAULT_MODEL}' was trained on (11.0-18.5 mm): its result may be worse than lbs") in out
    assert summary["deformer"]["training_range"]["edges"] == edge_range_report(Garment(v, f), trained)
    assert not summary["deformer"]["training_range"]["edges"]["within"] and summary["method"] == "model"
    # finer: the same edges' report, the garment scaled down (no bake needed)
    fine = Garment(v * np.float32(0.04), f)
    assert edge_range_report(fine, trained)["within"] is False and edge_range_report(examples[0], trained)["within"]
    assert edge_range_report(fine, None) is None  # a model that records no range: nothing said
    _, summary, out = _bake(ROOT / "examples" / "skirt.obj", tmp_path / "skirt", "--method", "model", "--frames",
                            "0:2")
    assert "has edges of" not in out and summary["deformer"]["training_range"]["edges"]["within"]


def test_a_garment_partly_inside_that_falls_back_to_lbs_is_warned_about_once(tmp_path, caplog):
    """The model's preparation bound the garment and warned that it lies partly inside the body; the lbs it gave
    way to bound it again and warned again, on stderr and in summary.json."""
    import logging

    from formats.obj import read_obj, write_obj

    g = read_obj(ROOT / "examples" / "tshirt.obj")
    centre = g.vertices.mean(axis=0)
    shrunk = tmp_path / "shrunk.obj"
    write_obj(shrunk, centre + 0.9 * (g.vertices - centre), g.faces, g.uvs, g.face_uvs)
    with caplog.at_level(logging.WARNING):
        _, summary, out = _bake(shrunk, tmp_path / "bake", "--model", _restricted_model(tmp_path))
    assert summary["method"] == "lbs" and "baking with lbs instead" in out
    inside = [r for r in caplog.records if "inside the body's rest surface" in r.getMessage()]
    assert len(inside) == 1 and "shrunk.obj" in inside[0].getMessage()
    assert sum("inside the body's rest surface" in w for w in summary["warnings"]) == 1


@pytest.mark.parametrize("layout", ["smplh", "smplx"])
def test_the_model_bakes_on_an_smplh_or_smplx_body_read_on_smpls_joints(layout, tmp_path):
    """An SMPL+H body (the default body with MANO's 15 finger joints on each wrist, as AMASS's bodies have them)
    and an SMPL-X one (jaw and eyes too): the shipped model of SMPL's 24 joints bakes on them (it fell back to
    lbs), reading the body on SMPL's joints (`Body.smpl_view`, said in summary.json): the skirt as on the
    default body to float rounding, also under a motion that curls the fingers (SMPL+H poses)."""
    from core.body import default_body
    from tests.meshes import with_fingers

    path = tmp_path / f"{layout}_like.npz"
    np.savez(path, **with_fingers(default_body(), layout, seed=None))
    run = np.load(ROOT / "examples" / "run.npz")
    poses = np.zeros((len(run["poses"]), 52, 3), np.float32)
    poses[:, :22] = run["poses"].reshape(-1, 24, 3)[:, :22]
    poses[:, 22:] = np.random.default_rng(0).uniform(0, 1.2, (len(poses), 30, 3))  # curled fingers
    curled = tmp_path / "curled.npz"
    np.savez(curled, poses=poses.reshape(len(poses), -1), trans=run["trans"], betas=run["betas"],
             mocap_framerate=run["mocap_framerate"])
    skirt = ROOT / "examples" / "skirt.obj"
    default, _, _ = _bake(skirt, tmp_path / "default")
    for motion in (ROOT / "examples" / "run.npz", curled):
        out = tmp_path / motion.stem
        r = invoke_default(["bake", skirt, motion, "--frames", "0:8", "--out", out, "--no-obj", "--body", path])
        assert r.exit_code == 0, r.output
        d = out / f"skirt_{motion.stem}"
        summary = json.loads((d / "summary.json").read_text())
        assert summary["method"] == "model" and "method_fallback" not in summary
        assert summary["deformer"]["trained_body"]["name"] == "default"  # SMPL's joints of another body
        joints = 52 + 3 * (layout == "smplx")
        assert summary["deformer"]["body_view"].startswith(
            f"body '{layout}_like' ({layout}, {joints} joints) read on SMPL's 24: the fingers follow the wrists")
        baked = read_usd(d / f"skirt_{motion.stem}.usd").tracks["garment"].points
        np.testing.assert_allclose(baked, default, atol=2e-5)


def _default_body_file(path, scale=1.0):
    """The embedded body written as an SMPL-format file, its mesh scaled by `scale` (1: the same body)."""
    from core.body import default_body

    b = default_body()
    kintree = np.stack([b.parents, np.arange(b.n_joints)])
    kintree[0, 0] = 2**32 - 1
    np.savez(path, v_template=b.v_template * np.float32(scale), shapedirs=b.shapedirs, J_regressor=b.J_regressor,
             weights=b.weights, kintree_table=kintree.astype(np.int64), f=b.faces.astype(np.uint32))
    return path


def test_a_body_other_than_the_models_is_warned_about_once_and_recorded(tmp_path, caplog):
    """The shipped model (trained on the embedded body, 'default') on another body of SMPL's joints baked
    without a word: it now says once that its accuracy there is not measured, naming both bodies' hashes, and
    summary.json records both; the embedded body written to a file (another name, the same arrays) is no other
    body. A checkpoint whose meta names no body says nothing."""
    from core.body import default_body
    from formats.checkpoint import load_checkpoint, save_checkpoint

    skirt = ROOT / "examples" / "skirt.obj"
    same = _default_body_file(tmp_path / "same.npz")
    taller = _default_body_file(tmp_path / "taller.npz", 1.03)
    _, summary, _ = _bake(skirt, tmp_path / "same", "--body", same)
    assert "was trained on body" not in caplog.text and "trained_body" not in summary["deformer"]
    _, summary, _ = _bake(skirt, tmp_path / "taller", "--body", taller)
    sha = default_body().content_hash()
    assert caplog.text.count(f"model '{DEFAULT_MODEL}' was trained on body 'default' (sha256 {sha[:8]}), got body 'taller' "
                     "(sha256 ") == 1, caplog.text
    assert "its accuracy on this body is not measured" in caplog.text
    record = summary["deformer"]["trained_body"]
    assert record["name"] == "default" and record["sha256"] == sha and record["body"] == "taller"
    assert record["body_sha256"] not in (None, sha)
    data = load_checkpoint(DEFAULT_MODEL)
    unnamed = save_checkpoint(tmp_path / "unnamed.pt", data["config"], data["model"],
                              {k: v for k, v in data["meta"].items() if k not in ("body", "body_sha256")})
    caplog.clear()
    _, summary, _ = _bake(skirt, tmp_path / "unnamed", "--body", taller, "--model", unnamed)
    assert "was trained on body" not in caplog.text and "trained_body" not in summary["deformer"]


def test_a_model_of_another_skeleton_is_left_for_lbs_unless_asked_for(tmp_path):
    """A model of SMPL+H's 52 joints on the default body of SMPL's 24: the default method bakes with lbs, saying
    why, recorded in summary.json; --method model is one line naming both skeletons (it was "expected a body with
    24 joints" from deep in the model)."""
    import dataclasses

    from formats.checkpoint import save_checkpoint
    from tests.core.model_fixtures import TINY_CONFIG, perturbed_model

    config52 = dataclasses.replace(TINY_CONFIG, n_joints=52)
    model = save_checkpoint(tmp_path / "m52.pt", config52, perturbed_model(config52, 0.2).state_dict())
    skirt = ROOT / "examples" / "skirt.obj"
    default, summary, out = _bake(skirt, tmp_path / "default", "--model", model)
    assert f"model '{model}' was trained for a body of 52 joints, got body 'default' with 24: baking with lbs " \
           "instead" in out
    assert summary["method"] == "lbs" and summary["method_fallback"]["model_joints"] == 52
    lbs, _, _ = _bake(skirt, tmp_path / "lbs", "--method", "lbs")
    np.testing.assert_allclose(default, lbs, atol=1e-6)
    r = invoke_default(["bake", skirt, ROOT / "examples" / "run.npz", "--frames", "0:8", "--model", model,
                        "--method", "model", "--out", tmp_path / "model"])
    assert r.exit_code != 0 and "Traceback" not in r.output and not (tmp_path / "model").exists()
    assert r.output.strip().splitlines()[-1].endswith(
        "got body 'default' with 24: bake with --method lbs (or psd), or train a model on this body "
        "(garment dataset/train --body)")


def test_training_range_shares():
    from core.model_deform import training_range

    w = np.zeros((4, 3))
    w[:, 0] = 1.0
    w[3] = [0.0, 0.2, 0.8]  # one vertex of four mostly on joint 2
    res = training_range(w, coverage=[0.5, 0.3, 0.0], joint_names=["a", "b", "c"])
    assert np.isclose(res["uncovered_share"], 0.2) and res["uncovered_joints"] == ["c"] and not res["within"]
    assert training_range(w, coverage=[0.5, 0.3, 0.02])["within"]


def test_model_option_needs_method_model(tmp_path):
    r = invoke(["bake", EXAMPLES[0], ROOT / "examples" / "walk.npz", "--method", "lbs", "--model", DEFAULT_MODEL,
                "--out", tmp_path])
    assert r.exit_code != 0 and "--model applies to --method model only" in r.output
    assert not any(tmp_path.iterdir())
    # --lbs-smooth with the default method, the model, did nothing
    r = invoke_default(["bake", EXAMPLES[0], ROOT / "examples" / "walk.npz", "--lbs-smooth", 20, "--out", tmp_path])
    assert r.exit_code != 0 and "--lbs-smooth applies to --method lbs only (got --method model)" in r.output
    assert not any(tmp_path.iterdir())


def test_contact_guard_is_the_default_and_can_be_left_out(tmp_path):
    dress = ROOT / "examples" / "dress.obj"
    guarded, summary, _ = _bake(dress, tmp_path / "guarded", "--strain-limit", "off")  # the guard alone
    raw, raw_summary, _ = _bake(dress, tmp_path / "raw", "--no-contact-guard", "--strain-limit", "off")
    assert "contact_guard" in summary["deformer"] and "contact_guard" not in raw_summary["deformer"]
    lifted = np.linalg.norm(guarded - raw, axis=-1)
    # The guard lifts some vertices where the network put them into the body (and their neighbours, less: the
    # spread), leaves the rest as they were, and what it lifts ends outside: fewer vertices inside the body than
    # in the network's raw output.
    moved = summary["deformer"]["contact_guard"]["vertices_moved_per_frame_mean"]
    assert 0 < moved < 0.35 * len(raw[0]) and 0 < (lifted > 1e-3).mean() < 0.25 and (lifted > 1e-6).mean() < 0.6
    np.testing.assert_allclose(moved, (lifted > 1e-4).sum(axis=1).mean(), rtol=0.01)
    assert summary["penetration"]["mean_percent"] < raw_summary["penetration"]["mean_percent"]
    r = invoke(["bake", dress, ROOT / "examples" / "walk.npz", "--method", "lbs", "--no-contact-guard",
                "--out", tmp_path / "bad"])
    assert r.exit_code != 0 and "--no-contact-guard applies to --method model and psd only" in r.output
    assert not (tmp_path / "bad").exists()


def test_missing_default_model_is_one_clear_line(tmp_path, monkeypatch):
    import core.model_deform

    monkeypatch.setattr(core.model_deform, "DEFAULT_MODEL", tmp_path / "gone.pt")
    r = invoke_default(["bake", EXAMPLES[0], ROOT / "examples" / "walk.npz", "--out", tmp_path / "out"])
    assert r.exit_code != 0 and "gone.pt" in r.output and "--method lbs" in r.output
    assert "Traceback" not in r.output and not (tmp_path / "out").exists()


def test_shipped_model_is_small_and_documented():
    assert DEFAULT_MODEL.is_file() and DEFAULT_MODEL.stat().st_size < 20e6
    card = json.loads(DEFAULT_MODEL.with_suffix(".json").read_text())
    for key in ("command", "dataset", "training", "metrics"):
        assert key in card, key


@pytest.mark.parametrize("native", [False, True])
def test_bfloat16_on_a_cpu_without_native_bfloat16_warns_and_is_recorded(tmp_path, monkeypatch, native):
    import core.model_deform

    monkeypatch.setattr(core.model_deform, "native_bfloat16", lambda cpuinfo=None: native)
    points, summary, output = _bake(ROOT / "examples" / "skirt.obj", tmp_path, "--precision", "bfloat16")
    assert summary["deformer"]["precision"] == "bfloat16" and summary["deformer"]["native_bfloat16"] is native
    assert ("no native bfloat16 arithmetic" in output) is not native and np.isfinite(points).all()


def test_native_bfloat16_reads_the_cpu_flags():
    from core.model_deform import native_bfloat16

    assert native_bfloat16("processor : 0\nflags\t\t: fpu sse2 avx2 fma\n") is False  # AVX2-only x86
    assert native_bfloat16("flags : avx2 avx512f avx512_bf16\n") is True
    assert native_bfloat16("flags : avx2 amx_bf16 amx_tile\n") is True
    assert native_bfloat16("Features\t: fp asimd sve bf16 i8mm\n") is True  # Arm
    assert native_bfloat16("Features : fp asimd\n") is False
    assert native_bfloat16("model name : something\n") is None  # no flags line: unknown


def test_device_is_recorded_and_bad_values_are_one_line(tmp_path):
    import torch

    dress = ROOT / "examples" / "dress.obj"
    _, summary, said = _bake(dress, tmp_path / "cpu", "--device", "cpu")
    assert summary["deformer"]["device"] == "cpu" and "ms/frame (model)" in said
    _, summary, _ = _bake(dress, tmp_path / "auto")
    assert summary["deformer"]["device"] == ("cuda:0" if torch.cuda.is_available() else "cpu")
    walk = ROOT / "examples" / "walk.npz"
    for value, said in (("tpu", "expected auto, cpu, cuda or cuda:N, got 'tpu'"),
                        ("cuda:x", "expected auto, cpu, cuda or cuda:N, got 'cuda:x'")):
        r = invoke_default(["bake", dress, walk, "--device", value, "--out", tmp_path / "bad"])
        assert r.exit_code == 2 and "--device" in r.output and said in r.output, r.output
    if not torch.cuda.is_available():
        r = invoke_default(["bake", dress, walk, "--device", "cuda", "--out", tmp_path / "bad"])
        assert r.exit_code == 2 and "no CUDA device is available on this machine" in r.output, r.output
    r = invoke(["bake", dress, walk, "--method", "lbs", "--device", "cpu", "--out", tmp_path / "bad"])
    assert r.exit_code != 0 and "--device applies to --method model only" in r.output
    assert not (tmp_path / "bad").exists()


def test_bfloat16_with_push_out(tmp_path):
    """--precision bfloat16 with --push-out: the network wrapped by the push-out, baked (the CPU's bfloat16 check
    once read the device off the wrapper, which has no network)."""
    _, summary, _ = _bake(ROOT / "examples" / "dress.obj", tmp_path / "b", "--precision", "bfloat16", "--push-out",
                          "--device", "cpu")
    assert summary["deformer"]["precision"] == "bfloat16" and "push_out" in summary["deformer"]


@pytest.mark.skipif(not __import__("torch").cuda.is_available(), reason="needs a CUDA device")
def test_model_on_a_gpu_matches_the_cpu(tmp_path):
    dress = ROOT / "examples" / "dress.obj"
    cpu, _, _ = _bake(dress, tmp_path / "cpu", "--device", "cpu")
    gpu, summary, said = _bake(dress, tmp_path / "gpu", "--device", "cuda")
    assert summary["deformer"]["device"] == "cuda:0" and "ms/frame (model on cuda:0)" in said
    assert summary["deformer"]["contact_guard"]["device"] == "cuda:0"  # per batch, on the GPU
    limited = summary["deformer"]["strain_limit"]
    assert limited["device"] == "cuda:0" and limited["frames_limited"] > 0  # per batch too; the run tears 2 frames
    # float32 on both; the GPU's kernels sum in other orders: far under a millimetre apart without the strain limit,
    # which amplifies rounding where it undoes a tear (millimetres at a few vertices: core/strain.py).
    cpu_raw, _, _ = _bake(dress, tmp_path / "cpu_raw", "--device", "cpu", "--strain-limit", "off")
    gpu_raw, _, _ = _bake(dress, tmp_path / "gpu_raw", "--device", "cuda", "--strain-limit", "off")
    assert np.abs(gpu_raw - cpu_raw).max() < 1e-4, np.abs(gpu_raw - cpu_raw).max()
    _near_after_the_limit(gpu, cpu)
    # Two motions in two worker processes after this process has started CUDA: spawned, each on the GPU.
    r = invoke_default(["bake", dress, ROOT / "examples" / "run.npz", ROOT / "examples" / "walk.npz", "--frames", "0:8",
                        "--out", tmp_path / "workers", "--no-obj", "--no-body", "--device", "cuda", "--workers", "2"])
    assert r.exit_code == 0, r.output
    for motion in ("run", "walk"):
        summary = json.loads((tmp_path / "workers" / f"dress_{motion}" / "summary.json").read_text())
        assert summary["deformer"]["device"] == "cuda:0"
    workers_run = read_usd(tmp_path / "workers" / "dress_run" / "dress_run.usd").tracks["garment"].points
    _near_after_the_limit(workers_run, gpu)  # a GPU's sums (atomic adds) need not repeat their order


def _near_after_the_limit(a, b):
    """Frames of two bakes whose inputs to the strain limit differ by rounding: it passes that on as it comes but
    where a frame's stop at its tolerance falls the other way (up to 0.9 mm measured at a few vertices of a tear:
    core/strain.py), not more on average."""
    apart = np.linalg.norm(a - b, axis=-1)
    assert apart.max() < 0.003 and apart.mean() < 1e-5, (apart.max(), apart.mean())


def test_threads_n_bakes_on_that_count_throughout_and_repeats_bit_for_bit(tmp_path, monkeypatch):
    """--threads N: torch's count set to N for the bake and given back after, no ThreadTuner (the summary has no
    cpu_threads choice; it records N), two bakes the same bits; left out: auto (the tuner's report); --workers
    hands each process N, not the cores shared out; a bad value is one line."""
    import os

    import torch

    import garmentcli.bake as bake_module

    dress = ROOT / "examples" / "dress.obj"
    before = torch.get_num_threads()
    seen = []
    monkeypatch.setattr(torch, "set_num_threads", lambda n, real=torch.set_num_threads: (seen.append(n), real(n)))
    a, summary, _ = _bake(dress, tmp_path / "a", "--threads", "1")
    assert seen[0] == 1 and seen[-1] == before == torch.get_num_threads()
    assert summary["options"]["threads"] == 1 and "cpu_threads" not in summary["deformer"]
    b, _, _ = _bake(dress, tmp_path / "b", "--threads", "1")
    assert np.array_equal(a, b)
    _, summary, _ = _bake(dress, tmp_path / "auto")
    assert summary["options"]["threads"] == "auto" and "chosen" in summary["deformer"]["cpu_threads"]

    specs = []
    monkeypatch.setattr(bake_module, "_bake_in_workers", lambda spec, *rest: specs.append(spec))
    motions = [ROOT / "examples" / "run.npz", ROOT / "examples" / "walk.npz"]
    for extra in (["--threads", "3"], []):
        r = invoke_default(["bake", dress, *motions, "--out", tmp_path / "w", "--workers", "2", *extra])
        assert r.exit_code == 0, r.output
    assert (specs[0].threads, specs[0].threads_fixed) == (3, True)
    assert (specs[1].threads, specs[1].threads_fixed) == (max(1, (os.cpu_count() or 1) // 2), False)

    for value, said in (("0", "expected a number of threads from 1 to 1024 or auto, got '0'"), ("many", "got 'many'")):
        r = invoke_default(["bake", dress, motions[0], "--threads", value, "--out", tmp_path / "bad"])
        assert r.exit_code == 2 and "--threads" in r.output and said in r.output, r.output
        assert "Traceback" not in r.output and not (tmp_path / "bad").exists()


def test_strain_limit_is_the_default_and_can_be_turned_off(tmp_path, monkeypatch):
    """On by default, off with `--strain-limit off`; the limit alone (one pass after the guard's spread rounds, not
    the default's top-up round and limit again after it) moves cloth only in the frames it limits."""
    from core import pushout
    from core.garment import mesh_edges

    dress = ROOT / "examples" / "dress.obj"
    default, _, _ = _bake(dress, tmp_path / "default")
    monkeypatch.setattr(pushout, "GUARD_LIMIT_ALTERNATIONS", 1)
    monkeypatch.setattr(pushout, "GUARD_TOP_UP", False)  # the guard alone, as the limit's first pass sees it
    limited, summary, _ = _bake(dress, tmp_path / "limited")
    raw, raw_summary, _ = _bake(dress, tmp_path / "raw", "--strain-limit", "off")
    report = summary["deformer"]["strain_limit"]
    assert report["limit"] == 1.5 and "strain_limit" not in raw_summary["deformer"]
    assert summary["options"]["strain_limit"] == 1.5 and raw_summary["options"]["strain_limit"] is None
    # The model stretches the dress between the legs on the run; the limit shortens those edges, and only moves
    # cloth in the frames that had one.
    from formats.obj import read_obj

    garment = read_obj(dress)
    edges = mesh_edges(garment.faces)
    rest = np.linalg.norm(garment.vertices[edges[:, 1]] - garment.vertices[edges[:, 0]], axis=1)
    length = lambda p: np.linalg.norm(p[:, edges[:, 1]] - p[:, edges[:, 0]], axis=-1)  # noqa: E731
    assert report["frames_limited"] > 0 and (length(raw) / rest).max() > 1.6 and (length(limited) / rest).max() < 1.6
    moved = np.abs(limited - raw).max(axis=(1, 2)) > 0
    assert moved.sum() == report["frames_limited"] and (length(raw)[~moved] <= 1.5 * rest + 1e-3 + 1e-6).all()
    assert (length(default) / rest).max() < 1.6 and np.abs(default - limited).max() > 1e-3


@pytest.mark.parametrize("value", ["1", "0.5", "nan", "inf", "loose"])
def test_a_bad_strain_limit_is_one_line(tmp_path, value):
    r = invoke_default(["bake", EXAMPLES[0], ROOT / "examples" / "walk.npz", "--strain-limit", value,
                        "--out", tmp_path / "out"])
    assert r.exit_code != 0 and not (tmp_path / "out").exists()
    assert (f"Invalid value for '--strain-limit': expected a number > 1 (an edge's longest, as a multiple of its rest "
            f"length) or 'off', got '{value}'") in r.output


def test_strain_limit_on_lbs_when_asked_and_not_on_the_simulator(tmp_path):
    dress = ROOT / "examples" / "dress.obj"
    _, summary, _ = _bake(dress, tmp_path / "lbs", "--method", "lbs", "--strain-limit", "1.2")
    assert summary["deformer"]["strain_limit"]["limit"] == summary["options"]["strain_limit"] == 1.2
    _, plain, _ = _bake(dress, tmp_path / "plain", "--method", "lbs")
    assert "strain_limit" not in plain["deformer"] and plain["options"]["strain_limit"] is None
    r = invoke(["bake", dress, ROOT / "examples" / "walk.npz", "--method", "sim", "--strain-limit", "1.5",
                "--out", tmp_path / "bad"])
    assert r.exit_code != 0 and "--strain-limit applies to --method lbs, model, psd only" in r.output
    assert not (tmp_path / "bad").exists()


def test_summary_says_whether_the_preprocessing_came_from_the_cache(tmp_path, monkeypatch):
    """bake reuses `garment preprocess`'s cache entry, and said nothing of it: the summary says a miss (computed
    and stored), then a hit."""
    monkeypatch.setenv("GARMENT_CACHE_DIR", str(tmp_path / "cache"))
    skirt = ROOT / "examples" / "skirt.obj"
    _, first, _ = _bake(skirt, tmp_path / "first")
    _, again, _ = _bake(skirt, tmp_path / "again")
    assert (first["deformer"]["preprocess_cache"], again["deformer"]["preprocess_cache"]) == ("miss", "hit")


def test_skip_existing_takes_the_model_defaults_spelled_out(tmp_path):
    """`--model` naming the shipped checkpoint and `--precision float32` are what a model bake without them uses:
    `--skip-existing` took them for other settings ("was baked with --model left out (this run: a file of sha256
    ...)"); a bake recorded before they were spelled out (its settings None) resumes too; another precision not."""
    args = ["bake", ROOT / "examples" / "skirt.obj", ROOT / "examples" / "walk.npz", "--method", "model",
            "--frames", "0:2", "--out", tmp_path, "--no-obj", "--no-body"]
    assert invoke_default(args).exit_code == 0
    summary = tmp_path / "skirt_walk" / "summary.json"
    record = json.loads(summary.read_text())
    assert record["settings"]["precision"] == "float32" and record["settings"]["model_path"].startswith("sha256:")
    r = invoke_default([*args, "--skip-existing", "--model", DEFAULT_MODEL, "--precision", "float32"])
    assert r.exit_code == 0 and "1 of 1 motions already baked, skipped" in r.output, r.output
    record["settings"].update(model_path=None, precision=None)  # as the previous version recorded them
    summary.write_text(json.dumps(record))
    r = invoke_default([*args, "--skip-existing", "--model", DEFAULT_MODEL])
    assert r.exit_code == 0 and "1 of 1 motions already baked, skipped" in r.output, r.output
    r = invoke_default([*args, "--skip-existing", "--precision", "bfloat16"])
    assert r.exit_code != 0 and "was baked with --precision float32 (this run: bfloat16)" in r.output, r.output
    assert json.loads(summary.read_text()) == record  # neither the skips nor the refusal rewrote it
