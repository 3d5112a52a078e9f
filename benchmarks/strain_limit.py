"""The strain limit (core/strain.py) on the model's and LBS's output: tears undone, error, penetration, cost.

    python benchmarks/strain_limit.py [--frames 60] [--garments dress ...] [--motions kick_right ...]
                                      [--data DIR ...] [--iterations 60 100]
    python benchmarks/strain_limit.py --figure    # the example dress torn and limited (PNG)

The example garments on the test motions of the dataset (30 fps, the first FRAMES frames), and every sequence of
the simulated datasets given with --data (against the simulator, after its settle frames), each baked once by
the shipped model (its contact guard on, as `bake` runs it) and once by LBS (10 smoothing passes), then limited
at STRAIN_LIMIT with each --iterations (at most that many passes), against the garment's rest lengths as authored
(every scene here is on the mean body shape, where the deformers' rest is the authored garment). Per method and limit: torn frames
(real_motion_stress's: an edge over TEAR_RATIO times its rest length and TEAR_EXCESS_M longer), the mean of
|edge length / rest length - 1| (%), the largest edge stretch, penetration (% of vertices > 2 mm inside the body,
on evenly spaced frames), E_verts (mm) against the simulator where simulated, and the limit's milliseconds per
frame (one torch thread). Writes benchmarks/results/strain_limit.md. Nothing here is asserted by the tests.
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

from benchmarks.contact_guard import scene_arguments, scene_command, scenes  # noqa: E402
from benchmarks.real_motion_stress import TEAR_EXCESS_M, TEAR_RATIO, torn_frames  # noqa: E402
from core.bake import penetration_stats  # noqa: E402
from core.body import default_body  # noqa: E402
from core.deform import LBSDeformer  # noqa: E402
from core.garment import mesh_edges  # noqa: E402
from core.geodesic import edge_lengths  # noqa: E402
from core.model_deform import load_model_deformer  # noqa: E402
from core.motion import poses_for_body  # noqa: E402
from core.strain import STRAIN_ITERATIONS, STRAIN_LIMIT, STRAIN_TOLERANCE_M, limit_sequence, strain_limit  # noqa: E402
from formats.report import markdown_table  # noqa: E402

STATS = ["frames", "torn frames", "strain %", "max stretch", "penetration %", "E_verts mm", "frames limited",
         "limit ms/frame"]


def statistics(points, settle, edges, rest, body_points, body, simulated, args) -> dict:
    """The statistics of one output (T, V, 3), its first `settle` frames left out but of penetration."""
    after = points[settle:]
    length = np.linalg.norm(after[:, edges[:, 1]] - after[:, edges[:, 0]], axis=-1)
    return {"frames": len(after), "torn frames": int(torn_frames(after, edges, rest).sum()),
            "strain %": 100.0 * float(np.abs(length / rest - 1.0).mean()), "max stretch": float((length / rest).max()),
            "penetration %": penetration_stats(points, body_points, body.faces,
                                               max_frames=args.penetration_frames)["mean_percent"],
            "E_verts mm": "" if simulated is None else 1e3 * float(np.linalg.norm(after - simulated, axis=-1).mean())}


def group_of(motion_name: str) -> str:
    """A scene's group: its dataset's folder name, or 'test motions' for the example scenes."""
    return motion_name.split("/")[0] if "/" in motion_name else "test motions"


def overall(rows: list[list], configs: list[str]) -> list[list]:
    """Per group, garment, method and configuration: counts summed, percentages, E_verts and ms/frame the mean
    over scenes (ms/frame weighted by frames), the largest stretch its max."""
    keys = sorted({(r[0], r[1], r[3]) for r in rows}, key=lambda k: (k[0], k[1], ["model", "lbs"].index(k[2])))
    out = []
    for group, garment, method in keys:
        for config in configs:
            sel = [r for r in rows if (r[0], r[1], r[3], r[4]) == (group, garment, method, config)]
            cols = dict(zip(STATS, zip(*(r[5:] for r in sel))))
            ev = [v for v in cols["E_verts mm"] if v != ""]
            frames = np.array(cols["frames"])
            out.append([group, garment, len(sel), method, config, int(frames.sum()), sum(cols["torn frames"]),
                        float(np.mean(cols["strain %"])), max(cols["max stretch"]),
                        float(np.mean(cols["penetration %"])), float(np.mean(ev)) if ev else "",
                        sum(cols["frames limited"]), float(np.average(cols["limit ms/frame"], weights=frames))])
    return out


def vertex_stretch(points: np.ndarray, edges: np.ndarray, rest: np.ndarray) -> np.ndarray:
    """(T, V): per vertex, the largest length / rest length of its edges."""
    ratio = np.linalg.norm(points[:, edges[:, 1]] - points[:, edges[:, 0]], axis=-1) / rest
    out = np.ones(points.shape[:2])
    for end in (0, 1):
        np.maximum.at(out, (slice(None), edges[:, end]), ratio)
    return out


def figure(args) -> None:
    """The example dress on the held-out walk_brisk, at the frame of its widest tear between the legs, seen from
    behind and from the front: the model and LBS, each without and with the limit, coloured by the largest stretch of a
    vertex's edges: strain_limit_dress.png."""
    from formats.obj import read_obj
    from formats.render import RenderOptions, contact_sheet, render_image, scene_from_sequence, write_png
    from formats.sequence import Sequence
    from core.motiongen import MOTION_LIBRARY

    body = default_body()
    garment = read_obj(ROOT / "examples" / "dress.obj")
    motion = MOTION_LIBRARY["walk_brisk"](fps=30.0)
    edges = mesh_edges(garment.faces)
    rest = edge_lengths(garment.vertices, edges)
    limit = strain_limit(garment.vertices, garment.faces)
    raw = {"model": load_model_deformer(strain_limit=None).deform(garment, body, motion),
           "lbs": LBSDeformer().deform(garment, body, motion)}
    frame = int(np.argmax(vertex_stretch(raw["model"][:args.frames], edges, rest).max(axis=1)))
    columns = []
    for method, points in raw.items():
        limited, _ = limit_sequence(points[frame:frame + 1].copy(), limit)
        columns += [(f"{method}, no limit", points[frame:frame + 1]), (f"{method}, limit {STRAIN_LIMIT:g}", limited)]
    images = []
    for azimuth in (180.0, 0.0):  # from behind, from the front
        options = RenderOptions(width=700, height=700, azimuth_deg=azimuth, elevation_deg=5.0)
        images.append([render_image(scene_from_sequence(Sequence(points, garment.faces, motion.fps, source=name),
                                                        color="scalar", scalars=vertex_stretch(points, edges, rest),
                                                        scalar_label="edge stretch", value_range=(1.0, 3.0)),
                                    0, "front", options) for name, points in columns])
    labels = [[f"{name}, frame {frame}, {side}" for name, _ in columns] for side in ("behind", "front")]
    out = write_png(args.out.with_name("strain_limit_dress.png"), contact_sheet(images, labels, thumb_width=450))
    print(f"wrote {out}")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    scene_arguments(ap, frames=60)
    ap.add_argument("--iterations", type=int, nargs="+", default=[STRAIN_ITERATIONS])
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "strain_limit.md")
    ap.add_argument("--figure", action="store_true", help="the example dress torn and limited "
                    "(strain_limit_dress.png)")
    args = ap.parse_args(argv)
    if args.figure:
        return figure(args)
    torch.set_num_threads(1)
    body = default_body()
    methods = {"model": load_model_deformer(strain_limit=None), "lbs": LBSDeformer()}
    methods["model"].tune_threads = False
    configs = ["off", *(f"{STRAIN_LIMIT:g}, {n} passes" for n in args.iterations)]
    rows = []
    for garment_name, name, garment, motion, simulated, settle in scenes(args):
        body_points, _ = body.pose(poses_for_body(motion, body.n_joints), motion.trans, body.fit_betas(motion.betas))
        edges = mesh_edges(garment.faces)
        rest = edge_lengths(garment.vertices, edges)
        limit = strain_limit(garment.vertices, garment.faces)
        for method, deformer in methods.items():
            raw = deformer.deform(garment, body, motion)
            for config, iterations in zip(configs, [0, *args.iterations]):
                t0 = time.perf_counter()
                points, report = (raw, {}) if not iterations else limit_sequence(raw.copy(), limit, iterations)
                ms = 1e3 * (time.perf_counter() - t0) / len(raw)
                stats = statistics(points, settle, edges, rest, body_points, body, simulated, args)
                rows.append([group_of(name), garment_name, name, method, config, *stats.values(),
                             report.get("frames_limited", 0), ms])
        print(f"{garment_name} {name}: " + ", ".join(f"{r[3]} {r[4]}: {r[6]} torn, {r[-1]:.1f} ms"
                                                     for r in rows[-len(methods) * len(configs):]), flush=True)
    command = " ".join([*scene_command(args), "--iterations " + " ".join(map(str, args.iterations)),
                        f"--out {args.out.name}"])
    headers = ["group", "garment", "motion", "method", "limit", *STATS]
    text = ("# The strain limit on the model's and LBS's output\n\n"
            f"Made by `python benchmarks/strain_limit.py {command}` on {platform.machine()}, one torch thread. The "
            "shipped model (float32, its contact guard on) and LBS (10 smoothing passes), each limited after: no "
            f"edge longer than {STRAIN_LIMIT:g} times its rest length (within {STRAIN_TOLERANCE_M * 1e3:g} mm), "
            "at most N Chebyshev-accelerated Jacobi passes (core/strain.py). Torn frames: frames with an edge over "
            f"{TEAR_RATIO:g} times its rest length and {TEAR_EXCESS_M * 100:g} cm longer; strain: mean |edge length "
            "/ rest length - 1|; max stretch: the largest edge length / rest length (tiny edges stretch most; the "
            "simulator's own reach 1.6-4.4 on these datasets); penetration: % of vertices > 2 mm inside the body; "
            "E_verts: against the simulator after its settle frames (simulated sequences only); limit ms/frame: "
            "the limit's own time, one torch thread.\n\n"
            "## By group and garment (scenes summed; percentages, E_verts and ms/frame their mean)\n\n"
            + markdown_table(["group", "garment", "scenes", "method", "limit", "frames", "torn frames", "strain %",
                              "max stretch", "penetration %", "E_verts mm", "frames limited", "limit ms/frame"],
                             overall(rows, configs))
            + "\n## Per scene\n\n" + markdown_table(headers, rows))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
