"""Training steps' CPU threads: torch's count against `garment train --threads auto`, on an idle machine and beside
busy processes, in one run.

    python benchmarks/train_threads.py [--steps 60] [--repeats 3] [--busy 0 --busy 1]

Data: the tests' synthetic dataset (`tests.core.model_fixtures.make_dataset`) with garments of 2,592 and 1,800
vertices on the tiny 642-vertex body; the model at its default size (core.model.ModelConfig), phase 1, 4 frames a
step. Per machine state (busy N: N other processes each spinning on a core), runs of --steps steps with torch's
count (fixed) and with the tuner alternate --repeats times; milliseconds per step, median of the runs (each run's
mean, its first steps included: the tuner's warm-up and trials are part of its cost), and the count the tuner
chose last. Writes benchmarks/results/train_threads.md (or --out). Nothing here is asserted by the tests.
"""

from __future__ import annotations

import argparse
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import garmentcli  # noqa: E402,F401  (the process settings `garment` makes: OpenBLAS threads, malloc)
import tests.core.model_fixtures as fixtures  # noqa: E402
from core.model import ModelConfig  # noqa: E402
from core.model_data import ModelDataset  # noqa: E402
from core.threads import ThreadTuner  # noqa: E402
from core.train import TrainConfig, Trainer  # noqa: E402
from formats.report import markdown_table, write_markdown  # noqa: E402
from tests.meshes import tiny_body  # noqa: E402

#: The fixtures' tubes made this many times finer each way: garments of a real one's size (2,592 vertices).
FINER = 6


def dataset(root: Path, config: ModelConfig) -> ModelDataset:
    tube = fixtures.tube
    fixtures.tube = lambda n_theta, n_rows, radius=(0.3, 0.2), y=(-0.35, 0.1): tube(n_theta * FINER, n_rows * FINER,
                                                                                   radius, y)
    try:
        fixtures.make_dataset(root, T=12)
    finally:
        fixtures.tube = tube
    return ModelDataset(root, tiny_body(), config)


def run(data: ModelDataset, config: ModelConfig, steps: int, tuned: bool) -> tuple[float, int | None]:
    """(seconds per step, the count the tuner chose last or None) of one run from a fresh model."""
    trainer = Trainer(data, config, TrainConfig(steps=steps, lr=1e-3, frames_per_step=4, val_every=10 ** 6,
                                                phases=(1,)))
    trainer.tuner = ThreadTuner() if tuned else None
    t = time.perf_counter()
    trainer.run()
    seconds = (time.perf_counter() - t) / steps
    chosen = None
    if trainer.tuner is not None:
        chosen = trainer.tuner.chosen
        trainer.tuner.close()
    return seconds, chosen


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=60)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--busy", type=int, action="append", default=None)
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "train_threads.md")
    args = ap.parse_args(argv)
    busy_levels = args.busy or [0, 1]
    config = ModelConfig(n_eigenvalues=4, n_landmarks=8)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        data = dataset(Path(tmp) / "ds", config)
        run(data, config, 4, False)  # first-use work out of the way
        for busy in busy_levels:
            spinners = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(busy)]
            try:
                fixed, tuned, chosen = [], [], []
                for _ in range(args.repeats):
                    fixed.append(run(data, config, args.steps, False)[0])
                    s, c = run(data, config, args.steps, True)
                    tuned.append(s)
                    chosen.append(c)
            finally:
                for p in spinners:
                    p.kill()
            f, t = 1e3 * float(np.median(fixed)), 1e3 * float(np.median(tuned))
            rows.append(["idle" if busy == 0 else f"busy {busy}", f"{f:.0f}", f"{t:.0f}", f"{f / t:.2f}",
                         ", ".join(str(c) for c in chosen)])
            print(rows[-1], flush=True)
    write_markdown(args.out, [
        "# Training steps' CPU threads: torch's count against `--threads auto`", "",
        f"Made by `python benchmarks/train_threads.py --steps {args.steps} --repeats {args.repeats}"
        + "".join(f" --busy {b}" for b in busy_levels) + f"` on {platform.processor() or platform.machine()} "
        f"({os.cpu_count()} cores, {torch.get_num_threads()} torch threads), torch {torch.__version__}. The tests' "
        "synthetic dataset with garments of 2,592 and 1,800 vertices, the model at its default size, phase 1, 4 "
        f"frames a step; ms/step of runs of {args.steps} steps (the tuner's warm-up and trials included), median "
        "of the runs; fixed and tuned alternate. busy N: N other processes each spinning on a core.", "",
        markdown_table(["machine", f"fixed ({torch.get_num_threads()} threads) ms/step", "auto ms/step",
                        "fixed / auto", "auto: chosen last, per run"], rows),
    ], show=True)


if __name__ == "__main__":
    main()
