"""`garment train` and `garment bake --method model` through click's CliRunner."""

import csv
import json
import traceback

import numpy as np
import pytest
import torch
from click.testing import CliRunner

from garmentcli.main import cli
from tests.core.model_fixtures import TINY_CONFIG, copy_recording_body, make_dataset, tube, write_obj
from tests.meshes import tiny_body


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    n = torch.get_num_threads()
    torch.set_num_threads(1)
    root = tmp_path_factory.mktemp("cli")
    data = make_dataset(root / "ds")
    b = tiny_body()
    body = root / "tiny_body.npz"
    np.savez(body, v_template=b.v_template, shapedirs=b.shapedirs, J_regressor=b.J_regressor, weights=b.weights,
             parents=b.parents, faces=b.faces)
    import dataclasses

    cfg = root / "cfg.json"
    cfg.write_text(json.dumps({"model": dataclasses.asdict(TINY_CONFIG),
                               "train": {"frames_per_step": 2, "val_every": 2, "patience": 1, "tolerance": 1.0}}))
    yield root, data, body, cfg
    torch.set_num_threads(n)


def _train(root, data, body, cfg, out, *extra):
    return CliRunner().invoke(cli, ["train", "--data", str(data), "--out", str(out), "--body", str(body),
                                    "--config", str(cfg), *extra])


def test_train_writes_model_log_and_resumes(setup):
    root, data, body, cfg = setup
    out = root / "m.pt"
    r = _train(root, data, body, cfg, out, "--steps", "4", "--checkpoint-every", "2", "--seed", "1")
    assert r.exit_code == 0, r.output
    assert out.is_file() and (root / "m.pt.ckpt").is_file() and (root / "m.pt.json").is_file()
    rows = list(csv.DictReader(open(root / "m.pt.csv")))
    assert [int(x["step"]) for x in rows] == [1, 2, 3, 4]
    r = _train(root, data, body, cfg, out, "--steps", "6", "--checkpoint-every", "2", "--seed", "1", "--resume")
    assert r.exit_code == 0, r.output
    resumed = list(csv.DictReader(open(root / "m.pt.csv")))
    # An uninterrupted 6-step run gives the same rows.
    full = root / "full.pt"
    r = _train(root, data, body, cfg, full, "--steps", "6", "--seed", "1")
    assert r.exit_code == 0, r.output
    assert resumed == list(csv.DictReader(open(root / "full.pt.csv")))
    # The forced plateaus switched phases: the model at the end of each phase was kept, and equals a model
    # the trainer held at that step (it differs from the final one).
    from formats.checkpoint import load_checkpoint

    phase_at = {int(r["step"]): int(r["phase"]) for r in resumed}
    ended = sorted({phase_at[s] for s in phase_at if phase_at.get(s + 1, phase_at[s]) != phase_at[s]})
    assert ended == [1]  # (val every 2 steps, patience 1: phase 1 ends at step 4, phase 2 runs on)
    snap = load_checkpoint(root / "full.phase1.pt")
    assert snap["meta"]["phase"] == 1 and phase_at[snap["meta"]["steps"]] == 1
    # it is a model bake can guard like the final one: it knows its training garments' joints
    assert snap["meta"]["joint_coverage"] == load_checkpoint(full)["meta"]["joint_coverage"]
    # and their edges' lengths (the dataset's garments, as read from it)
    from core.model_deform import garment_edge_range
    from formats.obj import read_obj

    edges = garment_edge_range([read_obj(p) for p in sorted((data / "garments").glob("*.obj"))])
    assert snap["meta"]["garment_edge_m"] == load_checkpoint(full)["meta"]["garment_edge_m"] == edges
    # and the shapes it was trained on: the two training sequences' betas[0] are 0 and 0.5, the rest 0
    shapes = load_checkpoint(full)["meta"]["trained_betas"]
    assert snap["meta"]["trained_betas"] == shapes and shapes["max"][0] == 0.5
    assert shapes["min"] == [0.0] * len(shapes["min"]) and shapes["max"][1:] == [0.0] * (len(shapes["max"]) - 1)
    assert not (root / "full.phase2.pt").exists()
    final = load_checkpoint(full)["model"]
    snap1 = load_checkpoint(root / "full.phase1.pt")["model"]
    assert any(not torch.equal(final[k], snap1[k]) for k in final)
    # bake --method model with the trained file.
    g = root / "g.obj"
    write_obj(g, *tube(12, 6))
    from tests.core.model_fixtures import sequence

    poses, trans, _ = sequence(tiny_body(), *tube(12, 6), 5, 0, None)
    motion = root / "walk.npz"
    np.savez(motion, poses=poses.reshape(5, -1), trans=trans, mocap_framerate=30.0, betas=np.zeros(4))
    r = CliRunner().invoke(cli, ["bake", str(g), str(motion), "--method", "model", "--model", str(out), "--body",
                                 str(body), "--out", str(root / "bake"), "--no-obj"])
    assert r.exit_code == 0, r.output
    assert (root / "bake" / "g_walk" / "summary.json").is_file()


