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


def mean_error_mm(points: np.ndarray, reference: np.ndarray | None) -> str:
    """The mean vertex distance (mm) of `points` from `reference`, as a table cell ('-' without one)."""
    return "-" if reference is None else f"{np.linalg.norm(points - reference, axis=2).mean() * 1e3:.2f}"


def write_report(out: Path, title: str, intro: str, header: list[str], rows: list[list]) -> None:
    """Write `# title`, `intro` and the table of `rows` to `out` (Markdown), and print them."""
    text = f"# {title}\n\n{intro}\n\n" + markdown_table(header, rows) + "\n"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(text)
    print(text)
