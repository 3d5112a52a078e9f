"""How closely SMPL's bones follow a rig's once its BVH, FBX, glTF or MVNX is retargeted (`core.retarget`), on
real captures.

    python benchmarks/retarget_fidelity.py CLIP.bvh|CLIP.fbx|CLIP.glb|CLIP.mvnx [...] [--sources TEXT] [--out FILE.md]

For each clip: the rig's joints posed by its own channels (`core.retarget.rig_pose`), and the embedded body's
joints posed by the SMPL motion `formats.motion.load_motion` reads from it; for every SMPL bone retargeting turns
onto one of the rig's (up the spine to the head, collar to shoulder, down the limbs), the angle between
SMPL's bone and the rig's in every frame (`bones`): the median, the 95th percentile and the largest over bones
and frames, and the bone worst at its 95th percentile. The angle is 0 where the rig's joints between two matched ones do
not turn (`core.retarget`'s docstring); a rig with more spine or neck joints than SMPL bends its spine
between them. Also the seconds `load_motion` takes. The clips are not in the repository (their sources: the
results file). Nothing here is asserted by tests.
"""

from __future__ import annotations

import argparse
import datetime
import platform
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from core.body import SMPL_JOINT_NAMES, default_body  # noqa: E402
from core.retarget import CHAIN_CHILD, chain_end, match_joints, rest_positions, rig_pose  # noqa: E402
from formats.motion import load_motion, read_rig  # noqa: E402
from formats.report import markdown_table, write_markdown  # noqa: E402


def bones(match: dict[int, int], rest: np.ndarray) -> list[tuple[int, int]]:
    """SMPL's bones retargeting turns onto the rig's: each matched joint to the first matched one down its chain
    (`core.retarget.chain_end`), where the rig's rest bone has a length. (The pelvis's bones to the hips and
    spine and spine3's to the collars turn with the body's frame, not onto the rig's own bones: the rigs place
    their hips and collars elsewhere, so they are left out.)"""
    ends = {k: chain_end(k, match) for k in CHAIN_CHILD if k in match}
    return [(k, c) for k, c in ends.items() if c is not None and np.linalg.norm(rest[match[c]] - rest[match[k]]) > 0]


def fidelity(path: Path) -> list:
    """A results row for the motion capture `path` (BVH, FBX, glTF, MVNX: `formats.motion.read_rig`)."""
    skeleton = read_rig(path, path.name)
    t0 = time.perf_counter()
    motion = load_motion(path, world_checks=False)
    seconds = time.perf_counter() - t0
    match = match_joints(skeleton.names, skeleton.parents, path.name, skeleton.trees)
    _, rig = rig_pose(skeleton.parents, skeleton.offsets, skeleton.rotations, skeleton.root, skeleton.moving)
    _, smpl = default_body().pose(motion.poses[:, :24], motion.trans)
    angles = {}
    for k, c in bones(match, rest_positions(skeleton.parents, skeleton.offsets)):
        a = smpl[:, c] - smpl[:, k]
        b = rig[:, match[c]] - rig[:, match[k]]
        cos = (a * b).sum(-1) / (np.linalg.norm(a, axis=-1) * np.linalg.norm(b, axis=-1))
        angles[f"{SMPL_JOINT_NAMES[k]}-{SMPL_JOINT_NAMES[c]}"] = np.degrees(np.arccos(np.clip(cos, -1, 1)))
    every = np.concatenate(list(angles.values()))
    worst = max(angles, key=lambda b: np.percentile(angles[b], 95))
    return [path.name, len(skeleton.names), len(match), len(motion.poses), f"{seconds:.3f}", len(angles),
            f"{np.median(every):.2f}", f"{np.percentile(every, 95):.2f}", f"{every.max():.1f}",
            f"{worst} ({np.percentile(angles[worst], 95):.1f})"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("clips", nargs="+", type=Path)
    parser.add_argument("--machine", default=platform.processor() or platform.machine())
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "retarget_fidelity.md")
    parser.add_argument("--sources", default="", help="where the clips came from, written under the table")
    args = parser.parse_args()
    rows = [fidelity(path) for path in args.clips]
    header = ["clip", "rig joints", "SMPL joints matched", "frames", "read s", "bones", "median deg", "p95 deg",
              "max deg", "worst bone (its p95)"]
    write_markdown(args.out, [
        "# SMPL's bones against the rig's, retargeted BVH, FBX and glTF clips", "",
        f"Made by `python benchmarks/retarget_fidelity.py {' '.join(p.name for p in args.clips)} --sources ...` on "
        f"{datetime.date.today().isoformat()}, {args.machine}, Python {platform.python_version()}. Angles between "
        f"each SMPL bone and the rig's over every frame (see the script's docstring).", "",
        markdown_table(header, rows), "", args.sources])
    print(args.out.read_text())


if __name__ == "__main__":
    main()
