"""Pooling comparison and levels ablation (paper section 5): the same network, data and training budget.

Variants: our structure-preserving pooling, PyTorch Geometric's TopKPool, SAGPool and ASAP in the
same U-Net (`ModelConfig.pooling`), no pooling (a single scale, levels 0), and the levels ablation
of ours (0, 1, 2, 3 levels). Each is trained with `garment train` on the same dataset with the same
steps and seed (phases 1 only unless --phases), then evaluated on the test split exactly as
benchmarks/model_table.py does (held-out motions; the held-out garment separately). Also per
variant: the connected components of every level on each test garment (ours keeps the garment's
own count; learned poolings usually split it) and renders of the levels side by side.

    python benchmarks/pooling_comparison.py --data data/sim_v1 --steps 3000
    python benchmarks/pooling_comparison.py --data data/sim_v1 --steps 3000 --levels-ablation

Models go to --models-dir (reused when present: the run resumes); tables to
benchmarks/results/pooling_comparison.md / levels_ablation.md, renders to docs/pooling/.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from model_table import COLUMNS, evaluate, summarise  # noqa: E402

from core.model import ModelConfig  # noqa: E402
from formats.report import write_markdown  # noqa: E402

POOLING_VARIANTS = {"ours (structure-preserving)": {"pooling": "structure", "levels": 2},
                    "TopKPool": {"pooling": "topk", "levels": 2},
                    "SAGPool": {"pooling": "sag", "levels": 2},
                    "ASAP": {"pooling": "asap", "levels": 2},
                    "no pooling (single scale)": {"pooling": "structure", "levels": 0}}
LEVEL_VARIANTS = {f"ours, {n} level{'s' if n != 1 else ''}": {"pooling": "structure", "levels": n} for n in range(4)}


def slug(name: str) -> str:
    """A file-name form of a variant's name."""
    return "".join(c if c.isalnum() else "_" for c in name).strip("_")


def variant_stem(overrides: dict, phases: str = "1") -> str:
    """The model file stem of one configuration: variants with equal settings share one model
    ("no pooling" is "ours, 0 levels")."""
    return f"pool_{overrides['pooling']}_L{overrides['levels']}_p{phases.replace(',', '')}"


def train(name: str, overrides: dict, args) -> Path:
    """Train (or reuse) the model of one variant; returns its path."""
    out = Path(args.models_dir) / f"{variant_stem(overrides, args.phases)}.pt"
    if out.is_file():
        return out
    out.parent.mkdir(parents=True, exist_ok=True)
    config = out.with_suffix(".config.json")
    config.write_text(json.dumps({"model": {**dataclasses.asdict(ModelConfig()), **overrides}}))
    subprocess.run([sys.executable, "-m", "garmentcli.main", "train", "--data", str(args.data), "--out", str(out),
                    "--steps", str(args.steps), "--seed", str(args.seed), "--phases", args.phases,
                    "--config", str(config)], check=True, cwd=ROOT)
    return out


