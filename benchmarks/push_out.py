"""`--push-out` (core/pushout.py): vertices inside the body by its winding number, moved to its outer surface
where that tears no edge, against the same without the tear check (before 2026-12-07) and the push-out before
2026-12-06 (inside by the nearest face's sign, moved to the closest body point).

    python benchmarks/push_out.py [--frames 60] [--garments dress skirt ...] [--motions walk crouch ...]

The shipped model (float32, contact guard on) on every example garment and the example motions given (30 fps,
the first FRAMES frames), then each push-out on its output, one torch thread. Per garment and push-out: its
time per frame (the median frame), the share of vertices inside the body after it (by winding number, as the
bake's penetration statistics count: any depth, and more than 2 mm), vertices moved per frame, those the
winding push-out moved to the outer surface (their closest point was inside another part), took back from it
not to tear an edge and left inside, the largest move, the frames with an edge more than twice its rest length
and the largest such stretch. Writes benchmarks/results/push_out.md. Nothing here is asserted by the tests.
"""

from __future__ import annotations

import argparse
import platform
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import torch  # noqa: E402

from core.body import default_body  # noqa: E402
from core.geometry import outward_offsets, points_inside_mesh  # noqa: E402
from core.model_deform import load_model_deformer  # noqa: E402
from core.motion import poses_for_body, resample, select_frames  # noqa: E402
from core.garment import mesh_edges  # noqa: E402
from core.geodesic import edge_lengths  # noqa: E402
from core.pushout import PUSH_OUT_MARGIN_M, push_out  # noqa: E402
from formats.motion import load_motion  # noqa: E402
from formats.obj import read_obj  # noqa: E402
from formats.report import markdown_table  # noqa: E402


def push_out_by_nearest_sign(points, body_points, body_faces, margin=PUSH_OUT_MARGIN_M):
    """The push-out before 2026-12-06 (no ground): inside by the nearest face's sign, to the closest point."""
    out = np.array(points, dtype=np.float32, copy=True)
    moved = np.zeros(len(out), dtype=np.int64)
    for t in range(len(out)):
        signed, closest, direction = outward_offsets(out[t], body_points[t], body_faces)
        sel = signed < margin
        out[t, sel] = (closest[sel] + margin * direction[sel]).astype(np.float32)
        moved[t] = int(sel.sum())
    return out, moved


def winding_without_tear_check(points, body_points, body_faces, report=None, edges=None):
    """The winding-number push-out before 2026-12-07: every vertex whose closest point lies inside another part to
    the outer surface, torn edges or not."""
    return push_out(points, body_points, body_faces, report=report)


def timed(fn, points, body_points, faces, edges):
    """(output, moved per frame, median seconds per frame, report): `fn` frame by frame."""
    outs, moved, seconds = [], [], []
    report = {"vertices_to_outer_surface": 0, "vertices_kept_off_outer_surface": 0, "vertices_left_inside": 0}
    for t in range(len(points)):
        extra = {}
        start = time.perf_counter()
        winding = fn is not push_out_by_nearest_sign
        o, m = fn(points[t:t + 1], body_points[t:t + 1], faces, **({"report": extra, "edges": edges} if winding else {}))
        seconds.append(time.perf_counter() - start)
        outs.append(o[0])
        moved.append(int(m[0]))
        for k in report:
            report[k] += extra.get(k, 0)
    return np.stack(outs), np.array(moved), float(np.median(seconds)), report


def largest_stretch(points, edges, rest_lengths) -> np.ndarray:
    """(T,) each frame's longest edge over its rest length."""
    return (np.linalg.norm(points[:, edges[:, 0]] - points[:, edges[:, 1]], axis=-1) / rest_lengths).max(axis=1)


