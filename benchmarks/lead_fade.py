"""The model's lead-in fade (`core.model_deform.LEAD_FADE_FRAMES`): the jump where the network's window leaves the
lead-in blend behind, and the error against the simulator, for fades of 0 (before 2026-12-06), 3, 5 and 8 frames.

    python benchmarks/lead_fade.py [--fades 0 3 5 8] [--out benchmarks/results/lead_fade.md]

The shipped model (float32, contact guard and strain limit on, one torch thread) on the example garments and
motions below, 30 fps. Per scene and fade: the largest vertex move from frame to frame at frames 3-8 (mm: the
window leaves the blend behind between written frames 4 and 5), the largest change of that move (mm: a
jump stands out against the frames around it), and, on the tradeoff scenes whose simulator references are
stored (`benchmarks/results/tradeoff_v5/<garment>_walk_brisk/simulations/`, 20 substeps with self-contact; the
held-out walk written by `benchmarks/tradeoff_examples.sh`), the mean vertex error over its 15 frames and over
frames 5-8. Writes benchmarks/results/lead_fade.md. Nothing here is asserted by the tests.
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

import core.model_deform as model_deform  # noqa: E402
from core.body import default_body  # noqa: E402
from formats.obj import read_garment  # noqa: E402
from formats.report import markdown_table  # noqa: E402
from garmentcli.common import prepare_motion  # noqa: E402

REFERENCES = ROOT / "benchmarks" / "results" / "tradeoff_v5"
HELD_OUT = ROOT / "data" / "heldout" / "walk_brisk.npz"
#: (garment, motion file, --frames, stored reference or None)
SCENES = [("skirt", HELD_OUT, "0:30", "skirt_walk_brisk"), ("dress", HELD_OUT, "0:30", "dress_walk_brisk"),
          ("skirt", ROOT / "examples" / "walk.npz", "0:40", None), ("dress", ROOT / "examples" / "run.npz", "0:40", None),
          ("trousers", ROOT / "examples" / "walk.npz", "0:40", None),
          ("jumpsuit", ROOT / "examples" / "jump.npz", "0:40", None)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--fades", type=int, nargs="+", default=[0, 3, 5, 8])
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "lead_fade.md")
    args = parser.parse_args()
    torch.set_num_threads(1)
    body = default_body()
    rows = []
    for garment_name, motion_path, frames, reference in SCENES:
        if not motion_path.is_file():
            print(f"skipped {garment_name} on {motion_path.name}: not on this machine", flush=True)
            continue
        garment = read_garment(ROOT / "examples" / f"{garment_name}.obj")
        motion, _ = prepare_motion(str(motion_path), 30.0, frames, 0)
        ref = None
        if reference is not None:
            ref = np.load(REFERENCES / reference / "simulations" / "sim_20_substeps_self-contact.npz")["points"]
        for fade in args.fades:
            model_deform.LEAD_FADE_FRAMES = fade
            points = model_deform.load_model_deformer().deform(garment, body, motion).astype(np.float64)
            move = np.linalg.norm(np.diff(points, axis=0), axis=2).max(1) * 1e3  # move[t]: frame t to t + 1
            change = np.linalg.norm(np.diff(points, 2, axis=0), axis=2).max(1) * 1e3
            err = [] if ref is None else list(np.linalg.norm(points[:len(ref)] - ref, axis=2).mean(1) * 1e3)
            rows.append([garment_name, f"{motion_path.stem} {frames}", fade,
                         " ".join(f"{m:.0f}" for m in move[2:8]), f"{change[2:8].max():.0f}",
                         f"{np.mean(err):.2f}" if err else "-", f"{np.mean(err[5:9]):.2f}" if err else "-"])
            print(rows[-1], flush=True)
    header = ["garment", "motion", "fade frames", "moves into frames 3-8 mm", "largest change mm",
              "error mm", "error frames 5-8 mm"]
    text = ("# The model's lead-in fade\n\n"
            f"`python benchmarks/lead_fade.py` on {platform.processor() or platform.machine()}, one torch thread: the "
            "shipped model, contact guard and strain limit on, 30 fps. Moves: the largest vertex move into each of "
            "frames 3-8 (the window leaves the lead-in blend behind between frames 4 and 5); largest change: of "
            "those moves from frame to frame (its second difference); error: mean vertex distance from the "
            "simulator's reference (20 substeps, self-contact), over its 15 frames and over frames 5-8.\n\n"
            + markdown_table(header, rows) + "\n")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text)
    print(text)


if __name__ == "__main__":
    main()