def model_levels(model, garment, body):
    """The levels of the model's U-Net on `garment` and their connected components.

    Ours: the precomputed hierarchy (preprocessing). Learned poolings: the levels the forward pass makes
    from the garment's rest features. Returns (an object with vertex_index, edges, n_levels for
    `render_hierarchy`, [components of level 0..L]).
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    from core.model import body_distances
    from core.model_data import prepare_garment
    from core.preprocess import preprocess_garment

    cfg = model.config
    if cfg.pooling == "structure":
        h = preprocess_garment(garment, body, levels=max(cfg.levels, 1), n_landmarks=cfg.n_landmarks,
                               n_eigenvalues=cfg.n_eigenvalues).hierarchy
        return h, list(h.components[: cfg.levels + 1])
    prep = prepare_garment(garment, body, cfg)
    fused = model.encode(prep.inputs, body_distances(body, None)).detach()
    graphs = model.unet.pooled_graphs(fused, prep.inputs)
    counts = []
    for kept, edge_index in graphs:
        n, e = len(kept), edge_index.numpy()
        counts.append(int(connected_components(coo_matrix((np.ones(e.shape[1]), (e[0], e[1])), shape=(n, n)),
                                               directed=False)[0]))
    edges = [np.unique(np.sort(e.numpy().T, axis=1), axis=0) for _, e in graphs]
    levels = SimpleNamespace(vertex_index=[k for k, _ in graphs], edges=edges, n_levels=len(graphs) - 1,
                             components=counts)
    return levels, counts


def run(variants: dict, args, table: Path) -> None:
    from core.body import default_body
    from core.model_deform import load_model_deformer
    from formats.checkpoint import load_model
    from formats.dataset import read_manifest
    from formats.obj import read_obj

    body = default_body()
    methods, models, steps = {}, {}, {}
    for name, overrides in variants.items():
        path = train(name, overrides, args)
        methods[name] = load_model_deformer(path)
        models[name], ck = load_model(path)
        steps[name] = ck["meta"].get("steps")
    rows = evaluate(args.data, methods, args.self_every, args.max_items)
    summary = summarise(rows, list(methods))
    manifest = read_manifest(args.data)
    test_garments = sorted({it["garment"] for it in manifest["items"] if it["split"] == "test"})
    components = {}
    for name, model in models.items():
        for g in test_garments:
            garment = read_obj(Path(args.data) / "garments" / f"{g}.obj")
            levels, components[(name, g)] = model_levels(model, garment, body)
            if not args.no_render and model.config.levels > 0:
                from formats.hierarchy_render import render_hierarchy

                render_hierarchy(ROOT / "docs" / "pooling" / f"{g}_{slug(name)}.png", garment.vertices, garment.faces,
                                 levels, title=f"{g}: {name}")
    lines = [f"# {table.stem.replace('_', ' ').capitalize()}", "",
             f"Same data (`{args.data}`), {args.steps} training steps (phases {args.phases}, seed {args.seed}) per "
             f"variant; test split as in model_table.md. Made by `python benchmarks/pooling_comparison.py "
             f"--data {args.data} --steps {args.steps}{' --levels-ablation' if args.levels_ablation else ''}`.", "",
             "| split | variant | sequences | " + " | ".join(COLUMNS) + " |", "|---|---|---:|" + "---:|" * len(COLUMNS)]
    for group, method, n, v in summary:
        lines.append(f"| {group} | {method} | {n} | " + " | ".join(f"{v[k]:.3f}" if k in v else "" for k in COLUMNS)
                     + " |")
    lines += ["", "Training steps reached (a variant stopped by its time limit has fewer) and connected components "
              "per level (level 0 = the garment):", "",
              "| variant | steps | " + " | ".join(test_garments) + " |", "|---|---:|" + "---|" * len(test_garments)]
    for name in models:
        lines.append(f"| {name} | {steps[name]} | "
                     + " | ".join(" / ".join(map(str, components[(name, g)])) for g in test_garments) + " |")
    write_markdown(table, lines)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, required=True)
    ap.add_argument("--steps", type=int, default=3000)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--phases", default="1")
    ap.add_argument("--models-dir", type=Path, default=ROOT / "data" / "models",
                    help="trained variants (benchmarks/train_variants.py writes the same files)")
    ap.add_argument("--levels-ablation", action="store_true", help="run the levels ablation instead")
    ap.add_argument("--self-every", type=int, default=6)
    ap.add_argument("--max-items", type=int, default=None)
    ap.add_argument("--no-render", action="store_true")
    ap.add_argument("--only", nargs="*", default=None, metavar="WORD",
                    help="run only the variants whose name contains one of these words (e.g. TopK ours)")
    ap.add_argument("--out", type=Path, default=None, help="table path (default: benchmarks/results/...)")
    args = ap.parse_args(argv)
    variants = LEVEL_VARIANTS if args.levels_ablation else POOLING_VARIANTS
    if args.only:
        variants = {k: v for k, v in variants.items() if any(w in k for w in args.only)}
    default = "levels_ablation.md" if args.levels_ablation else "pooling_comparison.md"
    run(variants, args, args.out or ROOT / "benchmarks" / "results" / default)


if __name__ == "__main__":
    main()