def test_a_resume_is_of_the_same_run_and_its_card_keeps_the_runs_last_validation(setup):
    """--resume with another --seed, learning rate or dataset is refused naming what differs (it trained on the new
    ones and the card recorded them as the whole run's); only --steps may change. Resumed for a step without a
    validation, the card gives the run's last one, read back from the CSV (it said "no validation yet")."""
    from formats.checkpoint import load_checkpoint

    root, data, body, cfg = setup
    out = root / "same.pt"
    assert _train(root, data, body, cfg, out, "--steps", "4", "--seed", "1").exit_code == 0
    other_cfg = root / "cfg_lr.json"
    other_cfg.write_text(json.dumps({**json.loads(cfg.read_text()),
                                     "train": {**json.loads(cfg.read_text())["train"], "lr": 0.05}}))
    other_data = make_dataset(root / "ds_other")
    for extra, named in ((["--seed", "7"], "seed"), (["--config", str(other_cfg)], "lr")):
        r = _train(root, data, body, cfg, out, "--steps", "6", "--seed", "1", "--resume", *extra)
        assert r.exit_code == 1 and f"differs in {named}" in r.output, r.output
    r = CliRunner().invoke(cli, ["train", "--data", str(other_data), "--out", str(out), "--body", str(body),
                                 "--config", str(cfg), "--steps", "6", "--seed", "1", "--resume"])
    assert r.exit_code == 1 and "differs in --data" in r.output, r.output
    rows = list(csv.DictReader(open(root / "same.pt.csv")))
    assert [int(x["step"]) for x in rows] == [1, 2, 3, 4] and rows[3]["val_verts_mm"] not in ("", None)
    r = _train(root, data, body, cfg, out, "--steps", "3", "--seed", "1", "--resume")  # it trained nothing, said done
    assert r.exit_code == 2 and "--steps: 3 is behind the checkpoint" in r.output and "at step 4" in r.output
    r = _train(root, data, body, cfg, out, "--steps", "5", "--seed", "1", "--resume")
    assert r.exit_code == 0 and "no validation yet" not in r.output, r.output
    meta = load_checkpoint(out)["meta"]
    # resumed without --steps or --seed: the run's own (it trained on towards the default 20000 and recorded that;
    # the seed left out was refused as another)
    r = _train(root, data, body, cfg, out, "--resume")
    assert r.exit_code == 0 and load_checkpoint(out)["meta"]["steps"] == 5, r.output
    assert load_checkpoint(out)["meta"]["train_config"]["steps"] == 5
    assert meta["val_verts_mm"] == float(rows[3]["val_verts_mm"])  # a number, as a run never stopped records
    # With lr_final the learning rate's curve spans the run's --steps: another count would bend it at the resume
    # (it fell to lr_final over 13 steps and jumped back to 6e-4 resumed to 30).
    cosine = root / "cfg_cosine.json"
    cosine.write_text(json.dumps({**json.loads(cfg.read_text()),
                                  "train": {**json.loads(cfg.read_text())["train"], "lr_final": 1e-5}}))
    out = root / "cosine.pt"
    assert _train(root, data, body, cosine, out, "--steps", "2", "--seed", "1").exit_code == 0
    r = _train(root, data, body, cosine, out, "--steps", "4", "--seed", "1", "--resume")
    assert r.exit_code == 2 and "decays to lr_final (1e-05) at its --steps (2)" in r.output, r.output


def test_a_resume_drops_a_csv_row_cut_by_a_kill(setup, tmp_path):
    """The CSV is flushed at checkpoints: a kill can leave a row cut inside its step number ('1' of '13,...'),
    which the resume kept as a row of step 1 with no values."""
    root, data, body, cfg = setup
    out = tmp_path / "cut.pt"
    assert _train(root, data, body, cfg, out, "--steps", "2", "--seed", "1").exit_code == 0
    with open(tmp_path / "cut.pt.csv", "a") as fh:
        fh.write("1")
    r = _train(root, data, body, cfg, out, "--steps", "3", "--seed", "1", "--resume")
    assert r.exit_code == 0, r.output
    rows = list(csv.DictReader(open(tmp_path / "cut.pt.csv")))
    assert [int(x["step"]) for x in rows] == [1, 2, 3] and all(x["loss"] for x in rows)


def test_train_time_limit_stops_early_and_resumes(setup):
    root, data, body, cfg = setup
    out = root / "timed.pt"
    r = _train(root, data, body, cfg, out, "--steps", "5", "--seed", "1", "--time-limit", "1e-9")
    assert r.exit_code == 0, r.output
    assert "stopped at the time limit" in r.output
    rows = list(csv.DictReader(open(root / "timed.pt.csv")))
    assert [int(row["step"]) for row in rows] == [1]
    r = _train(root, data, body, cfg, out, "--steps", "5", "--seed", "1", "--resume")
    assert r.exit_code == 0, r.output
    assert [int(row["step"]) for row in csv.DictReader(open(root / "timed.pt.csv"))] == [1, 2, 3, 4, 5]
    for limit in ("0", "nan"):  # nan was taken for no limit
        r = _train(root, data, body, cfg, root / "t2.pt", "--time-limit", limit)
        assert r.exit_code != 0 and "--time-limit" in r.output


@pytest.mark.parametrize("sig, code, what", [("SIGINT", 130, "Ctrl-C"), ("SIGTERM", 143, "SIGTERM")])
def test_train_ctrl_c_writes_the_checkpoint_and_resumes(setup, monkeypatch, sig, code, what):
    """Ctrl-C (SIGINT), or a scheduler's SIGTERM, finishes the step and stops as --time-limit does: checkpoint and
    model written, one line says so, --resume continues; Ctrl-C used to leave MODEL.json and MODEL.csv of a model
    never written, no checkpoint, and SIGTERM killed the run at once."""
    import os
    import signal

    from core.train import Trainer

    root, data, body, cfg = setup
    out = root / f"{sig}.pt"
    real_step = Trainer.train_step

    def step_then_signal(self):
        real_step(self)
        if self.step == 2:
            os.kill(os.getpid(), getattr(signal, sig))

    monkeypatch.setattr(Trainer, "train_step", step_then_signal)
    r = _train(root, data, body, cfg, out, "--steps", "5", "--seed", "1", "--checkpoint-every", "0")
    monkeypatch.undo()
    assert r.exit_code == code and f"interrupted ({what})" in r.output and f"{sig}.pt.ckpt" in r.output, r.output
    assert len(r.output.strip().splitlines()) == 1
    assert out.is_file() and (root / f"{sig}.pt.ckpt").is_file() and (root / f"{sig}.pt.json").is_file()
    assert [int(row["step"]) for row in csv.DictReader(open(root / f"{sig}.pt.csv"))] == [1, 2]
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL or sig == "SIGINT"  # the handlers are restored
    r = _train(root, data, body, cfg, out, "--steps", "3", "--seed", "1", "--resume")
    assert r.exit_code == 0, r.output
    assert [int(row["step"]) for row in csv.DictReader(open(root / f"{sig}.pt.csv"))] == [1, 2, 3]


