"""The model's contact guard (core/pushout.py): its lift cut off at the bounds or faded beyond them, each vertex
lifted alone or the lifts spread over the garment.

    python benchmarks/contact_guard.py [--frames 90] [--garments dress skirt ...] [--motions kick_right ...]
                                       [--data DIR ...]
    python benchmarks/contact_guard.py --timing     # the guard's own time, each vertex lifted alone and spread
    python benchmarks/contact_guard.py --figure     # the t-shirt's armpits: network, lone lifts, spread (PNG)
    python benchmarks/contact_guard.py --depth-bands  # the depth band before 2026-12-07 and now (Markdown)

The shipped model (float32) on every example garment and the four test motions of the dataset (30 fps, the
first FRAMES frames), and on every sequence of the simulated datasets given with --data (against the
simulator), run four times: guard off (the network alone); cut off at GUARD_REACH_M and GUARD_DEPTH_M, each
vertex lifted alone (the guard before 2026-12-02); faded over GUARD_REACH_FADE_M and GUARD_DEPTH_FADE_M beyond
them, alone (before 2026-12-06); faded, its lifts spread over the garment in GUARD_ROUNDS rounds (now). Per
configuration: penetration (% of vertices > 2 mm inside the body), the share of vertex-frames lifted, the
largest lift, pops (a vertex's lift changing by more than POP_M between consecutive frames while the network
moved it less than STILL_M relative to its anchor face, in depth and along the plane: a jump the cloth's own
motion does not explain), torn frames (real_motion_stress's: an edge over TEAR_RATIO times its rest length and
TEAR_EXCESS_M longer) and, on
simulated sequences, E_verts (mm) against the simulator after its settle frames.
Writes benchmarks/results/contact_guard.md. Nothing here is asserted by the tests.
"""

from __future__ import annotations

import argparse
import dataclasses
import platform
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.real_motion_stress import TEAR_EXCESS_M, TEAR_RATIO, torn_frames  # noqa: E402
import core.model_deform as model_deform  # noqa: E402
import core.pushout as pushout  # noqa: E402
from core.bake import penetration_stats  # noqa: E402
from core.body import default_body  # noqa: E402
from core.garment import mesh_edges  # noqa: E402
from core.geodesic import edge_lengths  # noqa: E402
from core.motion import poses_for_body, sequence_motion  # noqa: E402
from core.motiongen import MOTION_LIBRARY  # noqa: E402
from core.pushout import (GUARD_DEPTH_FADE_M, GUARD_DEPTH_M, GUARD_REACH_FADE_M, GUARD_REACH_M,  # noqa: E402
                          GUARD_ROUNDS, GUARD_SPREAD_M, anchor_offsets, guard_contact)
from formats.dataset import read_manifest, read_sequence, sequence_path  # noqa: E402
from formats.obj import read_obj  # noqa: E402
from formats.report import markdown_table  # noqa: E402

TEST_MOTIONS = ("arm_swing_fast", "kick_right", "turn_right_wide", "walk_brisk")
ALONE = {"passes": 0, "rounds": 1}
CONFIGS = {"off": None, "cut off": {"reach_fade": 0.0, "depth_fade": 0.0, **ALONE}, "faded": ALONE,
           "faded, spread": {}}
POP_M = 0.02
STILL_M = 0.005


def run(deformer, garment, body, motion, guard: dict | None):
    """(the deformer's output, its contact anchors) with the guard off (None: anchors None) or with these
    keyword arguments of guard_contact."""
    deformer.contact_guard = guard is not None
    seen = {}
    anchored_body = pushout.anchored_body

    def guarded(points, body_points, anchors):
        return guard_contact(points, body_points, anchors, **guard)

    def anchored(anchors):  # the anchors on the whole body (the guard gets them on the body vertices it poses)
        seen["anchors"] = anchors
        return anchored_body(anchors)

    # On a GPU the model guards batch by batch (model_deform's name), on a CPU the whole sequence (pushout's).
    model_deform.guard_contact = pushout.guard_contact = guarded
    model_deform.anchored_body = pushout.anchored_body = anchored
    try:
        return deformer.deform(garment, body, motion), seen.get("anchors")
    finally:
        model_deform.guard_contact = pushout.guard_contact = guard_contact
        model_deform.anchored_body = pushout.anchored_body = anchored_body


