"""Atomic output: write beside the target under a hidden temporary name, rename on success.

Every writer uses these, so an interrupted or failed write never leaves a
half-written file or directory under the final name, and what is written gets
the ordinary permissions the user's umask gives (not mkstemp's private 0600). A write
that runs out of room (a full disk or quota) is one line naming the output and the
space left.
"""

from __future__ import annotations

import errno
import logging
import os
import random
import shutil
import socket
import tempfile
import time
import uuid
from contextlib import ExitStack, contextmanager
from pathlib import Path

from core.distributed import raise_if_stopped
from core.errors import InputError, special_kind

log = logging.getLogger(__name__)


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


#: errno values of a write that ran out of room: the disk or the user's quota full, a file over the size limit.
OUT_OF_ROOM = (errno.ENOSPC, errno.EDQUOT, errno.EFBIG)
#: Free space under this on an output's file system is named when a writer fails without saying why (USD's).
LOW_SPACE_BYTES = 64 * 2**20


def size_text(n: int) -> str:
    """A byte count as a message says it: '8.0 kB', '1.5 GB', '12 bytes'."""
    for unit, size in (("GB", 2**30), ("MB", 2**20), ("kB", 2**10)):
        if n >= size:
            return f"{n / size:.1f} {unit}"
    return f"{n} bytes"


def nearest_existing(path: str | os.PathLike) -> Path:
    """`path` made absolute, or the nearest of its parents that exists (the root at worst): where an output that is
    not there yet would be made."""
    found = Path(path).absolute()
    while not found.exists() and found != found.parent:
        found = found.parent
    return found


def free_space(path: str | os.PathLike) -> int | None:
    """Bytes free to the user on the file system holding `path` (its nearest existing folder), None if unknown."""
    try:
        return shutil.disk_usage(nearest_existing(path)).free
    except OSError:
        return None


def low_space_note(path: str | os.PathLike) -> str:
    """"" or, where the file system holding `path` has under LOW_SPACE_BYTES free, "; 8.0 kB free on its file
    system (full?)", for the message of a writer that failed without saying why."""
    free = free_space(path)
    return "" if free is None or free >= LOW_SPACE_BYTES else f"; {size_text(free)} free on its file system (full?)"


@contextmanager
def _written(path: Path):
    """An OSError of a write that ran out of room (`OUT_OF_ROOM`) in the block as one InputError line naming
    `path` and the space left."""
    try:
        yield
    except OSError as exc:
        if exc.errno not in OUT_OF_ROOM:
            raise
        raise out_of_room(path, exc) from None


class OutOfRoom(InputError):
    """A write that ran out of room (`out_of_room`): a batch stops at it (the next outputs would not fit either)."""


def out_of_room(path, exc: OSError) -> InputError:
    """The one line of a write to `path` (None: unknown) that ran out of room, with the space left there."""
    free = None if path is None else free_space(path)
    left = "" if free is None else f"; {size_text(free)} free on its file system"
    what = "the outputs" if path is None else f"output '{path}'"
    return OutOfRoom(f"{what}: could not be written ({exc.strerror or exc}{left})")


def _host() -> str:
    return socket.gethostname().replace(".", "_")  # a temporary name's parts are split at dots


def _owner() -> str:
    """This process as the temporary names it writes say it ('host@pid'), for `_sweep`."""
    return f"{_host()}@{os.getpid()}"


def _temporary_extra() -> int:
    """Characters of a temporary name beside an output's own (`atomic_dir`'s ".NAME.HOST@PID.XXXXXXXX.partial" and
    `_swap_in`'s ".NAME.HOST@PID.XXXXXXXX.partial.old"), taken at a pid of 10 digits."""
    return len(f"..{_host()}@{'9' * 10}.{'x' * 8}.partial.old")


def check_name_fits(final: str | os.PathLike) -> None:
    """InputError where the output `final`, or the hidden temporary name it is written under first, is longer than
    its file system takes (NAME_MAX, 255 on most): said before any work (a motion's 225-character name failed with
    'File name too long' after it had been baked)."""
    final = Path(os.path.abspath(final))
    try:
        limit = os.pathconf(nearest_existing(final.parent), "PC_NAME_MAX")
    except (OSError, ValueError):
        limit = 255
    most = limit - _temporary_extra()
    if len(final.name.encode()) > most:
        raise InputError(f"output '{final}': its name is {len(final.name.encode())} bytes long, at most {most} fit "
                         f"there (its file system takes names of {limit}, and the output is written under a longer "
                         "hidden name first): shorten the file names it is made of, or rename the input")


