"""Atomic output: write beside the target under a hidden temporary name, rename on success.

Every writer uses these, so an interrupted or failed write never leaves a
half-written file or directory under the final name, and what is written gets
the ordinary permissions the user's umask gives (not mkstemp's private 0600).
"""

from __future__ import annotations

import os
import shutil
import tempfile
from contextlib import contextmanager
from pathlib import Path

from core.errors import InputError, special_kind


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextmanager
def _writing(path: Path):
    """An OSError making `path`'s folder or its temporary entry there as one InputError line naming `path`."""
    try:
        yield
    except OSError as exc:
        raise InputError(f"output '{path}': cannot write in '{path.parent}' ({exc.strerror or exc})") from None


def _refuse_special(path: Path) -> None:
    """InputError where `path` is a device, pipe or socket: renamed over, /dev/null became a file."""
    kind = special_kind(path)
    if kind:
        raise InputError(f"output '{path}' is {kind}: expected a file or folder to write (outputs are renamed into "
                         "place, which would replace it)")


@contextmanager
def atomic_file(path: str | os.PathLike):
    """Yield a temporary path beside `path` (same suffix); on success it replaces `path`.

    The parent directory is created. On an exception the temporary file is removed. A device, pipe or socket at
    `path` is refused (InputError).
    """
    path = Path(path)
    _refuse_special(path)
    with _writing(path):
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=".partial" + path.suffix, dir=path.parent)
    os.close(fd)
    tmp = Path(tmp)
    try:
        yield tmp
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def _remove(path: Path) -> None:
    """Remove `path`, a folder (with what it holds) or a file, if it exists."""
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        path.unlink(missing_ok=True)


@contextmanager
def atomic_dir(final: str | os.PathLike, overwrite: bool):
    """Yield a temporary directory beside `final`; on success it becomes `final`.

    Refuses an existing `final` unless `overwrite` (InputError naming it). On an
    exception the temporary directory is removed and `final` is untouched.
    """
    final = Path(final)
    _refuse_special(final)
    if final.exists() and not overwrite:
        raise InputError(f"output '{final}' exists: pass --overwrite to replace it")
    with _writing(final):
        final.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{final.name}.", suffix=".partial", dir=final.parent))
    os.chmod(tmp, 0o777 & ~_umask())
    try:
        yield tmp
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    if final.exists():
        old = final.with_name(f".{final.name}.old")
        _remove(old)
        os.replace(final, old)
        os.replace(tmp, final)
        _remove(old)  # a folder, or the file --overwrite replaced with one
    else:
        os.replace(tmp, final)
