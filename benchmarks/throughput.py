"""Throughput on a 4k-vertex garment: LBS, the shipped model and the simulator in one run, and where the model's time goes.

    python benchmarks/throughput.py [--sim-frames 20] [--device cpu|cuda]

Garment: the example dress remeshed at a finer spacing (about 4,000 vertices). Motion: the held-out
`walk_brisk` of the motion library at 30 fps (repeated to 1,800 frames for LBS). Measured, all on one
machine in one run: LBS frames per second; the model's frames per second at several batch sizes (its
default on the device, 8 and 32) in float32 and bfloat16 (median of --repeats after a warm-up; the contact
guard and the strain limit included, their shares reported); the simulator's seconds per output frame
(10 substeps, no self-contact, settling excluded); a `bake` of four motions (the held-out library motions,
each played three times: about 12 s) through the CLI with --workers 1 and 2 (frames per second including
writing, the penetration statistics and, with 2, starting the workers); and a profile of one model bake.
Writes benchmarks/results/throughput.md (or --out). Nothing here is asserted by the tests.
"""

from __future__ import annotations

import argparse
import os
import platform
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
os.environ.setdefault("WARP_CACHE_PATH", str(Path.home() / ".cache" / "garment" / "warp"))

import garmentcli  # noqa: E402,F401  (the process settings `garment` makes: OpenBLAS threads, malloc)
from core.body import default_body  # noqa: E402
from core.deform import LBSDeformer  # noqa: E402
from core.model_deform import default_batch_frames, load_model_deformer, native_bfloat16  # noqa: E402
from core.motion import Motion, resample  # noqa: E402
from formats.report import markdown_table, write_markdown  # noqa: E402

#: Times each motion of the CLI bake is played in a row (about 12 s each: a typical motion-capture clip).
CLI_REPEATS = 3
#: Spacing (metres) of the remeshed example dress: about 4,000 vertices (the shipped dress: 0.018, 3,240).
SPACING_4K_M = 0.0149


