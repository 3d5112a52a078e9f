"""The model's contact guard (core/pushout.py) with its lift cut off at the bounds and faded beyond them.

    python benchmarks/contact_guard.py [--frames 90] [--garments dress skirt ...] [--motions kick_right ...]

The shipped model (float32) on every example garment and the four test motions of the dataset (30 fps, the
first FRAMES frames), run three times: guard off (the network alone), guard cut off at GUARD_REACH_M and
GUARD_DEPTH_M (the guard before 2026-12-02), guard faded over GUARD_REACH_FADE_M and GUARD_DEPTH_FADE_M beyond
them (now). Per configuration: penetration (% of vertices > 2 mm inside the body, every frame), the share
of vertex-frames lifted, the largest lift, and pops: a vertex's lift changing by more than POP_M between
consecutive frames while the network moved it less than STILL_M relative to its anchor face (in depth and
along the plane), i.e. a jump the cloth's own motion does not explain.
Writes benchmarks/results/contact_guard.md. Nothing here is asserted by the tests.
"""

from __future__ import annotations

import argparse
import dataclasses
import platform
from pathlib import Path

import numpy as np

import core.model_deform as model_deform
from core.bake import penetration_stats
from core.body import default_body
from core.motion import poses_for_body
from core.motiongen import MOTION_LIBRARY
from core.pushout import (GUARD_DEPTH_FADE_M, GUARD_DEPTH_M, GUARD_REACH_FADE_M, GUARD_REACH_M, anchor_offsets,
                          guard_contact)
from formats.obj import read_obj
from formats.report import markdown_table

ROOT = Path(__file__).resolve().parents[1]
TEST_MOTIONS = ("arm_swing_fast", "kick_right", "turn_right_wide", "walk_brisk")
CONFIGS = {"off": None, "cut off": {"reach_fade": 0.0, "depth_fade": 0.0}, "faded": {}}
POP_M = 0.02
STILL_M = 0.005


def run(deformer, garment, body, motion, guard: dict | None):
    """(the deformer's output, its contact anchors) with the guard off (None: anchors None) or with these
    keyword arguments of guard_contact."""
    deformer.contact_guard = guard is not None
    seen = {}

    def guarded(points, body_points, anchors):
        seen["anchors"] = anchors
        return guard_contact(points, body_points, anchors, **guard)

    model_deform.guard_contact = guarded
    try:
        return deformer.deform(garment, body, motion), seen.get("anchors")
    finally:
        model_deform.guard_contact = guard_contact


def lift_stats(points: np.ndarray, raw: np.ndarray, still: np.ndarray) -> dict:
    """How far the guard moved each vertex-frame (T, V, 3) from the network's output, and its pops: changes
    of the lift by more than POP_M between frames t and t + 1 where still (T - 1, V) is true."""
    lift = np.linalg.norm(points - raw, axis=-1)
    jump = np.abs(np.diff(lift, axis=0))[still]
    return {"lifted %": 100.0 * float((lift > 1e-6).mean()), "max lift mm": 1e3 * float(lift.max()),
            "pops": int((jump > POP_M).sum()), "largest change still, mm": 1e3 * float(jump.max(initial=0.0))}


def report(headers: list[str], rows: list[list], frames: int) -> str:
    """The Markdown of the results: rows per scene and configuration (as `headers`: garment, motion, frames,
    guard, then the statistics) and, per configuration, over every scene."""
    overall = []
    for config in CONFIGS:
        columns = list(zip(*(r[4:] for r in rows if r[3] == config)))
        overall.append([config, *(float(np.mean(c)) if k.endswith("%") else max(c) if k.startswith(("max", "largest"))
                                  else sum(c) for k, c in zip(headers[4:], columns))])
    return (
        "# The contact guard: lift cut off at its bounds against faded beyond them\n\n"
        f"Made by `python benchmarks/contact_guard.py --frames {frames}` on {platform.machine()} with the "
        f"shipped model, float32. Bounds: reach {GUARD_REACH_M * 100:g} cm along the anchor face's plane, depth "
        f"{GUARD_DEPTH_M * 100:g} cm behind it; faded: the lift falls linearly to none over "
        f"{GUARD_REACH_FADE_M * 100:g} cm beyond the reach and {GUARD_DEPTH_FADE_M * 100:g} cm beyond the depth. "
        "Penetration: % of vertices > 2 mm inside the body, every frame; lift: distance a vertex is moved from "
        f"the network's output; pops: vertex-frames whose lift changes by more than {POP_M * 100:g} cm in one frame "
        f"while the network moved the vertex less than {STILL_M * 1e3:g} mm relative to its anchor face (depth "
        "below the guard's floor and distance along the plane): jumps the motion does not explain; largest change "
        "still: the largest change of the lift over those vertex-frames. The faded lift changes at most "
        "(1 + depth / depth fade) x the depth change + depth / reach fade x the lateral change, "
        f"{(1 + GUARD_DEPTH_M / GUARD_DEPTH_FADE_M + GUARD_DEPTH_M / GUARD_REACH_FADE_M) * STILL_M * 1e3:.1f} mm "
        "here.\n\n"
        "## Over every scene (percentages: mean; largest: max; counts: sum)\n\n"
        + markdown_table(["guard", *headers[4:]], overall)
        + "\n## Per scene\n\n" + markdown_table(headers, rows))


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=90, help="frames per motion (30 fps)")
    ap.add_argument("--garments", nargs="*", default=None)
    ap.add_argument("--motions", nargs="*", default=list(TEST_MOTIONS))
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "contact_guard.md")
    args = ap.parse_args(argv)
    body = default_body()
    deformer = model_deform.load_model_deformer()
    paths = sorted((ROOT / "examples").glob("*.obj"))
    if args.garments:
        paths = [p for p in paths if p.stem in args.garments]
    rows = []
    for path in paths:
        garment = read_obj(path)
        for name in args.motions:
            motion = MOTION_LIBRARY[name](fps=30.0)
            motion = dataclasses.replace(motion, poses=motion.poses[:args.frames], trans=motion.trans[:args.frames])
            body_points, _ = body.pose(poses_for_body(motion, body.n_joints), motion.trans,
                                       body.fit_betas(motion.betas))
            outputs = {config: run(deformer, garment, body, motion, guard) for config, guard in CONFIGS.items()}
            raw, anchors = outputs["off"][0], outputs["faded"][1]
            behind, lateral, _ = anchor_offsets(raw, body_points, anchors)
            still = (np.abs(np.diff(behind, axis=0)) < STILL_M) & (np.abs(np.diff(lateral, axis=0)) < STILL_M)
            for config, (points, _) in outputs.items():
                stats = {"penetration %": penetration_stats(points, body_points, body.faces,
                                                            max_frames=motion.n_frames)["mean_percent"],
                         **lift_stats(points, raw, still)}
                rows.append([path.stem, name, motion.n_frames, config, *stats.values()])
            print(f"{path.stem} {name}: " + ", ".join(f"{r[3]} {r[4]:.3f} %" for r in rows[-len(CONFIGS):]),
                  flush=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(report(["garment", "motion", "frames", "guard", *stats], rows, args.frames))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
