"""Smoothing the model's output in time (tried 2026-12-07, not shipped): the network's residual over LBS
(model - LBS, world frame) under a Gaussian of SIGMA frames before the contact guard and strain limit, against the
simulator's reference.

    python benchmarks/residual_smoothing.py [--sigmas 0 0.7 1 1.5 2] [--out benchmarks/results/residual_smoothing.md]

The temporal audit (2026-12-06) counted the model's accelerations beyond the body's as artefacts (the jumpsuit's
kick, the dress's hem on the crouch). Per scene and sigma: vertex-frames whose acceleration beyond LBS's (the
second difference of the output less the LBS bake) exceeds 10 and 30 mm/frame^2, the largest, and, where a
simulator reference is made (20 substeps, self-contact; cached in data/residual_smoothing/, about 5 minutes a
scene on 2 cores), the mean and 99th-percentile vertex error against it and the reference's own accelerations
beyond LBS. The shipped model, float32, its contact guard and strain limit on, one torch thread, 30 fps.
Nothing here is asserted by the tests.
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
from scipy.ndimage import gaussian_filter1d  # noqa: E402

import core.model_deform as model_deform  # noqa: E402
from core.body import default_body  # noqa: E402
from core.deform import LBSDeformer  # noqa: E402
from formats.obj import read_garment  # noqa: E402
from formats.report import markdown_table, write_markdown  # noqa: E402
from garmentcli.common import prepare_motion  # noqa: E402

CACHE = ROOT / "data" / "residual_smoothing"
#: (garment, example motion, --frames, simulate a reference)
SCENES = [("dress", "run", "0:60", True), ("skirt", "walk", "0:60", True), ("dress", "crouch", None, False),
          ("jumpsuit", "jump", None, False), ("tshirt", "turn", None, False)]


def accelerations_mm(points: np.ndarray, lbs: np.ndarray) -> np.ndarray:
    """(T-2, V) |second difference of points - lbs| in mm/frame^2: the acceleration beyond the skinned body's."""
    return np.linalg.norm(np.diff(points.astype(np.float64) - lbs, 2, axis=0), axis=2) * 1e3


def reference(garment_name, motion_name, garment, body, motion):
    """The simulator's reference of a scene (20 substeps, self-contact), cached in CACHE."""
    from core.sim import SimDeformer, SimOptions

    path = CACHE / f"{garment_name}_{motion_name}_{motion.n_frames}.npy"
    if not path.is_file():
        points = SimDeformer(options=SimOptions(substeps=20, self_contact=True)).deform(garment, body, motion)
        path.parent.mkdir(parents=True, exist_ok=True)
        np.save(path, points)
    return np.load(path).astype(np.float64)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sigmas", type=float, nargs="+", default=[0.0, 0.7, 1.0, 1.5, 2.0])
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "residual_smoothing.md")
    args = parser.parse_args()
    torch.set_num_threads(1)
    body = default_body()
    state = {}
    guard_and_limit = model_deform.guard_and_limit

    def smoothed(deformer, out, *rest, **kw):  # the network's output smoothed before the guard and the limit
        if state["sigma"] > 0:
            out[:] = state["lbs"] + gaussian_filter1d(out - state["lbs"], state["sigma"], axis=0, mode="nearest")
        return guard_and_limit(deformer, out, *rest, **kw)

    model_deform.guard_and_limit = smoothed
    rows = []
    for garment_name, motion_name, frames, simulate in SCENES:
        garment = read_garment(ROOT / "examples" / f"{garment_name}.obj")
        motion, _ = prepare_motion(str(ROOT / "examples" / f"{motion_name}.npz"), 30.0, frames, 0)
        lbs = LBSDeformer().deform(garment, body, motion).astype(np.float32)
        state["lbs"] = lbs
        ref = reference(garment_name, motion_name, garment, body, motion) if simulate else None
        scene = f"{garment_name} {motion_name} ({motion.n_frames} frames)"
        if ref is not None:
            acc = accelerations_mm(ref, lbs)
            rows.append([scene, "simulator", f"{(acc > 10).sum():,}", f"{(acc > 30).sum():,}", f"{acc.max():.1f}",
                         "-", "-"])
        for sigma in args.sigmas:
            state["sigma"] = sigma
            points = model_deform.load_model_deformer().deform(garment, body, motion).astype(np.float64)
            acc = accelerations_mm(points, lbs)
            err = None if ref is None else np.linalg.norm(points - ref, axis=2) * 1e3
            rows.append([scene, f"model, sigma {sigma:g}", f"{(acc > 10).sum():,}", f"{(acc > 30).sum():,}",
                         f"{acc.max():.1f}", "-" if err is None else f"{err.mean():.2f}",
                         "-" if err is None else f"{np.percentile(err, 99):.1f}"])
            print(rows[-1], flush=True)
    header = ["scene", "output", "vertex-frames > 10 mm/frame^2", "> 30", "largest", "error mm", "p99 mm"]
    write_markdown(args.out, ["# Smoothing the model's residual in time", "",
                              f"`python benchmarks/residual_smoothing.py` on {platform.processor() or platform.machine()}"
                              ", one torch thread: the shipped model (float32, contact guard and strain limit on), its "
                              "residual over LBS under a Gaussian of sigma frames before the guard; accelerations "
                              "beyond LBS's (mm/frame^2, vertex-frames); error against the simulator's reference (20 "
                              "substeps, self-contact) where one is made. Not shipped: the simulator's cloth "
                              "accelerates beyond the body more than the model's, and every sigma moves the model "
                              "away from it.", "", markdown_table(header, rows)], show=True)


if __name__ == "__main__":
    main()
