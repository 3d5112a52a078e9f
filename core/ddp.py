"""Multi-process training with torch DistributedDataParallel (under `torchrun --nproc_per_node N`).

`DistributedTrainer` extends `core.train.Trainer` so that one optimizer step uses a
global batch of `sequences_per_rank * world_size` samples (a sample: one training
sequence and `frames_per_step` frames of it). Every rank draws the whole global
batch from the same seeded generator (so all ranks agree on it, and the
generator's state in a checkpoint does not depend on the world size), then
computes only its own contiguous shard of it: rank r takes samples
[r*k, (r+1)*k) for k = sequences_per_rank. DDP averages the gradients, so the
step equals a single-process step over the global batch (loss = mean of the
per-sample losses); with one rank and one sequence per step it is exactly
`Trainer.train_step`. Validation runs identically on every rank (no randomness),
so phase switches agree without communication. Only rank 0 writes files (the CLI
checks `is_main`). Backend: gloo on CPU, nccl on CUDA.
"""

from __future__ import annotations

import json
import logging
import os

import torch
import torch.distributed as dist
from torch import nn

from core.errors import InputError
from core.train import LOSS_COLUMNS, Trainer, frame_losses, total_loss

log = logging.getLogger(__name__)


def torchrun_env() -> tuple[int, int, int] | None:
    """(rank, world_size, local_rank) from the variables torchrun sets, or None outside torchrun."""
    if "RANK" not in os.environ or "WORLD_SIZE" not in os.environ:
        return None
    return int(os.environ["RANK"]), int(os.environ["WORLD_SIZE"]), int(os.environ.get("LOCAL_RANK", "0"))


def backend_for(device: torch.device) -> str:
    """'nccl' for a CUDA device, 'gloo' otherwise."""
    return "nccl" if torch.device(device).type == "cuda" else "gloo"


def init_from_env(device: torch.device | str = "cpu") -> tuple[int, int]:
    """Join the process group described by torchrun's environment; (rank, world_size). (0, 1) outside torchrun."""
    env = torchrun_env()
    if env is None:
        return 0, 1
    if not dist.is_initialized():
        dist.init_process_group(backend=backend_for(torch.device(device)))
    return dist.get_rank(), dist.get_world_size()


class _ShardLoss(nn.Module):
    """The module DDP wraps: forward(samples) = mean total loss over this rank's samples (+ mean terms)."""

    def __init__(self, trainer: DistributedTrainer):
        super().__init__()
        self.model = trainer.model
        self._trainer = [trainer]  # a list, so nn.Module does not register the trainer

    def forward(self, samples: list, phase: int, frozen: bool):
        tr = self._trainer[0]
        losses, terms_sum = [], {}
        for seq, frames in samples:
            terms = frame_losses(self.model, tr.data, seq, frames, phase, frozen)
            losses.append(total_loss(terms, phase, tr.config.loss_scale))
            for k in LOSS_COLUMNS:
                if k in terms:
                    terms_sum[k] = terms_sum.get(k, 0.0) + terms[k].detach()
        n = len(samples)
        return torch.stack(losses).mean(), {k: v / n for k, v in terms_sum.items()}


class DistributedTrainer(Trainer):
    """Trainer whose step averages `sequences_per_rank * world_size` samples, sharded over the ranks.

    rank, world: from the initialised process group (0, 1 when there is none).
    """

    def __init__(self, data, model_config, config, progress=None, sequences_per_rank: int = 1, device="cpu"):
        super().__init__(data, model_config, config, progress, device=device)
        if sequences_per_rank < 1:
            raise InputError(f"--sequences-per-step: expected at least 1, got {sequences_per_rank}")
        self.distributed = dist.is_available() and dist.is_initialized()
        self.rank = dist.get_rank() if self.distributed else 0
        self.world = dist.get_world_size() if self.distributed else 1
        self.sequences_per_rank = int(sequences_per_rank)
        self.global_batch = self.sequences_per_rank * self.world
        self.is_main = self.rank == 0
        self._loss = _ShardLoss(self)
        self._ddp = None
        if self.world > 1:
            from torch.nn.parallel import DistributedDataParallel

            # Unused parameters: the rest-pose module is frozen (no_grad) from phase 2 on.
            self._ddp = DistributedDataParallel(self._loss, find_unused_parameters=True, broadcast_buffers=False)

    def draw_batch(self) -> list:
        """The global batch [(sequence, frames (F,) int64 sorted)], drawn in the same order as Trainer.train_step."""
        train = self.data.splits["train"]
        out = []
        for _ in range(self.global_batch):
            seq = train[int(self.rng.integers(len(train)))]
            frames = seq.draw_frames(self.rng, self.config.frames_per_step)
            out.append((seq, frames))
        return out

    def train_step(self) -> dict:
        self.model.train()
        batch = self.draw_batch()
        k = self.sequences_per_rank
        mine = batch[self.rank * k:(self.rank + 1) * k]
        self._step_cost = sum(len(f) * int(s.positions.shape[1]) for s, f in mine)
        phase = self.phase.phase
        frozen = phase >= 2
        loss, terms = (self._ddp or self._loss)(mine, phase, frozen)
        self.apply_gradients(loss, frozen)
        names = [c for c in LOSS_COLUMNS if c in terms]
        logged = torch.stack([loss.detach()] + [terms[c].reshape(()) for c in names]).double()
        if self.world > 1:  # the global batch's mean, for the log (every rank gets it)
            dist.all_reduce(logged)
            logged /= self.world
        return self.log_step(phase, "+".join(s.item_id for s, _ in batch), float(logged[0]),
                             {c: float(v) for c, v in zip(names, logged[1:])})

    def state(self) -> dict:
        return {**super().state(), "parallel": json.dumps({"global_batch": self.global_batch,
                                                           "world_size": self.world})}

    def load_state(self, model_state: dict, state: dict) -> None:
        saved = json.loads(state["parallel"])["global_batch"] if "parallel" in state else 1
        if saved != self.global_batch:
            raise InputError(f"checkpoint: trained with a global batch of {saved} sequences per step, this run has "
                             f"{self.global_batch} (--sequences-per-step x processes): keep the global batch to resume")
        super().load_state(model_state, state)
