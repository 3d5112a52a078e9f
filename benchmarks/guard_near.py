"""The contact guard's nearest-vertex planes (`core.pushout.GUARD_NEAR_FROM_M`, `GUARD_NEAR_TO_M`): vertices inside
the body, the guard's time and the error against the simulator, with them and without (before 2026-12-06).

    python benchmarks/guard_near.py [--out benchmarks/results/guard_near.md]

The shipped model (float32, contact guard and strain limit on, one torch thread) on every example garment, on the
example run and jump and the held-out brisk walk's first 15 frames at 30 fps. Inside: vertices more than 2 mm
inside the posed body (`core.bake.penetration_stats`, every frame: mean and worst frame); guard ms/frame: the
deformer's `seconds_per_frame_guard`; error: the mean vertex distance from the simulator's reference where
`benchmarks/results/tradeoff_v5/<garment>_walk_brisk/simulations/` holds one (20 substeps, self-contact).
Writes benchmarks/results/guard_near.md. Nothing here is asserted by the tests.
"""

from __future__ import annotations

import argparse
import platform
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import torch  # noqa: E402

import core.pushout as pushout  # noqa: E402
from core.bake import penetration_stats  # noqa: E402
from core.body import default_body  # noqa: E402
from core.model_deform import load_model_deformer  # noqa: E402
from core.motion import poses_for_body  # noqa: E402
from formats.obj import read_garment  # noqa: E402
from formats.report import markdown_table  # noqa: E402
from garmentcli.common import prepare_motion  # noqa: E402

REFERENCES = ROOT / "benchmarks" / "results" / "tradeoff_v5"
GARMENTS = ("skirt", "dress", "trousers", "jumpsuit", "tshirt")
MOTIONS = (("run", ROOT / "examples" / "run.npz", None), ("jump", ROOT / "examples" / "jump.npz", None),
           ("walk_brisk 0:30", ROOT / "data" / "heldout" / "walk_brisk.npz", "0:30"))
#: (row name, (GUARD_NEAR_FROM_M, GUARD_NEAR_TO_M)): the anchors' planes alone (beyond any lateral distance), now.
VARIANTS = (("anchor planes alone", (1e3, 1e3 + 0.02)),
            ("nearest vertex beyond", (pushout.GUARD_NEAR_FROM_M, pushout.GUARD_NEAR_TO_M)))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "guard_near.md")
    args = parser.parse_args()
    torch.set_num_threads(1)
    body = default_body()
    rows = []
    for garment_name in GARMENTS:
        garment = read_garment(ROOT / "examples" / f"{garment_name}.obj")
        for motion_name, motion_path, frames in MOTIONS:
            if not motion_path.is_file():
                print(f"skipped {garment_name} on {motion_name}: not on this machine", flush=True)
                continue
            motion, _ = prepare_motion(str(motion_path), 30.0, frames, 0, body=body)
            posed, _ = body.pose(poses_for_body(motion, body.n_joints), motion.trans, body.fit_betas(motion.betas))
            reference = REFERENCES / f"{garment_name}_walk_brisk" / "simulations" / "sim_20_substeps_self-contact.npz"
            ref = np.load(reference)["points"] if frames and reference.is_file() else None
            for name, (near_from, near_to) in VARIANTS:
                pushout.GUARD_NEAR_FROM_M, pushout.GUARD_NEAR_TO_M = near_from, near_to
                model = load_model_deformer()
                points = model.deform(garment, body, motion)
                inside = penetration_stats(points, posed, body.faces, max_frames=len(points))
                error = "-" if ref is None else f"{np.linalg.norm(points - ref, axis=2).mean() * 1e3:.2f}"
                guard_ms = model.report.get("seconds_per_frame_guard", float("nan")) * 1e3
                rows.append([garment_name, motion_name, name, f"{inside['mean_percent']:.2f}",
                             f"{inside['max_percent']:.2f}", f"{guard_ms:.1f}", error])
                print(rows[-1], flush=True)
    header = ["garment", "motion", "guard", "inside % mean", "inside % worst frame", "guard ms/frame", "error mm"]
    text = ("# The contact guard's nearest-vertex planes\n\n"
            f"`python benchmarks/guard_near.py` on {platform.processor() or platform.machine()}, one torch thread: "
            "the shipped model, contact guard and strain limit on, 30 fps. Inside: vertices more than 2 mm inside "
            "the posed body (every frame); guard: its time per frame; error: mean vertex distance from the "
            "simulator's reference (20 substeps, self-contact) where one is stored.\n\n"
            + markdown_table(header, rows) + "\n")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text)
    print(text)


if __name__ == "__main__":
    main()
