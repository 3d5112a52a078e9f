"""`garment train --data DIR --out MODEL`: hybrid three-phase training of the learned model (paper section 4).

Writes MODEL (config + weights, what `bake --method model --model MODEL` reads),
and beside it <MODEL>.ckpt (full training state, for --resume), <MODEL>.csv
(one row per step) and <MODEL>.json (the model and training configs used).
"""

from __future__ import annotations

import csv
import dataclasses
import json
from pathlib import Path

import click
from tqdm import tqdm

from core.errors import InputError
from core.model import ModelConfig, config_from_dict
from core.train import LOSS_COLUMNS, TrainConfig, Trainer, train_config_from_dict
from garmentcli.common import input_errors_as_click, load_body_option

CSV_COLUMNS = ("step", "phase", "item", "loss", *LOSS_COLUMNS, "val_verts_mm", "val_collision")


def _read_config(path: str | None) -> tuple[dict, dict]:
    if path is None:
        return {}, {}
    try:
        data = json.loads(Path(path).read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise InputError(f"config '{path}': expected a JSON file, got {exc}") from None
    if not isinstance(data, dict) or set(data) - {"model", "train"}:
        raise InputError(f"config '{path}': expected an object with keys 'model' and/or 'train', "
                         f"got {sorted(data) if isinstance(data, dict) else type(data).__name__}")
    return dict(data.get("model", {})), dict(data.get("train", {}))


def _parse_phases(text: str) -> tuple:
    try:
        phases = tuple(int(p) for p in text.split(","))
    except ValueError:
        phases = ()
    if phases not in ((1,), (1, 2), (1, 2, 3)):
        raise click.BadParameter(f"expected 1, 1,2 or 1,2,3, got {text!r}", param_hint="--phases")
    return phases


@click.command(name="train")
@click.option("--data", "data_dir", required=True, type=click.Path(file_okay=False), help="Simulator dataset directory.")
@click.option("--out", "out_path", required=True, type=click.Path(dir_okay=False), help="Model file to write.")
@click.option("--phases", default="1,2,3", show_default=True, help="Training phases: 1, 1,2 or 1,2,3.")
@click.option("--steps", type=click.IntRange(min=1), default=None, help="Optimizer steps (default from config).")
@click.option("--seed", type=int, default=None, help="Seed of initialisation and sampling (default 0).")
@click.option("--resume", is_flag=True, help="Continue from <MODEL>.ckpt exactly where it stopped.")
@click.option("--checkpoint-every", type=click.IntRange(min=0), default=None, help="Steps between checkpoints.")
@click.option("--config", "config_path", type=click.Path(dir_okay=False), default=None,
              help='JSON {"model": {...ModelConfig}, "train": {...TrainConfig}}; unknown keys are errors.')
@click.option("--body", "body_path", type=click.Path(dir_okay=False), default=None,
              help="SMPL-format body the dataset was simulated on. Default: the embedded body.")
@click.option("--cache-dir", type=click.Path(file_okay=False), default=None, help="Preprocessing cache directory.")
@click.option("--sequences-per-step", type=click.IntRange(min=1), default=1, show_default=True,
              help="Sequences per step and process; the global batch is this x the number of processes (torchrun).")
@input_errors_as_click
def train(data_dir, out_path, phases, steps, seed, resume, checkpoint_every, config_path, body_path, cache_dir,
          sequences_per_step=1):
    """Train the garment model on a simulator dataset (phases switch on validation plateaus).

    Under `torchrun --nproc_per_node N` it trains with DistributedDataParallel (gloo on CPU); only
    rank 0 writes the model, checkpoint, CSV and JSON.
    """
    from core.ddp import DistributedTrainer, init_from_env, torchrun_env

    rank, world = init_from_env()
    try:
        _train(data_dir, out_path, phases, steps, seed, resume, checkpoint_every, config_path, body_path, cache_dir,
               sequences_per_step, rank, world, DistributedTrainer if (world > 1 or sequences_per_step > 1) else None)
    finally:
        if torchrun_env() is not None:
            import torch.distributed as dist

            if dist.is_initialized():
                dist.destroy_process_group()


def _train(data_dir, out_path, phases, steps, seed, resume, checkpoint_every, config_path, body_path, cache_dir,
           sequences_per_step, rank, world, parallel_trainer):
    import os

    from core.model_data import ModelDataset
    from formats.checkpoint import load_checkpoint, save_checkpoint

    if not Path(data_dir).is_dir():
        raise click.BadParameter(f"expected a dataset directory, got '{data_dir}' (not found)", param_hint="--data")
    out = Path(out_path)
    ckpt_path, csv_path, json_path = (out.with_name(out.name + s) for s in (".ckpt", ".csv", ".json"))
    model_values, train_values = _read_config(config_path)
    body = load_body_option(body_path)
    model_values.setdefault("n_joints", body.n_joints)
    overrides = {"phases": list(_parse_phases(phases))}
    for key, val in (("steps", steps), ("seed", seed), ("checkpoint_every", checkpoint_every)):
        if val is not None:
            overrides[key] = val
    train_values.update(overrides)
    model_cfg: ModelConfig = config_from_dict(model_values, source=f"config '{config_path}'")
    train_cfg: TrainConfig = train_config_from_dict(train_values, source=f"config '{config_path}'")
    if not resume and ckpt_path.exists():
        raise click.ClickException(f"checkpoint '{ckpt_path}' exists: pass --resume to continue it, or remove it")

    data = ModelDataset(data_dir, body, model_cfg, cache_dir=cache_dir)
    if parallel_trainer is None:
        trainer = Trainer(data, model_cfg, train_cfg)
    else:
        trainer = parallel_trainer(data, model_cfg, train_cfg, sequences_per_rank=sequences_per_step)
    main = rank == 0
    rows = []
    if resume:
        ck = load_checkpoint(ckpt_path)
        if ck["config"] != dataclasses.asdict(model_cfg):
            raise click.ClickException(f"checkpoint '{ckpt_path}': its model config differs from this run's")
        trainer.load_state(ck["model"], ck["train"])
        if csv_path.exists():
            with open(csv_path, newline="") as fh:
                rows = [r for r in csv.DictReader(fh) if int(r["step"]) <= trainer.step]
    if main:
        out.parent.mkdir(parents=True, exist_ok=True)
        json_path.write_text(json.dumps({"model": dataclasses.asdict(model_cfg), "train": dataclasses.asdict(train_cfg),
                                         "data": str(data_dir), "processes": world,
                                         "sequences_per_step": sequences_per_step}, indent=2))
    # Only rank 0 writes: the others log into the null device.
    with (open(csv_path, "w", newline="") if main else open(os.devnull, "w")) as fh:
        writer = csv.DictWriter(fh, fieldnames=CSV_COLUMNS, extrasaction="ignore")
        writer.writeheader()
        writer.writerows(rows)
        fh.flush()
        bar = tqdm(total=train_cfg.steps, initial=trainer.step, unit="step", desc="train", disable=None if main else True)

        def progress(step, phase, row):
            writer.writerow(row)
            bar.update(1)
            bar.set_postfix_str(f"phase {phase} loss {row['loss']:.4g} vert {row['vert']:.3g}", refresh=False)

        def checkpoint(tr):
            fh.flush()
            if main:
                save_checkpoint(ckpt_path, model_cfg, tr.model.state_dict(), train=tr.state())

        trainer.progress = progress
        trainer.run(checkpoint=checkpoint)
        bar.close()
        checkpoint(trainer)
    last_val = next((r for r in reversed(trainer.rows) if "val_verts_mm" in r), {})
    meta = {"train_config": dataclasses.asdict(train_cfg), "data": str(data_dir),
            "manifest_splits": data.manifest.get("splits", {}), "steps": trainer.step,
            "phase": trainer.phase.phase, "phase_switches": trainer.phase.switches,
            "val_verts_mm": last_val.get("val_verts_mm"), "body": body.name}
    if not main:
        return
    save_checkpoint(out, model_cfg, trainer.model.state_dict(), meta=meta)
    click.echo(f"{out}: {trainer.step} steps, phase {trainer.phase.phase}, "
               f"validation E_verts {last_val.get('val_verts_mm', float('nan')):.2f} mm")
