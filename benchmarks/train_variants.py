"""Train the shipped model and every variant the reports compare, side by side on one machine.

    python benchmarks/train_variants.py --data data/sim_v1 --device cuda --minutes 8 [--only NAME ...]

One `garment train` process per variant, all at once (on a GPU they share it; on a CPU give each a
core), each stopped after --minutes and resumed by the next call of this script (its checkpoint is
continued exactly), until --steps. Variants:

- the Table-1 rows (benchmarks/model_table.py): phases 1,2,3 (the shipped model), 1 and 1,2;
- the pooling comparison and levels ablation (benchmarks/pooling_comparison.py, which reuses these
  files from the same --models-dir): ours, TopK, SAG, ASAP, and 0 (a single scale), 1, 2 and 3 levels
  of ours, each phase 1 only, one file per configuration (pool_<pooling>_L<levels>_p1.pt). Give them
  the same --steps: "ours, 2 levels" is trained again rather than taken from the longer model_p1.

Training settings for all: benchmarks/configs/train_default.json (validation every 100 steps, phase
switch after 4 validations without 0.5 % improvement). Writes MODELS_DIR/<variant>.pt (+ .ckpt, .csv,
.json, .log) and prints one line per variant.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import json
import os
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from pooling_comparison import LEVEL_VARIANTS, POOLING_VARIANTS, variant_stem  # noqa: E402

from core.model import ModelConfig  # noqa: E402

TRAIN_CONFIG = ROOT / "benchmarks" / "configs" / "train_default.json"


def variants() -> dict[str, tuple[str, dict]]:
    """file stem -> (phases, model config overrides)."""
    out = {"model_p123": ("1,2,3", {}), "model_p1": ("1", {}), "model_p12": ("1,2", {})}
    for over in {**POOLING_VARIANTS, **LEVEL_VARIANTS}.values():
        out.setdefault(variant_stem(over), ("1", over))
    return out


def steps_done(csv_path: Path) -> tuple[int, str]:
    """(last step, last validation E_verts) of a training log."""
    if not csv_path.is_file():
        return 0, ""
    last, val = 0, ""
    with open(csv_path, newline="") as fh:
        for row in csv.DictReader(fh):
            last = int(row["step"])
            val = row.get("val_verts_mm") or val
    return last, val


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, required=True)
    ap.add_argument("--models-dir", type=Path, default=ROOT / "data" / "models")
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--minutes", type=float, default=8.0, help="wall-clock budget of this call per variant")
    ap.add_argument("--steps", type=int, default=20000, help="steps of every variant in all")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--cache-dir", type=Path, default=ROOT / "data" / "prep_cache")
    ap.add_argument("--only", nargs="*", default=None, metavar="NAME", help="these variants only (file stems)")
    args = ap.parse_args(argv)
    args.models_dir.mkdir(parents=True, exist_ok=True)
    train_cfg = json.loads(TRAIN_CONFIG.read_text())["train"]
    procs = {}
    for stem, (phases, over) in variants().items():
        if args.only and stem not in args.only:
            continue
        out = args.models_dir / f"{stem}.pt"
        config = args.models_dir / f"{stem}.config.json"
        config.write_text(json.dumps({"model": {**dataclasses.asdict(ModelConfig()), **over}, "train": train_cfg}))
        cmd = [sys.executable, "-m", "garmentcli.main", "train", "--data", str(args.data), "--out", str(out),
               "--steps", str(args.steps), "--seed", str(args.seed), "--phases", phases, "--config", str(config),
               "--device", args.device, "--time-limit", str(args.minutes), "--cache-dir", str(args.cache_dir)]
        if out.with_name(out.name + ".ckpt").is_file():
            cmd.append("--resume")
        env = dict(os.environ, OMP_NUM_THREADS="1", PYTHONUNBUFFERED="1")
        log = open(out.with_name(out.name + ".log"), "a")
        procs[stem] = (subprocess.Popen(cmd, cwd=ROOT, stdout=log, stderr=subprocess.STDOUT, env=env), log)
        time.sleep(1.0)  # staggered: the first writes the preprocessing cache the others read
    for stem, (p, log) in procs.items():
        rc = p.wait()
        log.close()
        step, val = steps_done(args.models_dir / f"{stem}.pt.csv")
        print(f"{stem}: exit {rc}, step {step}, validation E_verts {val or '-'} mm", flush=True)


if __name__ == "__main__":
    main()
