"""Pack a simulator dataset small enough to carry to a GPU machine, and unpack it there.

    python benchmarks/dataset_pack.py pack data/sim_v1 data/sim_v1_pack --splits train,val
    python benchmarks/dataset_pack.py unpack data/sim_v1_pack data/sim_v1_gpu

Positions are stored relative to the frame's root translation, quantised to `--step-mm` (0.2 mm: a
uniform error of at most 0.1 mm, far below the model's errors of centimetres), as int16 differences between
consecutive frames, LZMA-compressed: about 13 % of the float32 size. Everything else (poses, trans, betas,
fps, manifest, garment templates) is copied exactly. Unpacking writes the ordinary dataset layout that
`garment train --data` reads; the manifest keeps only the packed splits' items.
"""

from __future__ import annotations

import argparse
import json
import lzma
import shutil
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from formats.dataset import MANIFEST, SEQUENCE_KEYS, Sequence, read_manifest, read_sequence, write_sequence  # noqa: E402

INT16_MAX = np.iinfo(np.int16).max


def pack(src: Path, dst: Path, splits: tuple, step_m: float) -> None:
    manifest = read_manifest(src)
    items = [it for it in manifest["items"] if it["split"] in splits]
    dst.mkdir(parents=True, exist_ok=True)
    shutil.copytree(src / "garments", dst / "garments", dirs_exist_ok=True)
    worst = 0.0
    for it in items:
        seq = read_sequence(src / it["file"])
        rel = seq.positions.astype(np.float64) - seq.trans.astype(np.float64)[:, None, :]
        q = np.round(rel / step_m)
        if np.abs(q).max() > INT16_MAX:
            raise SystemExit(f"{it['file']}: a vertex lies {np.abs(rel).max():.2f} m from the root translation, "
                             f"beyond the int16 range at {step_m * 1e3} mm steps")
        q = q.astype(np.int16)
        worst = max(worst, float(np.abs(q * step_m - rel).max()))
        delta = np.diff(q, axis=0, prepend=np.zeros_like(q[:1]))
        other = {k: getattr(seq, k) for k in SEQUENCE_KEYS if k != "positions"}
        np.savez(dst / f"{it['id']}.npz", delta_lzma=np.frombuffer(lzma.compress(delta.tobytes()), dtype=np.uint8),
                 shape=np.asarray(q.shape), step_m=np.float64(step_m), **other)
    kept = dict(manifest, items=items)
    (dst / MANIFEST).write_text(json.dumps(kept, indent=1))
    size = sum(p.stat().st_size for p in dst.rglob("*") if p.is_file())
    print(f"{dst}: {len(items)} sequences, {size / 1e6:.1f} MB, largest quantisation error {worst * 1e3:.3f} mm")


def unpack(src: Path, dst: Path) -> None:
    manifest = json.loads((src / MANIFEST).read_text())
    (dst / "sequences").mkdir(parents=True, exist_ok=True)
    shutil.copytree(src / "garments", dst / "garments", dirs_exist_ok=True)
    for it in manifest["items"]:
        d = np.load(src / f"{it['id']}.npz")
        delta = np.frombuffer(lzma.decompress(d["delta_lzma"].tobytes()), dtype=np.int16).reshape(d["shape"])
        rel = np.cumsum(delta.astype(np.int64), axis=0) * float(d["step_m"])
        positions = (rel + d["trans"].astype(np.float64)[:, None, :]).astype(np.float32)
        other = {k: d[k][()] if d[k].ndim == 0 else d[k] for k in SEQUENCE_KEYS if k != "positions"}
        write_sequence(dst / it["file"], Sequence(positions=positions, **other))
    (dst / MANIFEST).write_text(json.dumps(manifest, indent=1))
    print(f"{dst}: {len(manifest['items'])} sequences")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    p = sub.add_parser("pack")
    p.add_argument("src", type=Path)
    p.add_argument("dst", type=Path)
    p.add_argument("--splits", default="train,val")
    p.add_argument("--step-mm", type=float, default=0.2)
    u = sub.add_parser("unpack")
    u.add_argument("src", type=Path)
    u.add_argument("dst", type=Path)
    a = ap.parse_args()
    if a.cmd == "pack":
        pack(a.src, a.dst, tuple(a.splits.split(",")), a.step_mm * 1e-3)
    else:
        unpack(a.src, a.dst)


if __name__ == "__main__":
    main()
