"""core.ddp: 2-process DistributedDataParallel training (gloo, CPU) equals single-process training
with the same global batch; with one rank it is exactly the plain Trainer; resume across world sizes."""

import json
import socket

import numpy as np
import pytest
import torch
import torch.distributed as dist
import torch.multiprocessing as mp

from core.ddp import DistributedTrainer, backend_for, torchrun_env
from core.errors import InputError
from core.model_data import ModelDataset
from core.train import TrainConfig, Trainer
from tests.core.model_fixtures import TINY_CONFIG, make_dataset
from tests.meshes import tiny_body

CONFIG = TrainConfig(steps=4, lr=5e-3, frames_per_step=3, val_every=1000, phases=(1,), seed=3)


@pytest.fixture(scope="module")
def root(tmp_path_factory):
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield make_dataset(tmp_path_factory.mktemp("ds"), T=8)
    torch.set_num_threads(threads)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _ddp_worker(rank: int, world: int, port: int, root: str, out: str) -> None:
    torch.set_num_threads(1)
    dist.init_process_group("gloo", init_method=f"tcp://127.0.0.1:{port}", rank=rank, world_size=world)
    try:
        tr = DistributedTrainer(ModelDataset(root, tiny_body(), TINY_CONFIG), TINY_CONFIG, CONFIG, sequences_per_rank=1)
        tr.run()
        if tr.is_main:
            params = torch.cat([p.detach().reshape(-1) for p in tr.model.parameters()]).tolist()
            with open(out, "w") as fh:
                json.dump({"rows": tr.rows, "params": params}, fh)
        dist.barrier()  # neither rank tears gloo down while the other still uses it (a SIGABRT otherwise)
    finally:
        dist.destroy_process_group()


def test_two_process_ddp_matches_single_process_with_the_same_global_batch(root, tmp_path):
    out = tmp_path / "ddp.json"
    mp.spawn(_ddp_worker, args=(2, _free_port(), str(root), str(out)), nprocs=2, join=True)
    ddp = json.loads(out.read_text())
    single = DistributedTrainer(ModelDataset(root, tiny_body(), TINY_CONFIG), TINY_CONFIG, CONFIG, sequences_per_rank=2)
    single.run()
    assert single.world == 1 and single.global_batch == 2
    ls, ld = [r["loss"] for r in single.rows], [r["loss"] for r in ddp["rows"]]
    assert len(ld) == 4 and ld[0] != ld[-1]
    np.testing.assert_allclose(ld, ls, rtol=1e-4)
    np.testing.assert_allclose([r["vert"] for r in ddp["rows"]], [r["vert"] for r in single.rows], rtol=1e-4)
    assert [r["item"] for r in ddp["rows"]] == [r["item"] for r in single.rows]  # same global batches
    p_single = torch.cat([p.detach().reshape(-1) for p in single.model.parameters()]).numpy()
    np.testing.assert_allclose(ddp["params"], p_single, rtol=1e-3, atol=1e-5)


def test_one_rank_one_sequence_is_exactly_the_plain_trainer(root):
    data = ModelDataset(root, tiny_body(), TINY_CONFIG)
    a, b = Trainer(data, TINY_CONFIG, CONFIG), DistributedTrainer(data, TINY_CONFIG, CONFIG)
    a.run()
    b.run()
    assert [r["loss"] for r in a.rows] == [r["loss"] for r in b.rows]
    assert [r["item"] for r in a.rows] == [r["item"] for r in b.rows]


def test_resume_needs_the_same_global_batch(root):
    data = ModelDataset(root, tiny_body(), TINY_CONFIG)
    full = DistributedTrainer(data, TINY_CONFIG, CONFIG, sequences_per_rank=2)
    full.run()
    half = DistributedTrainer(data, TINY_CONFIG, CONFIG, sequences_per_rank=2)
    half.run(until=2)
    model_state, state = {k: v.clone() for k, v in half.model.state_dict().items()}, half.state()
    resumed = DistributedTrainer(data, TINY_CONFIG, CONFIG, sequences_per_rank=2)
    resumed.load_state(model_state, state)
    resumed.run()
    assert [r["loss"] for r in resumed.rows] == [r["loss"] for r in full.rows[2:]]
    with pytest.raises(InputError, match="global batch of 2 sequences per step, this run has 1"):
        DistributedTrainer(data, TINY_CONFIG, CONFIG).load_state(model_state, state)


def test_torchrun_env_and_backend(monkeypatch):
    monkeypatch.delenv("RANK", raising=False)
    monkeypatch.delenv("WORLD_SIZE", raising=False)
    assert torchrun_env() is None
    monkeypatch.setenv("RANK", "1")
    monkeypatch.setenv("WORLD_SIZE", "2")
    monkeypatch.setenv("LOCAL_RANK", "1")
    assert torchrun_env() == (1, 2, 1)
    assert backend_for(torch.device("cpu")) == "gloo" and backend_for(torch.device("cuda", 0)) == "nccl"
