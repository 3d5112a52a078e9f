"""`garment train` and `garment bake --method model` through click's CliRunner."""

import csv
import json

import numpy as np
import pytest
import torch
from click.testing import CliRunner

from garmentcli.main import cli
from tests.core.model_fixtures import TINY_CONFIG, make_dataset, tube, write_obj
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
    junk = root / "junk.pt"
    junk.write_bytes(b"junk")
    r = CliRunner().invoke(cli, ["bake", str(root / "g.obj"), str(root / "walk.npz"), "--method", "model", "--model",
                                 str(junk), "--body", str(body), "--out", str(root / "b2")])
    assert r.exit_code != 0 and "junk.pt" in r.output
