"""What growing Newton's self-contact buffers (`core.sim.ContactBuffers`) costs, and what it changes.

    python benchmarks/contact_buffers.py [--garments trousers tshirt ...] [--frames 0:30]

Newton stores the cloth-cloth pairs a detection finds in buffers of a fixed number per vertex (32) and per
edge (64) and drops the rest. On the tradeoff scene (the held-out `walk_brisk`, source frames 0:30, 15 frames
at 30 fps, 20 substeps with self-contact, settling and blend included), each garment is simulated with the
buffers fixed at Newton's sizes (`SimOptions(contact_buffer_mb=0)`, the simulator before version 3) and
growing (the default): seconds per simulated step, the steps whose detections overflowed (fixed: pairs
dropped; growing: re-run), the buffers reached, self-intersecting faces (every 3rd frame), and E_verts
between the two runs. Garments and configurations run in `--workers` processes at once (each simulation
uses one core). Writes benchmarks/results/contact_buffers.md; nothing here is asserted by the tests.
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
os.environ.setdefault("WARP_CACHE_PATH", str(Path.home() / ".cache" / "garment" / "warp"))

from self_contact_filter import SUBSTEPS, tradeoff_motion  # noqa: E402

from core.body import default_body  # noqa: E402
from core.metrics import e_verts, self_intersection_pct  # noqa: E402
from core.sim import SimDeformer, SimOptions  # noqa: E402
from formats.obj import read_obj  # noqa: E402
from formats.report import markdown_table  # noqa: E402

OUT = ROOT / "benchmarks/results/contact_buffers.md"
CONFIGS = {"fixed": 0.0, "growing": SimOptions.contact_buffer_mb}


def simulate(garment_name: str, config: str, frames: str) -> dict:
    """One run: the cloth (T, V, 3), seconds per simulated step, the overflowing steps and the buffers' report."""
    garment = read_obj(ROOT / "examples" / f"{garment_name}.obj")
    motion = tradeoff_motion(frames)
    d = SimDeformer(options=SimOptions(substeps=SUBSTEPS, self_contact=True, contact_buffer_mb=CONFIGS[config]))
    t = time.perf_counter()
    points = d.deform(garment, default_body(), motion)
    seconds = time.perf_counter() - t
    steps = d.report["settle_frames_internal"] + d.report["blend_frames_internal"] + motion.n_frames
    contact = d.report["self_contact"]  # None where the scene analysis left self-contact out
    buffers = contact and contact["buffers"]
    # The steps whose detections overflowed: re-run (growing) or kept with pairs dropped (fixed, or at the cap).
    overflowed = len({g["at"] for g in buffers["grown"]} | set(buffers["pairs_dropped_at"])) if buffers else 0
    print(f"{garment_name} {config}: {seconds / steps:.1f} s/step, {overflowed} steps overflowed", flush=True)
    return {"points": points, "s_per_step": seconds / steps, "steps": steps, "overflowed": overflowed,
            "buffers": buffers, "faces": garment.faces}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--garments", nargs="+", default=["trousers"])
    ap.add_argument("--frames", default="0:30", help="source frames of walk_brisk (60 fps)")
    ap.add_argument("--workers", type=int, default=2, help="processes (timings: each on its own core)")
    args = ap.parse_args()
    tasks = [(g, c) for g in args.garments for c in CONFIGS]
    with ProcessPoolExecutor(args.workers) as pool:
        runs = dict(zip(tasks, pool.map(simulate, *zip(*tasks), [args.frames] * len(tasks))))
    rows = []
    for g in args.garments:
        fixed, growing = runs[(g, "fixed")], runs[(g, "growing")]
        if growing["buffers"] is None:
            print(f"{g}: the scene analysis left self-contact out; no row")
            continue
        end = growing["buffers"]["end"]
        crossing = [float(self_intersection_pct(r["points"][::3], r["faces"]).mean()) for r in (fixed, growing)]
        rows.append([g, fixed["steps"], fixed["overflowed"], growing["overflowed"],
                     f"{end['pairs_per_vertex']} / {end['pairs_per_edge']}", fixed["s_per_step"],
                     growing["s_per_step"], f"{growing['s_per_step'] / fixed['s_per_step']:.2f}x", *crossing,
                     float(e_verts(fixed["points"], growing["points"]).mean())])
    text = [
        "# Self-contact: growing Newton's pair buffers\n",
        f"Made by `python benchmarks/contact_buffers.py --garments {' '.join(args.garments)} --frames {args.frames}` "
        f"on {platform.machine()} ({os.cpu_count()} cores), {time.strftime('%Y-%m-%d')}, {args.workers} runs at a "
        f"time. Scene: the held-out `walk_brisk`, source frames {args.frames} at 30 fps, {SUBSTEPS} substeps with "
        "self-contact; steps: settling, blend and output frames. Fixed: Newton's 32 vertex-triangle pairs per "
        "vertex and 64 edge-edge pairs per edge, the rest dropped (`contact_buffer_mb=0`, the simulator before "
        "version 3); growing: the default, a step that overflowed is re-run with larger buffers (its re-run is "
        "in its time). Self-intersection: % of faces crossing another, mean over every 3rd output frame; "
        "fixed vs growing: E_verts (mm) between the two runs' output frames.\n",
        markdown_table(["garment", "steps", "steps overflowed, fixed", "steps re-run, growing",
                        "buffers reached (vertex / edge)", "s/step fixed", "s/step growing", "cost",
                        "self-intersection % fixed", "self-intersection % growing", "fixed vs growing mm"],
                       rows, digits=2),
    ]
    OUT.write_text("\n".join(text))
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