def inside_share(points, body_points, faces, depth=0.0) -> float:
    return float(np.mean([points_inside_mesh(p, b, faces, depth).mean() for p, b in zip(points, body_points)]))


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--frames", type=int, default=60)
    p.add_argument("--garments", nargs="+", default=["dress", "jumpsuit", "skirt", "trousers", "tshirt"])
    p.add_argument("--motions", nargs="+", default=["walk", "crouch", "arms_raise"])
    p.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "push_out.md")
    args = p.parse_args(argv)
    torch.set_num_threads(1)
    body = default_body()
    deformer = load_model_deformer()
    methods = {"nearest face's sign (before 12-06)": push_out_by_nearest_sign,
               "winding number, tears (before 12-07)": winding_without_tear_check,
               "winding number (now)": push_out}
    rows = []
    for name in args.garments:
        garment = read_obj(ROOT / "examples" / f"{name}.obj")
        edges = mesh_edges(garment.faces)
        rest_lengths = edge_lengths(np.asarray(garment.vertices, dtype=np.float64), edges)
        acc = {m: {"s": [], "in": [], "deep": [], "moved": [], "outer": 0, "kept": 0, "left": 0, "max": 0.0,
                   "torn": 0, "stretch": 0.0} for m in methods}
        before_in, before_deep, before_torn, frames = [], [], 0, 0
        for motion_name in args.motions:
            motion = resample(load_motion(ROOT / "examples" / f"{motion_name}.npz"), 30.0)
            motion = select_frames(motion, 0, args.frames)
            points = deformer.deform(garment, body, motion)[: args.frames]
            n = len(points)
            body_points, _ = body.pose(poses_for_body(motion, body.n_joints)[:n], motion.trans[:n], motion.betas)
            before_in.append(inside_share(points, body_points, body.faces) * n)
            before_deep.append(inside_share(points, body_points, body.faces, 0.002) * n)
            before_torn += int((largest_stretch(points, edges, rest_lengths) > 2.0).sum())
            frames += n
            for label, fn in methods.items():
                out, moved, seconds, report = timed(fn, points, body_points, body.faces, edges)
                a = acc[label]
                a["s"].append(seconds)
                a["in"].append(inside_share(out, body_points, body.faces) * n)
                a["deep"].append(inside_share(out, body_points, body.faces, 0.002) * n)
                a["moved"].append(moved.sum())
                a["outer"] += report["vertices_to_outer_surface"]
                a["left"] += report["vertices_left_inside"]
                a["kept"] += report["vertices_kept_off_outer_surface"]
                stretch = largest_stretch(out, edges, rest_lengths)
                a["torn"] += int((stretch > 2.0).sum())
                a["stretch"] = max(a["stretch"], float(stretch.max()))
                a["max"] = max(a["max"], float(np.linalg.norm(out - points, axis=2).max()))
            print(f"{name} {motion_name}: {n} frames", flush=True)
        for label, a in acc.items():
            rows.append([name, garment.n_vertices, label, f"{1e3 * float(np.median(a['s'])):.1f}",
                         f"{100 * sum(before_in) / frames:.2f}", f"{100 * sum(a['in']) / frames:.2f}",
                         f"{100 * sum(a['deep']) / frames:.2f}", f"{sum(a['moved']) / frames:.0f}",
                         str(a["outer"]) if "winding" in label else "-",
                         str(a["kept"]) if "now" in label else "-", str(a["left"]) if "winding" in label else "-",
                         f"{1e3 * a['max']:.1f}", f"{before_torn} -> {a['torn']}", f"{a['stretch']:.2f}"])
    header = ["garment", "vertices", "push-out", "ms/frame", "inside before %", "inside after %",
              "> 2 mm after %", "moved/frame", "to outer surface", "taken back", "left inside", "largest move mm",
              "frames torn before -> after", "largest stretch"]
    text = (f"# `--push-out`: inside by winding number against the nearest face's sign\n\n"
            f"`python benchmarks/push_out.py --frames {args.frames} --motions {' '.join(args.motions)}` on "
            f"{platform.processor() or platform.machine()}, "
            f"one torch thread; the shipped model's output (contact guard on) on the example motions "
            f"{', '.join(args.motions)} (first {args.frames} frames at 30 fps each). Inside: the body's winding "
            "number, as `bake`'s penetration statistics count it; ms/frame: the push-out's median frame; "
            "to outer surface / taken back (not to tear an edge) / left inside: vertices over all frames; frames "
            "torn: frames with an edge longer than twice its rest length (largest stretch: the longest's ratio).\n\n"
            + markdown_table(header, rows) + "\n")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text)
    print(text)


if __name__ == "__main__":
    main()
