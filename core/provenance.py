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
