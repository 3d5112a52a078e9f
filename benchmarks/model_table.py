"""Table 1 of the paper on our data: training variants of the learned model and LBS against the simulator.

Every test-split sequence of a `garment dataset` directory is baked by each method
(LBS and every --model given) from its stored motion and body shape, and compared
with the simulated positions (settle frames excluded): the five metrics of
`core.metrics` (E_verts mm, E_vnorm deg, E_fnorm deg, E_edge, E_curv), body
penetration (% of garment vertices more than 2 mm inside the body) and
self-intersection (% of garment faces crossing another face, every
--self-every-th frame). Rows are averaged over sequences, separately for the
held-out motions with trained garments and for the held-out garment. The
simulator's own penetration and self-intersection rates are listed as the
reference row.

    python benchmarks/model_table.py --data data/sim_v1 \\
        --model "phase 1=models/p1.pt" --model "phases 1+2=models/p12.pt" \\
        --model "phases 1+2+3=models/p123.pt"

Writes benchmarks/results/model_table.md, .csv (per sequence) and .json (the summary) (or --out).
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from core.body import default_body  # noqa: E402
from core.deform import LBSDeformer  # noqa: E402
from core.geometry import points_inside_mesh  # noqa: E402
from core.metrics import compute_metrics, frames_inside, self_intersection_pct  # noqa: E402
from core.motion import poses_for_body, sequence_motion  # noqa: E402
from formats.dataset import read_manifest, read_sequence, sequence_path  # noqa: E402
from formats.obj import read_obj  # noqa: E402

PENETRATION_DEPTH_M = 0.002
#: core.metrics names (units in core.metrics.METRICS), then this report's own columns.
COLUMNS = ("e_verts", "e_vnorm", "e_fnorm", "e_edge", "e_curv", "penetration_pct", "self_intersection_pct",
           "ms_per_frame")


@dataclass
class Row:
    group: str
    method: str
    item: str
    values: dict


#: Group of every item of a --held-out-data dataset: garments of the trained families no model saw.
IN_RANGE_GROUP = "held-out garments in range"


def test_items(manifest: dict, group: str | None = None) -> list[dict]:
    """The test-split items of a dataset manifest, each with its evaluation group.

    With `group`, every item of the manifest, all in that group (a dataset made only for evaluation).
    """
    if group is not None:
        return [{**it, "group": group} for it in manifest["items"]]
    held = set(manifest["splits"]["held_out_garments"])
    out = []
    for it in manifest["items"]:
        if it["split"] == "test":
            out.append({**it, "group": "held-out garment" if it["garment"] in held else "held-out motions"})
    return out


def evaluate(data: Path, methods: dict, self_every: int = 6, max_items: int | None = None,
             group: str | None = None, skip=()) -> list[Row]:
    """Rows of every method on the test items of `data` (all its items in `group`), but the item ids in `skip`."""
    manifest = read_manifest(data)
    if manifest is None:
        raise SystemExit(f"{data}: no manifest.json (expected a `garment dataset` directory)")
    body = default_body()
    inside = frames_inside(lambda p, v, f: points_inside_mesh(p, v, f, depth=PENETRATION_DEPTH_M))
    rows = []
    items = [it for it in test_items(manifest, group)
             if it["id"] not in skip and sequence_path(data, it["id"]).exists()][:max_items]
    garments = {}
    for n, it in enumerate(items):
        seq = read_sequence(sequence_path(data, it["id"]))
        if seq.garment not in garments:
            garments[seq.garment] = read_obj(data / "garments" / f"{seq.garment}.obj")
        garment = garments[seq.garment]
        motion = sequence_motion(seq, it["id"])
        keep = slice(seq.n_settle, None)
        gt = seq.positions[keep]
        body_pts, _ = body.pose(poses_for_body(motion, body.n_joints), motion.trans, motion.betas)
        body_pts = body_pts[keep]
        sampled = slice(0, None, self_every)
        rows.append(Row(it["group"], "simulator (reference)", it["id"], {
            "penetration_pct": float(np.mean(100 * inside(gt, body_pts, body.faces).mean(axis=1))),
            "self_intersection_pct": float(self_intersection_pct(gt[sampled], garment.faces).mean())}))
        for name, deformer in methods.items():
            t0 = time.perf_counter()
            pred = deformer.deform(garment, body, motion)[keep]
            ms = (time.perf_counter() - t0) * 1e3 / len(seq.positions)
            m = compute_metrics(pred, gt, garment.faces, body_pts, body.faces, inside)
            values = {k: m.overall[k] for k in COLUMNS[:6]}
            values["self_intersection_pct"] = float(self_intersection_pct(pred[sampled], garment.faces).mean())
            values["ms_per_frame"] = ms
            rows.append(Row(it["group"], name, it["id"], values))
        print(f"[{n + 1}/{len(items)}] {it['id']}", flush=True)
    return rows


def summarise(rows: list[Row], order: list[str]) -> list[tuple[str, str, int, dict]]:
    out = []
    for group in dict.fromkeys(r.group for r in rows):
        for method in ["simulator (reference)", *order]:
            sel = [r for r in rows if r.group == group and r.method == method]
            if sel:
                keys = sel[0].values.keys()
                out.append((group, method, len(sel), {k: float(np.mean([r.values[k] for r in sel])) for k in keys}))
    return out


def write(out: Path, summary, rows, args) -> None:
    from formats.atomic import atomic_file

    command = ("python benchmarks/model_table.py " + "".join(f"--data {d} " for d in args.data)
               + "".join(f"--held-out-data {d} " for d in args.held_out_data)
               + (f'--group "{args.group}" ' if args.group != IN_RANGE_GROUP else "")
               + " ".join(f'--model "{m}"' for m in args.model) + (" --push-out" if args.push_out else "")
               + "".join(f' --network-only "{n}"' for n in args.network_only) + f" --self-every {args.self_every}")
    lines = ["# Learned model variants and LBS against the simulator (paper Table 1 layout)", "",
             "Data: " + "; ".join([", ".join(f"`{d}`" for d in args.data) + " test split (held-out motions; the "
                                   "held-out garment separately)"] * bool(args.data)
                                  + [f"every sequence of `{d}` ({args.group})" for d in args.held_out_data])
             + f". Made by `{command}`.", "",
             "E_verts in mm, normal errors in degrees, E_edge in %, E_curv in 1/m^2 (core.metrics); penetration: % "
             "of garment vertices > 2 mm inside the body; self-intersection: % of garment faces crossing another "
             f"(every {args.self_every}th frame); ms/frame: bake time per frame on this CPU.", "",
             "| split | method | sequences | " + " | ".join(COLUMNS) + " |",
             "|---|---|---:|" + "---:|" * len(COLUMNS)]
    for group, method, n, v in summary:
        cells = [f"{v[k]:.3f}" if k in v else "" for k in COLUMNS]
        lines.append(f"| {group} | {method} | {n} | " + " | ".join(cells) + " |")
    by_group = {}
    for group, method, n, v in summary:
        by_group.setdefault(group, {})[method] = {"sequences": n, **v}
    lines += ["", "Relative to LBS (negative: lower than LBS):", ""]
    for group, methods in by_group.items():
        lbs = methods.get("lbs")
        for method, v in methods.items():
            if lbs is None or method in ("lbs", "simulator (reference)"):
                continue
            rel = {k: 100.0 * (v[k] - lbs[k]) / lbs[k] for k in ("e_verts", "penetration_pct") if lbs.get(k)}
            lines.append(f"- {group}, {method}: E_verts {rel.get('e_verts', float('nan')):+.1f} %, "
                         f"penetration {rel.get('penetration_pct', float('nan')):+.1f} %")
    with atomic_file(out) as tmp:
        tmp.write_text("\n".join(lines) + "\n")
    with atomic_file(out.with_suffix(".json")) as tmp:
        tmp.write_text(json.dumps({"command": command, "columns": list(COLUMNS), "summary": by_group}, indent=1))
    with atomic_file(out.with_suffix(".csv")) as tmp, open(tmp, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["split", "method", "item", *COLUMNS])
        for r in rows:
            w.writerow([r.group, r.method, r.item, *[r.values.get(k, "") for k in COLUMNS]])


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, action="append", default=[],
                    help="`garment dataset` directory (repeatable: an item id already evaluated is not again)")
    ap.add_argument("--model", action="append", default=[], metavar="NAME=PATH", help="a trained model (repeatable)")
    ap.add_argument("--self-every", type=int, default=6, help="self-intersection on every Nth frame")
    ap.add_argument("--held-out-data", type=Path, action="append", default=[],
                    help="a `garment dataset` of garments no model was trained on: every sequence in "
                         f"'{IN_RANGE_GROUP}' (or --group)")
    ap.add_argument("--group", default=IN_RANGE_GROUP,
                    help="the name of --held-out-data's group (a dataset of other motions: 'real motions')")
    ap.add_argument("--max-items", type=int, default=None)
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "model_table.md")
    ap.add_argument("--push-out", action="store_true", help="also each model with the penetration push-out")
    ap.add_argument("--network-only", action="append", default=[], metavar="NAME",
                    help="also the --model NAME without its contact guard (the network's raw output; repeatable)")
    args = ap.parse_args(argv)
    if not args.data and not args.held_out_data:
        ap.error("expected --data or --held-out-data")
    methods = {"lbs": LBSDeformer()}
    for spec in args.model:
        name, sep, path = spec.partition("=")
        if not sep:
            raise SystemExit(f"--model: expected NAME=PATH, got {spec!r}")
        from core.model_deform import load_model_deformer

        methods[name] = load_model_deformer(path)
        if name in args.network_only:
            methods[f"{name} (network only)"] = load_model_deformer(path, contact_guard=False, strain_limit=None)
        if args.push_out:
            from core.pushout import PushOutDeformer

            methods[f"{name} +push-out"] = PushOutDeformer(load_model_deformer(path))
    rows = []
    for data in args.data:
        rows += evaluate(data, methods, args.self_every, args.max_items, skip={r.item for r in rows})
    for extra in args.held_out_data:
        rows += evaluate(extra, methods, args.self_every, args.max_items, group=args.group,
                         skip={r.item for r in rows})
    summary = summarise(rows, list(methods))
    write(args.out, summary, rows, args)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
