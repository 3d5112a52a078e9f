"""The hybrid trainer end to end on a tiny synthetic dataset: learns, switches phase, resumes exactly."""

import dataclasses
import itertools
import math

import numpy as np
import pytest
import torch

from core.errors import InputError
from core.model_data import ModelDataset
from core.train import TrainConfig, Trainer, train_config_from_dict
from formats.checkpoint import load_checkpoint, save_checkpoint
from tests.core.model_fixtures import TINY_CONFIG, make_dataset
from tests.meshes import tiny_body


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    # Tiny tensors: one thread avoids OpenMP hand-off costs that dominate on a busy 2-core machine.
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    root = make_dataset(tmp_path_factory.mktemp("ds"))
    yield ModelDataset(root, tiny_body(), TINY_CONFIG)
    torch.set_num_threads(threads)


def _train_error(tr: Trainer) -> float:
    """Mean vertex error (m) over every frame of the training sequences."""
    from core.train import frame_losses

    errs = []
    with torch.no_grad():
        for seq in tr.data.splits["train"]:
            frames = np.arange(seq.n_frames)
            x = frame_losses(tr.model, tr.data, seq, frames, 1, True)["_verts"]
            errs.append(float((x - seq.positions).norm(dim=-1).mean()))
    return float(np.mean(errs))


def test_dataset_loads(data):
    assert [s.item_id for s in data.splits["train"]] == ["s0", "s1"]
    assert set(data.garments) == {"a", "b"}
    s = data.splits["val"][0]
    assert s.motion.pose.shape == (12, TINY_CONFIG.pose_features)
    assert s.motion.velocity.shape == (12, TINY_CONFIG.velocity_features)


def test_training_decreases_the_error(data):
    tr = Trainer(data, TINY_CONFIG, TrainConfig(steps=40, lr=5e-3, frames_per_step=4, val_every=1000, phases=(1,)))
    before = _train_error(tr)
    tr.run()
    after = _train_error(tr)
    assert after < 0.8 * before
    assert all(r["phase"] == 1 for r in tr.rows)


def test_settle_frames_are_never_targets(tmp_path):
    # The settle blend (frames before n_settle) is input history, not ground truth of a bake's frames: moving
    # its positions by a metre changes neither a training step's loss nor the validation error.
    cfg = TrainConfig(steps=6, lr=5e-3, frames_per_step=6, val_every=3, phases=(1,))
    rows = []
    for shift in (0.0, 1.0):
        data = ModelDataset(make_dataset(tmp_path / f"shift{shift}", n_settle=4, settle_shift_m=shift),
                            tiny_body(), TINY_CONFIG)
        assert [s.n_settle for s in data.splits["train"]] == [4, 4]
        tr = Trainer(data, TINY_CONFIG, cfg)
        tr.run()
        rows.append([(r["loss"], r.get("val_verts_mm")) for r in tr.rows])
    assert rows[0] == rows[1]
    assert all(math.isfinite(v) for _, v in rows[0] if v is not None) and rows[0][2][1] < 1000


def test_settle_frames_draws_and_bad_count(tmp_path):
    data = ModelDataset(make_dataset(tmp_path / "ds", n_settle=4), tiny_body(), TINY_CONFIG)
    seq = data.splits["train"][0]
    drawn = seq.draw_frames(np.random.default_rng(0), 500)
    assert drawn.min() == 4 and drawn.max() == seq.n_frames - 1
    assert seq.even_frames(32).tolist() == list(range(4, seq.n_frames))
    assert seq.even_frames(3).tolist() == [4, 8, 11]
    from core.model_data import sequence_from_arrays
    from formats.dataset import read_sequence
    from dataclasses import asdict
    arrays = asdict(read_sequence(tmp_path / "ds" / "sequences" / "s0.npz"))
    arrays["n_settle"] = 12
    with pytest.raises(InputError, match=r"s0.npz.*expected n_settle in \[0, 12\).*got 12"):
        sequence_from_arrays("s0", "a", arrays, tiny_body(), data.garments["a"], str(tmp_path / "ds" / "sequences" / "s0.npz"))


