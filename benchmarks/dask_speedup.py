"""Speed-up of `garment dataset` from 1 to 2 Dask workers (LocalCluster, one thread each) on this machine.

Small scene: the tiny test body, a shell garment around it, 4 short motions x 2 body shapes (8 items).
Each cluster first runs a 1-item warm-up dataset (worker start, warp kernels), then the timed dataset.
Writes benchmarks/results/dask_speedup.md. Run: python benchmarks/dask_speedup.py
"""

from __future__ import annotations

import os
import platform
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("WARP_CACHE_PATH", str(Path.home() / ".cache" / "garment" / "warp"))

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # tests/ fixtures
from click.testing import CliRunner

from garmentcli.main import cli
from tests.garmentcli.conftest import write_motion, write_shell_obj, write_tiny_body

FRAMES, MOTIONS, BODIES = 20, 4, 2


def scene(d: Path) -> tuple[list, list]:
    body = write_tiny_body(d / "body.npz")
    write_shell_obj(d / "shell.obj", body)
    motions = []
    for k in range(MOTIONS):
        poses = np.zeros((FRAMES, 72), np.float32)
        poses[:, :3] = [np.pi / 2, 0, 0]
        poses[:, 3 * 16 + 2] = np.linspace(0.0, 0.1 * (k + 1), FRAMES)
        write_motion(d / f"m{k}.npz", n_frames=FRAMES, fps=30.0, poses=poses)
        motions.append(d / f"m{k}.npz")
    base = ["dataset", "--garments", d / "shell.obj", "--body", d / "body.npz", "--bodies", BODIES,
            "--betas-range", 0.5, "--settle", 1, "--substeps", 5]
    return base, motions


def timed(args) -> float:
    t0 = time.perf_counter()
    r = CliRunner().invoke(cli, [str(a) for a in args])
    if r.exit_code != 0:
        raise SystemExit(r.output)
    return time.perf_counter() - t0


def main() -> None:
    from distributed import Client, LocalCluster

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        base, motions = scene(d)
        for n in (1, 2):
            with LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None) as c, \
                    Client(c):
                timed(base + ["--motions", motions[0], "--out", d / f"warm{n}", "--scheduler", c.scheduler_address])
                args = base + [a for m in motions for a in ("--motions", m)] + ["--out", d / f"run{n}",
                                                                              "--scheduler", c.scheduler_address]
                load = os.getloadavg()[0]
                rows.append((n, timed(args), load))
    t1 = rows[0][1]
    items = MOTIONS * BODIES
    lines = ["# `garment dataset`: 1 vs 2 Dask workers", "",
             (f"Machine: {platform.machine()}, {os.cpu_count()} CPUs, Python {platform.python_version()}. "
              f"Scene: tiny body, shell garment (642 vertices), {MOTIONS} motions x {BODIES} bodies = {items} items of "
              f"{FRAMES}+1 frames, VBD 5 substeps x 10 iterations. LocalCluster, 1 thread per worker, after a warm-up."),
             "", "| workers | seconds | items/s | speed-up | load average before the run |",
             "|---:|---:|---:|---:|---:|"]
    for n, t, load in rows:
        lines.append(f"| {n} | {t:.1f} | {items / t:.2f} | {t1 / t:.2f}x | {load:.2f} |")
    lines += ["", "Load average: the 1-minute average just before each timed run; it includes this benchmark's own "
                  "warm-up and previous run, so compare it with the number of workers to see whether other work ran.",
              ""]
    out = Path(__file__).parent / "results" / "dask_speedup.md"
    out.write_text("\n".join(lines))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
