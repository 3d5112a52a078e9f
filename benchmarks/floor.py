"""The simulator's ground (`SimOptions.floor`): where garments reach it, with and without it, in one run.

Scenes (the embedded body, 30 fps, every run at the default 10 substeps, no self-contact):
- a floor-length gown (the example dress's tube, from under the armpits down to 1 cm above the soles) on the
  first frames of examples/walk.npz;
- the gown on examples/crouch.npz around its deepest squat (the clip starts crouched: the simulator's lead-in,
  the rest pose's straight legs, reaches below the ground, which is lowered under it there);
- the example trousers on the walk: their hem comes within reach of the ground, so it is simulated, but the
  cloth never touches it (the cloth must come out as without it).

For each run: whether the scene analysis kept the ground, seconds per output frame, the garment's lowest point
against the ground over the output frames, and the share of vertex-frames more than 5 mm below it; then the
largest difference between the two runs. Writes benchmarks/results/floor.md.

    python benchmarks/floor.py [--frames 10]
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
os.environ.setdefault("WARP_CACHE_PATH", str(Path.home() / ".cache" / "garment" / "warp"))

from core.body import default_body  # noqa: E402
from core.garmentgen import _levels, _RestBody, _tube_garment  # noqa: E402
from core.motion import Motion, resample  # noqa: E402
from formats.motion import load_motion  # noqa: E402
from formats.obj import read_garment  # noqa: E402
from formats.report import markdown_table  # noqa: E402

#: Depth below the ground from which a vertex counts as sunk into it (metres).
SUNK_M = 0.005


def gown(body):
    """The example dress's A-line tube, lengthened to 1 cm above the soles."""
    rest = _RestBody(body)
    lv = _levels(rest)
    soles = float(body.v_template[:, 1].min())
    return _tube_garment(rest, "gown", y_top=lv["armpits"] - 0.03, y_bottom=soles + 0.01, ease=0.012,
                         flare_from_y=lv["hips"] + 0.3 * (lv["pelvis"] - lv["hips"]), flare_slope=0.22)


def clip(motion: Motion, start: int, frames: int, name: str) -> Motion:
    return Motion(poses=motion.poses[start:start + frames], trans=motion.trans[start:start + frames],
                  betas=motion.betas, fps=motion.fps, name=name)


def main(argv=None) -> None:
    from core.sim import SimDeformer, SimOptions

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=10, help="simulated output frames per run")
    ap.add_argument("--scenes", nargs="*", default=None, help="scenes to run, e.g. 'gown / walk' (default: all)")
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "floor.md")
    args = ap.parse_args(argv)
    body = default_body()
    walk = resample(load_motion(ROOT / "examples" / "walk.npz"), 30.0)
    crouch = resample(load_motion(ROOT / "examples" / "crouch.npz"), 30.0)
    deepest = int(np.argmin(crouch.trans[:, 2]))  # the pelvis lowest: the deepest squat
    scenes = {
        "gown / walk": (gown(body), clip(walk, 0, args.frames, "walk")),
        "gown / crouch": (gown(body), clip(crouch, max(deepest - args.frames // 2, 0), args.frames, "crouch")),
        "trousers / walk": (read_garment(ROOT / "examples" / "trousers.obj"), clip(walk, 0, args.frames, "walk")),
    }
    rows = []
    for label, (garment, motion) in scenes.items():
        if args.scenes and label not in args.scenes:
            continue
        out, ground = {}, None
        for floor in ("auto", "none"):
            d = SimDeformer(options=SimOptions(floor=floor))
            t0 = time.perf_counter()
            out[floor] = d.deform(garment, body, motion)
            seconds = (time.perf_counter() - t0) / motion.n_frames
            scene = d.scene["floor"]
            if floor == "auto":  # the ground of the run with it, measured against in both
                ground = scene["ground_z_m"]
                kept = "skipped" if scene["skipped_work"] else "kept"
                reach = f"{scene['garment_lowest_above_ground_m'] * 100:.1f}"
            else:
                kept, reach = "off", ""
            z = out[floor][..., 2] - ground
            rows.append([label, garment.n_vertices, floor, kept, reach, f"{seconds:.2f}", f"{z.min() * 1e3:.1f}",
                         f"{np.mean(z < -SUNK_M) * 100:.2f}", (d.report["floor"] or {}).get("lifted_onto_it_at_start", ""),
                         f"{ground:.4f}", ""])
            print(rows[-1], flush=True)
        rows[-1][-1] = f"{np.abs(out['auto'] - out['none']).max() * 1e3:.3f}"
    text = (
        "# The simulator's ground, with and without\n\n"
        f"Made by `python benchmarks/floor.py --frames {args.frames}` on {platform.machine()} ({os.cpu_count()} "
        "cores): each scene simulated with `--floor auto` (the default: the ground where the garment comes within "
        "10 cm of it in the LBS preview) and `--floor none`, 10 substeps, no self-contact, the embedded body. The "
        "ground is the plane through the lowest point the body reaches in the motion's frames (lowered under the "
        "simulator's lead-in where the rest pose reaches lower: the crouch). Lowest point and sunk share over "
        f"the output frames, against that ground in both runs; sunk: more than {SUNK_M * 1e3:g} mm below it.\n\n"
        + markdown_table(["scene", "vertices", "--floor", "ground", "LBS preview's lowest above it, cm",
                          "s/frame", "lowest point, mm", "sunk, % of vertex-frames", "lifted at start",
                          "ground z, m", "largest difference of the two runs, mm"], rows)
        + "\n")
    args.out.write_text(text)
    print(text)


if __name__ == "__main__":
    main()
