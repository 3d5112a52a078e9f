"""LBS bake speed on the example garments: frames per second of the deformation, binding cost, penetration check cost.

Run: python benchmarks/bake_speed.py  (writes benchmarks/results/bake_speed.md)
Ratios in one run on one machine; nothing here is asserted by the tests.
"""

from __future__ import annotations

import platform
import time
from pathlib import Path

import numpy as np
import torch

from core.bake import penetration_stats
from core.body import default_body
from core.deform import LBSDeformer
from core.motion import resample
from formats.motion import load_motion
from formats.obj import read_obj
from formats.report import markdown_table

ROOT = Path(__file__).resolve().parents[1]


def main(repeats: int = 5) -> None:
    body = default_body()
    walk = resample(load_motion(ROOT / "examples" / "walk.npz"), 30.0)
    # A long clip (the walk repeated) so per-call overheads do not dominate.
    long = walk.__class__(poses=np.concatenate([walk.poses] * 22), trans=np.concatenate([walk.trans] * 22),
                          fps=walk.fps, name="walk x22")
    rows = []
    for path in sorted((ROOT / "examples").glob("*.obj")):
        garment = read_obj(path)
        deformer = LBSDeformer()
        t0 = time.perf_counter()
        deformer.prepare(garment, body)
        t_bind = time.perf_counter() - t0
        times = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            out = deformer.deform(garment, body, long)
            times.append(time.perf_counter() - t0)
        fps = long.n_frames / float(np.median(times))
        body_pts, _ = body.pose(long.poses[:30], long.trans[:30])
        t0 = time.perf_counter()
        penetration_stats(out[:30], body_pts, body.faces, max_frames=30)
        t_pen = (time.perf_counter() - t0) / 30
        rows.append([path.stem, garment.n_vertices, f"{t_bind:.2f}", f"{fps:,.0f}", f"{1e3 / fps:.3f}", f"{t_pen * 1e3:.0f}"])
    text = (
        "# LBS bake speed\n\n"
        f"Machine: {platform.machine()}, {torch.get_num_threads()} torch threads, Python {platform.python_version()}, "
        f"torch {torch.__version__}. Motion: examples/walk.npz at 30 fps repeated to {long.n_frames} frames; "
        f"median of {repeats} runs after binding.\n\n"
        + markdown_table(["garment", "vertices", "binding s (once)", "LBS frames/s", "ms/frame",
                          "penetration check ms/frame"], rows)
        + "\nBinding = exact closest body face for every garment vertex plus weight smoothing; it is done once per "
          "garment and body. The penetration check (share of vertices > 2 mm inside the body) runs on up to 60 "
          "frames of each bake and dominates a bake's time.\n"
    )
    out = ROOT / "benchmarks" / "results" / "bake_speed.md"
    out.write_text(text)
    print(text)


if __name__ == "__main__":
    main()
