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
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from core.bake import penetration_stats  # noqa: E402
from core.body import default_body  # noqa: E402
from core.deform import LBSDeformer, LBSOptions  # noqa: E402
from core.garment import mesh_edges  # noqa: E402
from core.motion import poses_for_body  # noqa: E402
from formats.obj import read_garment  # noqa: E402
from formats.report import markdown_table  # noqa: E402
from garmentcli.common import prepare_motion  # noqa: E402

REFERENCES = ROOT / "benchmarks" / "results" / "tradeoff_v5"
GARMENTS = ("skirt", "dress", "trousers", "jumpsuit", "tshirt")
#: (name, motion file, --frames)
MOTIONS = (("walk", ROOT / "examples" / "walk.npz", None), ("run", ROOT / "examples" / "run.npz", None),
           ("walk_brisk 0:30", ROOT / "data" / "heldout" / "walk_brisk.npz", "0:30"))


def torn_and_stretch(points: np.ndarray, edges: np.ndarray, rest: np.ndarray) -> tuple[int, float]:
    """(frames with an edge over twice its rest length and 2 cm longer, the largest length over rest length)."""
    length = np.linalg.norm(points[:, edges[:, 0]] - points[:, edges[:, 1]], axis=2)
    return int(((length > 2 * rest) & (length > rest + 0.02)).any(axis=1).sum()), float((length / rest).max())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--spreads", type=float, nargs="+", default=[0.0, 0.05, 0.1, 0.15, 0.2])
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "lbs_leg_spread.md")
    args = parser.parse_args()
    body = default_body()
    rows = []
    for garment_name in GARMENTS:
        garment = read_garment(ROOT / "examples" / f"{garment_name}.obj")
        edges = mesh_edges(garment.faces)
        rest = np.linalg.norm(garment.vertices[edges[:, 0]] - garment.vertices[edges[:, 1]], axis=1)
        for motion_name, motion_path, frames in MOTIONS:
            if not motion_path.is_file():
                print(f"skipped {garment_name} on {motion_name}: not on this machine", flush=True)
                continue
            motion, _ = prepare_motion(str(motion_path), 30.0, frames, 0, body=body)
            posed, _ = body.pose(poses_for_body(motion, body.n_joints), motion.trans, body.fit_betas(motion.betas))
            reference = REFERENCES / f"{garment_name}_walk_brisk" / "simulations" / "sim_20_substeps_self-contact.npz"
            ref = np.load(reference)["points"] if frames and reference.is_file() else None
            for spread in args.spreads:
                lbs = LBSDeformer(LBSOptions(leg_spread_m=spread or None))
                points = lbs.deform(garment, body, motion)
                torn, stretch = torn_and_stretch(points, edges, rest)
                inside = penetration_stats(points, posed, body.faces, max_frames=len(points))["mean_percent"]
                error = "-" if ref is None else f"{np.linalg.norm(points - ref, axis=2).mean() * 1e3:.2f}"
                rows.append([garment_name, motion_name, f"{spread:g}", lbs.report["leg_spread_passes"],
                             f"{torn} of {len(points)}", f"{stretch:.2f}", f"{inside:.2f}", error])
                print(rows[-1], flush=True)
    header = ["garment", "motion", "spread m", "passes", "torn frames", "largest stretch", "inside %", "error mm"]
    text = ("# LBS's legs' spread\n\n"
            f"`python benchmarks/lbs_leg_spread.py` on {platform.processor() or platform.machine()}: `lbs` (10 "
            "passes, no strain limit) at 30 fps; spread 0: no spread (LBS before 2026-12-06, `--lbs-smooth 10`). "
            "Torn: an edge over twice its rest length and 2 cm longer; inside: vertices more than 2 mm inside the "
            "posed body, mean over the frames; error: mean vertex distance from the simulator's reference (20 "
            "substeps, self-contact) where one is stored.\n\n" + markdown_table(header, rows) + "\n")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text)
    print(text)


if __name__ == "__main__":
    main()