def test_phase_switches_on_forced_plateau(data):
    # tolerance 1.0: no validation ever counts as an improvement after the first -> plateau at once.
    cfg = TrainConfig(steps=8, frames_per_step=2, val_every=2, patience=1, tolerance=1.0, phases=(1, 2, 3))
    tr = Trainer(data, TINY_CONFIG, cfg)
    before = [p.detach().clone() for p in tr.model.rest_pose.parameters()]
    tr.run(4)
    assert tr.phase.phase == 2 and tr.phase.switches == [(4, 2)]
    tr.run(6)
    # Phase 2: penetration and self-collision on, rest-pose module frozen (no longer changes).
    assert tr.rows[-1]["penetration"] != "" and tr.rows[-1]["gravity"] == ""
    frozen = [p.detach().clone() for p in tr.model.rest_pose.parameters()]
    tr.run(8)
    assert tr.phase.phase == 3 and tr.phase.switches == [(4, 2), (8, 3)]
    assert all(torch.equal(a, b) for a, b in zip(frozen, tr.model.rest_pose.parameters()))
    assert not all(torch.equal(a, b) for a, b in zip(before, frozen))
    tr.run(9)
    assert tr.rows[-1]["stretch"] != "" and tr.rows[-1]["gravity"] != ""
    # --phases 1,2 never reaches phase 3.
    tr2 = Trainer(data, TINY_CONFIG, TrainConfig(steps=8, frames_per_step=2, val_every=2, patience=1, tolerance=1.0,
                                                 phases=(1, 2)))
    tr2.run()
    assert tr2.phase.phase == 2


@pytest.mark.parametrize("lr_final", [None, 1e-5])
def test_resume_is_bitwise_exact(data, tmp_path, lr_final):
    cfg = TrainConfig(steps=10, frames_per_step=2, val_every=3, patience=1, tolerance=1.0, seed=3, lr_final=lr_final)
    full = Trainer(data, TINY_CONFIG, cfg)
    full.run()
    part = Trainer(data, TINY_CONFIG, cfg)
    part.run(5)
    path = save_checkpoint(tmp_path / "run.ckpt", TINY_CONFIG, part.model.state_dict(), train=part.state())
    ck = load_checkpoint(path)
    resumed = Trainer(data, TINY_CONFIG, cfg)
    resumed.load_state(ck["model"], ck["train"])
    assert resumed.step == 5
    resumed.run()
    assert [r for r in resumed.rows] == full.rows[5:]
    assert full.phase.switches == resumed.phase.switches and full.phase.switches  # switches crossed the checkpoint
    for a, b in zip(full.model.state_dict().values(), resumed.model.state_dict().values()):
        assert torch.equal(a, b)


def test_cosine_learning_rate_reaches_lr_final_at_the_last_step(data):
    cfg = TrainConfig(steps=4, lr=1e-2, lr_final=1e-3, frames_per_step=2, val_every=100, phases=(1,))
    lrs = [cfg.lr_at(s) for s in range(5)]
    assert lrs[0] == pytest.approx(1e-2) and lrs[2] == pytest.approx(5.5e-3) and lrs[4] == pytest.approx(1e-3)
    assert all(a > b for a, b in itertools.pairwise(lrs))
    assert TrainConfig(lr=1e-2).lr_at(3) == 1e-2  # no lr_final: constant
    tr = Trainer(data, TINY_CONFIG, cfg)
    tr.run()
    assert tr.optimizer.param_groups[0]["lr"] == pytest.approx(lrs[3])  # the last step used lr_at(3)
    with pytest.raises(InputError, match="lr_final"):
        train_config_from_dict({"lr": 1e-3, "lr_final": 1e-2})