def lift_stats(points: np.ndarray, raw: np.ndarray, still: np.ndarray) -> dict:
    """How far the guard moved each vertex-frame (T, V, 3) from the network's output, and its pops: changes
    of the lift by more than POP_M between frames t and t + 1 where still (T - 1, V) is true."""
    lift = np.linalg.norm(points - raw, axis=-1)
    jump = np.abs(np.diff(lift, axis=0))[still]
    return {"lifted %": 100.0 * float((lift > 1e-6).mean()), "max lift mm": 1e3 * float(lift.max()),
            "pops": int((jump > POP_M).sum()), "largest change still, mm": 1e3 * float(jump.max(initial=0.0))}


def summary(key: str, column) -> float | int | str:
    """A statistic over scenes: percentages and E_verts their mean (over the scenes that have one), largest
    values their max, counts their sum."""
    if key.startswith("E_verts"):
        values = [c for c in column if c != ""]
        return float(np.mean(values)) if values else ""
    if key.endswith("%"):
        return float(np.mean(column))
    return max(column) if key.startswith(("max", "largest")) else sum(column)


def report(headers: list[str], rows: list[list], command: str) -> str:
    """The Markdown of the results: rows per scene and configuration (as `headers`: garment, motion, frames,
    guard, then the statistics) and, per configuration, over every scene."""
    overall = []
    for config in CONFIGS:
        columns = list(zip(*(r[4:] for r in rows if r[3] == config)))
        overall.append([config, *(summary(k, c) for k, c in zip(headers[4:], columns))])
    return (
        "# The contact guard: lift cut off at its bounds or faded beyond them, alone or spread\n\n"
        f"Made by `python benchmarks/contact_guard.py {command}` on {platform.machine()} with the "
        f"shipped model, float32. Bounds: reach {GUARD_REACH_M * 100:g} cm along the anchor face's plane, depth "
        f"{GUARD_DEPTH_M * 100:g} cm behind it; faded: the lift falls linearly to none over "
        f"{GUARD_REACH_FADE_M * 100:g} cm beyond the reach and {GUARD_DEPTH_FADE_M * 100:g} cm beyond the depth; "
        f"spread: the lifts smoothed over about {GUARD_SPREAD_M * 100:g} cm of the garment (passes of half the "
        "neighbours' mean, as many as its median edge needs), "
        f"in {GUARD_ROUNDS} rounds (the second lifts what the spread left behind); the others lift each vertex "
        "alone. Torn frames: frames with an edge over "
        f"{TEAR_RATIO:g} times its rest length and {TEAR_EXCESS_M * 100:g} cm longer. E_verts: against the simulator "
        "(simulated sequences only). "
        "Penetration: % of vertices > 2 mm inside the body (on evenly spaced frames); lift: distance a vertex is "
        f"moved from the network's output; pops: vertex-frames whose lift changes by more than {POP_M * 100:g} cm "
        "in one frame "
        f"while the network moved the vertex less than {STILL_M * 1e3:g} mm relative to its anchor face (depth "
        "below the guard's floor and distance along the plane): jumps the motion does not explain; largest change "
        "still: the largest change of the lift over those vertex-frames. The faded lift changes at most "
        "(1 + depth / depth fade) x the depth change + depth / reach fade x the lateral change, "
        f"{(1 + GUARD_DEPTH_M / GUARD_DEPTH_FADE_M + GUARD_DEPTH_M / GUARD_REACH_FADE_M) * STILL_M * 1e3:.1f} mm "
        "here.\n\n"
        "## Over every scene (percentages and E_verts: mean; largest: max; counts: sum)\n\n"
        + markdown_table(["guard", *headers[4:]], overall)
        + "\n## Per scene\n\n" + markdown_table(headers, rows))


def scene_arguments(ap: argparse.ArgumentParser, frames: int) -> None:
    """The options `scenes` reads: --frames (default `frames`), --garments, --motions, --data, and
    --penetration-frames (the scenes' penetration statistics)."""
    ap.add_argument("--frames", type=int, default=frames, help="frames per test motion (30 fps)")
    ap.add_argument("--garments", nargs="*", default=None)
    ap.add_argument("--motions", nargs="*", default=list(TEST_MOTIONS))
    ap.add_argument("--data", action="append", default=[], help="a simulated dataset (garment dataset) to add")
    ap.add_argument("--penetration-frames", type=int, default=20, help="frames per scene checked for penetration "
                    "(evenly spaced)")


