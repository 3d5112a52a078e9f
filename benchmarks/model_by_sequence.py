"""Where the learned model gains on LBS and where it does not: E_verts per simulated sequence and per body.

Every sequence of the given garments in a `garment dataset` directory (the ones simulated so far) is
deformed by LBS, the model (the shipped one or --model) and, per garment, a `garment fit` (--fit
GARMENT=PATH), from its stored motion and body shape, and compared with the simulated positions (settle
frames excluded). The table lists each sequence (split, body, motion) with each method's mean vertex
distance and the model's share of LBS's error, and sums them up per garment, split and body: the model's
gain is uneven across bodies (a garment authored on the mean body fits it as LBS puts it, and what is left is
its motion) and across motions it never saw.

    python benchmarks/model_by_sequence.py --data data/sim_v4 --garments trousers tshirt \\
        --fit trousers=data/models/trousers.psd.npz

Writes benchmarks/results/model_by_sequence.md and .csv (or --out).
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from core.body import default_body  # noqa: E402
from core.deform import LBSDeformer  # noqa: E402
from core.motion import sequence_motion  # noqa: E402
from formats.dataset import read_manifest, read_sequence, sequence_path  # noqa: E402
from formats.obj import read_obj  # noqa: E402

SPLITS = ("train", "val", "test")


def body_of(item_id: str) -> str:
    """The body of a dataset item id (`<garment>__<motion>__cNN__bNN`)."""
    return item_id.rsplit("__", 1)[-1]


def summary_rows(rows: list[dict], methods: list[str]) -> list[dict]:
    """Per (garment, split, body), then per (garment, split): the mean of each method's error over the sequences
    and the model's share of LBS's (the ratio of the means)."""
    out = []
    for garment in sorted({r["garment"] for r in rows}):
        for split in SPLITS:
            mine = [r for r in rows if r["garment"] == garment and r["split"] == split]
            for body in [*sorted({r["body"] for r in mine}), "all"]:
                group = [r for r in mine if body in ("all", r["body"])]
                if not group:
                    continue
                means = {m: float(np.mean([r[m] for r in group if m in r])) for m in methods
                         if any(m in r for r in group)}
                out.append({"garment": garment, "split": split, "body": body, "sequences": len(group), **means,
                            "model / LBS": means["model"] / means["lbs"]})
    return out


def _table(rows: list[dict], columns: list[str]) -> list[str]:
    def cell(v):
        return f"{v:.1f}" if isinstance(v, float) else str(v)

    lines = ["| " + " | ".join(columns) + " |", "|" + "|".join("---" for _ in columns) + "|"]
    for r in rows:
        lines.append("| " + " | ".join(
            f"{100 * r[c]:.0f} %" if c == "model / LBS" else cell(r.get(c, "")) for c in columns) + " |")
    return lines


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", required=True, help="A `garment dataset` directory.")
    ap.add_argument("--garments", nargs="+", required=True, help="Garment names of the dataset (e.g. trousers).")
    ap.add_argument("--model", default=None, help="Model checkpoint [default: the shipped model].")
    ap.add_argument("--fit", action="append", default=[], metavar="GARMENT=PATH", help="A `garment fit` file.")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results" / "model_by_sequence"),
                    help="Output path without extension.")
    args = ap.parse_args(argv)

    from core.model_deform import load_model_deformer
    from formats.psd import psd_deformer

    data = Path(args.data)
    manifest = read_manifest(data)
    if manifest is None:
        ap.error(f"--data '{data}': no manifest.json")
    fits = dict(spec.split("=", 1) for spec in args.fit)
    body = default_body()
    model, lbs = load_model_deformer(args.model), LBSDeformer()
    rows = []
    for garment_name in args.garments:
        garment = read_obj(data / "garments" / f"{garment_name}.obj")
        methods = {"lbs": lbs, "model": model}
        if garment_name in fits:
            methods["psd"] = psd_deformer(fits[garment_name])
        for d in methods.values():
            d.prepare(garment, body)
        for it in manifest["items"]:
            path = sequence_path(data, it["id"])
            if it["garment"] != garment_name or not path.is_file():
                continue
            seq = read_sequence(path)
            motion, gt = sequence_motion(seq, it["id"], drop_settle=True), seq.positions[seq.n_settle:]
            row = {"garment": garment_name, "split": it["split"], "body": body_of(it["id"]), "motion": it["motion"]}
            for name, d in methods.items():
                row[name] = float(np.linalg.norm(d.deform(garment, body, motion) - gt, axis=-1).mean() * 1e3)
            row["model / LBS"] = row["model"] / row["lbs"]
            rows.append(row)
            print(f"{it['id']}: " + ", ".join(f"{k} {row[k]:.1f} mm" for k in methods), flush=True)
    names = ["lbs", "model", *(["psd"] if fits else [])]
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    columns = ["garment", "split", "body", "motion", *names, "model / LBS"]
    with open(out.with_suffix(".csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=columns)
        w.writeheader()
        w.writerows(rows)
    md = ["# The model's gain on LBS per sequence and per body", "",
          f"E_verts (mm) against the simulator, settle frames excluded; data `{data}` (the sequences simulated so "
          f"far), model `{args.model or 'shipped'}`. Made by `python benchmarks/model_by_sequence.py "
          f"{' '.join(argv if argv is not None else sys.argv[1:])}`.", "", "## Per garment, split and body", "",
          *_table(summary_rows(rows, names), ["garment", "split", "body", "sequences", *names, "model / LBS"]),
          "", "## Per sequence", "", *_table(rows, columns), ""]
    out.with_suffix(".md").write_text("\n".join(md))
    print(f"wrote {out.with_suffix('.md')} and .csv")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