def test_loss_scale_multiplies_each_term_on_top_of_its_paper_weight(data):
    from core.train import total_loss

    terms = {k: torch.tensor(v) for k, v in {"vert": 1.0, "edge": 2.0, "normal": 4.0, "penetration": 8.0,
                                              "self_collision": 16.0}.items()}
    assert float(total_loss(terms, 2)) == pytest.approx(0.05 * 7.0 + 24.0)
    assert float(total_loss(terms, 2, {"vert": 10.0, "self_collision": 0.5})) == pytest.approx(0.05 * 16.0 + 16.0)
    # Every active term scaled to zero: no gradient, so the step leaves the weights where they were.
    cfg = TrainConfig(steps=2, frames_per_step=2, val_every=100, phases=(1,),
                      loss_scale={"vert": 0.0, "edge": 0.0, "normal": 0.0})
    tr = Trainer(data, TINY_CONFIG, cfg)
    before = [p.detach().clone() for p in tr.model.parameters()]
    tr.run()
    assert all(torch.equal(a, b) for a, b in zip(before, tr.model.parameters()))
    assert tr.rows[-1]["vert"] > 0  # the logged terms keep their paper weight
    with pytest.raises(InputError, match="loss_scale: unknown term 'verts'"):
        train_config_from_dict({"loss_scale": {"verts": 2.0}})
    with pytest.raises(InputError, match="loss_scale: expected a finite factor >= 0 for 'edge'"):
        train_config_from_dict({"loss_scale": {"edge": -1}})
    with pytest.raises(InputError, match="loss_scale: expected a finite factor >= 0 for 'normal', got True"):
        train_config_from_dict({"loss_scale": {"normal": True}})
    with pytest.raises(InputError, match="loss_scale: expected a mapping"):
        train_config_from_dict({"loss_scale": [2.0]})


def test_same_seed_same_run(data):
    cfg = TrainConfig(steps=3, frames_per_step=2, val_every=100, seed=7)
    a, b = Trainer(data, TINY_CONFIG, cfg), Trainer(data, TINY_CONFIG, cfg)
    a.run()
    b.run()
    assert a.rows == b.rows


def test_train_config_rejects_unknown_key_and_bad_phases():
    with pytest.raises(InputError, match="unknown key 'lrate'"):
        train_config_from_dict({"lrate": 1.0})
    with pytest.raises(InputError, match="phases"):
        train_config_from_dict({"phases": [2, 3]})


@pytest.mark.parametrize("values, said", [
    ({"checkpoint_every": -5}, "expected checkpoint_every >= 0, got -5"),  # (one shared line named none of them)
    ({"lr": 0}, "expected lr > 0, got 0"),
    ({"grad_clip": -1.0}, "expected grad_clip >= 0, got -1.0"),
    ({"seed": -1}, "expected seed from 0 to 4294967295, got -1"),  # (numpy's traceback)
    ({"seed": 2**40}, "expected seed from 0 to 4294967295, got 1099511627776"),  # (taken; --seed refuses it)
    ({"frames_per_step": 1000}, "expected frames_per_step at most 256"),  # (24 GB, killed)
])
def test_train_config_names_the_value_it_refuses(values, said):
    with pytest.raises(InputError, match=f"cfg.json: {said}"):
        train_config_from_dict(values, source="cfg.json")
    from core.model import ModelConfig, config_from_dict

    with pytest.raises(InputError, match="cfg.json: expected levels from 0 to 8, got 9"):  # (no config named)
        config_from_dict({**dataclasses.asdict(ModelConfig()), "levels": 9}, source="cfg.json")


def test_checkpoint_rejects_other_version(tmp_path):
    path = save_checkpoint(tmp_path / "m.pt", TINY_CONFIG, {})
    ck = torch.load(path, weights_only=True)
    ck["version"] = 99
    torch.save(ck, path)
    with pytest.raises(InputError, match="version 1, got version 99"):
        load_checkpoint(path)
    (tmp_path / "junk.pt").write_bytes(b"not a checkpoint")
    with pytest.raises(InputError, match="junk.pt"):
        load_checkpoint(tmp_path / "junk.pt")


