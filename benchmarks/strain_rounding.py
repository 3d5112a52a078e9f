"""How far the strain limit (core/strain.py) moves rounding noise on its input, and what it costs, against an
earlier version of it, in one run.

    python benchmarks/strain_rounding.py [--against 95a47d2] [--frames 60] [--noise 1e-6]

The example dress, t-shirt and trousers on the kick, run and brisk walk of the motion library (60 frames at 30
fps), baked by the shipped model (contact guard on, strain limit off) and by LBS (10 smoothing passes), then
limited at STRAIN_LIMIT by this checkout's core/strain.py and by the one of git revision --against (read with
`git show`), each on the frames as baked and on them plus Gaussian noise of --noise metres (about ten float32
roundings at 1 m: what another thread count or a GPU changes). Per scene and version: the limited frames' distance
with and without the noise (mean and max over vertices and frames), the largest excess over the limit left, and
the limit's milliseconds per frame (one torch thread, the two versions one after the other on the same input).
Writes benchmarks/results/strain_rounding.md. Nothing here is asserted by the tests.
"""

from __future__ import annotations

import argparse
import importlib.util
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import core.strain as current  # noqa: E402
from core.bake import bake_item  # noqa: E402
from core.body import default_body  # noqa: E402
from core.deform import LBSDeformer  # noqa: E402
from core.model_deform import load_model_deformer  # noqa: E402
from core.motion import resample  # noqa: E402
from core.motiongen import MOTION_LIBRARY  # noqa: E402
from formats.obj import read_obj  # noqa: E402
from formats.report import markdown_table  # noqa: E402

GARMENTS = ("dress", "tshirt", "trousers")
MOTIONS = ("kick_right", "run", "walk_brisk")


def module_at(revision: str, folder: Path):
    """core/strain.py as git revision `revision` has it, imported as a module of its own."""
    text = subprocess.run(["git", "show", f"{revision}:core/strain.py"], cwd=ROOT, capture_output=True, text=True,
                          check=True).stdout
    path = folder / "strain_then.py"
    path.write_text(text)
    spec = importlib.util.spec_from_file_location("strain_then", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules["strain_then"] = module  # its dataclasses look themselves up there
    spec.loader.exec_module(module)
    return module


def measure(version, points: np.ndarray, noisy: np.ndarray, rest: np.ndarray, faces: np.ndarray) -> list:
    """[ms/frame, noise moved mean um, max mm, largest excess left mm] of one version on one output."""
    limit = version.strain_limit(rest, faces)
    t0 = time.perf_counter()
    clean, _ = version.limit_sequence(points.copy(), limit)
    ms = (time.perf_counter() - t0) / len(points) * 1e3
    moved = np.linalg.norm(version.limit_sequence(noisy.copy(), limit)[0] - clean, axis=-1)
    e = limit.edges
    excess = np.linalg.norm(clean[:, e[:, 1]] - clean[:, e[:, 0]], axis=-1) - limit.longest
    return [ms, 1e6 * float(moved.mean()), 1e3 * float(moved.max()), 1e3 * float(max(excess.max(), 0.0))]


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--against", default="95a47d2", help="git revision of the earlier core/strain.py")
    ap.add_argument("--frames", type=int, default=60)
    ap.add_argument("--noise", type=float, default=1e-6, help="metres")
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "strain_rounding.md")
    args = ap.parse_args(argv)
    torch.set_num_threads(1)
    rng = np.random.default_rng(0)
    body = default_body()
    deformers = {"model": load_model_deformer(strain_limit=None), "lbs": LBSDeformer()}
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        then = module_at(args.against, Path(tmp))
        for name in GARMENTS:
            garment = read_obj(ROOT / "examples" / f"{name}.obj")
            for motion_name in MOTIONS:
                motion = resample(MOTION_LIBRARY[motion_name](fps=60.0), 30.0)
                for method, deformer in deformers.items():
                    points = bake_item(garment, body, motion, deformer, with_body=False,
                                       check_penetration=False).garment_points[:args.frames].astype(np.float32)
                    noisy = (points + rng.normal(0.0, args.noise, points.shape)).astype(np.float32)
                    before = measure(then, points, noisy, garment.vertices, garment.faces)
                    now = measure(current, points, noisy, garment.vertices, garment.faces)
                    rows.append([name, motion_name, method, *before, *now])
                    print(name, motion_name, method, [f"{v:.3g}" for v in before + now], flush=True)
    head = ["garment", "motion", "method"] + [f"{v} {what}" for v in (args.against, "now") for what in
                                             ("ms/frame", "moved mean um", "moved max mm", "excess left mm")]
    cols = np.array([r[3:] for r in rows])
    lines = [
        "# The strain limit's passing-on of rounding, against an earlier version", "",
        f"Made by `python benchmarks/strain_rounding.py --against {args.against} --frames {args.frames} --noise "
        f"{args.noise:g}` on {platform.machine()}, one torch thread (module docstring: what is measured). Noise of "
        f"{args.noise:g} m on the limit's input; 'moved': how far it moved the limited frames.", "",
        markdown_table(head, rows), "",
        f"Over the {len(rows)} outputs: moved at most {cols[:, 2].max():.3g} mm ({args.against}) and "
        f"{cols[:, 6].max():.3g} mm (now), on average {cols[:, 1].mean():.3g} and {cols[:, 5].mean():.3g} um; the "
        f"limit's time summed {cols[:, 0].sum():.1f} and {cols[:, 4].sum():.1f} ms/frame; the largest excess left "
        f"{cols[:, 3].max():.2f} and {cols[:, 7].max():.2f} mm.", ""]
    args.out.write_text("\n".join(lines))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
