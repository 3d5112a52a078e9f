"""Errors raised by `core` and `formats` for bad input.

The CLI turns every `InputError` into one clear line and a non-zero exit, so the
message must name the file or option, what was expected and what was found.
"""

import errno
import functools
import logging
import os
import stat
import threading
from pathlib import Path


class InputError(ValueError):
    """Bad user input: a file, an array or an option value that cannot be used."""


def warnings_held(read):
    """Decorate a reader of a user's file: what it logs (its thread's records reaching the root logger's handlers)
    is shown once it returns, in order, and dropped where it refuses the file (InputError), so a refusal is its
    one line, not warnings about the file it then refuses (a garment of one point was warned about twice: its
    welded vertices, its dropped face). A reader called within another's holds nothing of its own: the outer one
    decides."""

    @functools.wraps(read)
    def held(*args, **kwargs):
        root = logging.getLogger()
        thread = threading.get_ident()
        if any(isinstance(f, _Held) and f.thread == thread for h in root.handlers for f in h.filters):
            return read(*args, **kwargs)
        records: list = []
        holds = [(h, _Held(thread, h, records)) for h in root.handlers]
        for h, hold in holds:
            h.addFilter(hold)
        try:
            result = read(*args, **kwargs)
        except InputError:
            records.clear()
            raise
        finally:
            for h, hold in holds:
                h.removeFilter(hold)
            for record, handler in records:  # in order, to the handlers they reached, once the reader is done
                handler.handle(record)
        return result

    return held


class _Held(logging.Filter):
    """Keeps the records of one thread that reach one of the root logger's handlers, with it, in `records`
    (`warnings_held`)."""

    def __init__(self, thread: int, handler: logging.Handler, records: list):
        super().__init__()
        self.thread, self.handler, self.records = thread, handler, records

    def filter(self, record: logging.LogRecord) -> bool:
        if record.thread != self.thread:
            return True
        self.records.append((record, self.handler))
        return False


def frames_text(n: int) -> str:
    """"1 frame", "5 frames": a frame count for messages (as `counted`, without its thousands' commas)."""
    return f"{n} frame" if n == 1 else f"{n} frames"


def counted(n: int, noun: str) -> str:
    """'1 frame', '2 frames', '1,000 frames': `n` with `noun`, plural but for one (the commands' lines)."""
    return f"{n:,} {noun}{'' if n == 1 else 's'}"


def check_finite_points(points, where: str, vertex: str = "vertex") -> None:
    """Raise InputError naming `where`, the first frame and vertex of (T, V, 3) `points` not finite, and which
    (NaN or Inf); `vertex` names the mesh's vertices in the message ("body vertex")."""
    import numpy as np  # errors.py is imported everywhere; numpy only when points are checked

    points = np.asarray(points)
    bad = ~np.isfinite(points).all(axis=-1)
    if bad.any():
        t, v = (int(i) for i in np.argwhere(bad)[0])
        kind = "NaN" if np.isnan(points[t, v]).any() else "Inf"
        raise InputError(f"{where}: expected finite coordinates, got {kind} at frame {t}, {vertex} {v}")


def refuse_non_finite(arrays: dict, where: str) -> None:
    """InputError naming `where` for the first of `arrays` ({key: array}) holding NaN or Inf: a simulated
    sequence's (a NaN in one made fit blame --ridge and train write a model of NaN weights, exit 0)."""
    import numpy as np  # errors.py is imported everywhere; numpy only when arrays are checked

    for key, value in arrays.items():
        value = np.asarray(value)
        if value.dtype.kind in "fc" and not np.isfinite(value).all():
            frame = int(np.argwhere(~np.isfinite(value))[0][0]) if value.ndim else 0
            raise InputError(f"{where}: expected finite '{key}', got NaN or Inf (first at frame {frame})")


def read_input(path, src: str) -> bytes:
    """The bytes of the input file `path`; InputError naming `src` where it cannot be read."""
    try:
        return Path(path).read_bytes()
    except OSError as exc:
        raise InputError(f"{src}: cannot read it ({exc.strerror or exc})") from None


def content_kind(path) -> str | None:
    """"an empty file" or "text ('its first line'...)" where the file `path` is one (a message's "got ..." for a
    reader that expected binary content: an OBJ renamed .pt), else None (binary, or unreadable)."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(64)
    except OSError:
        return None
    if not head:
        return "an empty file"
    text = head.decode("utf-8", errors="replace")
    if all(c.isprintable() or c in "\r\n\t" for c in text):
        return f"text ({text.splitlines()[0][:40]!r}...)"
    return None


def not_a_file(path) -> str | None:
    """Why `path` cannot be read as an input file (None: it is a regular file, or a link to one): "no such
    file", "a directory", "a pipe ..." (a shell's process substitution `<(...)`: read once, where the readers
    seek and read again), "a device", "a socket", "a symbolic link loop"."""
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        return "no such file"
    except OSError as exc:
        return "a symbolic link loop" if exc.errno == errno.ELOOP else (exc.strerror or str(exc)).lower()
    if stat.S_ISREG(mode):
        return None
    if stat.S_ISDIR(mode):
        return "a directory, expected a file"
    if stat.S_ISFIFO(mode):
        return "a pipe (such as the shell's <(...)), expected a file: write it to a file first"
    return f"{_special(mode)}, expected a file"


def require_input(path, label: str) -> None:
    """InputError "{label}: file not found" (or the other reasons of `not_a_file`: a directory, a pipe, a device)
    where `path` is no regular file to read (a pipe blocked a reader, and read as missing)."""
    reason = not_a_file(path)
    if reason:
        raise InputError(f"{label}: " + ("file not found" if reason == "no such file" else reason))


def special_kind(path) -> str | None:
    """"a pipe", "a socket" or "a device" where `path` is one (after links), else None (a file, a folder, nothing).
    Outputs are written beside their target and renamed over it: over /dev/null that replaced the device with a
    file (`formats.atomic` refuses)."""
    try:
        return _special(os.stat(path).st_mode)
    except OSError:
        return None


def _special(mode: int) -> str | None:
    """`special_kind` of a file of st_mode `mode`."""
    if stat.S_ISFIFO(mode):
        return "a pipe"
    if stat.S_ISSOCK(mode):
        return "a socket"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    return None
