"""The scenes `benchmarks/lbs_leg_spread.py` and `benchmarks/guard_near.py` measure, and their report's writing.

Every example garment on the example motions named and the held-out brisk walk's first 15 frames at 30 fps
(`benchmarks/tradeoff_examples.sh` writes it to data/heldout/), with the simulator's reference where
`benchmarks/results/tradeoff_v5/<garment>_walk_brisk/simulations/` holds one (20 substeps with self-contact).
"""

from __future__ import annotations

import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from core.body import Body  # noqa: E402
from core.garment import Garment  # noqa: E402
from core.motion import Motion, poses_for_body  # noqa: E402
from formats.obj import read_garment  # noqa: E402
from formats.report import markdown_table  # noqa: E402
from garmentcli.common import prepare_motion  # noqa: E402

REFERENCES = ROOT / "benchmarks" / "results" / "tradeoff_v5"
GARMENTS = ("skirt", "dress", "trousers", "jumpsuit", "tshirt")
HELD_OUT = ("walk_brisk 0:30", ROOT / "data" / "heldout" / "walk_brisk.npz", "0:30")


@dataclass
class Scene:
    """A garment on a motion: the posed body's points (T, Vb, 3), the simulator's reference (T, V, 3) or None."""

    garment_name: str
    garment: Garment
    motion_name: str
    motion: Motion
    posed: np.ndarray
    reference: np.ndarray | None


def example_scenes(body: Body, motions: tuple[str, ...]) -> Iterator[Scene]:
    """Every example garment on each of the example `motions` (names of examples/*.npz) and the held-out walk;
    a motion not on this machine is skipped, said."""
    named = [(name, ROOT / "examples" / f"{name}.npz", None) for name in motions] + [HELD_OUT]
    for garment_name in GARMENTS:
        garment = read_garment(ROOT / "examples" / f"{garment_name}.obj")
        for motion_name, motion_path, frames in named:
            if not motion_path.is_file():
                print(f"skipped {garment_name} on {motion_name}: not on this machine", flush=True)
                continue
            motion, _ = prepare_motion(str(motion_path), 30.0, frames, 0, body=body)
            posed, _ = body.pose(poses_for_body(motion, body.n_joints), motion.trans, body.fit_betas(motion.betas))
            stored = REFERENCES / f"{garment_name}_walk_brisk" / "simulations" / "sim_20_substeps_self-contact.npz"
            reference = np.load(stored)["points"] if frames and stored.is_file() else None
            yield Scene(garment_name, garment, motion_name, motion, posed, reference)


def benchmark_start(doc: str, out_name: str) -> tuple[Path, Body]:
    """A benchmark's `--out` (default benchmarks/results/`out_name`; `doc`'s first line its description) and the
    default body; torch on one thread (each row's time then does not depend on what else the machine runs)."""
    import argparse

    import torch

    from core.body import default_body

    parser = argparse.ArgumentParser(description=doc.split("\n")[0])
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / out_name)
    out = parser.parse_args().out
    torch.set_num_threads(1)
    return out, default_body()


def model_variants(body: Body, motions: tuple[str, ...], variants) -> Iterator[tuple[Scene, str, object, np.ndarray]]:
    """(scene, variant's name, the shipped model's deformer, its points (T, V, 3)) of every scene of
    `example_scenes` and each of `variants`: (name, {name of a `core.pushout` constant: value}), set while the
    model (float32, contact guard and strain limit on) bakes the scene, as they were after."""
    import core.pushout as pushout
    from core.model_deform import load_model_deformer

    for scene in example_scenes(body, motions):
        for name, settings in variants:
            before = {key: getattr(pushout, key) for key in settings}
            for key, value in settings.items():
                setattr(pushout, key, value)
            try:
                model = load_model_deformer()
                points = model.deform(scene.garment, body, scene.motion)
            finally:
                for key, value in before.items():
                    setattr(pushout, key, value)
            yield scene, name, model, points


def mean_error_mm(points: np.ndarray, reference: np.ndarray | None) -> str:
    """The mean vertex distance (mm) of `points` from `reference`, as a table cell ('-' without one)."""
    return "-" if reference is None else f"{np.linalg.norm(points - reference, axis=2).mean() * 1e3:.2f}"


def write_report(out: Path, title: str, intro: str, header: list[str], rows: list[list]) -> None:
    """Write `# title`, `intro` and the table of `rows` to `out` (Markdown), and print them."""
    text = f"# {title}\n\n{intro}\n\n" + markdown_table(header, rows) + "\n"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(text)
    print(text)
