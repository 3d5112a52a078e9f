"""On-disk cache of derived arrays (preprocessed garments) as version-stamped .npz files.

A cache entry is one `.npz` holding the arrays plus a `__meta__` JSON string
with the format version and the caller's key fields (content hash, settings,
body identity). `read_cache` returns None — a miss, never an error — when the
file is missing, unreadable, of another version or written for other key
fields, so a stale or broken entry is recomputed and overwritten. Writes go to
a temporary file renamed into place, so readers never see half an entry.
"""

from __future__ import annotations

import functools
import json
import logging
import os
import zipfile
from pathlib import Path

import numpy as np

from core.errors import InputError
from formats.atomic import atomic_file

log = logging.getLogger(__name__)

#: Bump when the layout or meaning of cached arrays changes: older entries become misses.
CACHE_FORMAT_VERSION = 1
CACHE_ENV = "GARMENT_CACHE_DIR"


def default_cache_dir() -> Path:
    """$GARMENT_CACHE_DIR if set, else garment/ in $XDG_CACHE_HOME if set, else ~/.cache/garment; where the home
    directory does not exist (a container's HOME=/nonexistent, a service account's), garment-cache-<uid> in the
    temporary directory, said once (it was created, home and all, where the user could: as root)."""
    env = os.environ.get(CACHE_ENV)
    if env:
        return Path(env).expanduser()
    xdg = os.environ.get("XDG_CACHE_HOME")
    if xdg:
        return Path(xdg).expanduser() / "garment"
    try:
        home = Path.home()
    except RuntimeError:  # no HOME and no password entry
        home = None
    return home / ".cache" / "garment" if home is not None and home.is_dir() else _homeless_cache_dir(str(home))


@functools.lru_cache(maxsize=None)
def _homeless_cache_dir(home: str) -> Path:
    import tempfile

    path = Path(tempfile.gettempdir()) / f"garment-cache-{os.getuid() if hasattr(os, 'getuid') else 'user'}"
    log.warning("home directory '%s' does not exist: caches in '%s' (set %s to keep them elsewhere)", home, path,
                CACHE_ENV)
    return path


def cache_path(cache_dir: str | os.PathLike, kind: str, key: str) -> Path:
    """Path of the entry `kind`-`key`.npz in `cache_dir` (key: hex digest; the first 40 characters are used)."""
    return Path(cache_dir) / f"{kind}-{key[:40]}.npz"


def read_cache(path: str | os.PathLike, expected_meta: dict) -> dict | None:
    """Arrays of the entry at `path`, or None when missing, broken, of another version or other key fields.

    expected_meta: JSON-serialisable dict that must equal the stored key fields.
    Returns {name: ndarray} without the meta entry.
    """
    path = Path(path)
    if not path.is_file():
        return None
    try:
        with np.load(path, allow_pickle=False) as data:
            meta = json.loads(str(data["__meta__"]))
            if meta.get("version") != CACHE_FORMAT_VERSION:
                log.info("cache '%s': version %s, expected %s: recomputing", path, meta.get("version"),
                         CACHE_FORMAT_VERSION)
                return None
            if meta.get("key") != json.loads(json.dumps(expected_meta)):
                log.info("cache '%s': written for other inputs or settings: recomputing", path)
                return None
            return {k: data[k] for k in data.files if k != "__meta__"}
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile, json.JSONDecodeError) as exc:
        log.warning("cache '%s' is unreadable (%s): recomputing", path, exc)
        return None


def write_cache(path: str | os.PathLike, arrays: dict, meta: dict) -> Path:
    """Write `arrays` ({name: ndarray}) and the key fields `meta` to `path` atomically; returns the path.

    Raises InputError naming the directory when it cannot be created or written.
    """
    path = Path(path)
    payload = {"__meta__": np.array(json.dumps({"version": CACHE_FORMAT_VERSION, "key": meta}))}
    payload.update({k: np.asarray(v) for k, v in arrays.items()})
    try:
        path.parent.mkdir(parents=True, exist_ok=True)  # here, to name the cache directory when it cannot be made
        with atomic_file(path) as tmp, open(tmp, "wb") as fh:
            np.savez(fh, **payload)
    except OSError as exc:
        raise InputError(f"cache directory '{path.parent}': cannot be written ({exc.strerror or exc})") from None
    return path