def test_train_under_torchrun_stops_at_ctrl_c_with_its_checkpoint(setup, tmp_path):
    """Ctrl-C in the terminal of a torchrun run reaches the launcher and every worker (one process group), and the
    launcher forwards it to them once more: the workers finish the step together (rank 0 decides), rank 0 writes
    the checkpoint and the model. It used to kill them mid-step with nothing written since the last checkpoint."""
    import os
    import shutil
    import signal
    import subprocess
    import sys
    import time

    root, data, body, cfg = setup
    out = tmp_path / "ddp.pt"
    garment = shutil.which("garment") or pytest.skip("the garment command is not on PATH")
    proc = subprocess.Popen([sys.executable, "-m", "torch.distributed.run", "--standalone", "--nproc_per_node", "2",
                             garment, "train", "--data", str(data), "--out", str(out), "--body", str(body),
                             "--config", str(cfg), "--steps", "100000", "--checkpoint-every", "0"],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True,
                            env={**os.environ, "OMP_NUM_THREADS": "1"})
    csv_path = out.with_name("ddp.pt.csv")
    try:
        end = time.monotonic() + 120
        while time.monotonic() < end and proc.poll() is None:
            if csv_path.is_file() and len(csv_path.read_text().splitlines()) > 3:  # header and a few steps
                break
            time.sleep(0.2)
        assert proc.poll() is None, proc.communicate()[0]
        os.killpg(proc.pid, signal.SIGINT)  # what the terminal does at Ctrl-C
        output = proc.communicate(timeout=60)[0]
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode != 0
    assert "interrupted (Ctrl-C): checkpoint" in output, output
    steps = [int(row["step"]) for row in csv.DictReader(open(csv_path))]
    assert out.is_file() and out.with_name("ddp.pt.ckpt").is_file() and 3 <= len(steps) < 100000
    from formats.checkpoint import load_checkpoint

    assert load_checkpoint(out)["meta"]["steps"] == steps[-1]


def test_train_aborted_leaves_no_json_of_a_model_never_written(setup, monkeypatch):
    """A second Ctrl-C stops training at once: exit 130 as the README says (click made it 1), and no .json nor
    loss CSV of a model never written (no checkpoint either: the CSV's rows were of weights that are nowhere)."""
    from core.train import Trainer

    root, data, body, cfg = setup

    def abort(self):
        raise KeyboardInterrupt  # a second Ctrl-C: stops at once

    monkeypatch.setattr(Trainer, "train_step", abort)
    r = _train(root, data, body, cfg, root / "aborted.pt", "--steps", "5")
    assert r.exit_code == 130 and "Aborted" in r.output, r.output
    assert not list(root.glob("aborted.pt*"))


def test_train_device_option(setup):
    root, data, body, cfg = setup
    r = _train(root, data, body, cfg, root / "d.pt", "--device", "tpu")
    assert r.exit_code != 0 and "--device" in r.output and "'tpu'" in r.output
    if not torch.cuda.is_available():
        r = _train(root, data, body, cfg, root / "d.pt", "--device", "cuda")
        assert r.exit_code != 0 and "no CUDA device" in r.output and not (root / "d.pt").exists()


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device")
def test_train_on_a_gpu_follows_the_cpu(setup):
    """Three phases' worth of steps on the GPU: the same losses as on the CPU at the first step (one initialisation,
    on the CPU, from the seed), a model written and loadable on the CPU."""
    root, data, body, cfg = setup
    runs = {}
    for device in ("cpu", "cuda"):
        out = root / f"{device}.pt"
        r = _train(root, data, body, cfg, out, "--steps", "4", "--seed", "3", "--device", device)
        assert r.exit_code == 0, (r.output, "".join(traceback.format_exception(*r.exc_info)) if r.exc_info else "")
        runs[device] = list(csv.DictReader(open(root / f"{device}.pt.csv")))
    assert json.loads((root / "cuda.pt.json").read_text())["device"].startswith("cuda")
    first_cpu, first_gpu = float(runs["cpu"][0]["loss"]), float(runs["cuda"][0]["loss"])
    assert abs(first_gpu - first_cpu) <= 1e-3 * abs(first_cpu), (first_cpu, first_gpu)
    from formats.checkpoint import load_model

    model, _ = load_model(root / "cuda.pt")
    assert next(model.parameters()).device.type == "cpu"


def test_train_phases_come_from_the_config_unless_given(setup):
    """--phases left out took its shown default, 1,2,3, over the phases --config names: the config's now, and
    --phases given overrides them."""
    from formats.checkpoint import load_checkpoint

    root, data, body, cfg = setup
    one = root / "cfg_phase1.json"
    one.write_text(json.dumps({**json.loads(cfg.read_text()),
                               "train": {**json.loads(cfg.read_text())["train"], "phases": [1]}}))
    assert _train(root, data, body, one, root / "p1.pt", "--steps", "1").exit_code == 0
    assert list(load_checkpoint(root / "p1.pt")["meta"]["train_config"]["phases"]) == [1]
    assert _train(root, data, body, one, root / "p12.pt", "--steps", "1", "--phases", "1,2").exit_code == 0
    assert list(load_checkpoint(root / "p12.pt")["meta"]["train_config"]["phases"]) == [1, 2]


