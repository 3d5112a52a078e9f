"""Provenance: the versions of the software that produced an output, for summaries and manifests."""

from __future__ import annotations

import platform
from importlib.metadata import PackageNotFoundError, version


def package_version(dist: str) -> str:
    """The installed version of distribution `dist`, or 'unknown'."""
    try:
        return version(dist)
    except PackageNotFoundError:
        return "unknown"


def software_versions(*dists: str) -> dict[str, str]:
    """{'python': ..., dist: version, ...} for the given distributions."""
    return {"python": platform.python_version(), **{d: package_version(d) for d in dists}}


def file_sha256(path) -> str:
    """sha256 of a file's bytes, read in blocks: an input recorded in a summary or a manifest, and checked against
    it (`formats.dataset.body_difference`)."""
    import hashlib

    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()
