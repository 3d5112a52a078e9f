"""The model's CPU thread count chosen while it runs (`core.threads.ThreadTuner`) against torch's count throughout,
on an idle machine and beside processes that keep cores busy, in one run.

    python benchmarks/cpu_threads.py [--repeats 5] [--busy 1]

Garment: the 4k-vertex dress of benchmarks/throughput.py; motion: the held-out `walk_brisk` at 30 fps played
three times (273 frames, 137 batches of 2). For each condition, the tuned and the fixed deformer alternate (so
that a change of the machine's load falls on both), `--repeats` bakes each; the median of the network's
milliseconds per frame counts. "busy N": N processes spinning on a core each, started before and stopped after
the condition's bakes. Writes benchmarks/results/cpu_threads.md (or --out). Nothing here is asserted by tests.
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np
import torch

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.throughput import dress_4k, repeated  # noqa: E402
import garmentcli  # noqa: E402,F401  (the process settings `garment` makes: OpenBLAS threads, malloc)
from core.body import default_body  # noqa: E402
from core.model_deform import load_model_deformer  # noqa: E402
from core.motion import resample  # noqa: E402
from formats.report import markdown_table, write_markdown  # noqa: E402


def _spin(stop) -> None:
    while not stop.is_set():
        pass


def measure(deformers: dict, garment, body, motion, repeats: int) -> dict:
    """{name: (median ms/frame of the network, the last report's cpu_threads)} over `repeats` alternating bakes."""
    times = {name: [] for name in deformers}
    for d in deformers.values():
        d.deform(garment, body, motion)  # warm-up
    for _ in range(repeats):
        for name, d in deformers.items():
            d.deform(garment, body, motion)
            times[name].append(1e3 * d.report["seconds_per_frame_network"])
    return {name: (float(np.median(t)), deformers[name].report.get("cpu_threads")) for name, t in times.items()}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--busy", type=int, action="append", help="busy processes of a condition (repeatable; default 1)")
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "cpu_threads.md")
    args = ap.parse_args(argv)
    from core.motiongen import MOTION_LIBRARY

    body = default_body()
    garment = dress_4k(body)
    motion = repeated(resample(MOTION_LIBRARY["walk_brisk"](fps=60.0), 30.0), 3)
    tuned, fixed = load_model_deformer(), load_model_deformer()
    fixed.tune_threads = False
    rows = []
    for busy in [0, *(args.busy or [1])]:
        stop = mp.Event()
        spinners = [mp.Process(target=_spin, args=(stop,), daemon=True) for _ in range(busy)]
        for p in spinners:
            p.start()
        time.sleep(0.5)
        try:
            res = measure({"tuned": tuned, "fixed": fixed}, garment, body, motion, args.repeats)
        finally:
            stop.set()
            for p in spinners:
                p.join()
        t, f = res["tuned"][0], res["fixed"][0]
        threads = res["tuned"][1] or {}
        rows.append([f"busy {busy}" if busy else "idle", f"{f:.1f}", f"{t:.1f}", f"{f / t:.2f}",
                     threads.get("chosen", "-"), ", ".join(f"{n}: {k}" for n, k in
                                                      threads.get("frames_by_threads", {}).items())])
        print(rows[-1], flush=True)
    table = markdown_table(["machine", f"fixed ({torch.get_num_threads()} threads) ms/frame", "tuned ms/frame",
                            "fixed / tuned", "tuned: chosen last", "tuned: frames by threads (last bake)"], rows)
    lines = ["# The model's CPU threads: chosen while it runs against torch's count", "",
             f"Made by `python benchmarks/cpu_threads.py --repeats {args.repeats}` on "
             f"{platform.processor() or platform.machine()} ({os.cpu_count()} cores, {torch.get_num_threads()} torch "
             f"threads), torch {torch.__version__}. Garment: "
             f"the 4k-vertex dress ({garment.n_vertices} vertices); motion: walk_brisk x3 at 30 fps "
             f"({motion.n_frames} frames, batches of 2). The network's milliseconds per frame, median of the bakes; "
             "tuned and fixed alternate. busy N: N other processes each spinning on a core.", "", table]
    write_markdown(args.out, lines, show=True)


if __name__ == "__main__":
    main()
