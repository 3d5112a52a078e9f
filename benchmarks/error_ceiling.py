"""How much of the simulator's deviation from LBS a rest-frame blend shape can take back: oracles and baselines.

Every simulated frame x_t of a `garment dataset` is pulled back into the rest
frame through the LBS blend of each vertex (M_t = sum_j w_j A_tj, the `lbs`
method's weights and the body's skinning transforms): the offset o_t = M_t^-1
(x_t) - rest is exactly the blend shape B of paper Eq. 1-2 that would
reproduce the simulator with LBS's weights. On the test split it compares,
by E_verts (mm, settle frames excluded, as `model_table.py`):

- `lbs`: no offset;
- `garment mean (train)`: each garment's mean offset over its training
  sequences, one fixed shape per garment: a baseline any model trained on
  these garments should beat;
- `linear in pose and shape (train)`: per garment, a ridge regression
  (RIDGE_LAMBDA) of each frame's offsets on the pose (rotation matrices
  minus identity, their rates), the root's velocity and acceleration in its
  own frame and the betas, fitted on the training sequences: the classic
  pose-space deformation of SMPL's pose blend shapes, with one weight matrix
  per garment, so it says nothing of unseen garments (the network's point)
  but is the bar the network must clear on these;
- `sequence mean (oracle)`: the test sequence's own mean offset (what a
  static correction could do at best);
- `PCA k (oracle)`: the best per-frame offsets in the span of the garment's
  first k principal offsets from training (how many numbers per frame a
  model must get right).

    python benchmarks/error_ceiling.py --data data/sim_v2

Writes benchmarks/results/error_ceiling.md and .csv (per sequence) (or --out).
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
from core.model_data import PRIOR_SMOOTH_ITERATIONS  # noqa: E402
from core.motion import poses_for_body, sequence_motion  # noqa: E402
from core.psd import DEFAULT_RIDGE, blended_transforms, pose_features, ridge_solve, unskin  # noqa: E402
from core.skinning import bind_garment, shaped_garment  # noqa: E402
from formats.dataset import read_manifest, read_sequence, sequence_path  # noqa: E402
from formats.obj import read_obj  # noqa: E402

PCA_RANKS = (8, 32, 128)
#: Ridge weight of the linear baseline (`core.psd`'s, which `garment fit` uses).
RIDGE_LAMBDA = DEFAULT_RIDGE


def skin(M: np.ndarray, rest: np.ndarray) -> np.ndarray:
    """Apply blended transforms M (T, V, 3, 4) to rest points (V, 3) or (T, V, 3)."""
    r = np.broadcast_to(rest, M.shape[:2] + (3,))
    return np.einsum("tvab,tvb->tva", M[..., :3], r) + M[..., 3]


def e_verts_mm(pred: np.ndarray, gt: np.ndarray) -> float:
    return float(np.linalg.norm(pred - gt, axis=-1).mean() * 1e3)


def load_offsets(data: Path, split: str, manifest: dict, body, bindings: dict, garments: dict):
    """Per item of `split`: (item, garment name, M, gt, rest, offsets), settle frames dropped."""
    out = []
    for it in manifest["items"]:
        if it["split"] != split or not sequence_path(data, it["id"]).exists():
            continue
        seq = read_sequence(sequence_path(data, it["id"]))
        name = seq.garment
        if name not in garments:
            garments[name] = read_obj(data / "garments" / f"{name}.obj")
            bindings[name] = bind_garment(garments[name], body, PRIOR_SMOOTH_ITERATIONS, 0.5)
        b = bindings[name]
        motion = sequence_motion(seq, it["id"], drop_settle=True)
        betas = body.fit_betas(motion.betas)
        poses = poses_for_body(motion, body.n_joints)
        M = blended_transforms(body, b.weights, poses, motion.trans, betas)
        rest = shaped_garment(garments[name].vertices, b, betas)
        gt = seq.positions[seq.n_settle:].astype(np.float64)
        X = pose_features(poses, motion.trans, betas, motion.fps)
        out.append((it["id"], name, M, gt, rest, unskin(M, gt) - rest, X))
    return out


def evaluate(data: Path) -> list[dict]:
    manifest = read_manifest(data)
    if manifest is None:
        raise SystemExit(f"{data}: no manifest.json (expected a `garment dataset` directory)")
    body = default_body()
    bindings, garments = {}, {}
    train = load_offsets(data, "train", manifest, body, bindings, garments)
    by_garment: dict[str, list[tuple[np.ndarray, np.ndarray]]] = {}
    for _, name, _, _, _, off, X in train:
        by_garment.setdefault(name, []).append((off.reshape(len(off), -1), X))
    basis, linear = {}, {}
    for name, pairs in by_garment.items():
        O = np.concatenate([o for o, _ in pairs])
        mean = O.mean(axis=0)
        basis[name] = (mean, np.linalg.svd(O - mean, full_matrices=False)[2][:max(PCA_RANKS)])
        linear[name] = ridge_solve(np.concatenate([x for _, x in pairs]), O, RIDGE_LAMBDA)
    rows = []
    for item, name, M, gt, rest, off, X in load_offsets(data, "test", manifest, body, bindings, garments):
        row = {"item": item, "garment": name, "lbs": e_verts_mm(skin(M, rest), gt)}
        if name not in basis:  # a held-out garment: no training offsets
            rows.append(row)
            continue
        mean, vt = basis[name]
        row["garment mean (train)"] = e_verts_mm(skin(M, rest + mean.reshape(-1, 3)), gt)
        row["linear in pose and shape (train)"] = e_verts_mm(skin(M, rest + (X @ linear[name]).reshape(off.shape)), gt)
        row["sequence mean (oracle)"] = e_verts_mm(skin(M, rest + off.mean(axis=0)), gt)
        centred = off.reshape(len(off), -1) - mean
        for k in PCA_RANKS:
            fit = mean + (centred @ vt[:k].T) @ vt[:k]
            row[f"PCA {k} (oracle)"] = e_verts_mm(skin(M, rest + fit.reshape(off.shape)), gt)
        rows.append(row)
        print(f"{item}: " + ", ".join(f"{k} {v:.1f}" for k, v in row.items() if k not in ("item", "garment")),
              flush=True)
    return rows


def write(out: Path, rows: list[dict], command: str) -> None:
    methods = [k for k in rows[0] if k not in ("item", "garment")] if rows else []
    garments = sorted({r["garment"] for r in rows})
    lines = ["# How much of the simulator's deviation from LBS a rest-frame blend shape can take back", "",
             (f"Made by `{command}`. E_verts in mm on the test split (settle frames excluded), mean over "
              "sequences; see the script's docstring for each row."), "",
             "| method | all | " + " | ".join(garments) + " |", "|---|" + "---:|" * (len(garments) + 1)]
    for m in methods:
        vals = [np.mean([r[m] for r in rows if m in r])]
        vals += [np.mean([r[m] for r in rows if r["garment"] == g and m in r] or [np.nan]) for g in garments]
        lines.append(f"| {m} | " + " | ".join(f"{v:.1f}" for v in vals) + " |")
    out.parent.mkdir(parents=True, exist_ok=True)
    out.with_suffix(".md").write_text("\n".join(lines) + "\n")
    with open(out.with_suffix(".csv"), "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=["item", "garment", *methods])
        w.writeheader()
        w.writerows(rows)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, required=True, help="`garment dataset` directory")
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "error_ceiling.md")
    args = ap.parse_args(argv)
    rows = evaluate(args.data)
    write(args.out, rows, "python benchmarks/error_ceiling.py " + " ".join(argv if argv is not None else sys.argv[1:]))
    print(args.out.with_suffix(".md").read_text())


if __name__ == "__main__":
    main()
