"""Record the training garments' median edges in a checkpoint made before they were recorded (meta
"garment_edge_m": `core.model_deform.garment_edge_range`), in place, the rest of it as it was.

    python benchmarks/record_edge_range.py core/assets/default_model.pt examples/dress.obj examples/skirt.obj \
        examples/trousers.obj examples/tshirt.obj examples/jumpsuit.obj

(the shipped model's training garments: its card's dataset commands; `garment train` records them itself since
2026-12-07, and `benchmarks/ship_model.py` from the datasets where a checkpoint lacks them).
"""

from __future__ import annotations

import argparse
from pathlib import Path


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("model", type=Path)
    ap.add_argument("garments", type=Path, nargs="+", help="the garments it was trained on (OBJ)")
    args = ap.parse_args(argv)
    from core.model_deform import garment_edge_range
    from formats.checkpoint import load_checkpoint, save_checkpoint
    from formats.obj import read_garment

    ck = load_checkpoint(args.model)
    meta = {**ck["meta"], "garment_edge_m": garment_edge_range([read_garment(p) for p in args.garments])}
    save_checkpoint(args.model, ck["config"], ck["model"], meta=meta, train=ck.get("train"))
    print(f"{args.model}: garment_edge_m {meta['garment_edge_m']}")


if __name__ == "__main__":
    main()