def test_train_bad_inputs(setup):
    root, data, body, cfg = setup
    r = _train(root, data, body, cfg, root / "x.pt", "--phases", "2,3")
    assert r.exit_code != 0 and "--phases" in r.output
    r = CliRunner().invoke(cli, ["train", "--data", str(root / "nope"), "--out", str(root / "y.pt")])
    assert r.exit_code != 0 and "nope" in r.output
    bad = root / "bad.json"
    bad.write_text(json.dumps({"train": {"speed": 3}}))
    r = _train(root, data, body, bad, root / "z.pt")
    assert r.exit_code != 0 and "unknown key 'speed'" in r.output and "Traceback" not in r.output
    r = _train(root, data, body, cfg, root / "never.pt", "--resume")  # (it named the resume state a model)
    assert r.exit_code == 1 and r.output.strip().splitlines()[-1] == (
        f"Error: --resume: expected the resume state '{root / 'never.pt.ckpt'}' of an earlier run to --out, found "
        "none (a run writes it at its checkpoints and when stopped)")
    assert not list(root.glob("never.pt*"))
    junk = root / "junk.pt"
    junk.write_bytes(b"junk")
    r = CliRunner().invoke(cli, ["bake", str(root / "g.obj"), str(root / "walk.npz"), "--method", "model", "--model",
                                 str(junk), "--body", str(body), "--out", str(root / "b2")])
    assert r.exit_code != 0 and "junk.pt" in r.output


def test_train_refuses_an_existing_out_an_empty_one_and_absurd_threads_or_seed(setup, tmp_path):
    """--out naming a file that exists (a garment, the shipped model: it was replaced) without --resume, --out '',
    --threads 2**31 (overflowed torch's int; 100000 killed the process as torch made them), --seed -1: one line, nothing written."""
    root, data, body, cfg = setup
    garment = tmp_path / "garment.obj"
    garment.write_text("v 0 0 0\n")
    r = _train(root, data, body, cfg, garment, "--steps", 1)
    assert r.exit_code != 0 and isinstance(r.exception, SystemExit) and f"output '{garment}' exists" in r.output
    assert garment.read_text() == "v 0 0 0\n" and not (tmp_path / "garment.obj.ckpt").exists()
    for extra, needle in (([], "an empty argument after '--out'"), (["--threads", 2**31], "from 1 to 1024"), (["--seed", -1], "0<=x<=4294967295")):
        out = "" if not extra else tmp_path / "m.pt"
        r = _train(root, data, body, cfg, out, "--steps", 1, *extra)
        assert r.exit_code != 0 and isinstance(r.exception, SystemExit), (extra, r.output)
        assert needle in r.output and not (tmp_path / "m.pt").exists(), (extra, r.output)


def test_train_config_binary_or_badly_typed_is_one_line(setup):
    root, data, body, cfg = setup
    binary = root / "binary.npz"
    np.savez(binary, poses=np.zeros((2, 72)))
    cases = [(binary, "binary"),
             (root / "badval.json", "'lr': expected a finite number, got 'fast'"),
             (root / "badint.json", "'steps': expected an integer"),
             (root / "badmodel.json", "'hidden': expected an integer")]
    cases[1][0].write_text(json.dumps({"train": {"lr": "fast"}}))
    cases[2][0].write_text(json.dumps({"train": {"steps": 2.5}}))
    cases[3][0].write_text(json.dumps({"model": {"hidden": "wide"}}))
    for path, want in cases:
        r = _train(root, data, body, path, root / "never.pt")
        assert r.exit_code != 0 and isinstance(r.exception, SystemExit), r.output  # no traceback
        assert "--config" in r.output and path.name in r.output and want in r.output, r.output
        assert not (root / "never.pt").exists()


