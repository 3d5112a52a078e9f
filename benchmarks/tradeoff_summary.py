"""One line per scene of the `garment tradeoff` results: LBS, a model and the simulator against the reference.

    python benchmarks/tradeoff_summary.py [--results benchmarks/results/tradeoff] [--model shipped]

Reads every RESULTS/<garment>_<motion>/tradeoff.json (`core.tradeoff.scene_summary`) and writes
RESULTS/summary.md: E_verts of LBS, of the model (float32, contact guard, no push-out) and of the
closest non-reference simulator row against the reference, the model's error as a share of LBS's,
milliseconds per frame of LBS and the model, the fastest simulator row's seconds per frame, and whether
every row keeps the time order lbs < model < sim; for runs with `--spread`, the reference's spread and the share
of LBS's error above it that the model removes.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from core.tradeoff import scene_summary  # noqa: E402
from formats.report import markdown_table  # noqa: E402

HEADERS = ("scene", "vertices", "frames", "LBS mm", "model mm", "model / LBS", "closest sim row", "its mm",
           "LBS ms/frame", "model ms/frame", "fastest sim s/frame", "lbs < model < sim")


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--results", type=Path, default=ROOT / "benchmarks/results/tradeoff")
    p.add_argument("--model", default="shipped", help="Model row name (without precision).")
    a = p.parse_args(argv)
    scenes = sorted(a.results.glob("*/tradeoff.json"))
    if not scenes:
        sys.exit(f"{a.results}: no */tradeoff.json")
    summaries = [(f.parent.name, scene_summary(json.loads(f.read_text()), a.model)) for f in scenes]
    with_spread = any(not math.isnan(s["spread_mm"]) for _, s in summaries)  # some run had --spread
    headers = (*HEADERS, "reference spread mm", "gap closed") if with_spread else HEADERS
    rows, refs = [], set()
    for name, s in summaries:
        refs.add(s["reference"])
        row = (name, s["vertices"], s["frames"], s["lbs_mm"], s["model_mm"], f"{100 * s['model_share_of_lbs']:.0f} %",
               s["closest_sim"], s["closest_sim_mm"], s["lbs_ms"], s["model_ms"], s["sim_s"],
               "yes" if s["time_ordered"] else "no")
        if with_spread:
            row += (s["spread_mm"], "" if math.isnan(s["gap_closed"]) else f"{100 * s['gap_closed']:.0f} %")
        rows.append(row)
    text = (f"# Speed against accuracy: every scene\n\nE_verts (mm) against the reference ({', '.join(sorted(refs))}); "
            f"model: the `{a.model}` row in float32 (contact guard on, no push-out). Made by "
            f"`python benchmarks/tradeoff_summary.py` from each scene's `tradeoff.json`.\n\n"
            + markdown_table(headers, rows, digits=4))
    (a.results / "summary.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
