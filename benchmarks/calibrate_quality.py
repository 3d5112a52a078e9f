"""The --quality auto calibration of a model from its Table-1 evaluation (benchmarks/model_table.py's CSV).

    python benchmarks/calibrate_quality.py --data data/sim_v1 --table benchmarks/results/model_table.csv \\
        --model-row "phases 1+2+3" --out core/assets/default_model.calibration.json

Each test sequence is one calibration scene: its features (`core.quality.scene_features`: the garment's
looseness on the sequence's body shape, the motion's joint speed) and, per configuration (lbs, the model,
the model with push-out), its E_verts against the simulator and its cost per frame per 1,000 vertices.
The simulator, with the dataset's solver settings, is the reference; its cost is the sequence's own, as
the dataset run measured it (`item_stats` of the manifest; without them, benchmarks/results/sim_report.md's
0.64 s per frame per 1,000 vertices at 10 substeps, scaled by the substeps). `garment tradeoff
--calibrate` adds scenes the same way.
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from core.body import default_body  # noqa: E402
from core.motion import sequence_motion  # noqa: E402
from core.quality import Calibration, add_scene, scene_features  # noqa: E402
from formats.dataset import read_manifest, read_sequence, sequence_path  # noqa: E402
from formats.obj import read_obj  # noqa: E402

SIM_SECONDS_PER_FRAME_PER_KVERT = 0.64


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, action="append", required=True,
                    help="the table's dataset(s) (repeatable, as model_table.py's; an item is read from the first "
                         "that has it)")
    ap.add_argument("--table", type=Path, required=True, help="model_table.py's per-sequence CSV")
    ap.add_argument("--model-row", required=True, help="the model's method name in the table")
    ap.add_argument("--base", type=Path, default=None,
                    help="a calibration to add the scenes to (its configurations, points and costs kept; the new "
                         "scenes' costs averaged in), such as the shipped one")
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args(argv)
    rows = list(csv.DictReader(open(args.table, newline="")))
    names = {"lbs": ("lbs", "lbs", {}),
             args.model_row: ("model float32", "model", {"precision": "float32", "push_out": False}),
             f"{args.model_row} +push-out": ("model float32 +push-out", "model",
                                             {"precision": "float32", "push_out": True})}
    manifests = {d: read_manifest(d) for d in args.data}
    solvers = {json.dumps([m["settings"]["solver"][k] for k in ("substeps", "self_contact")]) for m in manifests.values()}
    if len(solvers) > 1:
        raise SystemExit(f"--data: expected datasets simulated alike (substeps, self-contact), got {sorted(solvers)}")
    substeps, self_contact = json.loads(solvers.pop())
    sim_name = f"sim {substeps} substeps" + (" +self-contact" if self_contact else "")
    body = default_body()
    cal = Calibration.load(args.base) if args.base else Calibration({})
    garments = {}
    for item in sorted({r["item"] for r in rows}):
        data = next((d for d in args.data if sequence_path(d, item).is_file()), None)
        if data is None:
            raise SystemExit(f"{args.table}: item '{item}' is in none of --data {', '.join(map(str, args.data))}")
        seq = read_sequence(sequence_path(data, item))
        stats = manifests[data].get("item_stats", {})
        if seq.garment not in garments:
            garments[seq.garment] = read_obj(data / "garments" / f"{seq.garment}.obj")
        motion = sequence_motion(seq, item, drop_settle=True)
        features = scene_features(garments[seq.garment], body, motion)
        sim_seconds = stats.get(item, {}).get("seconds_per_frame",
                                              SIM_SECONDS_PER_FRAME_PER_KVERT * substeps / 10 * features["vertices"] / 1e3)
        scene = [{"config": sim_name, "method": "sim", "reference": True, "e_verts": 0.0,
                  "seconds_per_frame": sim_seconds, "options": {"substeps": substeps, "self_contact": self_contact}}]
        for r in rows:
            if r["item"] == item and r["method"] in names and r["e_verts"]:
                config, method, options = names[r["method"]]
                scene.append({"config": config, "method": method, "options": options, "e_verts": float(r["e_verts"]),
                              "seconds_per_frame": float(r["ms_per_frame"]) / 1e3})
        add_scene(cal, features, scene)
        print(f"{item}: looseness {features['looseness_m'] * 100:.1f} cm, speed {features['speed_m_s']:.2f} m/s")
    cal.save(args.out)
    print(f"wrote {args.out}: {', '.join(cal.configs)}")


if __name__ == "__main__":
    main()
