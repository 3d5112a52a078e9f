"""The model's artefacts in time, told apart from the cloth's swing: zig-zags and the snap-then-freeze, against the
simulator and LBS on the same scenes, in one run.

    python benchmarks/temporal_artefacts.py [--hold 30] [--out benchmarks/results/temporal_artefacts.md]

Counting accelerations beyond the body's (`benchmarks/residual_smoothing.py`) does not tell the network's
artefacts from the cloth's swing: the simulator's cloth accelerates more than the model's. Two measures do:

- **reversals**: vertex-frames where the garment's velocity beyond the skinned body's (the output less the LBS
  bake, differenced) turns back, u_t . u_(t-1) < 0, both over REVERSAL_MM mm/frame, per vertex and second of the
  moving frames. Cloth swinging turns back at the end of each swing (a few times a second); a zig-zag turns back
  every frame.
- **the hold**: the motion's last pose held for --hold frames (the body still, as at the end of a shot); the
  garment's speed beyond the body in the hold's first three frames (`hold 1-3`, mm/frame) and its last five (`hold
  end`), and the jump at the hold's first frame over the speed of the moving frames before it (`snap`: 1 goes on
  as before, 0 stops at once). The simulator's cloth swings on and settles; a network that reads the body's
  velocities stops the cloth the frame the body stops. `stops after`: the held frames until that speed stays
  under STILL_MM.

Scenes: the example dress on the run and the skirt on the walk (30 frames at 30 fps, then the hold), the
jumpsuit's jump (the model's kick; no simulator: 91 frames); the simulator at the bake's defaults (its output
cached in data/temporal_artefacts/: about 1 minute a scene on 2 cores, the first also compiles), the shipped
model in float32 (contact guard and strain limit on, one torch thread) and LBS. Nothing here is asserted by the tests.
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

import torch  # noqa: E402

from core.body import default_body  # noqa: E402
from core.deform import LBSDeformer  # noqa: E402
from core.model_deform import load_model_deformer  # noqa: E402
from formats.obj import read_garment  # noqa: E402
from formats.report import markdown_table, write_markdown  # noqa: E402
from garmentcli.common import prepare_motion  # noqa: E402

CACHE = ROOT / "data" / "temporal_artefacts"
#: (garment, example motion, --frames, simulated)
SCENES = [("dress", "run", "0:60", True), ("skirt", "walk", "0:60", True), ("jumpsuit", "jump", None, False)]
#: A velocity beyond the body's under this (mm/frame) turning back is not counted: the cloth at rest, rounding.
REVERSAL_MM = 2.0
#: Held, the garment has stopped once its speed beyond the body stays under this (mm/frame, mean over vertices).
STILL_MM = 0.5


def held(motion, frames: int):
    """`motion` with its last pose (and place) held for `frames` more frames."""
    return dataclasses.replace(motion, poses=np.concatenate([motion.poses, np.repeat(motion.poses[-1:], frames, 0)]),
                               trans=np.concatenate([motion.trans, np.repeat(motion.trans[-1:], frames, 0)]))


def beyond_body_mm(points: np.ndarray, lbs: np.ndarray) -> np.ndarray:
    """(T-1, V, 3) the garment's velocity beyond the skinned body's, mm/frame."""
    return np.diff(points.astype(np.float64) - lbs, axis=0) * 1e3


def reversals(u: np.ndarray, fps: float) -> float:
    """Turns back of velocities `u` (T, V, 3; mm/frame) over REVERSAL_MM, per vertex and second."""
    fast = np.linalg.norm(u, axis=2) > REVERSAL_MM
    back = (np.einsum("tvc,tvc->tv", u[1:], u[:-1]) < 0) & fast[1:] & fast[:-1]
    return float(back.sum() / (u.shape[1] * len(u) / fps))


def measures(points: np.ndarray, lbs: np.ndarray, moving: int, fps: float) -> dict:
    """The table's measures of an output `points` (T, V, 3) whose first `moving` frames move, the rest held."""
    u = beyond_body_mm(points, lbs)
    speed = np.linalg.norm(u, axis=2).mean(axis=1)  # (T-1,) mean over vertices, mm/frame
    before = float(speed[moving - 6:moving - 1].mean())  # the last moving frames' (u[t] is frame t to t+1)
    hold = speed[moving - 1:]
    moves = np.flatnonzero(hold >= STILL_MM)
    return {"reversals": reversals(u[:moving - 1], fps), "moving": before, "hold_start": float(hold[:3].mean()),
            "hold_end": float(hold[-5:].mean()), "snap": float(hold[0] / max(before, 1e-9)),
            "stops": None if len(moves) and moves[-1] == len(hold) - 1 else int(moves[-1] + 1 if len(moves) else 0)}


def simulated(garment_name: str, motion_name: str, garment, body, motion) -> np.ndarray:
    """The simulator's output at the bake's defaults, cached in CACHE."""
    from core.sim import SimDeformer

    path = CACHE / f"{garment_name}_{motion_name}_{motion.n_frames}.npy"
    if not path.is_file():
        path.parent.mkdir(parents=True, exist_ok=True)
        np.save(path, SimDeformer().deform(garment, body, motion))
    return np.load(path).astype(np.float64)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--hold", type=int, default=30, help="frames the last pose is held")
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "temporal_artefacts.md")
    args = parser.parse_args()
    torch.set_num_threads(1)
    body = default_body()
    rows = []
    for garment_name, motion_name, frames, simulate in SCENES:
        garment = read_garment(ROOT / "examples" / f"{garment_name}.obj")
        motion, _ = prepare_motion(str(ROOT / "examples" / f"{motion_name}.npz"), 30.0, frames, 0)
        moving = motion.n_frames
        motion = held(motion, args.hold)
        lbs = LBSDeformer().deform(garment, body, motion).astype(np.float64)
        outputs = {"simulator": simulated(garment_name, motion_name, garment, body, motion)} if simulate else {}
        outputs.update(model=load_model_deformer().deform(garment, body, motion), lbs=lbs)
        for name, points in outputs.items():
            m = measures(points, lbs, moving, motion.fps)
            rows.append([f"{garment_name} {motion_name} ({moving} + {args.hold} held)", name, f"{m['reversals']:.2f}",
                         f"{m['moving']:.2f}", f"{m['hold_start']:.2f}", f"{m['hold_end']:.2f}", f"{m['snap']:.2f}",
                         f"> {args.hold}" if m["stops"] is None else str(m["stops"])])
            print(rows[-1], flush=True)
    header = ["scene", "output", "reversals /vertex/s", "moving mm/frame", "hold 1-3", "hold end", "snap",
              "stops after (frames)"]
    write_markdown(args.out, [
        "# The model's artefacts in time: zig-zags and the snap-then-freeze", "",
        f"`python benchmarks/temporal_artefacts.py --hold {args.hold}` on {platform.processor() or platform.machine()}"
        f": the garment's velocity beyond the skinned body's (output less LBS, mm/frame, mean over vertices); "
        f"reversals: vertex-frames where it turns back (both over {REVERSAL_MM:g} mm/frame) per vertex and second "
        "of the moving frames; the hold: the last pose held, the speed in its first three frames and its last five; "
        f"snap: the first held frame's speed over the last moving frames' (1: goes on, 0: stops at once); stops "
        f"after: the held frames until its speed stays under {STILL_MM:g} mm/frame. LBS has none by definition. "
        "The simulator at the bake's defaults, the shipped model in float32.", "",
        markdown_table(header, rows)], show=True)


if __name__ == "__main__":
    main()
