"""The shipped model's frames per second on a GPU, against LBS and the model on the same machine's CPU.

    python benchmarks/throughput_gpu.py [--repeats 5] [--out benchmarks/results/throughput_gpu.md]

Same scene as benchmarks/throughput.py: the example dress remeshed to about 4,000 vertices, the held-out
`walk_brisk` at 30 fps, repeated to 910 frames (--long-repeats) for the GPU. Measured in one run on one machine:
LBS on the CPU; the model on the CPU (float32, its default batch) and on the GPU (batches of 8 to 512 frames;
float32 with and without the contact guard and strain limit, tf32 matrix products and bfloat16 without), each as a whole `deform`
(results copied back to the host, the contact guard and the strain limit included: per batch on the GPU, or
after it on the CPU) and as the network alone; the GPU's
results against the CPU's (same model, float32); and a profile of one GPU bake (kernels by device time, kernel
launches per frame, how much of the wall time the GPU is busy). Medians of --repeats after a warm-up (at most
about 5 s of runs per configuration). Nothing here is asserted by the tests. Writes a Markdown table (--out).
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np
import torch

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.throughput import dress_4k, median_seconds, repeated  # noqa: E402
from core.body import default_body  # noqa: E402
from core.deform import LBSDeformer  # noqa: E402
from core.model_deform import load_model_deformer  # noqa: E402
from core.strain import STRAIN_LIMIT  # noqa: E402
from core.motion import Motion, resample  # noqa: E402
from formats.report import markdown_table, write_markdown  # noqa: E402

#: Frames per forward pass tried on the GPU.
GPU_BATCHES = (8, 32, 128, 512)
#: Seconds one configuration is timed for at most (after its warm-up; at least one timed run).
TIME_PER_CONFIG_S = 5.0


def model_rate(garment, body, motion: Motion, device: str, precision: str, batch: int | None, guard: str,
               repeats: int) -> dict:
    """The shipped model's frames/s of a whole deform ("whole") and of the network alone ("network"), the GPU
    memory it peaked at ("peak_mib"), its batch and last result. guard (the contact guard and the strain limit):
    "device" (batch by batch on `device`), "host" (afterwards over the sequence on the CPU) or "off"; batch None:
    the device's default."""
    torch.set_float32_matmul_precision("high" if precision == "tf32" else "highest")
    d = load_model_deformer(precision="bfloat16" if precision == "bfloat16" else "float32", contact_guard=guard != "off",
                            strain_limit=None if guard == "off" else STRAIN_LIMIT)
    d.batch_frames, d.post_on_device = batch, guard == "device"
    d.model.to(device)
    d.prepare(garment, body)
    out = {}
    gpu = torch.device(device).type == "cuda"

    def once():
        out["verts"] = d.deform(garment, body, motion)
        if gpu:
            torch.cuda.synchronize()

    if gpu:
        torch.cuda.reset_peak_memory_stats()
    whole = median_seconds(once, repeats, TIME_PER_CONFIG_S)
    return {"whole": motion.n_frames / whole, "network": 1.0 / d.report["seconds_per_frame_network"],
            "peak_mib": torch.cuda.max_memory_allocated() / 2**20 if gpu else None, "batch": d.report["batch_frames"],
            "verts": out["verts"]}


def new_shape_rate(garment, body, motion: Motion, device: str) -> dict:
    """The default deformer's frames/s on a motion of a body shape it has not prepared ("whole") against one it
    has ("cached"), and their "prepare_seconds" (the garment's inputs on the shape, its encoding, the contact
    guard's anchors, the motion features)."""
    d = load_model_deformer()
    d.model.to(device)
    d.prepare(garment, body)
    gpu = torch.device(device).type == "cuda"
    out = {}
    for name, betas in (("warm-up", None), ("cached", None), ("whole", np.full(10, 0.5, dtype=np.float32))):
        t = time.perf_counter()
        d.deform(garment, body, motion if betas is None else dataclasses.replace(motion, betas=betas))
        if gpu:
            torch.cuda.synchronize()
        out[name] = motion.n_frames / (time.perf_counter() - t)
        out[f"{name}_prepare_ms"] = 1e3 * d.report["prepare_seconds"]
    return out


