"""Training-set storage: one compressed .npz per simulated sequence, a manifest.json, the garment templates.

Layout of a dataset directory DATA/:

    DATA/manifest.json              plan, splits, provenance (see core.dataset.build_manifest)
    DATA/garments/<name>.obj        the garment templates (copied byte for byte; sha256 in the manifest)
    DATA/sequences/<item id>.npz    one per (garment, motion clip, body shape)

A sequence file (`np.savez_compressed`) holds:
    positions (T, V, 3) float32  garment vertices, metres, the motion's Z-up world
    poses     (T, J, 3) float32  axis-angle radians in the body's joint layout (24 for SMPL-format)
    trans     (T, 3) float32     root translation, metres, Z-up world
    betas     (S,) float32       body shape coefficients
    fps       () float64         frames per second
    n_settle  () int64           leading frames before the clip: the blend from the rest pose, then any pre-roll
    garment   () str             template name (DATA/garments/<garment>.obj)
    garment_sha256 () str        core.garment.Garment.content_hash() of the template
    body      () str             body id (e.g. 'default' or the body file's name)
Every file is written atomically (temporary name, then rename), so a file that
exists is complete: resuming skips it.
"""

from __future__ import annotations

import json
import os
import shutil
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from core.errors import InputError, refuse_non_finite
from formats.atomic import atomic_file

SEQUENCE_KEYS = ("positions", "poses", "trans", "betas", "fps", "n_settle", "garment", "garment_sha256", "body")
MANIFEST = "manifest.json"


@dataclass(frozen=True, eq=False)
class Sequence:
    """One stored sequence (shapes and units as in the module docstring)."""

    positions: np.ndarray
    poses: np.ndarray
    trans: np.ndarray
    betas: np.ndarray
    fps: float
    n_settle: int
    garment: str
    garment_sha256: str
    body: str


def sequence_path(data_dir: str | os.PathLike, item_id: str) -> Path:
    return Path(data_dir) / "sequences" / f"{item_id}.npz"


def write_sequence(path: str | os.PathLike, seq: Sequence) -> None:
    """Write `seq` as a compressed .npz, atomically."""
    T = seq.positions.shape[0]
    if seq.poses.shape[0] != T or seq.trans.shape != (T, 3):
        raise InputError(f"sequence '{path}': positions, poses and trans must share T={T} frames, got "
                         f"{seq.poses.shape[0]} and {tuple(seq.trans.shape)}")
    arrays = {
        "positions": np.asarray(seq.positions, dtype=np.float32),
        "poses": np.asarray(seq.poses, dtype=np.float32),
        "trans": np.asarray(seq.trans, dtype=np.float32),
        "betas": np.asarray(seq.betas, dtype=np.float32).reshape(-1),
        "fps": np.float64(seq.fps),
        "n_settle": np.int64(seq.n_settle),
        "garment": np.array(str(seq.garment)),
        "garment_sha256": np.array(str(seq.garment_sha256)),
        "body": np.array(str(seq.body)),
    }
    with atomic_file(path) as tmp, open(tmp, "wb") as f:
        np.savez_compressed(f, **arrays)


def read_sequence(path: str | os.PathLike) -> Sequence:
    """Read a sequence file; InputError naming the file for a missing or unreadable one."""
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as d:
            missing = [k for k in SEQUENCE_KEYS if k not in d.files]
            if missing:
                raise InputError(f"sequence '{path}': missing keys {missing}")
            a = {k: d[k] for k in SEQUENCE_KEYS}
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
        raise InputError(f"sequence '{path}': could not read it ({str(exc).splitlines()[0][:120]})") from None
    refuse_non_finite({k: a[k] for k in ("positions", "poses", "trans", "betas")}, f"sequence '{path}'")
    return Sequence(positions=a["positions"], poses=a["poses"], trans=a["trans"], betas=a["betas"],
                    fps=float(a["fps"]), n_settle=int(a["n_settle"]), garment=str(a["garment"]),
                    garment_sha256=str(a["garment_sha256"]), body=str(a["body"]))


def write_manifest(data_dir: str | os.PathLike, manifest: dict) -> None:
    with atomic_file(Path(data_dir) / MANIFEST) as tmp:
        tmp.write_text(json.dumps(manifest, indent=1))


def read_manifest(data_dir: str | os.PathLike) -> dict | None:
    """The manifest of `data_dir`, or None when there is none."""
    path = Path(data_dir) / MANIFEST
    if not path.is_file():
        return None
    try:
        manifest = json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise InputError(f"dataset manifest '{path}': expected JSON, could not parse it ({exc})") from None
    if not isinstance(manifest, dict):  # fit, train and dataset took it for one: a traceback each
        raise InputError(f"dataset manifest '{path}': expected a JSON object (settings, items, ...), got a "
                         f"{type(manifest).__name__}")
    return manifest


def body_difference(manifest: dict, body_path: str | os.PathLike | None) -> str:
    """"" when the body at `body_path` (None: the embedded default) is the one the dataset of `manifest` was
    simulated on (the same file content: `inputs.body.sha256`, None for the default) or the manifest does not
    record it; else a sentence saying which body the dataset was simulated on and which was given."""
    from core.provenance import file_sha256

    inputs = manifest.get("inputs") if isinstance(manifest, dict) else None
    recorded = inputs.get("body") if isinstance(inputs, dict) else None
    if not isinstance(recorded, dict) or "sha256" not in recorded:
        return ""
    given = None if body_path is None else file_sha256(body_path)
    if given == recorded["sha256"]:
        return ""
    simulated_on = ("the embedded default body" if recorded["sha256"] is None
                    else f"body '{recorded.get('path')}' (file sha256 {str(recorded['sha256'])[:8]})")
    got = "the embedded default" if body_path is None else f"'{body_path}' (file sha256 {given[:8]})"
    return f"was simulated on {simulated_on}, got {got}"


def copy_garment_template(data_dir: str | os.PathLike, source: str | os.PathLike, name: str) -> Path:
    """Copy a garment OBJ to DATA/garments/<name>.obj (atomically; an identical copy is left alone); a USD
    garment is written there as the OBJ of the garment it reads as."""
    from formats.obj import USD_SUFFIXES, read_garment, write_obj

    source = Path(source)
    target = Path(data_dir) / "garments" / f"{name}.obj"
    if source.suffix.lower() in USD_SUFFIXES:
        g = read_garment(source)
        with atomic_file(target) as tmp:
            write_obj(tmp, g.vertices, g.faces, g.uvs, g.face_uvs, header=f"garment '{source.name}', read as OBJ")
        return target
    if target.is_file() and target.read_bytes() == source.read_bytes():
        return target
    with atomic_file(target) as tmp:
        shutil.copyfile(source, tmp)
    return target