def test_a_checkpoint_of_nan_weights_or_broken_parts_is_refused_naming_it(tmp_path):
    """A model of NaN weights (a training that diverged) was taken by every command (bake blamed the motion, info
    printed NaN, attribute a NaN table); a 'meta' of None, a 'config' list or a 'model' None made tracebacks; a
    weight missing was said as torch's empty first line."""
    from core.model import GarmentModel
    from formats.checkpoint import load_model

    weights = GarmentModel(TINY_CONFIG).state_dict()
    path = save_checkpoint(tmp_path / "m.pt", TINY_CONFIG, weights)
    assert load_model(path)[1]["meta"] == {}
    name = next(k for k, w in weights.items() if w.is_floating_point())

    def edited(edit):
        ck = torch.load(path, weights_only=True)
        edit(ck)
        torch.save(ck, tmp_path / "e.pt")
        return tmp_path / "e.pt"

    nan = edited(lambda ck: ck["model"][name].fill_(float("nan")))
    with pytest.raises(InputError, match=f"model '{nan}': expected finite weights, got NaN or Inf in '{name}'"):
        load_checkpoint(nan)
    for key, value, kind in (("meta", None, "NoneType"), ("config", [1, 2], "list"), ("model", None, "NoneType")):
        broken = edited(lambda ck: ck.__setitem__(key, value))
        with pytest.raises(InputError, match=f"expected the checkpoint's '{key}' a dict, got {kind}"):
            load_checkpoint(broken)
    assert load_checkpoint(edited(lambda ck: ck.pop("meta")))["meta"] == {}  # absent: none recorded
    missing = edited(lambda ck: ck["model"].pop(name))
    with pytest.raises(InputError, match=rf"weights do not match its config \(missing \['{name}'\]\)"):
        load_model(missing)
    other = edited(lambda ck: ck["model"].__setitem__(name, torch.zeros(3, 1)))
    with pytest.raises(InputError, match=f"weights do not match its config \\(size mismatch for {name}"):
        load_model(other)


def _edited_copy(src, dst, edit=None, ids=None):
    """A copy of dataset `src` at `dst` whose manifest `edit` changed in place; `ids` renames its items."""
    import json
    import shutil

    shutil.copytree(src, dst)
    manifest = json.loads((dst / "manifest.json").read_text())
    for rec in manifest["items"]:
        if ids:
            old, rec["id"] = rec["id"], ids[rec["id"]]
            rec["file"] = f"sequences/{rec['id']}.npz"
            (dst / "sequences" / f"{old}.npz").rename(dst / rec["file"])
    if edit:
        edit(manifest)
    (dst / "manifest.json").write_text(json.dumps(manifest))
    return dst


def test_several_datasets_train_together(tmp_path):
    a = make_dataset(tmp_path / "a")
    b = _edited_copy(a, tmp_path / "b", ids={"s0": "t0", "s1": "t1", "s2": "t2"})
    data = ModelDataset([a, b], tiny_body(), TINY_CONFIG)
    assert [s.item_id for s in data.splits["train"]] == ["s0", "s1", "t0", "t1"]
    assert [s.item_id for s in data.splits["val"]] == ["s2", "t2"] and set(data.garments) == {"a", "b"}
    # A dataset that holds another's items (the same ids and records, e.g. linked in) adds each once.
    same = _edited_copy(a, tmp_path / "same")
    assert [s.item_id for s in ModelDataset([a, same], tiny_body(), TINY_CONFIG).splits["train"]] == ["s0", "s1"]
    # An item only the second one has simulated yet comes from there.
    (a / "sequences" / "s1.npz").rename(tmp_path / "s1.npz")
    data = ModelDataset([a, same], tiny_body(), TINY_CONFIG)
    assert [str(s.item_id) for s in data.splits["train"]] == ["s0", "s1"] and not data.missing["train"]


def _set(path, value):
    def edit(manifest):
        *keys, last = path
        node = manifest
        for k in keys:
            node = node[k]
        node[last] = value
    return edit


@pytest.mark.parametrize("edit, ids, message", [
    (_set(("items", 2, "split"), "train"), {"s0": "t0", "s1": "t1", "s2": "t2"},
     r"b': expected motion 'm2' in the 'val' split as in dataset '.*a', got 'train' \(a motion trained on"),
    (_set(("items", 0, "garment"), "b"), None, r"b': expected item 's0' to be the item of that id in dataset "
     r"'.*a', got a different one"),
    (_set(("settings",), {"settle": 4, "fps": 30.0}), {"s0": "t0", "s1": "t1", "s2": "t2"},
     r"b': expected the settle blend of dataset '.*a' \(\{'settle': None, 'fps': None\}\), got \{'settle': 4"),
])
def test_several_datasets_that_disagree_are_refused(tmp_path, edit, ids, message):
    a = make_dataset(tmp_path / "a")
    b = _edited_copy(a, tmp_path / "b", edit, ids)
    with pytest.raises(InputError, match=message):
        ModelDataset([a, b], tiny_body(), TINY_CONFIG)


