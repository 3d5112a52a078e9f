"""The penetration share by winding number (core.geometry.points_inside_mesh since 2026-12-06) against the nearest
face's sign it replaced, on the example garments' bakes, in one run.

    python benchmarks/inside_test.py [--frames 60] [--motions walk run arms_raise crouch]

Each example garment baked by LBS and by the shipped model over the example motions (the first --frames frames at
30 fps), then, on the frames `bake` checks (`core.bake.checked_frames`), the share of garment vertices more than
2 mm inside the posed body by both tests, and each test's milliseconds per frame (the two one after the other on
the same frames). Where the new share is higher, the vertices it adds lie between body parts that pass into each
other (an arm pressed into the torso: the nearest face, the arm's, inside the torso, read as outside by its sign).
Writes benchmarks/results/inside_test.md. Nothing here is asserted by the tests.
"""

from __future__ import annotations

import argparse
import platform
import sys
import time
from pathlib import Path

import numpy as np
import torch

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from core.bake import PENETRATION_DEPTH_M, bake_item, checked_frames  # noqa: E402
from core.body import default_body  # noqa: E402
from core.deform import LBSDeformer  # noqa: E402
from core.geometry import TriangleMesh, points_inside_mesh  # noqa: E402
from core.model_deform import load_model_deformer  # noqa: E402
from core.motion import resample, select_frames  # noqa: E402
from formats.motion import load_motion  # noqa: E402
from formats.obj import read_obj  # noqa: E402
from formats.report import markdown_table  # noqa: E402

GARMENTS = ("dress", "skirt", "trousers", "tshirt", "jumpsuit")


def nearest_face_sign(points, verts, faces, depth):
    """The test before: the sign of the nearest face's (pseudo-)normal, one candidate pass."""
    return TriangleMesh(verts, faces).signed_distance(points, exact=False) < -depth


def shares(test, points, body_points, faces) -> tuple[float, float]:
    """(mean % of vertices inside over the frames, ms per frame) of one test."""
    t0 = time.perf_counter()
    inside = [test(p, b, faces, PENETRATION_DEPTH_M) for p, b in zip(points, body_points)]
    return 100.0 * float(np.mean(inside)), (time.perf_counter() - t0) / len(points) * 1e3


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=60)
    ap.add_argument("--motions", nargs="+", default=["walk", "run", "arms_raise", "crouch"])
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "inside_test.md")
    args = ap.parse_args(argv)
    torch.set_num_threads(1)
    body = default_body()
    methods = {"lbs": LBSDeformer(), "model": load_model_deformer(None)}
    rows, totals = [], {"old": [], "new": [], "old_ms": [], "new_ms": []}
    for name in GARMENTS:
        garment = read_obj(ROOT / "examples" / f"{name}.obj")
        for motion_name in args.motions:
            motion = resample(load_motion(ROOT / "examples" / f"{motion_name}.npz"), 30.0)
            motion = select_frames(motion, 0, min(args.frames, motion.n_frames))
            for method, deformer in methods.items():
                result = bake_item(garment, body, motion, deformer, with_body=True, check_penetration=False)
                frames = checked_frames(*result.garment_points.shape[:2])
                p, b = result.garment_points[frames], result.body_points[frames]
                old, old_ms = shares(nearest_face_sign, p, b, body.faces)
                new, new_ms = shares(points_inside_mesh, p, b, body.faces)
                rows.append([name, motion_name, method, len(frames), f"{old:.3f}", f"{new:.3f}",
                             f"{new / old:.2f}" if old else "-", f"{old_ms:.1f}", f"{new_ms:.1f}"])
                for key, value in (("old", old), ("new", new), ("old_ms", old_ms), ("new_ms", new_ms)):
                    totals[key].append(value)
                print(*rows[-1], flush=True)
    mean = {k: float(np.mean(v)) for k, v in totals.items()}
    text = [
        "# The penetration share: winding number against the nearest face's sign", "",
        f"`python benchmarks/inside_test.py --frames {args.frames} --motions {' '.join(args.motions)}`; "
        f"{platform.processor() or platform.machine()}, one torch thread. Share of garment vertices more than "
        f"{PENETRATION_DEPTH_M * 1e3:g} mm inside the posed body on the frames `bake` checks (up to 60 of the "
        f"first {args.frames}), % mean over them; each test's ms per frame.", "",
        markdown_table(["garment", "motion", "method", "frames", "nearest face's sign %", "winding number %",
                        "new / old", "old ms/frame", "new ms/frame"], rows), "",
        f"Mean over the {len(rows)} bakes: {mean['old']:.3f} % -> {mean['new']:.3f} % inside; "
        f"{mean['old_ms']:.1f} -> {mean['new_ms']:.1f} ms per frame.", "",
    ]
    args.out.write_text("\n".join(text))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
