"""What each scene-analysis skip (core/scene.py) saves, and what it changes, on the example garments.

    python benchmarks/scene_skips.py [--frames 20] [--garments skirt trousers ...]

In one run on one machine, per example garment on examples/walk.npz:
- joints: LBS (a long clip) and the shipped model, seconds per frame with and without the skip, joints used,
  largest vertex difference;
- body-faces: the simulator's seconds per output frame with the collider cut to the faces in reach and with
  the whole body (self-contact off), faces kept, largest vertex difference;
- self-contact: the decision of the analysis for every example garment on every example motion (what
  `bake --method sim --self-contact` would simulate), and the time of the analysis.
Writes benchmarks/results/scene_skips.md. Timings are medians; nothing here is asserted by the tests.
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from pathlib import Path

import numpy as np
import torch

ROOT = Path(__file__).resolve().parents[1]
os.environ.setdefault("WARP_CACHE_PATH", str(Path.home() / ".cache" / "garment" / "warp"))

from core.body import default_body  # noqa: E402
from core.deform import LBSDeformer  # noqa: E402
from core.geometry import outward_faces  # noqa: E402
from core.motion import Motion, poses_for_body, resample  # noqa: E402
from core.scene import SKIPS, SceneAnalysis, analyse_collisions, parse_no_skip  # noqa: E402
from core.skinning import bind_garment  # noqa: E402
from formats.motion import load_motion  # noqa: E402
from formats.obj import read_obj  # noqa: E402
from formats.report import markdown_table  # noqa: E402


def timed_ab(deformer, garment, body, motion, repeats):
    """Median seconds per frame and output of `deformer` with every skip on and with none, runs alternating
    (on, off, on, off, ...) so that a change in the machine's load falls on both alike."""
    times = {True: [], False: []}
    out = {}
    for _ in range(repeats):
        for on in (True, False):
            deformer.skips = frozenset(SKIPS) if on else parse_no_skip(["all"])
            t0 = time.perf_counter()
            out[on] = deformer.deform(garment, body, motion)
            times[on].append(time.perf_counter() - t0)
            if on:
                scene = deformer.scene
    deformer.scene = scene
    return (float(np.median(times[True])) / motion.n_frames, out[True],
            float(np.median(times[False])) / motion.n_frames, out[False])


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=20, help="simulated output frames per run")
    ap.add_argument("--garments", nargs="*", default=None)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "scene_skips.md")
    args = ap.parse_args(argv)
    from core.model_deform import load_model_deformer
    from core.sim import SimDeformer, SimOptions

    body = default_body()
    walk = resample(load_motion(ROOT / "examples" / "walk.npz"), 30.0)
    long = Motion(poses=np.concatenate([walk.poses] * 10), trans=np.concatenate([walk.trans] * 10), fps=walk.fps,
                  name="walk x10")
    short = Motion(poses=walk.poses[:args.frames], trans=walk.trans[:args.frames], fps=walk.fps, name="walk")
    paths = sorted((ROOT / "examples").glob("*.obj"))
    if args.garments:
        paths = [p for p in paths if p.stem in args.garments]
    model = load_model_deformer()
    joint_rows, face_rows = [], []
    for path in paths:
        garment = read_obj(path)
        lbs = LBSDeformer()
        lbs.prepare(garment, body)
        lbs.deform(garment, body, long)  # warm-up
        t_on, a, t_off, b = timed_ab(lbs, garment, body, long, args.repeats)
        used = lbs.scene["joints"]["used"]
        model.prepare(garment, body)
        model.deform(garment, body, walk)  # warm-up
        m_on, c, m_off, d = timed_ab(model, garment, body, walk, args.repeats)
        m_used = model.scene["joints"]["used"]
        joint_rows.append([path.stem, garment.n_vertices, f"{used} / {m_used}", f"{t_on * 1e3:.3f}",
                           f"{t_off * 1e3:.3f}", f"{t_off / t_on:.2f}x", f"{np.abs(a - b).max() * 1e3:.4f}",
                           f"{m_on * 1e3:.1f}", f"{m_off * 1e3:.1f}", f"{m_off / m_on:.2f}x",
                           f"{np.abs(c - d).max() * 1e3:.4f}"])
        sim = SimDeformer(options=SimOptions())
        sim.prepare(garment, body)
        s_on, e, s_off, f = timed_ab(sim, garment, body, short, 1)
        faces = sim.scene["body-faces"]  # its kept_faces are the reach's, the collider whole where not applied
        kept = faces["kept_faces"] if faces["skipped_work"] else len(body.faces)
        face_rows.append([path.stem, garment.n_vertices, f"{kept:,} / {len(body.faces):,}", f"{s_on:.2f}",
                          f"{s_off:.2f}", f"{s_off / s_on:.2f}x", f"{np.abs(e - f).max() * 1e3:.2f}",
                          f"{np.linalg.norm(e - f, axis=-1).mean() * 1e3:.2f}"])
        print(path.stem, joint_rows[-1], face_rows[-1], flush=True)
    contact_rows = []
    for mpath in sorted((ROOT / "examples").glob("*.npz")):
        motion = resample(load_motion(mpath), 30.0)
        poses = poses_for_body(motion, body.n_joints)
        pts, _, tr = body.pose_with_transforms(poses, motion.trans, body.fit_betas(motion.betas))
        faces_b = outward_faces(pts[0], body.faces)
        row = [mpath.stem, motion.n_frames]
        for path in paths:
            garment = read_obj(path)
            binding = bind_garment(garment, body, 10)
            an = SceneAnalysis()
            t0 = time.perf_counter()
            analyse_collisions(an, garment, pts, faces_b, garment.vertices, binding.weights, np.asarray(tr), True)
            sc = an.report["self-contact"]
            row.append(("skip" if sc["skipped_work"] else f"keep (frame {sc['first_frame']})")
                       + f", {time.perf_counter() - t0:.1f} s")
        contact_rows.append(row)
    text = (
        "# Scene-analysis skips\n\n"
        f"Made by `python benchmarks/scene_skips.py --frames {args.frames}` on {platform.machine()} "
        f"({os.cpu_count()} cores, {torch.get_num_threads()} torch threads), torch {torch.__version__}. "
        "Skip on vs off in the same run (`bake --no-skip all` is off).\n\n"
        "## joints (LBS, and the shipped model)\n\n"
        f"LBS on examples/walk.npz repeated to {long.n_frames} frames (median of {args.repeats}); the model on "
        f"the {walk.n_frames}-frame walk; skip on and off alternate run by run. Joints used: LBS / model, of "
        f"{body.n_joints}.\n\n"
        + markdown_table(["garment", "vertices", "joints used", "LBS ms/frame skip", "LBS ms/frame all",
                          "LBS saving", "LBS max diff mm", "model ms/frame skip", "model ms/frame all",
                          "model saving", "model max diff mm"], joint_rows)
        + f"\n## body-faces (sim)\n\nThe simulator (10 substeps, no self-contact) on the first {args.frames} frames "
          "of the walk, seconds per output frame including settling, one run each.\n\n"
        + markdown_table(["garment", "vertices", "collider faces", "s/frame skip", "s/frame whole body", "saving",
                          "max diff mm", "mean diff mm"], face_rows)
        + "\n## self-contact (sim --self-contact)\n\nThe decision per garment and motion (keep: distant parts of "
          "the garment come within 5 cm in the LBS preview at that frame) and the analysis time.\n\n"
        + markdown_table(["motion", "frames", *[p.stem for p in paths]], contact_rows)
    )
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