def test_several_datasets_with_different_meshes_of_one_garment_are_refused(tmp_path):
    from tests.core.model_fixtures import tube, write_obj

    a = make_dataset(tmp_path / "a")
    b = _edited_copy(a, tmp_path / "b", ids={"s0": "t0", "s1": "t1", "s2": "t2"})
    write_obj(b / "garments" / "a.obj", *tube(12, 6, radius=(0.31, 0.2)))
    with pytest.raises(InputError, match=r"dataset '.*b': expected its garment 'a' to be the mesh of '.*a/garments/"
                                         r"a.obj', got a different '.*b/garments/a.obj'"):
        ModelDataset([a, b], tiny_body(), TINY_CONFIG)


def test_a_thread_tuner_times_the_steps_by_vertex_frames_and_not_the_validations(data):
    """`Trainer.tuner` (garment train --threads auto) is told each step's vertex-frames (steps of larger garments
    take longer), and nothing of a step that also validated."""

    class Recorder:
        def __init__(self):
            self.calls = []

        def before(self):
            self.calls.append("before")

        def after(self, cost):
            self.calls.append(cost)

    tr = Trainer(data, TINY_CONFIG, TrainConfig(steps=6, lr=1e-3, frames_per_step=4, val_every=3, phases=(1,)))
    tr.tuner = Recorder()
    tr.run()
    n_vertices = {s.item_id: int(s.positions.shape[1]) for s in data.splits["train"]}
    costs = [c for c in tr.tuner.calls if c != "before"]
    assert tr.tuner.calls.count("before") == 6 and len(costs) == 4  # steps 3 and 6 validated
    assert costs == [4 * n_vertices[r["item"]] for r in tr.rows if "val_verts_mm" not in r]


def test_a_usd_garments_template_edited_since_is_refused(tmp_path):
    """A garment read from USD is written into the dataset anew as the OBJ of its mesh: it was not compared, so an
    edited template was trained on unnoticed (an OBJ's byte copy was); now compared by the mesh's content."""
    from pxr import Usd, UsdGeom, Vt, Gf

    from core.model_data import _refuse_edited_template
    from core.provenance import file_sha256
    from formats.dataset import copy_garment_template
    from formats.obj import read_garment, write_obj

    usd = tmp_path / "cloth.usda"
    stage = Usd.Stage.CreateNew(str(usd))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 0.01)  # centimetres, Z-up: read as metres, Y-up
    mesh = UsdGeom.Mesh.Define(stage, "/cloth")
    points = [(0.0, 0.0, 100.0), (31.41592, 0.0, 100.0), (0.0, 27.18281, 110.0), (31.41592, 27.18281, 90.0)]
    mesh.CreatePointsAttr(Vt.Vec3fArray([Gf.Vec3f(*p) for p in points]))
    mesh.CreateFaceVertexCountsAttr([3, 3])
    mesh.CreateFaceVertexIndicesAttr([0, 1, 2, 1, 3, 2])
    stage.GetRootLayer().Save()
    garment = read_garment(usd)
    template = copy_garment_template(tmp_path / "ds", usd, "cloth")
    # as `garment dataset` records it (the mesh's own hash, of the USD's floats, is not the template's 6 decimals:
    # compared by it, every real USD garment's dataset was refused)
    recorded = {"path": str(usd), "sha256": file_sha256(usd), "mesh_sha256": garment.content_hash(),
                "template_sha256": file_sha256(template)}
    _refuse_edited_template(template, recorded)  # as written: the same file
    moved = garment.vertices.copy()
    moved[0, 0] += 0.01
    write_obj(template, moved, garment.faces)
    with pytest.raises(InputError, match=r"cloth.obj': expected the file its sequences were simulated with "
                                         r"\('.*cloth.usda', sha256 [0-9a-f]{12}\), got a file edited "
                                         r"since"):
        _refuse_edited_template(template, recorded)
    _refuse_edited_template(template, {k: v for k, v in recorded.items() if k != "template_sha256"})  # before
