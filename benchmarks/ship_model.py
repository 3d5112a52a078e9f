"""Copy a trained model into the package as the default of `bake`, with its model card.

    python benchmarks/ship_model.py data/models/model_p123.pt --data data/sim_v1 \\
        --table benchmarks/results/model_table.json --name "phases 1+2+3"

Writes core/assets/default_model.pt (weights and config only: no optimizer state) and
core/assets/default_model.json: the commands that made it, the dataset it was trained on
(manifest digest, splits, sizes), the training run (configs, steps, phase switches, validation
error) and its Table-1 metrics against LBS (from benchmarks/model_table.py's JSON).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from core.body import SMPL_JOINT_NAMES  # noqa: E402
from core.model_deform import DEFAULT_MODEL  # noqa: E402
from formats.checkpoint import load_checkpoint, save_checkpoint  # noqa: E402
from formats.dataset import MANIFEST, read_manifest  # noqa: E402


def dataset_card(data: Path) -> dict:
    manifest = read_manifest(data)
    items = manifest["items"]
    per_split = {}
    for it in items:
        s = per_split.setdefault(it["split"], {"sequences": 0, "frames": 0, "garments": set(), "motions": set()})
        s["sequences"] += 1
        s["frames"] += int(it["n_frames"])
        s["garments"].add(it["garment"])
        s["motions"].add(it["motion"])
    return {"directory": data.name, "manifest_sha256": hashlib.sha256((data / MANIFEST).read_bytes()).hexdigest(),
            "settings": manifest.get("settings", {}), "splits_declared": manifest.get("splits", {}),
            "splits": {k: {**v, "garments": sorted(v["garments"]), "motions": sorted(v["motions"])}
                       for k, v in sorted(per_split.items())},
            "totals": manifest.get("totals", {})}


def training_coverage(data: Path) -> list[float]:
    """`core.model_deform.joint_coverage` of the dataset's training and validation garments on the default body."""
    from core.body import default_body
    from core.model_data import PRIOR_SMOOTH_ITERATIONS
    from core.model_deform import joint_coverage
    from core.skinning import bind_garment
    from formats.obj import read_obj

    body = default_body()
    return joint_coverage([bind_garment(read_obj(data / "garments" / f"{n}.obj"), body, PRIOR_SMOOTH_ITERATIONS,
                                        0.5).weights.clip(min=0) for n in training_garments(data)])


def training_garments(data: Path) -> list[str]:
    """The names of a dataset's training and validation garments."""
    return sorted({it["garment"] for it in read_manifest(data)["items"] if it["split"] in ("train", "val")})


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("model", type=Path)
    ap.add_argument("--data", type=Path, action="append", required=True,
                    help="the dataset(s) it was trained on (repeatable, as `garment train --data`)")
    ap.add_argument("--table", type=Path, required=True, help="model_table.py's JSON summary")
    ap.add_argument("--name", required=True, help="the model's row name in the table")
    ap.add_argument("--train-command", default="python benchmarks/train_variants.py --data data/sim_v1 "
                    "--models-dir data/models --minutes 92 --only model_p123 model_p1")
    ap.add_argument("--dataset-command", default="see README 'Training data' (garment dataset ... --held-out tshirt ...)")
    args = ap.parse_args(argv)
    ck = load_checkpoint(args.model)
    run = json.loads(args.model.with_name(args.model.name + ".json").read_text())
    table = json.loads(args.table.read_text())
    keep = ("lbs", args.name, f"{args.name} (network only)", "simulator (reference)")
    metrics = {group: {m: v for m, v in rows.items() if m in keep}
               for group, rows in table["summary"].items()}
    if not all(args.name in rows for rows in metrics.values()):
        raise SystemExit(f"{args.table}: no rows named {args.name!r}")
    card = {
        "model": DEFAULT_MODEL.name,
        "source": str(args.model),
        "command": {"dataset": args.dataset_command,
                    "train": args.train_command,
                    "evaluate": table.get("command", ""),
                    "ship": "python " + " ".join([Path(__file__).relative_to(ROOT).as_posix(), *map(str, argv or sys.argv[1:])])},
        "dataset": dataset_card(args.data[0]) if len(args.data) == 1 else [dataset_card(d) for d in args.data],
        "training": {"config": ck["config"], "run": run, "meta": ck["meta"]},
        "metrics": metrics,
    }
    meta = {**ck["meta"], "card": DEFAULT_MODEL.with_suffix(".json").name}
    if "garment_edge_m" not in meta:  # models trained before it was recorded: their datasets' garments
        from core.model_deform import garment_edge_range
        from formats.obj import read_obj

        meta["garment_edge_m"] = garment_edge_range([read_obj(d / "garments" / f"{n}.obj") for d in args.data
                                                     for n in training_garments(d)])
    if "joint_coverage" not in meta:
        meta["joint_coverage"] = [max(c) for c in zip(*(training_coverage(d) for d in args.data))]  # models trained before it was recorded
    card["training_joint_coverage"] = dict(zip(SMPL_JOINT_NAMES, meta["joint_coverage"]))
    save_checkpoint(DEFAULT_MODEL, ck["config"], ck["model"], meta=meta)
    DEFAULT_MODEL.with_suffix(".json").write_text(json.dumps(card, indent=1, default=str) + "\n")
    print(f"{DEFAULT_MODEL}: {DEFAULT_MODEL.stat().st_size / 1e6:.2f} MB; card {DEFAULT_MODEL.with_suffix('.json')}")


if __name__ == "__main__":
    main()
