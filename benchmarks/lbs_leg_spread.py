"""LBS's legs' spread (`core.skinning.spread_leg_weights`, `LEG_SPREAD_M`): torn frames, penetration and the error
against the simulator for spreads of 0 (before 2026-12-06: 10 passes alone), 0.05, 0.1, 0.15 and 0.2 m.

    python benchmarks/lbs_leg_spread.py [--spreads 0 0.05 0.1 0.15 0.2] [--out benchmarks/results/lbs_leg_spread.md]

`lbs` (10 passes of smoothing, no strain limit) on every example garment, on the example walk and run and on the
held-out brisk walk's first 15 frames at 30 fps (`benchmarks/tradeoff_examples.sh` writes it to data/heldout/).
Per scene and spread: frames torn (an edge over twice its rest length and 2 cm longer), the largest edge stretch
(length over rest length), the share of vertices more than 2 mm inside the posed body (mean over the frames,
`core.bake.penetration_stats`, every frame), and, where `benchmarks/results/tradeoff_v5/<garment>_walk_brisk/
simulations/` holds the simulator's reference (20 substeps with self-contact), the mean vertex error against it.
Writes benchmarks/results/lbs_leg_spread.md. Nothing here is asserted by the tests.
"""

from __future__ import annotations

import argparse
import platform
from pathlib import Path

import numpy as np

from example_scenes import ROOT, example_scenes, mean_error_mm, write_report  # (benchmarks/ is the script's folder)

from benchmarks.real_motion_stress import torn_frames
from core.bake import penetration_stats
from core.body import default_body
from core.deform import LBSDeformer, LBSOptions
from core.garment import mesh_edges
from core.geodesic import edge_lengths


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--spreads", type=float, nargs="+", default=[0.0, 0.05, 0.1, 0.15, 0.2])
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "lbs_leg_spread.md")
    args = parser.parse_args()
    body = default_body()
    rows = []
    for scene in example_scenes(body, ("walk", "run")):
        garment = scene.garment
        edges = mesh_edges(garment.faces)
        rest = edge_lengths(garment.vertices, edges)
        for spread in args.spreads:
            lbs = LBSDeformer(LBSOptions(leg_spread_m=spread or None))
            points = lbs.deform(garment, body, scene.motion)
            length = np.linalg.norm(points[:, edges[:, 0]] - points[:, edges[:, 1]], axis=2)
            inside = penetration_stats(points, scene.posed, body.faces, max_frames=len(points))["mean_percent"]
            rows.append([scene.garment_name, scene.motion_name, f"{spread:g}", lbs.report["leg_spread_passes"],
                         f"{torn_frames(points, edges, rest).sum()} of {len(points)}", f"{(length / rest).max():.2f}",
                         f"{inside:.2f}", mean_error_mm(points, scene.reference)])
            print(rows[-1], flush=True)
    write_report(args.out, "LBS's legs' spread",
                 f"`python benchmarks/lbs_leg_spread.py` on {platform.processor() or platform.machine()}: `lbs` (10 "
                 "passes, no strain limit) at 30 fps; spread 0: no spread (LBS before 2026-12-06, `--lbs-smooth "
                 "10`). Torn: an edge over twice its rest length and 2 cm longer; inside: vertices more than 2 mm "
                 "inside the posed body, mean over the frames; error: mean vertex distance from the simulator's "
                 "reference (20 substeps, self-contact) where one is stored.",
                 ["garment", "motion", "spread m", "passes", "torn frames", "largest stretch", "inside %", "error mm"],
                 rows)


if __name__ == "__main__":
    main()
