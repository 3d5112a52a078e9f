"""The model's frames per forward pass on a CPU: milliseconds per frame against the batch, for garments of several
sizes, in one run.

    python benchmarks/cpu_batch.py [--batches 1,2,4,8,16,32] [--rounds 5] [--threads 2]

Garments: the example skirt (2,016 vertices), the 4k-vertex dress of benchmarks/throughput.py (3,960), and the
example dress subdivided once (12,816). Motion: walk_brisk at 30 fps (about 90 frames). Each round bakes every
garment at every batch size, the sizes in a rotated order each round (this VM's speed drifts over minutes: only
settings alternating within one run compare). The network's milliseconds per frame (`seconds_per_frame_network`,
float32, the contact guard excluded), median over the rounds, and each batch's time against the default's.
The thread count is fixed (the tuner off) so that only the batch differs. Writes benchmarks/results/cpu_batch.md
(or --out). Nothing here is asserted by the tests.
"""

from __future__ import annotations

import argparse
import platform
import sys
from pathlib import Path

import numpy as np
import torch

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import garmentcli  # noqa: E402,F401  (the process settings `garment` makes: OpenBLAS threads, malloc)
from benchmarks.malloc_scaling import subdivided  # noqa: E402
from benchmarks.throughput import dress_4k  # noqa: E402
from core.body import default_body  # noqa: E402
from core.model_deform import DEFAULT_BATCH_FRAMES, load_model_deformer  # noqa: E402
from core.motion import resample  # noqa: E402
from formats.obj import read_garment  # noqa: E402
from formats.report import markdown_table, write_markdown  # noqa: E402


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--batches", default="1,2,4,8,16,32")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "cpu_batch.md")
    args = ap.parse_args(argv)
    from core.motiongen import MOTION_LIBRARY

    torch.set_num_threads(args.threads)
    batches = [int(b) for b in args.batches.split(",")]
    default = DEFAULT_BATCH_FRAMES["cpu"]
    if default not in batches:
        batches = sorted(batches + [default])
    body = default_body()
    garments = [read_garment(ROOT / "examples" / "skirt.obj"), dress_4k(body),
                subdivided(read_garment(ROOT / "examples" / "dress.obj"))]
    motion = resample(MOTION_LIBRARY["walk_brisk"](fps=60.0), 30.0)
    d = load_model_deformer()
    d.tune_threads = False
    d.contact_guard = False
    for g in garments:
        d.prepare(g, body)
        d.batch_frames = default
        d.deform(g, body, motion)  # warm-up: the shaped inputs made once
    ms = {(g.name, b): [] for g in garments for b in batches}
    for r in range(args.rounds):
        order = batches[r % len(batches):] + batches[:r % len(batches)]
        for g in garments:
            for b in order:
                d.batch_frames = b
                d.deform(g, body, motion)
                ms[(g.name, b)].append(1e3 * d.report["seconds_per_frame_network"])
        print(f"round {r + 1}/{args.rounds}", {k: round(v[-1], 1) for k, v in ms.items()}, flush=True)
    rows = []
    for g in garments:
        base = np.median(ms[(g.name, default)])
        for b in batches:
            m = float(np.median(ms[(g.name, b)]))
            rows.append([g.name, g.n_vertices, b, f"{m:.1f}", f"{1e3 / m:.1f}", f"{m / base:.2f}"])
    write_markdown(args.out, [
        "# The model's CPU batch: milliseconds per frame against frames per forward pass", "",
        f"Made by `python benchmarks/cpu_batch.py --rounds {args.rounds} --threads {args.threads}` on "
        f"{platform.machine()} ({torch.get_num_threads()} torch threads, the tuner off), torch {torch.__version__}. "
        f"Motion: walk_brisk at 30 fps ({motion.n_frames} frames); float32, the contact guard off; the network's "
        f"ms/frame, median of {args.rounds} rounds, the batch sizes in a rotated order each round. Default: "
        f"{default} (`core.model_deform.DEFAULT_BATCH_FRAMES`).", "",
        markdown_table(["garment", "vertices", "batch frames", "ms/frame", "frames/s", "/ default"], rows),
    ])
    print(args.out.read_text())


if __name__ == "__main__":
    main()
