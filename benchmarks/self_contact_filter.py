"""What the self-contact surface filter (`core.sim.self_contact_filters`) saves, and what it changes.

    python benchmarks/self_contact_filter.py [--garments dress skirt ...] [--quality-garments skirt dress]

On the held-out `walk_brisk` (the tradeoff scene: source frames 0:30, 15 frames at 30 fps), the simulator at
20 substeps with self-contact, the filter on (the default) and off (`bake --no-skip self-contact`):
- speed, every example garment: seconds per simulated frame and the cloth-cloth pairs the detector keeps,
  over the first SETTLE_FRAMES frames of the settling (the garment hanging on the rest body; the detection
  distance is sized for the walk). Without the filter the larger garments take minutes per frame, so the
  whole scene is simulated for the quality part only.
- quality, the smaller garments, the whole scene: self-intersecting faces (every 3rd frame) with the filter,
  without it and without self-contact; E_verts between filter on and off, next to the reference's spread
  (the run with the filter repeated from starting positions moved by 1 um, as `garment tradeoff --spread`).
Writes benchmarks/results/self_contact_filter.md. Garments run in `--workers` processes at once (each
simulation uses one core); nothing here is asserted by the tests.
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from concurrent.futures import ProcessPoolExecutor
from contextlib import contextmanager
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
os.environ.setdefault("WARP_CACHE_PATH", str(Path.home() / ".cache" / "garment" / "warp"))

import core.sim  # noqa: E402
from core.body import default_body  # noqa: E402
from core.metrics import e_verts, self_intersection_pct  # noqa: E402
from core.motiongen import MOTION_LIBRARY  # noqa: E402
from core.scene import parse_no_skip  # noqa: E402
from core.sim import SimDeformer, SimOptions  # noqa: E402
from formats.motion import save_motion  # noqa: E402
from formats.obj import read_obj  # noqa: E402
from formats.report import markdown_table  # noqa: E402
from garmentcli.common import prepare_motion  # noqa: E402

OUT = ROOT / "benchmarks/results/self_contact_filter.md"
SUBSTEPS = 20
SETTLE_FRAMES = 3
JITTER_M = 1e-6


class _Enough(Exception):
    pass


@contextmanager
def first_frames(n: int):
    """Record (seconds, pairs) of each `ClothSim.advance` (one simulated frame); stop the run after `n`."""
    original = core.sim.ClothSim.advance
    calls = []

    def advance(self, *args, **kwargs):
        t = time.perf_counter()
        out = original(self, *args, **kwargs)
        calls.append((time.perf_counter() - t, self.contact_pairs(), self.contact_filter))
        if len(calls) >= n:
            raise _Enough
        return out

    core.sim.ClothSim.advance = advance
    try:
        yield calls
    except _Enough:
        pass
    finally:
        core.sim.ClothSim.advance = original


def tradeoff_motion(frames: str):
    """The tradeoff scene's motion: the held-out `walk_brisk` (60 fps; written to data/heldout when missing),
    source `frames` (a slice) at 30 fps."""
    motion_path = ROOT / "data/heldout/walk_brisk.npz"
    if not motion_path.is_file():
        motion_path.parent.mkdir(parents=True, exist_ok=True)
        save_motion(motion_path, MOTION_LIBRARY["walk_brisk"](fps=60.0))
    return prepare_motion(str(motion_path), 30.0, frames, 0)[0]


def deformer(filtered: bool, self_contact: bool = True, jitter_m: float = 0.0) -> SimDeformer:
    d = SimDeformer(options=SimOptions(substeps=SUBSTEPS, self_contact=self_contact), jitter_m=jitter_m)
    if not filtered:
        d.skips = parse_no_skip(["self-contact"])
    return d


def speed_row(garment, body, motion) -> list:
    row = [garment.name, garment.n_vertices]
    seconds, pairs, radius = {}, {}, None
    for filtered in (True, False):
        with first_frames(SETTLE_FRAMES) as calls:
            deformer(filtered).deform(garment, body, motion)
        seconds[filtered] = float(np.median([c[0] for c in calls]))
        p = calls[-1][1]
        pairs[filtered] = (p["vertex_triangle"] + p["edge_edge"]) / garment.n_vertices
        if filtered:
            radius = calls[-1][2]["surface_radius_m"]
        print(f"{garment.name} filter {'on' if filtered else 'off'}: {seconds[filtered]:.2f} s/frame, "
              f"{pairs[filtered]:.1f} pairs/vertex", flush=True)
    return row + [radius * 100, pairs[True], pairs[False], seconds[True], seconds[False],
                  f"{seconds[False] / seconds[True]:.2f}x"]


def quality_row(garment, body, motion) -> list:
    runs, seconds = {}, {}
    for name, d in {"on": deformer(True), "off": deformer(False), "none": deformer(True, self_contact=False),
                    "on, jittered": deformer(True, jitter_m=JITTER_M)}.items():
        t = time.perf_counter()
        runs[name] = d.deform(garment, body, motion)
        seconds[name] = (time.perf_counter() - t) / motion.n_frames
        print(f"{garment.name} {name}: {seconds[name]:.2f} s/frame", flush=True)
    crossing = {k: float(self_intersection_pct(v[::3], garment.faces).mean()) for k, v in runs.items()}
    return [garment.name, motion.n_frames, seconds["on"], seconds["off"], seconds["none"],
            crossing["on"], crossing["off"], crossing["none"],
            float(e_verts(runs["on"], runs["off"]).mean()), float(e_verts(runs["on"], runs["on, jittered"]).mean())]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--garments", nargs="+", default=["skirt", "dress", "jumpsuit", "trousers", "tshirt"])
    ap.add_argument("--quality-garments", nargs="*", default=["skirt", "dress"])
    ap.add_argument("--frames", default="0:30", help="source frames of walk_brisk (60 fps)")
    ap.add_argument("--workers", type=int, default=2, help="processes (timings: each on its own core)")
    args = ap.parse_args()
    motion = tradeoff_motion(args.frames)
    body = default_body()
    garments = {g: read_obj(ROOT / "examples" / f"{g}.obj") for g in {*args.garments, *args.quality_garments}}
    # The longest runs first, one process per worker (Warp's CPU kernels use one core each).
    tasks = [(quality_row, g) for g in args.quality_garments] + [(speed_row, g) for g in reversed(args.garments)]
    with ProcessPoolExecutor(args.workers) as pool:
        futures = [pool.submit(fn, garments[g], body, motion) for fn, g in tasks]
        rows = [f.result() for f in futures]
    quality = rows[:len(args.quality_garments)]
    speed = rows[len(args.quality_garments):][::-1]
    text = [
        "# Self-contact: the surface filter\n",
        f"Made by `python benchmarks/self_contact_filter.py` on {platform.machine()} ({os.cpu_count()} cores), "
        f"{time.strftime('%Y-%m-%d')}, {args.workers} garments at a time. Scene: the held-out `walk_brisk`, "
        f"source frames {args.frames} at 30 fps ({motion.n_frames} frames), {SUBSTEPS} substeps with self-contact. "
        "Filter off: `--no-skip self-contact`.\n",
        "## Speed\n",
        f"Median seconds per simulated frame over the first {SETTLE_FRAMES} frames of the settling (the detection "
        "distance already sized for the walk); pairs: vertex-triangle and edge-edge pairs the detector keeps, per "
        "garment vertex, at the last of them.\n",
        markdown_table(["garment", "vertices", "filter radius cm", "pairs/vertex on", "pairs/vertex off",
                        "s/frame on", "s/frame off", "saving"], speed, digits=2),
    ]
    if quality:
        text += [
            "\n## What it changes\n",
            "The whole scene (settling and blend included in s/frame). Self-intersection: % of faces crossing "
            "another, mean over every 3rd frame. `on vs off`: E_verts (mm) between the runs with and without the "
            f"filter; `spread`: E_verts between the run with the filter and its rerun from starting positions "
            f"moved by {JITTER_M * 1e6:g} um (two equally valid simulations).\n",
            markdown_table(["garment", "frames", "s/frame on", "s/frame off", "s/frame no self-contact",
                            "self-intersection % on", "self-intersection % off", "self-intersection % none",
                            "on vs off mm", "spread mm"], quality, digits=2),
        ]
    OUT.write_text("\n".join(text))
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
