"""Preprocessing time and peak memory against garment vertex count (2k, 8k, 30k).

A dress-like tube (a cone around the default body's legs, 0.95 m long) is
meshed at each size; every size runs in a fresh subprocess so peak memory
(tracemalloc peak of Python/NumPy allocations, and the process's max RSS) is
its own. Stages: vertex features, pooling hierarchy (L=2), the geodesic graph,
the Nystrom descriptor (N*=64 farthest-point landmarks = 64 Dijkstra runs),
and the Eq. 6 near set (truncated Dijkstra within 10 cm from every vertex).

    python benchmarks/preprocess_scaling.py   # writes benchmarks/results/preprocess_scaling.md
"""

from __future__ import annotations

import json
import platform
import subprocess
import sys
from pathlib import Path

SIZES = (2_000, 8_000, 30_000)
OUT = Path(__file__).resolve().parent / "results" / "preprocess_scaling.md"


def tube(n_vertices: int):
    import numpy as np

    height, r_top, r_bottom = 0.95, 0.17, 0.32
    circumference = np.pi * (r_top + r_bottom)
    n_theta = max(8, int(round(np.sqrt(n_vertices * circumference / height))))
    n_rows = max(2, int(round(n_vertices / n_theta)) - 1)
    th = np.linspace(0, 2 * np.pi, n_theta, endpoint=False)
    t = np.linspace(0, 1, n_rows + 1)
    T, S = np.meshgrid(th, t)
    R = r_top + (r_bottom - r_top) * S
    v = np.stack([R * np.sin(T), 0.05 - height * S, R * np.cos(T)], axis=-1).reshape(-1, 3)
    idx = np.arange((n_rows + 1) * n_theta).reshape(n_rows + 1, n_theta)
    a, b = idx[:-1], np.roll(idx[:-1], -1, axis=1)
    c, d = np.roll(idx[1:], -1, axis=1), idx[1:]
    f = np.concatenate([np.stack([a.ravel(), c.ravel(), b.ravel()], 1), np.stack([a.ravel(), d.ravel(), c.ravel()], 1)])
    return v.astype(np.float32), f.astype(np.int64)


def measure(n_vertices: int) -> dict:
    import resource
    import time
    import tracemalloc

    import numpy as np

    from core.body import default_body
    from core.descriptor import style_descriptor
    from core.garment import Garment
    from core.geodesic import geodesic_graph, geodesic_neighbourhood
    from core.graph import undirected_edges, vertex_features
    from core.hierarchy import build_hierarchy

    body = default_body()
    v, f = tube(n_vertices)
    g = Garment(vertices=v, faces=f)
    v64 = v.astype(np.float64)
    row = {"V": len(v), "E": int(len(undirected_edges(f)))}
    tracemalloc.start()
    stages = [("features", lambda: vertex_features(g, body)),
              ("hierarchy", lambda: build_hierarchy(undirected_edges(f), v64, 2)),
              ("geodesic_graph", lambda: geodesic_graph(v64, f))]
    for name, fn in stages:
        tracemalloc.reset_peak()
        t = time.perf_counter()
        out = fn()
        row[f"{name}_s"] = time.perf_counter() - t
        row[f"{name}_peak_mb"] = tracemalloc.get_traced_memory()[1] / 2**20
        if name == "geodesic_graph":
            graph = out
    tracemalloc.reset_peak()
    t = time.perf_counter()
    style_descriptor(v64, f, graph, n_landmarks=64)
    row["descriptor_s"] = time.perf_counter() - t
    row["descriptor_peak_mb"] = tracemalloc.get_traced_memory()[1] / 2**20
    tracemalloc.reset_peak()
    t = time.perf_counter()
    near = geodesic_neighbourhood(v64, graph, 0.10, distances=False)  # as preprocess_garment stores it
    row["near_s"] = time.perf_counter() - t
    row["near_peak_mb"] = tracemalloc.get_traced_memory()[1] / 2**20
    row["near_pairs_per_vertex"] = near.nnz / len(v)
    row["near_mb"] = (near.nnz * 4 + (len(v) + 1) * 4) / 2**20  # bool pattern as stored: int32 indices + indptr
    tracemalloc.stop()
    row["max_rss_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    return row


def main() -> None:
    from formats.report import write_markdown

    rows = []
    for n in SIZES:
        res = subprocess.run([sys.executable, __file__, "--one", str(n)], capture_output=True, text=True, check=True)
        rows.append(json.loads(res.stdout.strip().splitlines()[-1]))
        print(rows[-1], flush=True)
    lines = ["# Preprocessing scaling (time and peak memory vs vertex count)", "",
             f"Machine: {platform.processor() or platform.machine()}, Python {platform.python_version()}; "
             "one run per size, each in a fresh process. Garment: a dress-like cone tube around the default body. "
             "Peak MB = tracemalloc peak of the stage (NumPy/SciPy arrays); RSS = process max resident set.", "",
             "| V | E | features s | hierarchy (L=2) s | geodesic graph s | descriptor (N*=64) s | "
             "Eq. 6 near set s | near pairs / vertex | near set MB | peak MB hierarchy | peak MB descriptor | "
             "peak MB near set | max RSS MB |",
             "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {r['V']} | {r['E']} | {r['features_s']:.3f} | {r['hierarchy_s']:.3f} | "
                     f"{r['geodesic_graph_s']:.3f} | {r['descriptor_s']:.2f} | {r['near_s']:.2f} | "
                     f"{r['near_pairs_per_vertex']:.0f} | {r['near_mb']:.1f} | {r['hierarchy_peak_mb']:.1f} | "
                     f"{r['descriptor_peak_mb']:.1f} | {r['near_peak_mb']:.1f} | {r['max_rss_mb']:.0f} |")
    a, b = rows[0], rows[-1]
    ratio = b["V"] / a["V"]
    lines += ["", f"From {a['V']} to {b['V']} vertices (x{ratio:.1f}): features x{b['features_s'] / a['features_s']:.1f}, "
              f"hierarchy x{b['hierarchy_s'] / a['hierarchy_s']:.1f}, geodesic graph "
              f"x{b['geodesic_graph_s'] / a['geodesic_graph_s']:.1f}, descriptor x{b['descriptor_s'] / a['descriptor_s']:.1f}, "
              f"near set x{b['near_s'] / a['near_s']:.1f}.", "",
              "Cost of the geodesic part:",
              "- Descriptor: N* farthest-point landmarks, each one Dijkstra over the geodesic graph "
              "(mesh edges + unfolded diagonals, about 5V directed pairs): O(N* E log V) time, O(N* V) memory "
              "(the N* x V distance block; 64 x 30k float64 = 15 MB). Linear in V for fixed N*.",
              "- Eq. 6 near set (pairs within 10 cm along the rest surface): a Dijkstra truncated at 10 cm from "
              "every vertex on the local subgraph only, O(V k log k) time and O(V k) memory where k is the number "
              "of vertices in a 10 cm disc. For a garment of fixed size k grows with resolution (k ~ V / area), so "
              "this part is quadratic in V at fixed garment size: the output itself has V k entries. Nothing is "
              "V x V dense. Callers that only need a few candidate pairs use `core.geodesic.geodesically_far`, "
              "which searches from those pairs' vertices only.",
              "- Everything else (features, hierarchy, graph) is O(V + E)."]
    write_markdown(OUT, lines)


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "--one":
        sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
        print(json.dumps(measure(int(sys.argv[2]))))
    else:
        main()
