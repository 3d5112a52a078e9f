"""Model and training checkpoints: one torch file holding the model config, weights and (optionally) training state.

Layout (a dict saved with `torch.save`, read with `weights_only=True`, so
loading never runs pickled code): format "garment-model", version,
config (ModelConfig as a dict), model (state dict), meta (free JSON-able
dict), and for training checkpoints `train` (optimizer state, RNG states,
phase state, step). Written atomically (temporary file, rename).
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import torch

from core.errors import InputError, not_a_file
from formats.atomic import atomic_file

FORMAT = "garment-model"
VERSION = 1


def save_checkpoint(path: str | os.PathLike, config, model_state: dict, meta: dict | None = None,
                    train: dict | None = None) -> Path:
    """Write a checkpoint atomically. config: a ModelConfig (dataclass) or dict."""
    cfg = dataclasses.asdict(config) if dataclasses.is_dataclass(config) else dict(config)
    payload = {"format": FORMAT, "version": VERSION, "config": cfg, "model": model_state, "meta": meta or {}}
    if train is not None:
        payload["train"] = train
    path = Path(path)
    with atomic_file(path) as tmp:
        torch.save(payload, tmp)
    return path


def load_checkpoint(path: str | os.PathLike) -> dict:
    """Read and check a checkpoint; InputError naming the file when it is not one of this version."""
    path = Path(path)
    reason = not_a_file(path)
    if reason:
        raise InputError(f"model '{path}': " + ("expected a checkpoint file, found none" if reason == "no such file"
                                                 else reason))
    try:
        data = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # torch raises many types for foreign or damaged files
        raise InputError(f"model '{path}': expected a garment model checkpoint, could not read it "
                         f"({type(exc).__name__})") from None
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise InputError(f"model '{path}': expected a '{FORMAT}' checkpoint, got another kind of file")
    if data.get("version") != VERSION:
        raise InputError(f"model '{path}': expected checkpoint format version {VERSION}, "
                         f"got version {data.get('version')!r}")
    for key in ("config", "model"):
        if key not in data:
            raise InputError(f"model '{path}': checkpoint lacks '{key}'")
    data.setdefault("meta", {})  # (save_checkpoint writes one; a checkpoint of another writer may lack it)
    for key in ("config", "model", "meta"):  # (a list or None made tracebacks in bake, info, attribute, train)
        if not isinstance(data[key], dict):
            raise InputError(f"model '{path}': expected the checkpoint's '{key}' a dict, got "
                             f"{type(data[key]).__name__}")
    bad = next((name for name, w in data["model"].items()
                if isinstance(w, torch.Tensor) and w.is_floating_point() and not torch.isfinite(w).all()), None)
    if bad is not None:  # (every command took it: bake blamed the motion, info printed NaN, attribute a NaN table)
        raise InputError(f"model '{path}': expected finite weights, got NaN or Inf in '{bad}' (a training that "
                         "diverged?)")
    return data


def load_model(path: str | os.PathLike):
    """The GarmentModel stored in a checkpoint (eval mode) and the checkpoint dict."""
    from core.model import GarmentModel, config_from_dict

    data = load_checkpoint(path)
    model = GarmentModel(config_from_dict(data["config"], source=f"model '{path}'"))
    try:
        loaded = model.load_state_dict(data["model"], strict=False)
    except RuntimeError as exc:  # weights of other sizes: torch's first line names none of them
        said = "; ".join(line.strip() for line in str(exc).splitlines()[1:] if line.strip())
        raise InputError(f"model '{path}': weights do not match its config ({said[:400] or 'other sizes'})") from None
    if loaded.missing_keys or loaded.unexpected_keys:
        said = ", ".join(f"{what} {keys[:3]}{' ...' if len(keys) > 3 else ''}" for what, keys in
                         (("missing", loaded.missing_keys), ("unexpected", loaded.unexpected_keys)) if keys)
        raise InputError(f"model '{path}': weights do not match its config ({said})")
    model.eval()
    return model, data
