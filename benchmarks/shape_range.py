"""The shipped model's accuracy across body shapes: on the shapes it was trained on, between them, on unseen
shapes within the dataset's range and beyond it (where a bake clips the shape the network sees,
`core.model_deform.within_trained`), each against the simulator on the same body, beside LBS.

    python benchmarks/shape_range.py [--garments dress trousers] [--frames 30] [--motion data/heldout/walk_brisk.npz]
        [--shapes LABEL ...] [--sims data/shape_range]

Per garment and body shape: the simulator as `garment dataset` runs it by default (10 substeps, no self-contact:
what the model learned from) is the reference; LBS and the model (float32, its default post-processes) are
measured against it as `garment tradeoff` does (`core.tradeoff.measure` and `compare`): E_verts (mm) and the
share of vertices more than 2 mm inside the body; beyond the trained shapes also the model given the body's own
shape unclipped (the bake before 2026-12-07). The motion's first FRAMES frames at 30 fps. Writes
benchmarks/results/shape_range.md (or --out). Nothing here is asserted by the tests.
"""

from __future__ import annotations

import argparse
import platform
import re
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import torch  # noqa: E402

from core.body import default_body  # noqa: E402
from core.dataset import sample_betas  # noqa: E402
from core.model_deform import DEFAULT_TRAINED_BODIES, within_trained  # noqa: E402
from core.tradeoff import (Config, compare, load_simulation, measure, save_simulation, simulation_key,  # noqa: E402
                           simulation_scene)
from formats.obj import read_garment  # noqa: E402
from formats.report import markdown_table  # noqa: E402
from garmentcli.common import prepare_motion  # noqa: E402

N_BETAS = 10


