"""The shipped model's frames per second on a GPU, against LBS and the model on the same machine's CPU.

    python benchmarks/throughput_gpu.py [--repeats 5] [--out benchmarks/results/throughput_gpu.md]

Same scene as benchmarks/throughput.py: the example dress remeshed to about 4,000 vertices, the held-out
`walk_brisk` at 30 fps, repeated to 910 frames (--long-repeats) for the GPU. Measured in one run on one machine:
LBS on the CPU; the model on the CPU (float32, its default batch) and on the GPU (batches of 8 to 512 frames;
float32 with and without the contact guard, tf32 matrix products and bfloat16 without), each as a whole `deform`
(results copied back to the host, the contact guard on the CPU included) and as the network alone; the GPU's
results against the CPU's (same model, float32); and a profile of one GPU bake (kernels by device time, kernel
launches per frame, how much of the wall time the GPU is busy). Medians of --repeats after a warm-up (at most
about 5 s of runs per configuration). Nothing here is asserted by the tests. Writes a Markdown table (--out).
"""

from __future__ import annotations

import argparse
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
from core.model_deform import default_batch_frames, load_model_deformer  # noqa: E402
from core.motion import Motion, resample  # noqa: E402
from formats.report import markdown_table  # noqa: E402

#: Frames per forward pass tried on the GPU.
GPU_BATCHES = (8, 32, 128, 512)
#: Seconds one configuration is timed for at most (after its warm-up; at least one timed run).
TIME_PER_CONFIG_S = 5.0


def timed_median(fn, repeats: int, limit_s: float = TIME_PER_CONFIG_S) -> float:
    """Median seconds of up to `repeats` runs of `fn` after a warm-up, stopping once `limit_s` is spent."""
    fn()
    times = []
    while len(times) < repeats and sum(times) < limit_s:
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return float(np.median(times))


def model_rate(garment, body, motion: Motion, device: str, precision: str, batch: int, guard: bool,
               repeats: int) -> tuple[float, float, np.ndarray]:
    """(frames/s of a whole deform, frames/s of the network alone, the last result) of the shipped model."""
    torch.set_float32_matmul_precision("high" if precision == "tf32" else "highest")
    d = load_model_deformer(precision="bfloat16" if precision == "bfloat16" else "float32", contact_guard=guard)
    d.batch_frames = batch
    d.model.to(device)
    d.prepare(garment, body)
    out = {}

    def once():
        out["verts"] = d.deform(garment, body, motion)
        if device != "cpu":
            torch.cuda.synchronize()

    whole = timed_median(once, repeats)
    network = d.report["seconds_per_frame_network"]  # the last run's: results copied back included
    return motion.n_frames / whole, 1.0 / network, out["verts"]