def scene_command(args) -> list[str]:
    """The options of `scene_arguments` as given but --penetration-frames, for a results file's command line
    (--motions where not the test motions)."""
    return [f"--frames {args.frames}", *(["--motions", *args.motions] if args.motions != list(TEST_MOTIONS) else []),
            *(f"--data {d}" for d in args.data)]


def scenes(args):
    """(garment name, motion name, garment, motion, simulated positions after the settle or None, settle frames)
    of the example garments on the test motions, then of every sequence in --data."""
    paths = sorted((ROOT / "examples").glob("*.obj"))
    if args.garments:
        paths = [p for p in paths if p.stem in args.garments]
    for path in paths:
        garment = read_obj(path)
        for name in args.motions:
            motion = MOTION_LIBRARY[name](fps=30.0)
            motion = dataclasses.replace(motion, poses=motion.poses[:args.frames], trans=motion.trans[:args.frames])
            yield path.stem, name, garment, motion, None, 0
    for data in args.data:
        for item in read_manifest(data)["items"]:
            seq_path = sequence_path(data, item["id"])
            if seq_path.exists():
                seq = read_sequence(seq_path)
                garment = read_obj(Path(data) / "garments" / f"{seq.garment}.obj")
                yield (seq.garment, f"{Path(data).name}/{item['id']}", garment, sequence_motion(seq, item["id"]),
                       seq.positions[seq.n_settle:], seq.n_settle)


def timing(args) -> None:
    """The guard's milliseconds per frame on each example garment (the rest pose through the first 64 frames of
    walk_brisk; one torch thread; the body posed as the bake poses it, at the anchor faces' vertices,
    `guard_chunk_frames` frames at a time; best of 3),
    each vertex lifted alone and spread: benchmarks/results/contact_guard_timing.md."""
    import time

    import torch

    torch.set_num_threads(1)
    body = default_body()
    motion = MOTION_LIBRARY["walk_brisk"](fps=30.0)
    frames = 64
    betas = body.fit_betas(motion.betas)
    poses = poses_for_body(motion, body.n_joints)[:frames]
    rows = []
    for path in sorted((ROOT / "examples").glob("*.obj")):
        garment = read_obj(path)
        ids, anchors = pushout.anchored_body(pushout.body_anchors(garment.vertices, garment.faces, body, betas))
        points = np.repeat(garment.vertices[None].astype(np.float32), frames, axis=0)
        chunk = pushout.guard_chunk_frames(garment.n_vertices)
        ms = {}
        for name, guard in (("alone", ALONE), ("spread", {})):
            best = np.inf
            for _ in range(3):
                t0 = time.perf_counter()
                for s in range(0, frames, chunk):
                    body_points = body.pose_at(ids, poses[s:s + chunk], motion.trans[s:s + chunk], betas)
                    guard_contact(points[s:s + chunk], body_points, anchors, **guard)
                best = min(best, (time.perf_counter() - t0) / frames * 1e3)
            ms[name] = best
        rows.append([path.stem, garment.n_vertices, chunk, anchors.passes, ms["alone"], ms["spread"]])
        print(rows[-1], flush=True)
    out = args.out.with_name("contact_guard_timing.md")
    out.write_text("# The contact guard's time per frame\n\n"
                   f"Made by `python benchmarks/contact_guard.py --timing` on {platform.machine()}, one torch thread: "
                   "the body posed at the anchor faces' vertices (Body.pose_at) and the guard, frames at once as a "
                   f"bake does it (guard_chunk_frames), on the first {frames} frames of "
                   "walk_brisk (best of 3). Spread: over about "
                   f"{GUARD_SPREAD_M * 100:g} cm, {GUARD_ROUNDS} rounds.\n\n"
                   + markdown_table(["garment", "vertices", "frames at once", "spread passes", "alone ms/frame",
                                    "spread ms/frame"],
                                    rows))
    print(f"wrote {out}")


