"""Fitted blend shapes (`core.psd.PSDFit`) on disk: one `.npz` (no pickles) written atomically.

Keys: format ("garment-psd"), version, mean (3V,), basis (K, 3V), weights (F, K), and `header`: JSON with the
garment's mesh hash, the body's name, joint and beta counts, the LBS binding's smoothing and the fit's meta.
"""

from __future__ import annotations

import json
import os
import zipfile
from pathlib import Path

import numpy as np

from core.errors import InputError, require_input
from core.psd import PSDDeformer, PSDFit
from core.strain import STRAIN_LIMIT
from formats.atomic import atomic_file

FORMAT = "garment-psd"
VERSION = 1


def save_fit(path: str | os.PathLike, fit: PSDFit) -> Path:
    path = Path(path)
    header = {"garment_sha256": fit.garment_sha256, "body": fit.body, "body_sha256": fit.body_sha256,
              "n_joints": fit.n_joints,
              "n_betas": fit.n_betas, "smooth_iterations": fit.smooth_iterations,
              "smooth_strength": fit.smooth_strength, "meta": fit.meta}
    with atomic_file(path) as tmp, open(tmp, "wb") as fh:
        garment = {} if fit.garment_vertices is None else {"garment_vertices": fit.garment_vertices,
                                                           "garment_faces": fit.garment_faces}
        np.savez(fh, format=np.array(FORMAT), version=np.array(VERSION), header=np.array(json.dumps(header)),
                 mean=fit.mean, basis=fit.basis, weights=fit.weights, **garment)
    return path


def load_fit(path: str | os.PathLike) -> PSDFit:
    """Read a fit written by `save_fit`; InputError naming the file for a missing, foreign or broken one."""
    path = Path(path)
    where = f"psd fit '{path}'"
    require_input(path, where)
    try:
        with np.load(path, allow_pickle=False) as d:
            if "format" not in d.files or str(d["format"]) != FORMAT:
                if any(k.endswith(("/data.pkl", "serialization_id")) for k in d.files):  # torch.save's zip
                    raise InputError(f"{where}: expected a fit written by `garment fit`, got a torch checkpoint (a "
                                     f"model? bake it with --method model --model '{path}')")
                raise InputError(f"{where}: expected a fit written by `garment fit` (format '{FORMAT}'), got "
                                 f"keys {sorted(d.files)[:6]}")
            if int(d["version"]) > VERSION:
                raise InputError(f"{where}: version {int(d['version'])} is newer than this garment ({VERSION})")
            header = json.loads(str(d["header"]))
            mean, basis, weights = (np.asarray(d[k], np.float32) for k in ("mean", "basis", "weights"))
            garment_vertices, garment_faces = None, None  # a fit written before they were kept
            if "garment_vertices" in d.files and "garment_faces" in d.files:
                garment_vertices = np.asarray(d["garment_vertices"], np.float32)
                garment_faces = np.asarray(d["garment_faces"]).astype(np.int64)
    except InputError:
        raise
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as exc:
        raise InputError(f"{where}: cannot be read ({exc})") from None
    if basis.ndim != 2 or mean.shape != (basis.shape[1],) or weights.ndim != 2 or weights.shape[1] != basis.shape[0]:
        raise InputError(f"{where}: expected mean (3V,), basis (K, 3V), weights (F, K), got {mean.shape}, "
                         f"{basis.shape}, {weights.shape}")
    if garment_vertices is not None and (garment_vertices.shape != (mean.shape[0] // 3, 3) or garment_faces.ndim != 2
                                         or garment_faces.shape[1:] != (3,)):
        raise InputError(f"{where}: expected garment vertices ({mean.shape[0] // 3}, 3) and faces (F, 3), got "
                         f"{garment_vertices.shape}, {garment_faces.shape}")
    return PSDFit(garment_sha256=header["garment_sha256"], body=header["body"], n_joints=int(header["n_joints"]),
                  n_betas=int(header["n_betas"]), mean=mean, basis=basis, weights=weights,
                  smooth_iterations=int(header["smooth_iterations"]),
                  smooth_strength=float(header["smooth_strength"]), meta=dict(header.get("meta", {})),
                  body_sha256=header.get("body_sha256"), garment_vertices=garment_vertices,
                  garment_faces=garment_faces)


def psd_deformer(path: str | os.PathLike, contact_guard: bool = True,
                 strain_limit: float | None = STRAIN_LIMIT) -> PSDDeformer:
    """The `psd` method of the fit at `path` (`load_fit`), its errors naming the file."""
    return PSDDeformer(load_fit(path), source=f"psd fit '{path}'", contact_guard=contact_guard,
                       strain_limit=strain_limit)