def test_train_init_starts_from_a_model(setup):
    root, data, body, cfg = setup
    from formats.checkpoint import load_checkpoint

    base = root / "base.pt"
    r = _train(root, data, body, cfg, base, "--steps", "3", "--seed", "2")
    assert r.exit_code == 0, r.output
    # With a vanishing learning rate one step leaves the weights where they started: the base model's
    # (a run without --init starts from the seed's initialisation instead).
    tiny_lr = root / "tiny_lr.json"
    tiny_lr.write_text(json.dumps({"train": {**json.loads(cfg.read_text())["train"], "lr": 1e-12}}))
    tuned = root / "tuned.pt"
    r = CliRunner().invoke(cli, ["train", "--data", str(data), "--out", str(tuned), "--body", str(body), "--config",
                                 str(tiny_lr), "--init", str(base), "--steps", "1", "--seed", "1"])
    assert r.exit_code == 0, r.output
    b, t = load_checkpoint(base), load_checkpoint(tuned)
    assert t["config"] == b["config"]
    assert all(torch.allclose(t["model"][k], b["model"][k], atol=1e-9) for k in b["model"])
    assert t["meta"]["init"] == str(base) and json.loads((root / "tuned.pt.json").read_text())["init"] == str(base)
    from core.provenance import file_sha256

    assert t["meta"]["init_sha256"] == file_sha256(base)  # by content: a later file of that name is another
    # the base was trained on the same garments: the coverage is the data's either way
    assert t["meta"]["joint_coverage"] == pytest.approx(b["meta"]["joint_coverage"])
    fresh = root / "fresh.pt"
    r = CliRunner().invoke(cli, ["train", "--data", str(data), "--out", str(fresh), "--body", str(body), "--config",
                                 str(cfg), "--steps", "1", "--seed", "1"])
    assert r.exit_code == 0, r.output
    f = load_checkpoint(fresh)["model"]
    assert any(not torch.allclose(f[k], b["model"][k], atol=1e-6) for k in f)
    # --config may add the shape input and pose codes to an --init network: it starts as that network
    # (zero-initialised layers).
    add_shape = root / "add_shape.json"
    add_shape.write_text(json.dumps({"model": {"shape_input": 1, "pose_codes": 1},
                                     "train": json.loads(tiny_lr.read_text())["train"]}))
    r = CliRunner().invoke(cli, ["train", "--data", str(data), "--out", str(root / "shape.pt"), "--body", str(body),
                                 "--config", str(add_shape), "--init", str(base), "--steps", "1", "--seed", "1"])
    assert r.exit_code == 0, r.output
    s = load_checkpoint(root / "shape.pt")
    assert s["config"] == {**b["config"], "shape_input": 1, "pose_codes": 1}
    assert all(torch.allclose(s["model"][k], b["model"][k], atol=1e-9) for k in b["model"])
    assert sorted(set(s["model"]) - set(b["model"])) == ["pose_codes.bias", "pose_codes.weight", "shape_code.bias",
                                                          "shape_code.weight"]
    # Weights may be missing only for an input this --config adds: a network that claims the shape input
    # but lacks its layer is refused.
    broken = load_checkpoint(root / "shape.pt")
    del broken["model"]["shape_code.weight"]
    torch.save(broken, root / "broken_shape.pt")
    r = CliRunner().invoke(cli, ["train", "--data", str(data), "--out", str(root / "t7.pt"), "--body", str(body),
                                 "--init", str(root / "broken_shape.pt"), "--steps", "1"])
    assert r.exit_code != 0 and "--init" in r.output and "shape_code.weight" in r.output
    assert not (root / "t7.pt").exists()
    # The network comes from --init: a model section in --config is refused, as is a file that is no model.
    r = _train(root, data, body, cfg, root / "t3.pt", "--init", str(base))
    assert r.exit_code != 0 and "--init" in r.output and "'model' section" in r.output
    junk = root / "junk_init.pt"
    junk.write_bytes(b"junk")
    r = CliRunner().invoke(cli, ["train", "--data", str(data), "--out", str(root / "t4.pt"), "--body", str(body),
                                 "--init", str(junk)])
    assert r.exit_code != 0 and "junk_init.pt" in r.output and not (root / "t4.pt").exists()
    # A network made for another skeleton is refused up front, from --init as from --config.
    other = load_checkpoint(base)
    other["config"]["n_joints"] += 1
    other_path = root / "other_skeleton.pt"
    torch.save(other, other_path)
    r = CliRunner().invoke(cli, ["train", "--data", str(data), "--out", str(root / "t5.pt"), "--body", str(body),
                                 "--init", str(other_path)])
    assert r.exit_code != 0 and "--init" in r.output and "joints" in r.output and not (root / "t5.pt").exists()
    other_cfg = root / "other_skeleton.json"
    values = json.loads(cfg.read_text())
    values["model"]["n_joints"] = other["config"]["n_joints"]
    other_cfg.write_text(json.dumps(values))
    r = _train(root, data, body, other_cfg, root / "t6.pt")
    assert r.exit_code != 0 and "--config" in r.output and "joints" in r.output and "Traceback" not in r.output


def test_train_init_with_fewer_levels_keeps_the_finer_ones(setup):
    """--init with a smaller "levels" in --config starts from the model's weights without its deeper levels'
    (the 0- and 1-level rows of the tradeoff from the shipped model); more levels than it has are refused."""
    root, data, body, cfg = setup
    from formats.checkpoint import load_checkpoint

    base = root / "levels_base.pt"
    r = _train(root, data, body, cfg, base, "--steps", "1", "--seed", "3")
    assert r.exit_code == 0, r.output
    b = load_checkpoint(base)
    assert b["config"]["levels"] == 1
    train_values = {**json.loads(cfg.read_text())["train"], "lr": 1e-12}
    fewer = root / "levels0.json"
    fewer.write_text(json.dumps({"model": {"levels": 0}, "train": train_values}))
    r = CliRunner().invoke(cli, ["train", "--data", str(data), "--out", str(root / "l0.pt"), "--body", str(body),
                                 "--config", str(fewer), "--init", str(base), "--steps", "1", "--seed", "1"])
    assert r.exit_code == 0, r.output
    t = load_checkpoint(root / "l0.pt")
    assert t["config"] == {**b["config"], "levels": 0}
    dropped = sorted(set(b["model"]) - set(t["model"]))
    assert dropped and all(k.startswith(("unet.down.0.", "unet.merge.0.", "unet.up.0.")) for k in dropped)
    assert set(t["model"]) <= set(b["model"])
    assert all(torch.allclose(t["model"][k], b["model"][k], atol=1e-9) for k in t["model"])
    more = root / "levels2.json"
    more.write_text(json.dumps({"model": {"levels": 2}, "train": train_values}))
    r = CliRunner().invoke(cli, ["train", "--data", str(data), "--out", str(root / "l2.pt"), "--body", str(body),
                                 "--config", str(more), "--init", str(base), "--steps", "1"])
    assert r.exit_code != 0 and "'levels'" in r.output and "levels2.json" in r.output and "got 2" in r.output
    assert not (root / "l2.pt").exists()


