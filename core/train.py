"""Hybrid three-phase training of the garment model (paper section 4).

Phase 1: supervised (vertex x100, edge x15, normal x50). Phase 2, when the
validation vertex error plateaus: + penetration and self-collision, supervised
x0.05, rest-pose module frozen. Phase 3, when the validation collision loss
plateaus: + gravity, stretch and shear, supervised x0.2 (phase-2 terms kept).
A plateau is `patience` validations in a row without a relative improvement
of more than `tolerance` over the best value of the phase.

Deterministic on CPU given the seed: the model is initialised from the seed,
batches are drawn from a numpy PCG64 generator held in the trainer's state,
validation uses fixed frames and no randomness. A checkpoint holds the model,
optimizer, both RNG states, the phase state and the step, so resuming gives
bitwise the same losses as an uninterrupted run.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import math
from dataclasses import dataclass, field

import numpy as np
import torch

from core import losses as L
from core.errors import InputError
from core.model import GarmentModel, ModelConfig, window_index
from core.model_data import ModelDataset, Sequence

log = logging.getLogger(__name__)

LOSS_COLUMNS = ("vert", "edge", "normal", "penetration", "self_collision", "gravity", "stretch", "shear")
SUPERVISED_SCALE = {1: 1.0, 2: 0.05, 3: 0.2}


#: frames_per_step's largest: a step holds each frame's forward and backward pass at once (1,000 frames of a
#: 2,016-vertex skirt took the machine's 24 GB and the kernel killed the run).
MAX_FRAMES_PER_STEP = 256
#: The seed's largest (numpy's and `garment train --seed`'s range).
MAX_SEED = 2**32 - 1

#: A training step's memory (bytes) per frame of a garment of V vertices, at the network's `hidden` width 32 (the
#: shipped model's; it grows in proportion to the width): STEP_BYTES_V * V + STEP_BYTES_V2 * V**2, plus
#: STEP_BASE_BYTES for the process. Fitted on the largest steps (phase 3) of the shipped configuration on the example
#: skirt (2,016 vertices: 0.80, 1.88 and 3.11 GB at 8, 32 and 64 frames) and t-shirt (6,698: 2.35, 7.77, 15.0 GB);
#: the dress (3,240) and jumpsuit (6,552) at 32 frames measured 2.70 and 7.76 GB (estimated 2.96 and 7.5), the
#: dress at width 64 4.92 GB (`garment train`'s peak resident memory on this machine).
STEP_BYTES_V = 14_600
STEP_BYTES_V2 = 2.86
STEP_BASE_BYTES = 0.5e9


def step_memory(n_vertices: int, frames: int, hidden: int) -> float:
    """About the largest memory (bytes) one training step of `frames` frames of a garment of `n_vertices` takes
    on the CPU, with a network of width `hidden` (see STEP_BYTES_V)."""
    per_frame = (STEP_BYTES_V * n_vertices + STEP_BYTES_V2 * n_vertices ** 2) * max(hidden, 1) / 32
    return STEP_BASE_BYTES + frames * per_frame


def frames_beyond_memory(garments: dict, frames: int, hidden: int, free: float) -> tuple[str, float, int] | None:
    """Where a step of `frames` frames of the largest of `garments` (name -> vertex count) would not fit in `free`
    bytes: (its name, the bytes it needs, the most frames that fit, 0 where none); None where it fits."""
    if not garments:
        return None
    name = max(garments, key=garments.get)
    need = step_memory(garments[name], frames, hidden)
    if need <= free:
        return None
    fit = int((free - STEP_BASE_BYTES) // max(step_memory(garments[name], 1, hidden) - STEP_BASE_BYTES, 1))
    return name, need, max(fit, 0)


@dataclass(frozen=True)
class TrainConfig:
    """Training settings (dumped next to the model).

    steps: optimizer steps in all. lr: Adam learning rate. seed: init and sampling seed.
    phases: enabled phases, (1,), (1, 2) or (1, 2, 3). frames_per_step: frames of one sequence per step.
    val_every: steps between validations (phase switches happen there). val_frames: frames per val sequence.
    patience, tolerance: plateau detection (relative improvement). checkpoint_every: steps (0 = only at end).
    grad_clip: max gradient norm (0 = off). lr_final: when set, the learning rate follows a cosine from lr at
    step 0 to lr_final at `steps` (a function of the step alone, so a resumed run follows the same curve).
    loss_scale: {term: factor} on top of a term's paper weight (terms of LOSS_COLUMNS; missing = 1). The
    paper's weights with positions in metres leave the vertex term (x100 on m^2: 0.13 at 36 mm) far below the
    normal term (x50 on 1 - cos: about 5), so the network learns normals before positions.
    """

    steps: int = 20000
    lr: float = 1e-3
    seed: int = 0
    phases: tuple = (1, 2, 3)
    frames_per_step: int = 8
    val_every: int = 200
    val_frames: int = 32
    patience: int = 5
    tolerance: float = 1e-3
    checkpoint_every: int = 1000
    grad_clip: float = 1.0
    lr_final: float | None = None
    loss_scale: dict = field(default_factory=dict)

    def lr_at(self, step: int) -> float:
        """Learning rate of the optimiser step taken after `step` steps."""
        if self.lr_final is None:
            return self.lr
        t = min(step / self.steps, 1.0)
        return self.lr_final + 0.5 * (self.lr - self.lr_final) * (1.0 + math.cos(math.pi * t))

    def validate(self, source: str = "train config") -> None:
        if tuple(self.phases) not in ((1,), (1, 2), (1, 2, 3)):
            raise InputError(f"{source}: expected phases 1, 1,2 or 1,2,3, got {','.join(map(str, self.phases))}")
        for name in ("steps", "frames_per_step", "val_every", "val_frames", "patience"):
            if int(getattr(self, name)) < 1:
                raise InputError(f"{source}: expected {name} >= 1, got {getattr(self, name)!r}")
        if self.frames_per_step > MAX_FRAMES_PER_STEP:
            raise InputError(f"{source}: expected frames_per_step at most {MAX_FRAMES_PER_STEP} (each frame's "
                             f"forward and backward pass held at once), got {self.frames_per_step!r}")
        if not 0 <= self.seed <= MAX_SEED:
            raise InputError(f"{source}: expected seed from 0 to {MAX_SEED}, got {self.seed!r}")
        if not self.lr > 0:
            raise InputError(f"{source}: expected lr > 0, got {self.lr!r}")
        for name in ("tolerance", "checkpoint_every", "grad_clip"):
            if not getattr(self, name) >= 0:
                raise InputError(f"{source}: expected {name} >= 0, got {getattr(self, name)!r}")
        if self.lr_final is not None and not 0 <= self.lr_final <= self.lr:
            raise InputError(f"{source}: expected 0 <= lr_final <= lr ({self.lr}), got {self.lr_final!r}")
        if not isinstance(self.loss_scale, dict):
            raise InputError(f"{source}: loss_scale: expected a mapping of loss term to factor, got {self.loss_scale!r}")
        for term, factor in self.loss_scale.items():
            if term not in LOSS_COLUMNS:
                raise InputError(f"{source}: loss_scale: unknown term {term!r} (expected one of {', '.join(LOSS_COLUMNS)})")
            if isinstance(factor, bool) or not (isinstance(factor, (int, float)) and math.isfinite(factor) and factor >= 0):
                raise InputError(f"{source}: loss_scale: expected a finite factor >= 0 for {term!r}, got {factor!r}")


def train_config_from_dict(values: dict, source: str = "train config") -> TrainConfig:
    known = {f.name for f in dataclasses.fields(TrainConfig)}
    for key in values:
        if key not in known:
            raise InputError(f"{source}: unknown key '{key}' (expected one of {', '.join(sorted(known))})")
    defaults = TrainConfig()
    for key, val in values.items():
        default = getattr(defaults, key)
        if key == "phases":
            ok = isinstance(val, (list, tuple)) and all(isinstance(p, int) and not isinstance(p, bool) for p in val)
            want = "a list of phase numbers, e.g. [1, 2, 3]"
        elif key == "loss_scale":  # checked term by term by TrainConfig.validate
            continue
        elif isinstance(default, int) and not isinstance(default, bool):
            ok, want = isinstance(val, int) and not isinstance(val, bool), "an integer"
        else:  # float fields (lr_final may also be null)
            ok = (val is None and key == "lr_final") or (
                isinstance(val, (int, float)) and not isinstance(val, bool) and math.isfinite(val))
            want = "a finite number" + (" or null" if key == "lr_final" else "")
        if not ok:
            raise InputError(f"{source}: '{key}': expected {want}, got {val!r}")
    v = dict(values)
    if "phases" in v:
        v["phases"] = tuple(int(p) for p in v["phases"])
    cfg = TrainConfig(**v)
    cfg.validate(source)
    return cfg


class TrainingDiverged(InputError):
    """The training loss or validation error is not finite: the run stops there, its model not written (it trained
    on NaN to the end, then wrote a NaN model and called it finished)."""


#: What makes a loss not finite, said with `TrainingDiverged`.
DIVERGED_CAUSES = ("a sequence far off or broken (its positions), weights not finite (--init), or too high a learning "
                   "rate ('lr' in --config)")


@dataclass
class PhaseState:
    """phase: current phase; best: best watched value in this phase; bad: validations without improvement."""

    phase: int = 1
    best: float = math.inf
    bad: int = 0
    switches: list = field(default_factory=list)  # [(step, new phase)]


def frame_losses(model: GarmentModel, data: ModelDataset, seq: Sequence, frames: np.ndarray, phase: int,
                 freeze_rest: bool) -> dict:
    """All loss terms active in `phase` for `frames` (B,) of `seq` (unweighted by the phase scale)."""
    g = data.garments[seq.garment_name]
    gi = g.inputs
    cfg = model.config
    if freeze_rest:
        with torch.no_grad():
            fused = model.encode(gi, seq.body_dist)
    else:
        fused = model.encode(gi, seq.body_dist)
    dev = seq.positions.device
    win = window_index(frames, cfg.window).to(dev)
    fr = torch.as_tensor(frames, dtype=torch.long, device=dev)
    out = model.forward_frames(fused, gi, seq.rest, seq.motion.pose[win], seq.motion.velocity[win],
                               seq.motion.transforms[fr])
    x, gt = out.verts, seq.positions[fr]
    terms = {"vert": L.vertex_loss(x, gt), "edge": L.edge_loss(x, gt, gi.edges), "normal": L.normal_loss(x, gt, gi.faces)}
    if phase >= 2:
        body = data.posed_body(seq, frames)
        terms["penetration"] = L.penetration_loss(x, body, data.body_faces)
        terms["self_collision"] = (L.self_collision_loss(x, g.near) if g.near is not None else x.new_zeros(()))
    if phase >= 3:
        terms["gravity"] = L.gravity_loss(x, g.masses)
        terms["stretch"] = L.stretch_loss(x, gi.faces, g.dm_inv, g.area)
        terms["shear"] = L.shear_loss(x, gi.faces, g.dm_inv, g.area)
    terms["_verts"] = x
    return terms


def total_loss(terms: dict, phase: int, scale: dict | None = None) -> torch.Tensor:
    """The phase's weighted sum of `terms`; scale: optional {term: factor} (TrainConfig.loss_scale)."""
    scale = scale or {}
    s = SUPERVISED_SCALE[phase]
    total = s * sum(scale.get(k, 1.0) * terms[k] for k in ("vert", "edge", "normal"))
    for k in ("penetration", "self_collision", "gravity", "stretch", "shear"):
        if k in terms:
            total = total + scale.get(k, 1.0) * terms[k]
    return total