def gpu_profile(garment, body, motion: Motion, batch: int, rows: int = 10) -> tuple[list[list], dict]:
    """Top CUDA kernels of one network-only bake by device time, and the totals."""
    from torch.profiler import ProfilerActivity, profile

    d = load_model_deformer(contact_guard=False)
    d.batch_frames = batch
    d.model.to("cuda")
    d.prepare(garment, body)
    d.deform(garment, body, motion)
    torch.cuda.synchronize()
    t = time.perf_counter()
    with profile(activities=[ProfilerActivity.CPU, ProfilerActivity.CUDA]) as prof:
        d.deform(garment, body, motion)
        torch.cuda.synchronize()
    wall = time.perf_counter() - t
    kernels = [e for e in prof.events() if e.device_type == torch.autograd.DeviceType.CUDA]
    busy_us = sum(e.device_time for e in kernels)
    by_name: dict[str, list] = {}
    for e in kernels:
        acc = by_name.setdefault(e.name, [0, 0.0])
        acc[0] += 1
        acc[1] += e.device_time
    top = sorted(by_name.items(), key=lambda kv: kv[1][1], reverse=True)[:rows]
    table = [[name[:60], n, f"{us / 1e3:.1f}", f"{100 * us / max(busy_us, 1e-9):.1f}"] for name, (n, us) in top]
    totals = {"kernels": len(kernels), "kernels_per_frame": len(kernels) / motion.n_frames,
              "busy_ms": busy_us / 1e3, "wall_ms": wall * 1e3}
    return table, totals


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

    lbs = LBSDeformer()
    lbs.prepare(garment, body)
    t = median_seconds(lambda: lbs.deform(garment, body, long), args.repeats)
    lbs_fps = long.n_frames / t
    rows.append(["lbs", "cpu", "float32", "-", "-", f"{lbs_fps:,.0f}", "-"])
    print(rows[-1], flush=True)
    cpu_batch = default_batch_frames("cpu")
    cpu_fps, cpu_net, cpu_verts = model_rate(garment, body, walk, "cpu", "float32", cpu_batch, True, args.repeats)
    rows.append(["model", "cpu", "float32", cpu_batch, "yes", f"{cpu_fps:.1f}", f"{cpu_net:.1f}"])
    print(rows[-1], flush=True)

    gpu = {}
    configs = [("float32", b, True) for b in GPU_BATCHES] + [(p, b, False) for p in ("float32", "tf32", "bfloat16")
                                                              for b in GPU_BATCHES]
    for precision, batch, guard in configs:
        fps, net, _ = model_rate(garment, body, long, args.device, precision, batch, guard, args.repeats)
        gpu[(precision, batch, guard)] = (fps, net)
        rows.append(["model", args.device, precision, batch, "yes" if guard else "no", f"{fps:.1f}", f"{net:.1f}"])
        print(rows[-1], flush=True)
    _, _, gpu_verts = model_rate(garment, body, walk, args.device, "float32", cpu_batch, True, 1)
    diff_mm = 1e3 * np.linalg.norm(gpu_verts - cpu_verts, axis=-1)
    scale_mm = 1e3 * np.linalg.norm(cpu_verts - cpu_verts.mean(axis=1, keepdims=True), axis=-1).mean()
    print(f"gpu vs cpu: max {diff_mm.max():.4f} mm, mean {diff_mm.mean():.5f} mm", flush=True)
    on_gpu = torch.device(args.device).type == "cuda"
    if on_gpu:
        prof_rows, totals = gpu_profile(garment, body, long, 128)
        print(totals, flush=True)

    best_guard = max(gpu.items(), key=lambda kv: kv[1][0] if kv[0][2] else 0)
    best_any = max(gpu.items(), key=lambda kv: kv[1][0])
    best_net = max(gpu.items(), key=lambda kv: kv[1][1])

    def cfg(key):
        precision, batch, guard = key
        return f"{precision}, batch {batch}, contact guard {'on' if guard else 'off'}"

    name = torch.cuda.get_device_name(0) if torch.cuda.is_available() else args.device
    lines = [
        "# The model's throughput on a GPU",
        "",
        f"Made by `python benchmarks/throughput_gpu.py --repeats {args.repeats}` on one {name} (host: "
        f"{platform.machine()}, {os.cpu_count()} cores, {torch.get_num_threads()} torch threads), torch "
        f"{torch.__version__}, Python {platform.python_version()}. Garment: the example dress remeshed to "
        f"{garment.n_vertices:,} vertices. Motion: walk_brisk (held out from training) at 30 fps, repeated to "
        f"{long.n_frames:,} frames ({walk.n_frames} for the model on the CPU). The shipped model "
        "(core/assets/default_model.pt). \"whole\": `ModelDeformer.deform`, results copied back to the host and the "
        "contact guard (on the CPU) included where on; \"network\": its forward passes and the copies back alone.",
        "",
        markdown_table(["method", "device", "precision", "batch frames", "contact guard", "frames/s whole",
                        "frames/s network"], rows),
        "",
        f"- fastest with the contact guard (the default): {best_guard[1][0]:,.0f} frames/s ({cfg(best_guard[0])}), "
        f"{best_guard[1][0] / cpu_fps:.0f}x the model on this machine's CPU; without it {best_any[1][0]:,.0f} "
        f"({cfg(best_any[0])}); the network alone {best_net[1][1]:,.0f} ({cfg(best_net[0])}). The paper reports 402 "
        "frames/s on an RTX 4090.",
        f"- LBS on this machine's CPU: {lbs_fps:,.0f} frames/s.",
        f"- the GPU's float32 results against the CPU's (walk_brisk, {walk.n_frames} frames, contact guard on): "
        f"largest difference {diff_mm.max():.4f} mm, mean {diff_mm.mean():.5f} mm (the garment's mean distance "
        f"from its centre: {scale_mm:.0f} mm).",
    ]
    if on_gpu:
        lines += [
            f"- profile of one network-only bake (float32, batch 128, {long.n_frames:,} frames): {totals['kernels']:,} "
            f"kernel launches ({totals['kernels_per_frame']:.1f} per frame), the GPU busy {totals['busy_ms']:.0f} ms of "
            f"{totals['wall_ms']:.0f} ms wall ({100 * totals['busy_ms'] / totals['wall_ms']:.0f} %; the rest is the "
            "host: launches, the frame windows, copies back).",
            "",
            "Kernels of that bake by device time:",
            "",
            markdown_table(["kernel", "launches", "ms", "%"], prof_rows),
        ]
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