def cpu_name() -> str:
    """The CPU's model name as Linux reports it (the machine's kind: these VMs differ run to run), else the
    platform's processor string."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def _yes_no(flag: bool | None) -> str:
    return {True: "yes", False: "no"}.get(flag, "unknown")


def dress_4k(body):
    """The example dress at SPACING_4K_M (core.garmentgen's builder, finer)."""
    from core.garmentgen import _levels, _RestBody, _tube_garment

    rest = _RestBody(body)
    lv = _levels(rest)
    return _tube_garment(rest, "dress4k", y_top=lv["armpits"] - 0.03, y_bottom=lv["knees"] - 0.06, ease=0.012,
                         flare_from_y=lv["hips"] + 0.3 * (lv["pelvis"] - lv["hips"]), flare_slope=0.22,
                         spacing=SPACING_4K_M)


def repeated(motion: Motion, times: int) -> Motion:
    """`motion` played `times` times in a row."""
    return Motion(poses=np.concatenate([motion.poses] * times), trans=np.concatenate([motion.trans] * times),
                  fps=motion.fps, name=f"{motion.name} x{times}")


def median_seconds(fn, repeats: int, limit_s: float | None = None) -> float:
    """Median seconds of `repeats` runs of `fn` after a warm-up; with `limit_s`, fewer once that many seconds are
    spent (at least one)."""
    fn()  # warm-up
    times = []
    while len(times) < repeats and (limit_s is None or sum(times) < limit_s):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return float(np.median(times))


def profile_table(deformer, garment, body, motion, rows: int = 12) -> list[list]:
    """Top operators of one model bake of `motion` by self CPU time."""
    from torch.profiler import ProfilerActivity, profile

    with profile(activities=[ProfilerActivity.CPU]) as prof:
        deformer.deform(garment, body, motion)
    events = sorted(prof.key_averages(), key=lambda e: e.self_cpu_time_total, reverse=True)
    total = sum(e.self_cpu_time_total for e in events)
    return [[e.key, e.count, f"{e.self_cpu_time_total / 1e3:.0f}", f"{100 * e.self_cpu_time_total / total:.1f}"]
            for e in events[:rows]]


def cli_bake_fps(garment_path: Path, motions: list[Path], workers: int) -> float:
    with tempfile.TemporaryDirectory() as out:
        res = subprocess.run([sys.executable, "-m", "garmentcli.main", "bake", str(garment_path), *map(str, motions),
                              "--out", out, "--no-obj", "--no-body", "--workers", str(workers)],
                             cwd=ROOT, capture_output=True, text=True, check=True)
    return float(re.search(r"([\d.]+) frames/s", res.stdout).group(1))


def startup_seconds(repeats: int = 3) -> float:
    """Median wall time of `garment bake --help` in a new process: Python, torch and the bake command imported
    (`garment --help` imports no command since 2026-12-07)."""
    def once():
        subprocess.run([sys.executable, "-m", "garmentcli.main", "bake", "--help"], cwd=ROOT, capture_output=True,
                       check=True)

    return median_seconds(once, repeats)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sim-frames", type=int, default=20)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--device", default="cpu", help="the model's device (cuda where there is one)")
    ap.add_argument("--no-sim", action="store_true")
    ap.add_argument("--no-cli", action="store_true")
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "throughput.md")
    args = ap.parse_args(argv)
    from core.motiongen import MOTION_LIBRARY
    from formats.cache import default_cache_dir
    from formats.motion import save_motion
    from formats.obj import write_obj

    body = default_body()
    garment = dress_4k(body)
    motion = resample(MOTION_LIBRARY["walk_brisk"](fps=60.0), 30.0)
    long = repeated(motion, 20)
    rows = []
    lbs = LBSDeformer()
    lbs.prepare(garment, body)
    t = median_seconds(lambda: lbs.deform(garment, body, long), args.repeats)
    lbs_fps = long.n_frames / t
    rows.append(["lbs", "-", f"{1e3 / lbs_fps:.3f}", f"{lbs_fps:,.0f}"])
    print(rows[-1], flush=True)
    model_fps, guard_ms, strain_ms = {}, [], []
    default_batch = default_batch_frames(args.device)
    for precision in ("float32", "bfloat16"):
        for batch in sorted({default_batch, 8, 32}):
            d = load_model_deformer(cache_dir=default_cache_dir(), precision=precision)
            d.batch_frames = batch
            if args.device != "cpu":
                d.model.to(args.device)
            d.prepare(garment, body)
            t = median_seconds(lambda: d.deform(garment, body, motion), args.repeats)
            fps = motion.n_frames / t
            model_fps[(precision, batch)] = fps
            guard_ms.append(1e3 * d.report.get("seconds_per_frame_guard", 0.0))
            strain_ms.append(1e3 * d.report.get("strain_limit", {}).get("seconds_per_frame", 0.0))
            rows.append([f"model {precision}", batch, f"{1e3 / fps:.1f}", f"{fps:.1f}"])
            print(rows[-1], flush=True)
    sim_s = None
    if not args.no_sim:
        from core.sim import SimDeformer

        sim = SimDeformer()
        short = Motion(poses=motion.poses[:args.sim_frames], trans=motion.trans[:args.sim_frames], fps=30.0, name="w")
        sim.prepare(garment, body)
        sim.deform(garment, body, short)
        sim_s = sim.report["seconds_per_output_frame"]
        rows.append(["sim 10 substeps", "-", f"{sim_s * 1e3:.0f}", f"{1 / sim_s:.2f}"])
        print(rows[-1], flush=True)
    best = max(model_fps.values())
    default = model_fps[("float32", default_batch)]
    cli_rows, cli_frames = [], 0
    if not args.no_cli:
        with tempfile.TemporaryDirectory() as tmp:
            gpath = Path(tmp) / "dress4k.obj"
            write_obj(gpath, garment.vertices, garment.faces, garment.uvs, garment.face_uvs)
            motions = []
            for name in ("walk_brisk", "kick_right", "turn_right_wide", "arm_swing_fast"):
                motions.append(Path(tmp) / f"{name}.npz")
                clip = repeated(MOTION_LIBRARY[name](fps=30.0), CLI_REPEATS)
                save_motion(motions[-1], clip)
                cli_frames += clip.n_frames
            for workers in (1, 2):
                cli_rows.append([workers, f"{cli_bake_fps(gpath, motions, workers):.1f}"])
                print(cli_rows[-1], flush=True)
            startup = startup_seconds()
    d = load_model_deformer(cache_dir=default_cache_dir())
    d.prepare(garment, body)
    d.deform(garment, body, motion)
    prof = profile_table(d, garment, body, motion)
    lines = [
        "# Throughput on a 4k-vertex garment",
        "",
        f"Made by `python benchmarks/throughput.py --sim-frames {args.sim_frames}` on {platform.machine()} "
        f"({cpu_name()}, {os.cpu_count()} cores, {torch.get_num_threads()} torch threads, CPU vector unit "
        f"{torch.backends.cpu.get_cpu_capability()}, native bfloat16: {_yes_no(native_bfloat16())}, model on "
        f"{args.device}), torch "
        f"{torch.__version__}. Garment: the example dress remeshed to {garment.n_vertices:,} vertices. Motion: "
        f"walk_brisk (held out from training), {motion.n_frames} frames at 30 fps ({long.n_frames} for LBS).",
        "",
        markdown_table(["method", "batch frames", "ms/frame", "frames/s"], rows),
        "",
        f"- model (default: float32, batch {default_batch}) vs LBS: {lbs_fps / default:.0f}x slower; fastest model "
        f"configuration {best:.1f} frames/s.",
        f"- the model's rows include its contact guard (on by default): {np.median(guard_ms):.1f} ms/frame of them; "
        f"and its strain limit (on by default): {np.median(strain_ms):.1f} ms/frame.",
    ]
    if sim_s is not None:
        lines.append(f"- model (default) vs simulator: {sim_s * default:.0f}x faster per frame; fastest configuration "
                     f"{sim_s * best:.0f}x.")
    if cli_rows:
        lines += ["", f"`garment bake` of 4 held-out motions (each played {CLI_REPEATS} times: about 12 s, "
                  f"{cli_frames:,} frames in all; model, USD and summary written, penetration checked on up to 60 "
                  "frames of each), frames per second of the whole command after its own start-up (with 2 workers "
                  "including theirs: each imports and loads the model and preprocesses the garment):", "",
                  markdown_table(["--workers", "frames/s"], cli_rows), "",
                  f"The command's start-up (`garment bake --help` in a new process: Python, torch and the bake "
                  f"command imported), median of 3: {startup:.2f} s."]
    lines += ["", f"Profile of one model bake (float32, batch {default_batch}), operators by self CPU time:", "",
              markdown_table(["operator", "calls", "self ms", "%"], prof)]
    write_markdown(args.out, lines)


if __name__ == "__main__":
    main()
