"""A tiny synthetic simulator dataset (manifest + garments + .npz sequences) and a tiny model config.

Garments are open cylinders around the tiny body's torso; ground truth is LBS of the rest garment
plus a smooth pose-dependent offset (a flare that follows the hips), so there is something to learn.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from core.model import ModelConfig
from formats.dataset import Sequence as DatasetSequence
from formats.dataset import sequence_path, write_manifest, write_sequence
from formats.obj import write_obj
from tests.meshes import tiny_body

TINY_CONFIG = ModelConfig(hidden=8, heads=1, encoder_layers=1, level_layers=1, bottom_layers=1, levels=1,
                          window=3, lstm_hidden=16, inducing_points=4, attention_heads=1, n_eigenvalues=4,
                          n_landmarks=8)


def tube(n_theta: int, n_rows: int, radius=(0.3, 0.2), y=(-0.35, 0.1)):
    """An open elliptic cylinder about the Y axis: verts (n_theta*n_rows, 3) float32, faces int64."""
    th = np.linspace(0, 2 * np.pi, n_theta, endpoint=False)
    ys = np.linspace(y[0], y[1], n_rows)
    v = np.array([[radius[0] * np.cos(t), yy, radius[1] * np.sin(t)] for yy in ys for t in th], dtype=np.float32)
    f = []
    for r in range(n_rows - 1):
        for k in range(n_theta):
            a, b = r * n_theta + k, r * n_theta + (k + 1) % n_theta
            c, d = a + n_theta, b + n_theta
            f += [[a, c, b], [b, c, d]]
    return v, np.array(f, dtype=np.int64)


def sequence(body, v, f, T: int, seed: int, betas):
    """Poses (T, 24, 3), trans (T, 3) and ground-truth positions (T, V, 3) for garment (v, f)."""
    import torch

    from core.body import skin_points
    from core.garment import Garment
    from core.motion import Y_UP_TO_Z_UP
    from core.skinning import bind_garment

    rng = np.random.default_rng(seed)
    t = np.arange(T) / 30.0
    poses = np.zeros((T, 24, 3), dtype=np.float32)
    poses[:, 0] = Y_UP_TO_Z_UP
    ph = rng.uniform(0, 2 * np.pi)
    poses[:, 1, 0] = 0.5 * np.sin(2 * np.pi * t + ph)
    poses[:, 2, 0] = -0.5 * np.sin(2 * np.pi * t + ph)
    poses[:, 3, 1] = 0.2 * np.sin(np.pi * t)
    trans = np.stack([0.1 * t, np.zeros(T), np.zeros(T)], 1).astype(np.float32)
    binding = bind_garment(Garment(v, f), body, 10)
    rest = v + np.einsum("vcs,s->vc", binding.shapedirs, body.fit_betas(betas))
    hip = poses[:, 1, 0]
    low = np.clip((0.1 - v[:, 1]) / 0.45, 0, 1)  # 0 at the waist, 1 at the hem
    offset = 0.03 * hip[:, None, None] * low[None, :, None] * np.array([0, 0, 1.0])[None, None]
    offset = offset + 0.02 * np.abs(hip)[:, None, None] * low[None, :, None] * np.c_[v[:, 0], 0 * v[:, 1], v[:, 2]][None]
    A = body.skinning_transforms(poses, trans, betas)
    x = torch.from_numpy((rest[None] + offset).astype(np.float32))
    pos = skin_points(x, torch.from_numpy(binding.weights), torch.from_numpy(A)).numpy()
    return poses, trans, pos.astype(np.float32)


def make_dataset(root: Path, T: int = 12, n_settle: int = 0, settle_shift_m: float = 0.0) -> Path:
    """Write a 3-sequence dataset (2 train on garment 'a', 1 val on garment 'b'). Returns root.

    n_settle: the first frames flagged as a settle blend; settle_shift_m: moves their positions along +X."""
    root = Path(root)
    (root / "garments").mkdir(parents=True, exist_ok=True)
    body = tiny_body()
    garments = {"a": tube(12, 6), "b": tube(10, 5, radius=(0.32, 0.21))}
    for name, (v, f) in garments.items():
        write_obj(root / "garments" / f"{name}.obj", v, f)
    items = []
    for k, (gname, seed, split) in enumerate([("a", 0, "train"), ("a", 1, "train"), ("b", 2, "val")]):
        betas = np.zeros(4, np.float32)
        betas[0] = 0.5 * k
        v, f = garments[gname]
        poses, trans, pos = sequence(body, v, f, T, seed, betas)
        pos[:n_settle, :, 0] += np.float32(settle_shift_m)
        iid = f"s{k}"
        write_sequence(sequence_path(root, iid), DatasetSequence(
            positions=pos, poses=poses, trans=trans, betas=betas, fps=30.0, n_settle=n_settle, garment=gname,
            garment_sha256="", body="tiny"))
        items.append({"id": iid, "garment": gname, "motion": f"m{k}", "split": split, "betas": betas.tolist(),
                      "file": f"sequences/{iid}.npz"})
    # The layout `garment dataset` writes (core.dataset.build_manifest): the split is a field of each item.
    write_manifest(root, {"format": "garment-dataset/1", "items": items,
                          "splits": {"motions": {"train": ["m0", "m1"], "val": ["m2"], "test": []},
                                     "garments": {"train": ["a"], "val": ["b"], "test": []}, "held_out_garments": []}})
    return root


def copy_recording_body(data: Path, body: Path, dest: Path) -> Path:
    """A copy of dataset `data` at `dest` whose manifest records `body` as the body it was simulated on (path and
    sha256, as `garment dataset` writes). Returns dest."""
    import hashlib
    import json
    import shutil

    shutil.copytree(data, dest)
    manifest = json.loads((dest / "manifest.json").read_text())
    manifest["inputs"] = {"body": {"path": str(body), "sha256": hashlib.sha256(Path(body).read_bytes()).hexdigest()}}
    (dest / "manifest.json").write_text(json.dumps(manifest))
    return dest


def perturbed_model(config: ModelConfig = TINY_CONFIG, scale: float = 0.2, seed: int = 0):
    """A GarmentModel whose every parameter got N(0, scale^2) noise: away from the LBS-reproducing start."""
    import torch

    from core.model import GarmentModel

    torch.manual_seed(seed)
    model = GarmentModel(config)
    with torch.no_grad():
        for p in model.parameters():
            p.add_(scale * torch.randn_like(p))
    return model