def test_train_partial_uses_the_sequences_simulated_so_far(setup, tmp_path):
    """A dataset whose run has not finished (a training sequence missing) is refused, naming --partial; with it
    the model trains on the others and records what was missing; a split with nothing simulated is refused."""
    import shutil

    root, data, body, cfg = setup
    part = tmp_path / "part"
    shutil.copytree(data, part)
    (part / "sequences" / "s1.npz").unlink()
    r = _train(root, part, body, cfg, tmp_path / "m.pt", "--steps", "2")
    assert r.exit_code != 0 and "1 of 3 sequences are missing (e.g. 's1')" in r.output and "--partial" in r.output
    assert not (tmp_path / "m.pt").exists()
    r = _train(root, part, body, cfg, tmp_path / "m.pt", "--steps", "2", "--partial")
    assert r.exit_code == 0, r.output
    from formats.checkpoint import load_checkpoint

    meta = load_checkpoint(tmp_path / "m.pt")["meta"]
    assert meta["sequences"] == {"train": 1, "val": 1} and meta["sequences_missing"] == {"train": 1, "val": 0}
    assert meta["lead_in_s"] is None  # a manifest without `garment dataset`'s settings: the default lead-in
    from formats.body import load_body

    assert meta["body_sha256"] == load_body(body).content_hash()  # what `bake` checks its body against
    assert meta["sequences_per_step"] == 1 and "sequences_before_resume" not in meta
    assert meta["init_sha256"] is None and meta["software"]["torch"] == torch.__version__  # what made it
    # Resumed once the missing sequence is there: said, and the card keeps the counts the steps before trained on
    # (it read as if the whole run had had them all)
    shutil.copy(data / "sequences" / "s1.npz", part / "sequences" / "s1.npz")
    r = _train(root, part, body, cfg, tmp_path / "m.pt", "--steps", "3", "--partial", "--resume")
    assert r.exit_code == 0 and "note: --resume: the dataset holds {'train': 2, 'val': 1} sequences" in r.output
    meta = load_checkpoint(tmp_path / "m.pt")["meta"]
    assert meta["sequences"] == {"train": 2, "val": 1} and meta["sequences_before_resume"] == {"train": 1, "val": 1}
    (part / "sequences" / "s2.npz").unlink()
    r = _train(root, part, body, cfg, tmp_path / "n.pt", "--steps", "2", "--partial")
    assert r.exit_code != 0 and "expected sequences in its 'val' split, got none simulated yet" in r.output


def test_train_records_the_datasets_settle_blend_as_the_models_lead_in(setup, tmp_path):
    """Its training sequences start with the dataset's settle blend, so a bake gives the model's window the same."""
    import shutil

    from core.model_deform import load_model_deformer
    from formats.checkpoint import load_checkpoint

    root, data, body, cfg = setup
    copy = tmp_path / "ds"
    shutil.copytree(data, copy)
    manifest = json.loads((copy / "manifest.json").read_text())
    manifest["settings"] = {"settle": 3, "fps": 30.0}
    (copy / "manifest.json").write_text(json.dumps(manifest))
    r = _train(root, copy, body, cfg, tmp_path / "m.pt", "--steps", "2")
    assert r.exit_code == 0, r.output
    assert load_checkpoint(tmp_path / "m.pt")["meta"]["lead_in_s"] == 0.1
    assert load_model_deformer(tmp_path / "m.pt").lead_in_s == 0.1


def test_train_garment_trains_on_that_garments_sequences_only(setup, tmp_path):
    """--garment NAME: a garment's own fine-tune; a name the dataset has no sequences of is refused, naming them."""
    from formats.checkpoint import load_checkpoint

    root, data, body, cfg = setup
    r = _train(root, data, body, cfg, tmp_path / "a.pt", "--steps", "2", "--garment", "a")
    assert r.exit_code == 0, r.output
    meta = load_checkpoint(tmp_path / "a.pt")["meta"]
    assert meta["garments"] == ["a"] and meta["sequences"] == {"train": 2, "val": 0}
    r = _train(root, data, body, cfg, tmp_path / "z.pt", "--steps", "2", "--garment", "z")
    assert r.exit_code != 0 and "expected a garment of its sequences (a, b), got 'z'" in r.output
    assert "Traceback" not in r.output and not (tmp_path / "z.pt").exists()


def test_train_on_several_datasets(setup, tmp_path):
    """--data A --data B: trained on together; the card records both; a missing one is named."""
    import shutil

    from formats.checkpoint import load_checkpoint

    root, data, body, cfg = setup
    other = tmp_path / "other"
    shutil.copytree(data, other)
    manifest = json.loads((other / "manifest.json").read_text())
    manifest["items"] = [rec for rec in manifest["items"] if rec["garment"] == "a"]
    for rec in manifest["items"]:
        (other / rec["file"]).rename(other / "sequences" / f"x{rec['id']}.npz")
        rec["id"], rec["file"] = f"x{rec['id']}", f"sequences/x{rec['id']}.npz"
    (other / "manifest.json").write_text(json.dumps(manifest))
    r = _train(root, data, body, cfg, tmp_path / "m.pt", "--steps", "2", "--data", str(other))
    assert r.exit_code == 0, r.output
    meta = load_checkpoint(tmp_path / "m.pt")["meta"]
    assert meta["data"] == [str(data), str(other)] and meta["sequences"] == {"train": 4, "val": 1}
    assert json.loads((tmp_path / "m.pt.json").read_text())["data"] == [str(data), str(other)]
    r = _train(root, data, body, cfg, tmp_path / "n.pt", "--steps", "2", "--data", str(tmp_path / "nowhere"))
    assert r.exit_code != 0 and f"expected a dataset directory, got '{tmp_path / 'nowhere'}' (not found)" in r.output
    assert not (tmp_path / "n.pt").exists()


def test_train_refuses_a_body_other_than_the_datasets(setup, tmp_path):
    """A dataset records the body it was simulated on (`inputs.body`: its file's sha256, None for the embedded
    one): training against another body (--body forgotten, or another file of the same name) is refused in one
    line naming both; the dataset's own body passes."""
    root, data, body, cfg = setup
    ds = copy_recording_body(data, body, tmp_path / "ds")
    r = CliRunner().invoke(cli, ["train", "--data", str(ds), "--out", str(tmp_path / "a.pt"), "--config", str(cfg),
                                 "--steps", "1"])
    assert r.exit_code != 0 and "Traceback" not in r.output
    assert f"dataset '{ds}' was simulated on body '{body}' (file sha256 " in r.output and "the embedded default" in r.output
    assert not (tmp_path / "a.pt").exists()
    r = _train(root, ds, body, cfg, tmp_path / "b.pt", "--steps", "1")
    assert r.exit_code == 0, r.output


