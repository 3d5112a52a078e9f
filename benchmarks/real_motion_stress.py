"""The shipped model and LBS on many real motions: finite, bounded, and where the garment tears.

    python benchmarks/real_motion_stress.py --garment examples/dress.obj --motions DIR [--every 10] [--out FILE.md]

Every motion file under DIR (`garmentcli.common.motion_files`; every `--every`-th of them, sorted) is read as
`garment bake` reads it (at 30 fps, `--motion-up` left out) and deformed by the model (the default method, its
contact guard on) and by LBS on the embedded body. Per clip and method: whether every point is finite; the largest
distance of a garment vertex from the body's vertices (every fourth frame; the stability suite's bound is the
garment's own size); the share of frames where the garment tears, an edge over twice its rest length and over
2 cm longer (LBS tears a skirt or dress between the legs of a wide stride; a simulated cloth stretches a few per
cent); the mean distance between the model's vertices and LBS's. The clips are not in the repository (their
source: the results file). No reference simulation: errors against the simulator are `garment tradeoff`'s and
`benchmarks/model_table.py`'s. Nothing here is asserted by tests.
"""

from __future__ import annotations

import argparse
import datetime
import logging
import platform
import sys
import time
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from core.body import default_body  # noqa: E402
from core.deform import LBSDeformer  # noqa: E402
from core.errors import InputError  # noqa: E402
from core.garment import mesh_edges  # noqa: E402
from core.geodesic import edge_lengths  # noqa: E402
from core.model_deform import load_model_deformer  # noqa: E402
from core.motion import poses_for_body  # noqa: E402
from formats.obj import read_garment  # noqa: E402
from formats.report import markdown_table, write_markdown  # noqa: E402
from garmentcli.common import motion_files, prepare_motion  # noqa: E402

#: A tear: an edge over this many times its rest length ...
TEAR_RATIO = 2.0
#: ... and over this much longer (metres): a short edge stretched twice is no tear to see.
TEAR_EXCESS_M = 0.02


def torn_frames(points: np.ndarray, edges: np.ndarray, rest: np.ndarray) -> np.ndarray:
    """(T,) bool: frames where an edge is over TEAR_RATIO times its rest length and TEAR_EXCESS_M longer."""
    length = np.linalg.norm(points[:, edges[:, 0]] - points[:, edges[:, 1]], axis=-1)
    return ((length > TEAR_RATIO * rest) & (length - rest > TEAR_EXCESS_M)).any(axis=1)


def farthest_from_body(points: np.ndarray, body_points: np.ndarray, step: int = 4) -> float:
    """The largest distance (metres) of a garment vertex from the body's vertices, every `step`-th frame."""
    return max(float(cKDTree(body_points[t]).query(points[t])[0].max()) for t in range(0, len(points), step))


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--garment", type=Path, required=True)
    ap.add_argument("--motions", type=Path, required=True, help="a motion file or a directory of them")
    ap.add_argument("--every", type=int, default=1, help="every N-th motion file (sorted)")
    ap.add_argument("--source", default="", help="where the motions come from (written to the results)")
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "real_motion_stress.md")
    args = ap.parse_args(argv)
    logging.disable(logging.WARNING)  # a folded rig's or a fast clip's warnings, once per clip
    body, garment = default_body(), read_garment(args.garment)
    edges = mesh_edges(garment.faces)
    rest = edge_lengths(garment.vertices, edges)
    size = float(np.ptp(garment.vertices, axis=0).max())
    methods = {"model": load_model_deformer(), "lbs": LBSDeformer()}
    files = motion_files([str(args.motions)])[::args.every]
    rows, refused, frames = [], [], 0
    t0 = time.perf_counter()
    for n, path in enumerate(files):
        try:
            motion, _ = prepare_motion(str(path), 30.0, None, 0, body=body, motion_up=None)
        except InputError as exc:
            refused.append((path, str(exc)))
            continue
        body_points, _ = body.pose(poses_for_body(motion, body.n_joints), motion.trans, motion.betas)
        out = {name: d.deform(garment, body, motion) for name, d in methods.items()}
        row = {"clip": Path(path).stem, "frames": motion.n_frames,
               "gap_mm": float(np.linalg.norm(out["model"] - out["lbs"], axis=-1).mean() * 1e3)}
        for name, points in out.items():
            row[f"{name}_finite"] = bool(np.isfinite(points).all())
            row[f"{name}_far_m"] = farthest_from_body(points, body_points) if row[f"{name}_finite"] else float("inf")
            row[f"{name}_torn"] = float(torn_frames(points, edges, rest).mean())
        rows.append(row)
        frames += motion.n_frames
        print(f"[{n + 1}/{len(files)}] {row['clip']}: model far {row['model_far_m']:.3f} m, torn "
              f"{row['model_torn']:.0%} (lbs {row['lbs_torn']:.0%})", flush=True)
    seconds = time.perf_counter() - t0
    if not rows:
        raise SystemExit(f"{args.motions}: no motion read ({len(refused)} refused)")

    def stat(key, f):
        return f(np.array([r[key] for r in rows], dtype=np.float64))

    summary = [[name, f"{sum(r[f'{name}_finite'] for r in rows)} / {len(rows)}",
                f"{stat(f'{name}_far_m', np.median):.3f}", f"{stat(f'{name}_far_m', np.max):.3f}",
                f"{sum(r[f'{name}_torn'] * r['frames'] for r in rows) / frames:.1%}",
                f"{sum(r[f'{name}_torn'] > 0 for r in rows)}"] for name in methods]
    worst = sorted(rows, key=lambda r: -r["model_torn"])[:10]
    lines = [f"# {len(rows)} real motions on `{args.garment}`: finite, bounded, torn",
             "", f"Made by `python benchmarks/real_motion_stress.py --garment {args.garment} --motions "
             f"{args.motions.name} --every {args.every}` on {datetime.date.today()}, {platform.machine()}, Python "
             f"{platform.python_version()}, in {seconds / 60:.1f} min ({frames} frames at 30 fps). "
             + (f"Motions: {args.source}. " if args.source else "")
             + f"{len(refused)} refused. The garment spans {size:.2f} m. See the script's docstring.", "",
             markdown_table(["method", "finite clips", "farthest vertex from the body, median (m)", "largest (m)",
                             "frames torn", "clips with a torn frame"], summary),
             "", f"Mean distance between the model's vertices and LBS's: median {stat('gap_mm', np.median):.1f} mm "
             f"over clips, largest {stat('gap_mm', np.max):.1f} mm.", "", "Clips the model tears most:", "",
             markdown_table(["clip", "frames", "model torn", "lbs torn", "model far (m)", "model - lbs (mm)"],
                            [[r["clip"], r["frames"], f"{r['model_torn']:.0%}", f"{r['lbs_torn']:.0%}",
                              f"{r['model_far_m']:.3f}", f"{r['gap_mm']:.1f}"] for r in worst])]
    write_markdown(args.out, lines)


if __name__ == "__main__":
    main()