def _sweep(folder: Path, name: str) -> None:
    """Remove the temporary files and folders a killed run (SIGKILL: the out-of-memory killer, a scheduler after
    its grace) left for the output `name` in `folder`: those of a process of this host that no longer exists.
    Others' (another host's, a living process's) are left alone."""
    import glob

    import psutil

    host = _host()
    for leftover in folder.glob(f".{glob.escape(name)}.*@*.*partial*"):
        owner = leftover.name[len(name) + 2:].split(".", 1)[0]
        owner_host, _, pid = owner.rpartition("@")
        if owner_host != host or not pid.isdigit() or psutil.pid_exists(int(pid)):
            continue
        _remove(leftover)
        log.info("removed '%s', left by an interrupted run", leftover)


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
    `path`, or a folder (the rename failed after the work with IsADirectoryError, naming the temporary file), is
    refused (InputError).
    """
    path = Path(path)
    _refuse_special(path)
    if path.is_dir():
        raise InputError(f"output '{path}' is a folder: expected a file to write (or nothing there)")
    with _writing(path):
        path.parent.mkdir(parents=True, exist_ok=True)
        _sweep(path.parent, path.stem)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.{_owner()}.", suffix=".partial" + path.suffix,
                                   dir=path.parent)
    os.close(fd)
    tmp = Path(tmp)
    try:
        with _written(path):
            yield tmp
        raise_if_stopped(path)
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


@contextmanager
def atomic_files(paths):
    """`atomic_file` for several outputs at once: yields their temporary paths (in order); each replaces its output
    only when the block wrote them all (a set of reports is whole, or as it was)."""
    with ExitStack() as stack:
        yield [stack.enter_context(atomic_file(path)) for path in paths]


def _remove(path: Path) -> None:
    """Remove `path`, a folder (with what it holds) or a file, if it exists."""
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        path.unlink(missing_ok=True)


def refuse_replacing(final: str | os.PathLike, inputs=()) -> None:
    """InputError where replacing the folder `final` whole (`--overwrite`) would take the working folder, a folder
    above it, or one of `inputs` with it (`render --out BAKE --overwrite` deleted the bake it rendered; `--out .`
    everything in the working folder)."""
    given = final
    final = Path(os.path.abspath(final))
    if not final.is_dir():
        return
    here = Path.cwd().resolve()
    target = final.resolve()
    if target == here or target in here.parents:
        raise InputError(f"output '{given}' is the working folder or holds it: --overwrite replaces the output "
                         f"folder whole; expected a folder of the outputs' own (--out)")
    for path in inputs:
        read = None if path is None else Path(os.path.abspath(path)).resolve()
        if read is not None and (read == target or target in read.parents):
            raise InputError(f"output '{given}' holds the input '{path}': --overwrite replaces the output folder "
                             f"whole; expected a folder of the outputs' own (--out)")


@contextmanager
def atomic_dir(final: str | os.PathLike, overwrite: bool, inputs=()):
    """Yield a temporary directory beside `final`; on success it becomes `final`.

    Refuses an existing `final` unless `overwrite` (InputError naming it), and one whose replacing would take the
    working folder or `inputs` with it (`refuse_replacing`). On an exception the temporary directory is removed
    and `final` is untouched.
    """
    final = Path(final)
    if final.name in ("", ".."):  # '.' or '..': by the name of the folder it is
        final = Path(os.path.abspath(final))
    _refuse_special(final)
    if final.exists() and not overwrite:
        raise InputError(f"output '{final}' exists: pass --overwrite to replace it")
    refuse_replacing(final, inputs)
    check_name_fits(final)
    raise_if_stopped(final)  # (a stopped run's task made its --out again, empty, where it began writing)
    with _writing(final):
        final.parent.mkdir(parents=True, exist_ok=True)
        _sweep(final.parent, final.name)
        tmp = Path(tempfile.mkdtemp(prefix=f".{final.name}.{_owner()}.", suffix=".partial", dir=final.parent))
    os.chmod(tmp, 0o777 & ~_umask())
    try:
        try:
            with _written(final):
                yield tmp
        except InputError as exc:  # a writer's message names what it wrote by its final path, not the hidden one
            raise InputError(str(exc).replace(str(tmp), str(final))) from None
        raise_if_stopped(final)  # a cluster's task whose run was stopped meanwhile
        _swap_in(tmp, final, overwrite)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)  # gone already where it became `final`


#: Tries of `_swap_in` where another run puts its own output in place between its steps, each after a random
#: wait of up to SWAP_WAIT_S times 2**try (at most 2**6): four runs writing one output 200 times each on a busy
#: machine ran out of 8 tries without a wait.
SWAP_TRIES = 16
SWAP_WAIT_S = 0.001


def _swap_in(tmp: Path, final: Path, overwrite: bool) -> None:
    """Rename the finished folder `tmp` to `final`. An output at `final` now, made by another run while this one
    worked (two bakes into one --out), is refused without `overwrite` (the check at the start saw none), and with it
    moved aside under a name of this process's own and removed (one shared name let two runs at once remove each
    other's, or fail on it)."""
    for attempt in range(SWAP_TRIES):
        if attempt:
            time.sleep(random.uniform(0.0, SWAP_WAIT_S * 2 ** min(attempt, 6)))
        old = None
        if final.exists() or final.is_symlink():
            if not overwrite:
                raise InputError(f"output '{final}' was written by another run while this one worked: pass "
                                 f"--overwrite to replace it, or give each run its own --out")
            old = final.with_name(f".{final.name}.{_owner()}.{uuid.uuid4().hex[:8]}.partial.old")
            try:
                os.replace(final, old)
            except FileNotFoundError:  # another run moved it away first
                old = None
        try:
            os.rename(tmp, final)  # a folder: fails where another run's folder took the name since
            return
        except OSError as exc:
            if exc.errno not in (errno.ENOTEMPTY, errno.EEXIST, errno.ENOTDIR, errno.EISDIR):
                raise
        finally:
            if old is not None:
                _remove(old)  # a folder, or the file --overwrite replaced with one
    raise InputError(f"output '{final}': other runs kept writing it; give each run its own --out")
