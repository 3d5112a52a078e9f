"""Garments no model was trained on but within its training range, simulated on the held-out motions.

    python benchmarks/heldout_garments.py [--out data/heldout_garments]

The shipped model's training garments are the example dress, skirt and trousers (`data/sim_v1`); its
held-out example garment, the t-shirt, is outside its training range (30 % of its skinning weight on
joints no training garment covers, see `core.model_deform.training_range`). These two garments are new
meshes of the trained families, built by the same generator with other cuts, lengths and eases:

- mini_dress: a tube dress from under the armpits to mid-thigh, wider flare than the example dress;
- shorts: a one-piece offset garment from the waist to above the knees, looser at the legs than the
  example trousers.

Each is simulated with the settings of the dataset the model was trained on (--like, default `data/sim_v1`:
substeps, self-contact, settle frames, clip length, body shapes) on that dataset's held-out test motions
with `garment dataset` (one dataset per garment, under --out). Evaluate with `python
benchmarks/model_table.py --data data/sim_v1 --held-out-data data/heldout_garments/mini_dress
--held-out-data data/heldout_garments/shorts ...`. Heavy output (the sequences) stays out of git.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from core.body import default_body  # noqa: E402
from core.garmentgen import (  # noqa: E402
    _above, _below, _ease_per_joint, _levels, _offset_garment, _RestBody, _tube_garment,
)
from core.motiongen import MOTION_LIBRARY  # noqa: E402
from formats.motion import save_motion  # noqa: E402
from formats.obj import write_obj  # noqa: E402

#: The held-out motions of data/sim_v1 (its manifest's test split), used when that manifest is absent.
TEST_MOTIONS = ("arm_swing_fast", "kick_right", "turn_right_wide", "walk_brisk")


def mini_dress(rest: _RestBody):
    lv = _levels(rest)
    return _tube_garment(rest, "mini_dress", y_top=lv["armpits"] - 0.03, y_bottom=0.5 * (lv["hips"] + lv["knees"]),
                         ease=0.015, flare_from_y=lv["hips"] + 0.3 * (lv["pelvis"] - lv["hips"]), flare_slope=0.3)


def shorts(rest: _RestBody):
    lv = _levels(rest)
    y_waist = lv["pelvis"] + 0.5 * (lv["spine1"] - lv["pelvis"])
    ease = _ease_per_joint(rest.n_joints, torso=0.014, arms=0.02, legs=0.04, neck=0.008)
    return _offset_garment(rest, "shorts", [_below(y_waist), _above(lv["knees"] + 0.08)], rest.joint("pelvis"), ease)


GARMENTS = {"mini_dress": mini_dress, "shorts": shorts}


#: The settings of data/sim_v1, used when no --like manifest is there.
SIM_V1 = {"frames_per_clip": 54, "settle": 6, "bodies": 3, "seed": 0, "solver": {"substeps": 10, "self_contact": False}}


def like_settings(like: Path) -> tuple[dict, list[str]]:
    """(settings, test motions) of the dataset at `like` (those of data/sim_v1 when it has no manifest)."""
    manifest = like / "manifest.json"
    if manifest.exists():
        m = json.loads(manifest.read_text())
        return m["settings"], list(m["splits"]["motions"]["test"])
    return SIM_V1, list(TEST_MOTIONS)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=ROOT / "data" / "heldout_garments")
    ap.add_argument("--inputs-only", action="store_true", help="write the garments and motions, simulate nothing")
    ap.add_argument("--like", type=Path, default=ROOT / "data" / "sim_v1",
                    help="the training dataset whose settings and test motions to use")
    args = ap.parse_args(argv)
    settings, motions = like_settings(args.like)
    rest = _RestBody(default_body())
    inputs = args.out / "inputs"
    inputs.mkdir(parents=True, exist_ok=True)
    garment_paths = []
    for name, build in GARMENTS.items():
        g = build(rest)
        garment_paths.append(inputs / f"{name}.obj")
        write_obj(garment_paths[-1], g.vertices, g.faces, g.uvs, g.face_uvs)
        print(f"{name}: {g.n_vertices} vertices, {len(g.faces)} faces")
    motion_paths = []
    for name in motions:
        motion_paths.append(inputs / f"{name}.npz")
        save_motion(motion_paths[-1], MOTION_LIBRARY[name](fps=30.0))
    if args.inputs_only:
        return
    # One dataset per garment: with a single garment `garment dataset` holds none out, so every garment
    # gets every motion and body. The datasets run side by side (one process each).
    procs = []
    for g in garment_paths:
        cmd = [sys.executable, "-m", "garmentcli.main", "dataset", "--garments", str(g),
               *[a for p in motion_paths for a in ("--motions", str(p))],
               "--bodies", str(settings["bodies"]), "--bodies-per-clip", "1",
               "--frames-per-clip", str(settings["frames_per_clip"]), "--max-clips-per-motion", "1",
               "--settle", str(settings["settle"]), "--seed", str(settings["seed"]),
               "--substeps", str(settings["solver"]["substeps"]),
               *(["--self-contact"] if settings["solver"]["self_contact"] else []), "--out", str(args.out / g.stem)]
        print(" ".join(cmd), flush=True)
        procs.append(subprocess.Popen(cmd, cwd=ROOT))
    if any(p.wait() for p in procs):
        raise SystemExit("a simulation failed (see its output above)")


if __name__ == "__main__":
    main()