def test_train_threads_fixed_or_chosen_while_it_trains(setup, monkeypatch):
    """--threads N trains on N threads and gives torch its count back; auto hands the steps to a ThreadTuner (its
    choice recorded in the model's meta, said at the end); a bad value, or auto off the CPU, is one line."""
    import core.threads
    from formats.checkpoint import load_checkpoint

    root, data, body, cfg = setup
    before = torch.get_num_threads()
    seen = []
    monkeypatch.setattr(torch, "set_num_threads", lambda n, real=torch.set_num_threads: (seen.append(n), real(n)))
    r = _train(root, data, body, cfg, root / "t1.pt", "--steps", "2", "--threads", "2")
    assert r.exit_code == 0, r.output
    assert seen[0] == 2 and seen[-1] == before == torch.get_num_threads()
    assert load_checkpoint(root / "t1.pt")["meta"]["threads"] == {"fixed": 2}
    monkeypatch.setattr(core.threads, "WARMUP_BATCHES", 1)
    monkeypatch.setattr(core.threads, "TRIAL_BATCHES", 1)
    torch.set_num_threads(2)  # the counts tried: 2 and 1
    try:
        r = _train(root, data, body, cfg, root / "ta.pt", "--steps", "12", "--threads", "auto")
        assert r.exit_code == 0, r.output
        threads = load_checkpoint(root / "ta.pt")["meta"]["threads"]
        assert threads["most"] == 2 and threads["rounds"] >= 1, threads
        assert set(threads["frames_by_threads"]) == {"1", "2"}, threads  # the steps ran on both counts
        assert f"threads chosen: {threads['chosen']}" in r.output and torch.get_num_threads() == 2
    finally:
        torch.set_num_threads(before)
    for value, needle in (("0", "expected a number of threads from 1 to 1024 or auto, got '0'"),
                          ("many", "got 'many'")):
        r = _train(root, data, body, cfg, root / "tb.pt", "--threads", value)
        assert r.exit_code != 0 and "--threads" in r.output and needle in r.output and "Traceback" not in r.output
    if not torch.cuda.is_available():  # auto chooses a CPU's threads; the device is refused first otherwise
        return
    r = _train(root, data, body, cfg, root / "tb.pt", "--threads", "auto", "--device", "cuda")
    assert r.exit_code != 0 and "auto chooses the threads of one process on the CPU" in r.output


def test_a_manifest_that_is_no_object_or_a_sequence_with_a_nan_is_one_line_for_train_and_fit(setup, tmp_path):
    """A manifest.json of a list (a traceback in fit, train and dataset), an item without an id (fit: a KeyError;
    train refused it), a NaN in a simulated sequence (fit blamed --ridge; train wrote a model of NaN weights and
    exited 0): one line each naming the file, nothing written."""
    import shutil

    root, data, body, cfg = setup
    garment = data / "garments" / "a.obj"
    for case in ("list", "no id", "nan"):
        copy = tmp_path / case.replace(" ", "_")
        shutil.copytree(data, copy)
        manifest = json.loads((copy / "manifest.json").read_text())
        if case == "list":
            (copy / "manifest.json").write_text("[]")
            expected = "expected a JSON object (settings, items, ...), got a list"
        elif case == "no id":
            manifest["items"] = [{k: v for k, v in it.items() if k != "id"} for it in manifest["items"]]
            (copy / "manifest.json").write_text(json.dumps(manifest))
            expected = "expected items with an 'id'"
        else:
            from formats.dataset import sequence_path

            item = next(it for it in manifest["items"] if it["split"] == "train")
            path = sequence_path(copy, item["id"])
            arrays = dict(np.load(path))
            arrays["positions"][1, 0, 0] = np.nan
            np.savez(path, **arrays)
            expected = "expected finite 'positions', got NaN or Inf (first at frame 1)"
        runs = {"train": _train(root, copy, body, cfg, tmp_path / f"{case}.pt", "--steps", "2"),
                "fit": CliRunner().invoke(cli, ["fit", str(garment), "--data", str(copy), "--body", str(body),
                                                "--out", str(tmp_path / f"{case}.npz")])}
        for command, r in runs.items():
            lines = [line for line in r.output.splitlines() if line.startswith("Error")]
            assert r.exit_code != 0 and len(lines) == 1 and expected in lines[0], (case, command, r.output)
        assert not (tmp_path / f"{case}.pt").exists() and not (tmp_path / f"{case}.npz").exists()



@pytest.mark.parametrize("where", ["train", "val"])
def test_training_that_diverges_stops_writing_no_model(setup, tmp_path, monkeypatch, where):
    """Training that went non-finite (a sequence 1e30 m off, before such a sequence was refused at load) trained on
    NaN to the last step, then wrote a model of NaN weights, exited 0 and printed 'validation E_verts nan mm'. Now
    the first loss (or validation error) that is not finite stops the run in one line naming the step (and the
    item); no model, nor its card. The loss (from the second step) or the validation error is made infinite here."""
    import core.train

    root, data, body, cfg = setup
    if where == "train":
        total_loss, calls = core.train.total_loss, []

        def diverging(*args):  # finite at the first step, inf from the second
            calls.append(1)
            return total_loss(*args) * (float("inf") if len(calls) > 1 else 1.0)

        monkeypatch.setattr(core.train, "total_loss", diverging)
    else:
        monkeypatch.setattr(core.train.Trainer, "validate", lambda self: {"val_verts_mm": float("inf")})
    out = tmp_path / "m.pt"
    r = _train(root, data, body, cfg, out, "--steps", "4")
    lines = [line for line in r.output.splitlines() if line.startswith("Error")]
    said = "training diverged at step 2: the loss is inf (its sum) on item 's" if where == "train" else \
        "training diverged at step 2: the validation error is not finite (val_verts_mm inf"
    assert r.exit_code == 1 and len(lines) == 1 and said in lines[0], r.output
    assert "the model not written" in lines[0] and "Traceback" not in r.output
    assert not out.exists() and not out.with_name("m.pt.json").exists()


