"""`garment metrics` with a body: this checkout's metrics and penetration kernel against a baseline commit's.

    python benchmarks/metrics_speed.py [--frames 30] [--repeats 3] [--baseline 9047df1]

Garments: the example dress (3,240 vertices) and the dress subdivided twice (50,976), each baked by LBS over the
first --frames frames of examples/walk.npz twice (weights smoothed, the `lbs` default, as PRED; unsmoothed as GT),
with the posed body. Each is scored by `core.metrics.compute_metrics` as `garment metrics` does (all five metrics
and both penetrations, the CLI's inside test and default depth, glibc's malloc keeping freed blocks as the CLI
sets it), once with `core.metrics` and `core.geometry` of --baseline (read from git) and once with this
checkout's, alternating, --repeats times. Reports the seconds (median), the baseline / this ratio of each pair
(median and range), and whether every per-frame value of the two is the same (it must be: the kernel returns the
same bits). Writes benchmarks/results/metrics_speed.md (or --out). Nothing here is asserted by tests.
"""

from __future__ import annotations

import argparse
import datetime
import importlib.util
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import scipy

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import garmentcli  # noqa: E402,F401  (sets glibc's malloc to keep freed blocks, as `garment` does)
from core.bake import bake_item  # noqa: E402
from core.body import default_body  # noqa: E402
from core.deform import LBSDeformer, LBSOptions  # noqa: E402
from core.garment import Garment  # noqa: E402
from core.garmentgen import _subdivide_midpoint  # noqa: E402
from core.metrics import compute_metrics, frames_inside  # noqa: E402
from core.motion import select_frames  # noqa: E402
from formats.motion import load_motion  # noqa: E402
from formats.obj import read_garment  # noqa: E402
from formats.report import markdown_table, write_markdown  # noqa: E402
from garmentcli.metrics import _default_depth_mm, _inside_fn  # noqa: E402


def baseline_module(rev: str, module: str, tmp: Path):
    """`module` (e.g. "core.geometry") as it was at git revision `rev`, imported under another name."""
    src = subprocess.run(["git", "-C", str(ROOT), "show", f"{rev}:{module.replace('.', '/')}.py"], check=True,
                         capture_output=True, text=True).stdout
    name = module.replace(".", "_") + "_baseline"
    path = tmp / f"{name}.py"
    path.write_text(src)
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def cpu_model() -> str:
    try:
        return next(line.split(":", 1)[1].strip() for line in Path("/proc/cpuinfo").read_text().splitlines()
                    if line.startswith("model name"))
    except (OSError, StopIteration):
        return platform.processor() or platform.machine()


def sequences(garment: Garment, frames: int):
    """(PRED (T, V, 3), GT (T, V, 3), body points (T, Vb, 3), body faces) of an LBS bake over walk.npz."""
    body = default_body()
    motion = select_frames(load_motion(ROOT / "examples" / "walk.npz"), 0, frames)
    pred = bake_item(garment, body, motion, LBSDeformer(), check_penetration=False)
    gt = bake_item(garment, body, motion, LBSDeformer(LBSOptions(smooth_iterations=0, leg_spread_m=None)), check_penetration=False)
    return pred.garment_points, gt.garment_points, pred.body_points, body.faces


def subdivided(g: Garment) -> Garment:
    (v,), faces = _subdivide_midpoint([g.vertices], g.faces)
    return Garment(v.astype(np.float32), faces, name=g.name)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=30)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--baseline", default="9047df1", help="git revision whose core/geometry.py is the baseline")
    ap.add_argument("--machine", default=None, help="how the report names the machine (default: its CPU model)")
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "metrics_speed.md")
    args = ap.parse_args(argv)
    depth_m = _default_depth_mm() * 1e-3
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        old = baseline_module(args.baseline, "core.geometry", Path(tmp))
        old_metrics = baseline_module(args.baseline, "core.metrics", Path(tmp))
        inside = {"baseline": frames_inside(lambda p, v, f: old.points_inside_mesh(p, v, f, depth=depth_m)),
                  "this": _inside_fn(depth_m)}
        metrics = {"baseline": old_metrics.compute_metrics, "this": compute_metrics}
        g = read_garment(ROOT / "examples" / "dress.obj")
        for level in (0, 2):
            garment = g
            for _ in range(level):
                garment = subdivided(garment)
            pred, gt, body_points, body_faces = sequences(garment, args.frames)
            times = {name: [] for name in inside}
            results = {}
            for _ in range(args.repeats):
                for name, fn in inside.items():
                    t0 = time.perf_counter()
                    results[name] = metrics[name](pred, gt, garment.faces, body_points, body_faces, fn)
                    times[name].append(time.perf_counter() - t0)
            a, b = (results[n].per_frame for n in inside)
            same = a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)
            ratio = np.array(times["baseline"]) / np.array(times["this"])
            rows.append([f"{garment.n_vertices:,}", str(args.frames), f"{np.median(times['baseline']):.2f}",
                         f"{np.median(times['this']):.2f}", f"{np.median(ratio):.2f}",
                         f"{ratio.min():.2f}-{ratio.max():.2f}",
                         f"{results['this'].overall['penetration_pct']:.3f} / "
                         f"{results['this'].overall['gt_penetration_pct']:.3f}", "yes" if same else "NO"])
            print(rows[-1], flush=True)
    table = markdown_table(["vertices", "frames", "baseline s", "this s", "baseline / this (median)", "(range)",
                            "penetration % PRED / GT", "same per-frame values"], rows)
    command = "python benchmarks/metrics_speed.py" + "".join(
        f" --{k} {v}" for k, v in (("frames", args.frames), ("repeats", args.repeats), ("baseline", args.baseline)))
    if args.machine:
        command += f' --machine "{args.machine}"'
    machine = args.machine or f"{cpu_model()}, {os.cpu_count()} cores"
    lines = ["# `garment metrics` with a body: the penetration kernel against its baseline", "",
             f"Made by `{command}` on {datetime.date.today().isoformat()}, {machine}, Python "
             f"{platform.python_version()}, numpy {np.__version__}, scipy {scipy.__version__}. `compute_metrics` (all five metrics, PRED and GT penetration at "
             f"{depth_m * 1e3:g} mm) of LBS bakes of the example dress over walk.npz, with `core.metrics` and "
             f"`core.geometry` at "
             f"{args.baseline} and in this checkout, alternating {args.repeats} times; seconds are medians, the "
             "ratio is of each alternating pair.", "", table]
    write_markdown(args.out, lines, show=True)


if __name__ == "__main__":
    main()