def gpu_profile(garment, body, motion: Motion, rows: int = 10) -> tuple[list[list], dict]:
    """Top CUDA kernels of one default bake (float32, the default batch, the guard and limit on the GPU) by device time,
    and the totals: kernel launches, the GPU's busy milliseconds."""
    from torch.profiler import ProfilerActivity, profile

    d = load_model_deformer()
    d.model.to("cuda")
    d.prepare(garment, body)
    d.deform(garment, body, motion)
    torch.cuda.synchronize()
    with profile(activities=[ProfilerActivity.CPU, ProfilerActivity.CUDA], acc_events=True) as prof:
        d.deform(garment, body, motion)
        torch.cuda.synchronize()
    kernels = [e for e in prof.events() if e.device_type == torch.autograd.DeviceType.CUDA]
    busy_us = sum(e.device_time for e in kernels)
    by_name: dict[str, list] = {}
    for e in kernels:
        acc = by_name.setdefault(e.name, [0, 0.0])
        acc[0] += 1
        acc[1] += e.device_time
    top = sorted(by_name.items(), key=lambda kv: kv[1][1], reverse=True)[:rows]
    table = [[name[:60], n, f"{us / 1e3:.1f}", f"{100 * us / max(busy_us, 1e-9):.1f}"] for name, (n, us) in top]
    return table, {"kernels": len(kernels), "kernels_per_frame": len(kernels) / motion.n_frames,
                   "busy_ms": busy_us / 1e3}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--device", default="cuda")
    ap.add_argument("--long-repeats", type=int, default=10, help="times walk_brisk is played for the GPU rows")
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "throughput_gpu.md")
    args = ap.parse_args(argv)
    from core.motiongen import MOTION_LIBRARY

    torch.manual_seed(0)
    body = default_body()
    garment = dress_4k(body)
    walk = resample(MOTION_LIBRARY["walk_brisk"](fps=60.0), 30.0)
    long = repeated(walk, args.long_repeats)
    rows = []

    def row(method, device, precision, batch, guard, whole, network=None, peak=None):
        rows.append([method, device, precision, batch, guard, f"{whole:,.1f}", "-" if network is None else
                     f"{network:,.1f}", "-" if peak is None else f"{peak:,.0f}"])
        print(rows[-1], flush=True)

    lbs = LBSDeformer()
    lbs.prepare(garment, body)
    lbs_fps = long.n_frames / median_seconds(lambda: lbs.deform(garment, body, long), args.repeats)
    row("lbs", "cpu", "float32", "-", "-", lbs_fps)
    cpu = model_rate(garment, body, walk, "cpu", "float32", None, "host", args.repeats)
    row("model", "cpu", "float32", cpu["batch"], "cpu, after", cpu["whole"], cpu["network"])

    guard_names = {"device": "gpu, per batch", "host": "cpu, after", "off": "off"}
    configs = ([("float32", None, "device")] + [("float32", b, "device") for b in GPU_BATCHES]
               + [("float32", None, "host")] + [("float32", b, "off") for b in GPU_BATCHES]
               + [(p, b, "off") for p in ("tf32", "bfloat16") for b in GPU_BATCHES[2:]])
    gpu = {}
    for precision, batch, guard in configs:
        r = model_rate(garment, body, long, args.device, precision, batch, guard, args.repeats)
        gpu[(precision, batch, guard)] = r
        row("model", args.device, precision, f"{r['batch']}{' (default)' if batch is None else ''}",
            guard_names[guard], r["whole"], r["network"], r["peak_mib"])
    default = gpu[("float32", None, "device")]
    shape = new_shape_rate(garment, body, long, args.device)
    print(shape, flush=True)
    same = model_rate(garment, body, walk, args.device, "float32", None, "device", 1)
    diff_mm = 1e3 * np.linalg.norm(same["verts"] - cpu["verts"], axis=-1)
    scale_mm = 1e3 * np.linalg.norm(cpu["verts"] - cpu["verts"].mean(axis=1, keepdims=True), axis=-1).mean()
    print(f"gpu vs cpu: max {diff_mm.max():.4f} mm, mean {diff_mm.mean():.5f} mm", flush=True)
    on_gpu = torch.device(args.device).type == "cuda"
    if on_gpu:
        prof_rows, totals = gpu_profile(garment, body, long)
        print(totals, flush=True)
    best = max(gpu.items(), key=lambda kv: kv[1]["whole"])
    best_net = max(gpu.items(), key=lambda kv: kv[1]["network"])

    def cfg(key):
        precision, batch, guard = key
        return f"{precision}, batch {gpu[key]['batch']}, guard and limit {guard_names[guard]}"

    name = torch.cuda.get_device_name(0) if torch.cuda.is_available() else args.device
    lines = [
        "# The model's throughput on a GPU",
        "",
        f"Made by `python benchmarks/throughput_gpu.py --repeats {args.repeats}` (in `benchmarks/gpu_check.sh`) on one "
        f"{name} (host: {platform.machine()}, {os.cpu_count()} cores, {torch.get_num_threads()} torch threads), "
        f"torch {torch.__version__}, Python {platform.python_version()}. Garment: the example dress remeshed to "
        f"{garment.n_vertices:,} vertices. Motion: walk_brisk (held out from training) at 30 fps, repeated to "
        f"{long.n_frames:,} frames ({walk.n_frames} for the model on the CPU). The shipped model "
        "(core/assets/default_model.pt). \"whole\": `ModelDeformer.deform` as `garment bake` runs it (motion "
        "features, the network, the contact guard and the strain limit, the frames copied back to the host); "
        "\"network\": its batches alone (forward passes, the guard and limit where they run per batch, the copies "
        "back). Guard and limit: \"gpu, per batch\" (the default on a GPU), \"cpu, after\" (over the whole "
        "sequence on the host, the default on a CPU) or off. Peak: the GPU memory allocated at most.",
        "",
        markdown_table(["method", "device", "precision", "batch frames", "guard and limit", "frames/s whole",
                        "frames/s network", "GPU peak MiB"], rows),
        "",
        f"- the default on the GPU (float32, batch {default['batch']}, the guard and limit per batch on the GPU): "
        f"{default['whole']:,.0f} frames/s, {default['whole'] / cpu['whole']:.0f}x the model's default on this "
        f"machine's CPU ({cpu['whole']:.0f} frames/s); the fastest: {best[1]['whole']:,.0f} ({cfg(best[0])}); the "
        f"network alone at most {best_net[1]['network']:,.0f} ({cfg(best_net[0])}). The paper reports 402 frames/s "
        "on an RTX 4090.",
        f"- a motion of a body shape the deformer has not prepared yet (the default as above): {shape['whole']:,.0f} "
        f"frames/s against {shape['cached']:,.0f} for one it has; preparing took {shape['whole_prepare_ms']:.0f} ms "
        f"against {shape['cached_prepare_ms']:.0f} ms (the motion features alone).",
        f"- LBS on this machine's CPU: {lbs_fps:,.0f} frames/s.",
        f"- the GPU's default against the CPU's (float32, walk_brisk, {walk.n_frames} frames, the guard and limit on each's "
        f"default path; the limit amplifies rounding where it undoes a tear): largest difference {diff_mm.max():.4f} mm, mean {diff_mm.mean():.5f} mm (the garment's "
        f"mean distance from its centre: {scale_mm:.0f} mm).",
    ]
    if on_gpu:
        wall_ms = 1e3 * long.n_frames / default["whole"]
        lines += [
            f"- profile of one default bake ({long.n_frames:,} frames): {totals['kernels']:,} kernel launches "
            f"({totals['kernels_per_frame']:.1f} per frame), the GPU busy {totals['busy_ms']:.0f} ms of the "
            f"{wall_ms:.0f} ms it takes unprofiled ({100 * totals['busy_ms'] / wall_ms:.0f} %; the rest is host "
            "work: the motion features, launches, the copies back).",
            "",
            "Kernels of that bake by device time:",
            "",
            markdown_table(["kernel", "launches", "ms", "%"], prof_rows),
        ]
    write_markdown(args.out, lines, show=True)


if __name__ == "__main__":
    main()