def shapes() -> dict[str, tuple[str, np.ndarray]]:
    """{label: (kind, betas (10,))}: the shipped model's three training bodies (`garment dataset`'s defaults), two
    points between them, two unseen draws in the dataset's +-2 (another seed), all coefficients +-3 and the
    first +4 (a tall body: the shipped model tore the jumpsuit's leg off there before the clip)."""
    trained = sample_betas(DEFAULT_TRAINED_BODIES, N_BETAS, 2.0, seed=0).astype(np.float64)
    unseen = sample_betas(3, N_BETAS, 2.0, seed=7).astype(np.float64)
    return {
        "mean (trained 0)": ("trained", trained[0]),
        "trained 1": ("trained", trained[1]),
        "trained 2": ("trained", trained[2]),
        "half of trained 1": ("between", 0.5 * trained[1]),
        "trained 1 and 2's midpoint": ("between", 0.5 * (trained[1] + trained[2])),
        "unseen draw 1 (+-2)": ("unseen", unseen[1]),
        "unseen draw 2 (+-2)": ("unseen", unseen[2]),
        "all +3": ("beyond", np.full(N_BETAS, 3.0)),
        "all -3": ("beyond", np.full(N_BETAS, -3.0)),
        "betas[0] +4": ("beyond", np.eye(N_BETAS)[0] * 4.0),
    }


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--garments", nargs="+", default=["dress", "trousers"])
    p.add_argument("--motion", type=Path, default=ROOT / "data" / "heldout" / "walk_brisk.npz")
    p.add_argument("--frames", type=int, default=30)
    p.add_argument("--shapes", nargs="+", default=None, help="labels of `shapes()` to run (default: all)")
    p.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "shape_range.md")
    p.add_argument("--sims", type=Path, default=ROOT / "data" / "shape_range",
                   help="where the simulations are kept and reused (keyed on their scene)")
    args = p.parse_args(argv)
    torch.set_num_threads(1)
    body = default_body()
    reference = Config("sim 10 substeps", "sim", {"substeps": 10, "self_contact": False}, reference=True)
    model = Config("model", "model", {"path": None, "precision": "float32", "push_out": False})
    unclipped = Config("model, unclipped", "model", {"path": None, "precision": "float32", "push_out": False})
    lbs = Config("lbs", "lbs")
    rows, start = [], time.perf_counter()
    chosen = {k: v for k, v in shapes().items() if args.shapes is None or k in args.shapes}
    trained = _shipped_range()
    for name in args.garments:
        garment = read_garment(ROOT / "examples" / f"{name}.obj")
        for label, (kind, betas) in chosen.items():
            motion, _ = prepare_motion(str(args.motion), 30.0, f"0:{args.frames}", 0,
                                       ",".join(f"{b:.6f}" for b in betas), body=body)
            seen = within_trained(betas, trained)
            kept = args.sims / f"{name}_{re.sub('[^A-Za-z0-9+-]+', '_', label)}.npz"
            results = [_simulated(reference, garment, body, motion, kept)]
            results += [measure(c, garment, body, motion, repeats=1) for c in (lbs, model)]
            if not np.array_equal(seen, betas):
                m = _measure_unclipped(unclipped, garment, body, motion)
                results.append(m)
            compare(results, garment, body, motion)
            by = {r.config.name: r.metrics for r in results}
            clipped = int(np.sum(seen != betas))
            row = [name, label, kind, f"{np.abs(betas).max():.2f}", str(clipped),
                   f"{by['lbs']['e_verts']:.1f}", f"{by['model']['e_verts']:.1f}",
                   f"{by['model']['e_verts'] / by['lbs']['e_verts']:.2f}",
                   f"{by['model, unclipped']['e_verts']:.1f}" if "model, unclipped" in by else "-",
                   f"{by[reference.name]['penetration_pct']:.2f}", f"{by['lbs']['penetration_pct']:.2f}",
                   f"{by['model']['penetration_pct']:.2f}",
                   f"{by['model, unclipped']['penetration_pct']:.2f}" if "model, unclipped" in by else "-"]
            rows.append(row)
            print(" | ".join(row), f"({time.perf_counter() - start:.0f} s)", flush=True)
    header = ["garment", "body shape", "kind", "largest abs beta", "betas clipped", "LBS E_verts mm",
              "model E_verts mm", "model / LBS", "unclipped model E_verts mm", "sim inside %", "LBS inside %",
              "model inside %", "unclipped model inside %"]
    text = (f"# The shipped model across body shapes\n\n`python benchmarks/shape_range.py --garments "
            f"{' '.join(args.garments)} --frames {args.frames} --motion {args.motion.relative_to(ROOT)}` on "
            f"{platform.processor() or platform.machine()}, one torch thread ({time.perf_counter() - start:.0f} s). "
            f"The first {args.frames} frames at 30 fps; reference: the simulator as `garment dataset` runs it by "
            "default (10 substeps, no self-contact); E_verts: mean vertex distance to it; inside: % of vertices more "
            "than 2 mm inside the body (winding number). Kinds: the three bodies the shipped model was trained on "
            "(`garment dataset`'s defaults: `sample_betas(3, 10, 2.0, seed=0)`), points between them, unseen draws "
            "within the dataset's +-2 (seed 7), all coefficients +-3 and the first +4; betas clipped: coefficients beyond the "
            "trained range that a bake clips for the network (`within_trained`); the unclipped model is the bake "
            "before 2026-12-07.\n\n" + markdown_table(header, rows) + "\n")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text)
    print(text)


def _simulated(config: Config, garment, body, motion, path: Path):
    """The reference row, from `path` where it holds this scene's simulation, else simulated and kept there."""
    key = simulation_key(config, simulation_scene(garment, body, motion))
    kept = load_simulation(path, config, key)
    if kept is not None:
        return kept
    m = measure(config, garment, body, motion, repeats=1)
    path.parent.mkdir(parents=True, exist_ok=True)
    save_simulation(path, m, key, garment.faces, motion.fps)
    return m


def _shipped_range():
    from core.model_deform import load_model_deformer

    return load_model_deformer().trained_betas


def _measure_unclipped(config: Config, garment, body, motion):
    """`measure` of the shipped model given the body's own shape (no trained range)."""
    import core.tradeoff as tradeoff

    made = tradeoff.make_deformer

    def unclipped(c, *a, **k):
        d = made(c, *a, **k)
        d.trained_betas = None
        return d

    tradeoff.make_deformer = unclipped
    try:
        return measure(config, garment, body, motion, repeats=1)
    finally:
        tradeoff.make_deformer = made


if __name__ == "__main__":
    main()