def figure(args) -> None:
    """The example t-shirt on frame 30 of arm_swing_fast seen from either side (garment only): the network alone,
    the guard lifting each vertex alone, the guard spreading its lifts: contact_guard_armpit.png."""
    from formats.render import RenderOptions, contact_sheet, render_image, scene_from_sequence, write_png
    from formats.sequence import Sequence

    body = default_body()
    garment = read_obj(ROOT / "examples" / "tshirt.obj")
    motion = MOTION_LIBRARY["arm_swing_fast"](fps=30.0)
    frame = 30
    motion = dataclasses.replace(motion, poses=motion.poses[:frame + 1], trans=motion.trans[:frame + 1])
    deformer = model_deform.load_model_deformer(contact_guard=False, strain_limit=None)
    raw = deformer.deform(garment, body, motion)[frame:]
    betas = body.fit_betas(motion.betas)
    body_points, _ = body.pose(poses_for_body(motion, body.n_joints)[frame:], motion.trans[frame:], betas)
    anchors = pushout.body_anchors(garment.vertices, garment.faces, body, betas)
    columns = [("network alone", raw), ("guard, lone lifts (before)", guard_contact(raw, body_points, anchors,
                                                                                   **ALONE)[0]),
               ("guard, spread (now)", guard_contact(raw, body_points, anchors)[0])]
    images = []
    for azimuth in (90.0, -90.0):
        options = RenderOptions(width=700, height=700, azimuth_deg=azimuth, elevation_deg=-10.0)
        images.append([render_image(scene_from_sequence(Sequence(points, garment.faces, motion.fps, source=name)),
                                    0, "front", options) for name, points in columns])
    out = write_png(args.out.with_name("contact_guard_armpit.png"),
                    contact_sheet(images, [[name for name, _ in columns]] * 2, thumb_width=500))
    print(f"wrote {out}")


#: `--depth-bands`' scenes: (garment, motion file under the repository, --frames).
DEPTH_SCENES = [("dress", "examples/crouch.npz", "0:"), ("trousers", "examples/crouch.npz", "0:"),
                ("dress", "examples/run.npz", "0:40"), ("tshirt", "examples/run.npz", "0:40"),
                ("jumpsuit", "examples/jump.npz", "0:40"), ("skirt", "examples/jump.npz", "0:40"),
                ("dress", "data/heldout/walk_brisk.npz", "0:30")]


class _EveryRound(dict):
    """A guard's state that never holds its depth share: each round decides it anew, as before 2026-12-07."""

    def __contains__(self, key):
        return key != "depth_share" and super().__contains__(key)


def _before_depth_share(behind, depth, fade):
    """The depth share before 2026-12-07: its weight linear over a 3 cm band (the lift up to 3.7x as fast)."""
    return pushout._fade(behind, depth, 0.03)


