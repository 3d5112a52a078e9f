"""Shared CLI plumbing: turning `InputError` into one clear line, atomic output directories."""

from __future__ import annotations

import functools
import os
import shutil
import tempfile
from contextlib import contextmanager
from pathlib import Path

import click

from core.body import Body, default_body
from core.errors import InputError
from core.motion import parse_frame_range, resample, select_frames, settle


def input_errors_as_click(func):
    """Decorator: an `InputError` from core/formats becomes a one-line `click.ClickException`."""

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        try:
            return func(*args, **kwargs)
        except InputError as exc:
            raise click.ClickException(str(exc)) from None

    return wrapper


@contextmanager
def atomic_output_dir(final: Path, overwrite: bool):
    """Yield a temporary directory beside `final`; rename it to `final` only on success.

    Refuses an existing `final` unless `overwrite`; on any error the temporary
    directory is removed, so nothing half-written is left.
    """
    final = Path(final)
    if final.exists() and not overwrite:
        raise click.ClickException(f"output '{final}' exists: pass --overwrite to replace it")
    final.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{final.name}.", suffix=".partial", dir=final.parent))
    try:
        yield tmp
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    if final.exists():
        old = final.with_name(f".{final.name}.old")
        shutil.rmtree(old, ignore_errors=True)
        os.replace(final, old)
        os.replace(tmp, final)
        shutil.rmtree(old, ignore_errors=True)
    else:
        os.replace(tmp, final)


def load_body_option(body_path: str | None) -> Body:
    """The body named by --body, or the embedded default body."""
    if body_path is None:
        return default_body()
    from formats.body import load_body

    return load_body(body_path)


def prepare_motion(path: str, fps: float, frames: str | None, settle_frames: int):
    """Read a motion file and apply --frames (source frames), --fps and --settle, in that order."""
    from formats.motion import load_motion

    motion = load_motion(path)
    source_fps = motion.fps
    if frames:
        motion = select_frames(motion, *parse_frame_range(frames))
    motion = resample(motion, fps)
    return settle(motion, settle_frames), source_fps