class Trainer:
    """Runs the hybrid schedule on a ModelDataset.

    progress: optional callable(step, phase, row dict) after every step. log_rows: every step's row.
    on_switch: optional callable(trainer, ending phase) just before a phase switch (the model at the end of
    that phase: the ablation rows of Table 1 without training again).
    """

    def __init__(self, data: ModelDataset, model_config: ModelConfig, config: TrainConfig, progress=None,
                 device="cpu"):
        config.validate()
        if not data.splits.get("train"):
            raise InputError(f"dataset '{data.root}': expected sequences in the 'train' split, got none")
        self.data, self.config, self.progress = data, config, progress
        torch.manual_seed(config.seed)
        # Initialised on the CPU from the seed (the same weights on any device), then moved with the data.
        self.model = GarmentModel(model_config).to(device)
        data.to(device)
        self.optimizer = torch.optim.Adam(self.model.parameters(), lr=config.lr)
        self.rng = np.random.Generator(np.random.PCG64(config.seed))
        self.step = 0
        self.phase = PhaseState()
        self.rows: list[dict] = []
        self.on_switch = None
        #: Chooses torch's CPU threads step by step where set (`core.threads.ThreadTuner`; `garment train
        #: --threads auto`): the steps' float rounding then follows the counts chosen.
        self.tuner = None
        self._step_cost = 1
        self.val = data.splits.get("val") or data.splits["train"]
        if not data.splits.get("val"):
            log.warning("no 'val' split: validating on the training sequences")

    # -- one step ---------------------------------------------------------------------------------------
    def train_step(self) -> dict:
        self.model.train()
        train = self.data.splits["train"]
        seq = train[int(self.rng.integers(len(train)))]
        frames = seq.draw_frames(self.rng, self.config.frames_per_step)
        self._step_cost = len(frames) * int(seq.positions.shape[1])  # vertex-frames: steps of larger garments take longer
        phase = self.phase.phase
        frozen = phase >= 2
        terms = frame_losses(self.model, self.data, seq, frames, phase, frozen)
        loss = total_loss(terms, phase, self.config.loss_scale)
        if not torch.isfinite(loss):  # before the step: the model keeps its last finite weights
            bad = ", ".join(f"{k} {float(terms[k].detach()):g}" for k in LOSS_COLUMNS
                            if k in terms and not math.isfinite(float(terms[k].detach())))
            raise TrainingDiverged(f"training diverged at step {self.step + 1}: the loss is {float(loss.detach()):g} "
                                   f"({bad or 'its sum'}) on item '{seq.item_id}'; stopped, the model not written: "
                                   f"{DIVERGED_CAUSES}")
        self.apply_gradients(loss, frozen)
        return self.log_step(phase, seq.item_id, float(loss.detach()),
                             {k: float(terms[k].detach()) for k in LOSS_COLUMNS if k in terms})

    def apply_gradients(self, loss: torch.Tensor, frozen: bool) -> None:
        """Backward, optional freeze of the rest-pose module, clipping, one optimiser step; counts the step."""
        self.optimizer.zero_grad(set_to_none=True)
        loss.backward()
        if frozen:  # rest-pose module frozen: no gradient, so Adam leaves it (and its moments) untouched
            for p in self.model.rest_pose.parameters():
                p.grad = None
        if self.config.grad_clip > 0:
            torch.nn.utils.clip_grad_norm_(self.model.parameters(), self.config.grad_clip)
        for group in self.optimizer.param_groups:
            group["lr"] = self.config.lr_at(self.step)
        self.optimizer.step()
        self.step += 1

    def log_step(self, phase: int, item: str, loss: float, terms: dict[str, float]) -> dict:
        """The step's CSV row (validation and phase switch every val_every steps); reports progress."""
        row = {"step": self.step, "phase": phase, "item": item, "loss": loss}
        row.update({k: terms.get(k, "") for k in LOSS_COLUMNS})
        if self.step % self.config.val_every == 0:
            row.update(self.validate_and_switch())
        self.rows.append(row)
        if self.progress is not None:
            self.progress(self.step, phase, row)
        return row

    # -- validation and phase switches --------------------------------------------------------------------
    def validate(self) -> dict:
        """Validation vertex error (E_verts, mm) and, from phase 2, collision loss (pen + self-coll)."""
        self.model.eval()
        errs, coll = [], []
        with torch.no_grad():
            for seq in self.val:
                frames = seq.even_frames(self.config.val_frames)
                terms = frame_losses(self.model, self.data, seq, frames, min(self.phase.phase, 2), True)
                x = terms["_verts"]
                errs.append(float((x - seq.positions[torch.as_tensor(frames, device=x.device)]).norm(dim=-1).mean()) * 1e3)
                if "penetration" in terms:
                    coll.append(float(terms["penetration"] + terms["self_collision"]))
        out = {"val_verts_mm": float(np.mean(errs))}
        if coll:
            out["val_collision"] = float(np.mean(coll))
        return out

    def validate_and_switch(self) -> dict:
        v = self.validate()
        if not all(math.isfinite(x) for x in v.values()):
            raise TrainingDiverged(f"training diverged at step {self.step}: the validation error is not finite "
                                   f"({', '.join(f'{k} {x:g}' for k, x in v.items())}); stopped, the model not "
                                   f"written: {DIVERGED_CAUSES}")
        ps = self.phase
        watched = v["val_verts_mm"] if ps.phase == 1 else v.get("val_collision", math.inf)
        improved = (not math.isfinite(ps.best)) or watched < ps.best * (1.0 - self.config.tolerance)
        if improved:
            ps.best, ps.bad = watched, 0
        else:
            ps.bad += 1
        if ps.bad >= self.config.patience and ps.phase + 1 in self.config.phases:
            if self.on_switch is not None:
                self.on_switch(self, ps.phase)
            ps.phase += 1
            ps.best, ps.bad = math.inf, 0
            ps.switches.append((self.step, ps.phase))
            log.info("step %d: plateau, switching to phase %d", self.step, ps.phase)
        return v

    def run(self, until: int | None = None, checkpoint=None, should_stop=None) -> None:
        """Train up to step `until` (default config.steps); checkpoint(trainer) every checkpoint_every steps.

        should_stop: optional callable() -> bool asked after every step (a wall-clock budget); True ends the run
        early, resumable from a checkpoint written then.
        """
        until = self.config.steps if until is None else until
        while self.step < until:
            if self.tuner is not None:
                self.tuner.before()
            row = self.train_step()
            if self.tuner is not None and "val_verts_mm" not in row:  # a validation's time is no step's
                self.tuner.after(self._step_cost)
            if should_stop is not None and self.step < until and should_stop():
                log.info("step %d: stopping early (time limit)", self.step)
                break
            if checkpoint is not None and self.config.checkpoint_every and self.step % self.config.checkpoint_every == 0:
                checkpoint(self)

    # -- state ----------------------------------------------------------------------------------------------
    def state(self) -> dict:
        """Everything needed to continue exactly (tensors, numbers, strings only)."""
        return {"optimizer": self.optimizer.state_dict(), "torch_rng": torch.get_rng_state(),
                "numpy_rng": json.dumps(self.rng.bit_generator.state), "step": self.step,
                "phase": json.dumps(dataclasses.asdict(self.phase)),
                "train_config": json.dumps(dataclasses.asdict(self.config))}

    def load_state(self, model_state: dict, state: dict) -> None:
        self.model.load_state_dict(model_state)
        self.optimizer.load_state_dict(state["optimizer"])
        torch.set_rng_state(state["torch_rng"])
        self.rng.bit_generator.state = json.loads(state["numpy_rng"])
        self.step = int(state["step"])
        p = json.loads(state["phase"])
        self.phase = PhaseState(phase=p["phase"], best=p["best"], bad=p["bad"],
                                switches=[tuple(s) for s in p["switches"]])