@pytest.mark.parametrize("where", ["train", "val"])
@pytest.mark.parametrize("off_m", [1e30, 100.0])
def test_a_sequence_far_off_is_refused_before_training(setup, tmp_path, where, off_m):
    """A sequence finite but far off (a simulation that blew up and stayed finite): 1e30 m trained on NaN (then
    stopped by its loss), 100 m gave a finite loss and was trained on. Now the dataset's load refuses it, naming the
    sequence, the vertex, the frame and how far; nothing written."""
    import shutil

    from formats.dataset import sequence_path

    root, data, body, cfg = setup
    copy = tmp_path / "far"
    shutil.copytree(data, copy)
    manifest = json.loads((copy / "manifest.json").read_text())
    item = next(it for it in manifest["items"] if it["split"] == where)
    path = sequence_path(copy, item["id"])
    arrays = dict(np.load(path))
    arrays["positions"][5, 3, 0] += off_m
    np.savez(path, **arrays)
    out = tmp_path / "m.pt"
    r = _train(root, copy, body, cfg, out, "--steps", "4")
    lines = [line for line in r.output.splitlines() if line.startswith("Error")]
    assert r.exit_code == 1 and len(lines) == 1 and "Traceback" not in r.output, r.output
    assert f"dataset sequence '{path}': expected its cloth within 2 times the garment's size" in lines[0], lines
    assert f"got vertex 3 {off_m:.4g} m from it at frame 5" in lines[0] or \
        (off_m == 100 and "got vertex 3 99." in lines[0] and "m from it at frame 5" in lines[0]), lines
    assert not out.exists() and not out.with_name("m.pt.json").exists()
    # the sequence as simulated (its cloth within the bound) trains
    np.savez(path, **dict(np.load(sequence_path(data, item["id"]))))
    assert _train(root, copy, body, cfg, out, "--steps", "2").exit_code == 0


def test_a_step_beyond_the_free_memory_is_warned_of_naming_the_frames_that_fit(setup, tmp_path, monkeypatch):
    """A step's frames are held at once: 64 frames of the example t-shirt took 15 GB, and a step beyond the
    memory was killed by the kernel at its first step, without a word. Now warned of before the first step, naming
    the frames that fit by the estimate (a warning: the estimate is fitted on the shipped configuration); a
    container's memory limit counts."""
    import psutil

    import garmentcli.train
    from core.train import step_memory

    root, data, body, cfg = setup
    largest = 72  # garment 'a' (12 x 6 vertices) of the train split; 'b' (50) is the validation's
    need = step_memory(largest, 2, 8)  # frames_per_step 2 (setup's config), TINY_CONFIG's width 8
    one = step_memory(largest, 1, 8)
    memory = type("Memory", (), {})
    memory.total, memory.available = 64e9, one + 1.0
    monkeypatch.setattr(psutil, "virtual_memory", lambda: memory)
    r = _train(root, data, body, cfg, tmp_path / "m.pt", "--steps", "2")
    assert r.exit_code == 0 and (tmp_path / "m.pt").is_file(), r.output
    assert (f"warning: frames_per_step 2: a training step of garment 'a' (72 vertices) holds about {need / 1e9:.3g} "
            f"GB, {memory.available / 1e9:.3g} GB is free (64 GB in all): the run may be killed; at most 1 frames "
            "fit by the estimate (set frames_per_step in --config)") in r.output, r.output
    memory.available = 64e9  # free, but a container's limit below the step
    monkeypatch.setattr(garmentcli.train, "_container_memory_limit", lambda: one + 1.0)
    r = _train(root, data, body, cfg, tmp_path / "m2.pt", "--steps", "2")
    assert r.exit_code == 0 and "(0.5 GB in all): the run may be killed" in r.output, r.output
    monkeypatch.setattr(garmentcli.train, "_container_memory_limit", lambda: None)
    r = _train(root, data, body, cfg, tmp_path / "m3.pt", "--steps", "2")
    assert r.exit_code == 0 and "warning: frames_per_step" not in r.output, r.output


def test_step_memory_grows_with_frames_vertices_and_width():
    from core.train import STEP_BASE_BYTES, frames_beyond_memory, step_memory

    # the fit's points: the t-shirt's 64 frames about 15 GB, the skirt's 8 about 0.8
    assert 14e9 < step_memory(6698, 64, 32) < 16e9 and 0.7e9 < step_memory(2016, 8, 32) < 0.9e9
    assert step_memory(3240, 32, 64) - STEP_BASE_BYTES == pytest.approx(2 * (step_memory(3240, 32, 32) - STEP_BASE_BYTES))
    assert frames_beyond_memory({"skirt": 2016, "tshirt": 6698}, 64, 32, 20e9) is None
    name, need, fit = frames_beyond_memory({"skirt": 2016, "tshirt": 6698}, 64, 32, 8e9)
    assert name == "tshirt" and need == step_memory(6698, 64, 32) and step_memory(6698, fit, 32) <= 8e9 < \
        step_memory(6698, fit + 1, 32)
    assert frames_beyond_memory({"huge": 10**6}, 1, 32, 24e9)[2] == 0
