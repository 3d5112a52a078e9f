"""Point caches: a garment's points per frame in one file, in the order of its own file's points, so that a tool
applies the bake to the user's own copy of the garment (with its modifiers, materials and rig): 3ds Max's PC2
(Point Cache 2; Blender's Mesh Cache modifier, Cinema 4D) and LightWave's MDD (Blender's Mesh Cache modifier,
Cinema 4D, Houdini's MDD import).

PC2: the 12 bytes 'POINTCACHE2\\0', int32 version 1, int32 points, float32 start frame, float32 sample rate
(frames between samples: 1), int32 samples, then every sample's points as float32 x y z; little-endian.
MDD: big-endian int32 frames, int32 points, float32 each frame's time in seconds, then every frame's points as
float32 x y z.

`bake --point-cache` writes the points in the garment file's own frame (metres, Y-up, the bake's Z-up world turned
back): Blender's OBJ import keeps a file's points as they are and turns the object to its Z-up, so the cache plays
on the garment imported as it comes, the Mesh Cache modifier's Frame Start set to the bake's first frame number
(`benchmarks/results/point_cache_check.md`).
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

from core.errors import InputError

#: The point cache formats `bake --point-cache` writes, by their files' suffixes.
POINT_CACHE_FORMATS = ("pc2", "mdd")
_PC2_MAGIC = b"POINTCACHE2\0"


def write_point_cache(path: Path, points: np.ndarray, fps: float, start_frame: int = 0) -> Path:
    """Write points (T, V, 3) as the point cache its suffix names (.pc2 or .mdd): frames numbered from
    `start_frame` (PC2's start frame; MDD's times start_frame / fps, 1 / fps apart). Returns the path."""
    path = Path(path)
    points = np.ascontiguousarray(points, dtype=np.float32)
    T, V = points.shape[:2]
    kind = path.suffix.lower().lstrip(".")
    if kind == "pc2":
        header = _PC2_MAGIC + struct.pack("<iiffi", 1, V, float(start_frame), 1.0, T)
        path.write_bytes(header + points.astype("<f4").tobytes())
    elif kind == "mdd":
        times = (start_frame + np.arange(T)) / float(fps)
        path.write_bytes(struct.pack(">ii", T, V) + times.astype(">f4").tobytes() + points.astype(">f4").tobytes())
    else:
        raise ValueError(f"expected a .pc2 or .mdd path, got '{path}'")
    return path


def read_point_cache(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """(points (T, V, 3) float32, each frame's number (PC2) or time in seconds (MDD) (T,)) of a .pc2 or .mdd file;
    InputError naming the file where it is not one, or is cut short."""
    path = Path(path)
    src = f"point cache '{path}'"
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise InputError(f"{src}: cannot be read ({exc.strerror or exc})") from None
    kind = path.suffix.lower().lstrip(".")
    try:
        if kind == "pc2":
            if data[:12] != _PC2_MAGIC:
                raise InputError(f"{src}: expected a PC2 file (starting 'POINTCACHE2' and a NUL byte), got "
                                 f"{data[:12]!r}" + (f" ({len(data)} bytes: cut short?)" if len(data) < 32 else ""))
            _, V, start, rate, T = struct.unpack_from("<iiffi", data, 12)
            _counts(T, V, src)
            values, stamps = np.frombuffer(data, "<f4", T * V * 3, 32), start + rate * np.arange(T)
        elif kind == "mdd":
            T, V = struct.unpack_from(">ii", data, 0)
            _counts(T, V, src)
            stamps = np.frombuffer(data, ">f4", T, 8).astype(np.float64)
            values = np.frombuffer(data, ">f4", T * V * 3, 8 + 4 * T)
        else:
            raise InputError(f"{src}: expected a .pc2 or .mdd file, got '{path.suffix}'")
    except InputError:
        raise
    except (struct.error, ValueError):
        raise InputError(f"{src}: cut short or damaged (its header's frames and points exceed its "
                         f"{len(data):,} bytes)") from None
    return values.astype(np.float32).reshape(T, V, 3), np.asarray(stamps, dtype=np.float64)


def _counts(frames: int, points: int, src: str) -> None:
    if frames < 1 or points < 1:
        raise InputError(f"{src}: expected a header of at least 1 frame and 1 point, got {frames} and {points}")