def depth_bands(args) -> None:
    """The guard's depth band before 2026-12-07 and now, in the default model bake (contact guard alternating with
    the strain limit) on DEPTH_SCENES: E_verts against the simulator (10 substeps, no self-contact; kept in
    --sims), % of vertices more than 2 mm inside, and the vertex-frames the guard accelerates (second difference,
    mm/frame^2) more than 10 and 20 mm beyond the network's own output with the limit alone:
    benchmarks/results/contact_guard_depth.md."""
    import re

    import torch

    from benchmarks.shape_range import _simulated
    from core.tradeoff import Config, compare, measure
    from formats.obj import read_garment
    from garmentcli.common import prepare_motion

    torch.set_num_threads(1)
    body = default_body()
    reference = Config("sim 10 substeps", "sim", {"substeps": 10, "self_contact": False}, reference=True)
    model = Config("model", "model", {"path": None, "precision": "float32", "push_out": False})
    share, guard = pushout._depth_share, pushout.guard_contact

    def before(*a, state=None, **k):
        every = _EveryRound() if state is None else _EveryRound(state)
        try:
            return guard(*a, state=every, **k)
        finally:
            if state is not None:  # what the guard kept for the next guard of these frames
                state.clear()
                state.update(every)

    rows = []
    for name, motion_path, frames in DEPTH_SCENES:
        garment = read_garment(ROOT / "examples" / f"{name}.obj")
        motion, _ = prepare_motion(str(ROOT / motion_path), 30.0, frames, 0, body=body)
        kept = args.sims / f"{name}_{re.sub('[^A-Za-z0-9]+', '_', Path(motion_path).stem + '_' + frames)}.npz"
        ref = _simulated(reference, garment, body, motion, kept)
        unguarded = model_deform.load_model_deformer()
        unguarded.contact_guard = False
        network = unguarded.deform(garment, body, motion).astype(np.float64)
        steady = np.linalg.norm(np.diff(network, 2, axis=0), axis=2) * 1e3
        for label in ("before", "now"):
            if label == "before":
                pushout._depth_share, pushout.guard_contact = _before_depth_share, before
            try:
                m = measure(model, garment, body, motion, repeats=1)
            finally:
                pushout._depth_share, pushout.guard_contact = share, guard
            compare([ref, m], garment, body, motion)
            added = np.linalg.norm(np.diff(m.points.astype(np.float64), 2, axis=0), axis=2) * 1e3 - steady
            rows.append([name, f"{Path(motion_path).stem} {frames}", label, f"{m.metrics['e_verts']:.2f}",
                         f"{m.metrics['penetration_pct']:.3f}", int((added > 10).sum()), int((added > 20).sum()),
                         f"{added.max():.1f}"])
            print(" | ".join(map(str, rows[-1])), flush=True)
    header = ["garment", "motion", "depth band", "E_verts mm", "inside %", "accelerated > 10 mm", "> 20 mm",
              "largest mm"]
    text = ("# The contact guard's depth band, before 2026-12-07 and now\n\n"
            f"`python benchmarks/contact_guard.py --depth-bands` on {platform.processor() or platform.machine()}, "
            "one torch thread: the default model bake (contact guard alternating with the strain limit), 30 fps. "
            "Before: the lift's weight falling linearly over 3 cm beyond the 5 cm depth, decided anew in every "
            "round; now: the lift falling linearly over 5 cm, its share decided on the network's output. E_verts "
            "against the simulator (10 substeps, no self-contact); inside: % of vertices more than 2 mm inside the "
            "body; accelerated: vertex-frames whose second difference is more than 10 (20) mm/frame^2 larger than "
            "the unguarded bake's (the network and the strain limit), and the largest such excess.\n\n"
            + markdown_table(header, rows) + "\n")
    out = ROOT / "benchmarks" / "results" / "contact_guard_depth.md"
    out.write_text(text)
    print(f"wrote {out}")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    scene_arguments(ap, frames=90)
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "contact_guard.md",
                    help="a bare name goes to benchmarks/results/ (as the results' own command lines name it)")
    ap.add_argument("--timing", action="store_true", help="time the guard alone (contact_guard_timing.md)")
    ap.add_argument("--figure", action="store_true", help="the t-shirt's armpits (contact_guard_armpit.png)")
    ap.add_argument("--depth-bands", action="store_true",
                    help="the depth band before 2026-12-07 and now (contact_guard_depth.md)")
    ap.add_argument("--sims", type=Path, default=ROOT / "data" / "guard_sims",
                    help="--depth-bands: where the simulations are kept and reused")
    args = ap.parse_args(argv)
    if args.out.parent == Path("."):
        args.out = ROOT / "benchmarks" / "results" / args.out
    if args.timing:
        return timing(args)
    if args.figure:
        return figure(args)
    if args.depth_bands:
        return depth_bands(args)
    body = default_body()
    deformer = model_deform.load_model_deformer(strain_limit=None)  # the guard alone (core/strain.py after it)
    rows = []
    for garment_name, name, garment, motion, simulated, settle in scenes(args):
        body_points, _ = body.pose(poses_for_body(motion, body.n_joints), motion.trans, body.fit_betas(motion.betas))
        outputs = {config: run(deformer, garment, body, motion, guard) for config, guard in CONFIGS.items()}
        raw, anchors = outputs["off"][0], outputs["faded"][1]
        edges = mesh_edges(garment.faces)
        rest = edge_lengths(garment.vertices, edges)
        behind, lateral, _ = anchor_offsets(raw, body_points, anchors)
        still = (np.abs(np.diff(behind, axis=0)) < STILL_M) & (np.abs(np.diff(lateral, axis=0)) < STILL_M)
        for config, (points, _) in outputs.items():
            after = points[settle:]
            stats = {"penetration %": penetration_stats(points, body_points, body.faces,
                                                        max_frames=args.penetration_frames)["mean_percent"],
                     **lift_stats(points, raw, still),
                     "torn frames": int(torn_frames(after, edges, rest).sum()),
                     "E_verts mm": "" if simulated is None else
                     1e3 * float(np.linalg.norm(after - simulated, axis=-1).mean())}
            rows.append([garment_name, name, len(after), config, *stats.values()])
        print(f"{garment_name} {name}: " + ", ".join(f"{r[3]} {r[4]:.3f} % {r[-2]} torn"
                                                     for r in rows[-len(CONFIGS):]), flush=True)
    command = " ".join([*scene_command(args), f"--penetration-frames {args.penetration_frames}",
                        f"--out {args.out.name}"])
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(report(["garment", "motion", "frames", "guard", *stats], rows, command))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
