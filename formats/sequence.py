"""Animated garment sequences: one reader for every form a baked result can take.

`read_sequence` accepts a directory of OBJ frames (with an optional
`sequence.json` giving the fps), an `.npz` sequence file, a USD stage, or a
single OBJ (one frame), and returns a `Sequence` of points that keep the
vertex numbering they were written with (nothing is cleaned), so sequences of
the same garment can be compared vertex by vertex (`garment metrics`, renders).
The writers here produce the first two forms.
"""

from __future__ import annotations

import json
import logging
import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from core.errors import InputError, frames_text, not_a_file, warnings_held
from formats.motion import open_npz
from formats.obj import STAGE_SUFFIXES, mtllib_text, obj_face_text, obj_vertex_text, parse_obj, triangulate
from formats.usd import read_usd

log = logging.getLogger(__name__)

SEQUENCE_JSON = "sequence.json"


@dataclass(frozen=True, eq=False)
class Sequence:
    """A garment's animation, with the body it moved on when the file has it.

    points: (T, V, 3) float32, metres. faces: (F, 3) int64. fps: frames per
    second, or None when the file does not say. body_points: (T, Vb, 3) float32
    metres or None; body_faces: (Fb, 3) int64 or None. source: the path read.
    first_frame: the number of its first frame (a USD stage's start time code, the first OBJ frame's file
    number: a bake's `--start-frame`; 0 where the file tells none).
    """

    points: np.ndarray
    faces: np.ndarray
    fps: float | None
    body_points: np.ndarray | None = None
    body_faces: np.ndarray | None = None
    source: str = ""
    first_frame: int = 0

    @property
    def n_frames(self) -> int:
        return int(self.points.shape[0])


def _natural_key(name: str):
    """Sort key that orders embedded numbers by value: frame_2 < frame_10."""
    return [(0, int(tok), "") if tok.isdigit() else (1, 0, tok.lower())
            for tok in re.split(r"(\d+)", name) if tok]


def _fps(value, where: str) -> float | None:
    if value is None:
        return None
    try:
        if isinstance(value, bool) or np.asarray(value).dtype.kind in "bcmMO":  # True is no frame rate
            raise TypeError
        fps = float(np.asarray(value).reshape(()))
    except (TypeError, ValueError):
        raise InputError(f"{where}: expected fps as one positive number, got {value!r}") from None
    if not (np.isfinite(fps) and fps > 0):
        raise InputError(f"{where}: expected fps > 0, got {fps}")
    return fps


def _check_faces(faces: np.ndarray, n_points: int, what: str, where: str) -> np.ndarray:
    faces = np.asarray(faces)
    if faces.ndim != 2 or faces.shape[1] != 3 or not np.issubdtype(faces.dtype, np.integer):
        raise InputError(f"{where}: expected {what} (F, 3) integers, got shape {faces.shape} {faces.dtype}")
    if faces.size and (faces.min() < 0 or faces.max() >= n_points):
        bad = int(faces.min()) if faces.min() < 0 else int(faces.max())
        raise InputError(f"{where}: {what} index {bad} out of range for {n_points} vertices")
    return faces.astype(np.int64)


def _check_points(points: np.ndarray, what: str, where: str) -> np.ndarray:
    points = np.asarray(points)
    if points.ndim != 3 or points.shape[2] != 3 or points.shape[0] == 0 or points.shape[1] == 0 \
            or points.dtype.kind not in "fiu":  # complex would lose its imaginary part, bool is no coordinate
        raise InputError(f"{where}: expected {what} (T, V, 3) real numbers with T, V >= 1, got shape {points.shape} "
                         f"{points.dtype}")
    with np.errstate(over="ignore"):  # past float32's range becomes Inf, refused naming the frame and vertex
        return points.astype(np.float32)


def _obj_files(directory: Path) -> list[Path]:
    """The `.obj` files directly in `directory`, ordered by the numbers in their names (`_natural_key`)."""
    return sorted((p for p in directory.iterdir() if p.suffix.lower() == ".obj" and p.is_file()),
                  key=lambda p: _natural_key(p.name))


_FRAME_NAME = re.compile(r"^(.*?)(\d+)$")


def _frame_files(directory: Path, files: list[Path], recorded_prefix: str | None = None) -> list[Path]:
    """The numbered frames among the `.obj` files of `directory` (`_obj_files`): the files whose stems end in a
    number (frame_0003, Blender skirt_000001, Houdini skirt.0001) with the prefix `sequence.json` records
    (`recorded_prefix`) where some have it, else the most common prefix, in frame order.
    Other OBJ files are left out with a warning naming them; a frame number used twice, or missing between the
    first and the last frame, is an InputError naming the file expected."""
    where = f"garment sequence '{directory}'"
    if len(files) == 1:
        return files
    groups: dict[str, list[tuple[int, Path]]] = {}
    stray = []
    for path in files:
        match = _FRAME_NAME.match(path.stem)
        if match is None:
            stray.append(path)
        else:
            groups.setdefault(match.group(1).lower(), []).append((int(match.group(2)), path))
    if not groups:
        raise InputError(f"{where}: expected numbered OBJ frames (frame_0000.obj, ...), got "
                         f"{', '.join(p.name for p in files[:4])}{', ...' if len(files) > 4 else ''}")
    # the key write_obj_sequence's names get (a recorded prefix ending in digits, f1 of f10000, groups as f)
    recorded = None if recorded_prefix is None else _FRAME_NAME.match(f"{recorded_prefix}0000").group(1).lower()
    most = max(len(g) for g in groups.values())
    several = sorted(k for k in groups if len(groups[k]) == most)
    if recorded not in groups and most > 1 and len(several) > 1:  # (Houdini's and Maya's folders: body.0001,
        # cloth.0001, ... as many of each; fewer others, such as backup1.obj and backup2.obj, are left out, warned)
        named = ", ".join(f"{min(groups[k])[1].name} ({most} files)" for k in several[:4])
        raise InputError(f"{where}: expected the frames of one garment, got {len(several)} numbered sequences: "
                         f"{named}{', ...' if len(several) > 4 else ''}: give a folder holding one (or a "
                         f"{SEQUENCE_JSON} naming its 'prefix')")
    prefix = max(groups, key=lambda k: (k == recorded, len(groups[k]), k == "frame_"))
    frames = sorted(groups.pop(prefix), key=lambda nf: nf[0])
    stray += [p for group in groups.values() for _, p in group]
    if stray:
        names = sorted(p.name for p in stray)
        log.warning("%s: left out %s not numbered like the frames (%s): %s", where,
                    "1 OBJ file" if len(names) == 1 else f"{len(names)} OBJ files", frames[0][1].name,
                    ", ".join(names[:5]) + (", ..." if len(names) > 5 else ""))
    for (n_a, a), (n_b, b) in zip(frames, frames[1:]):
        if n_b == n_a:
            raise InputError(f"{where}: expected one file per frame number, got {a.name} and {b.name} "
                             f"for frame {n_a}")
        if n_b != n_a + 1:
            stem = _FRAME_NAME.match(a.stem)
            missing = f"{stem.group(1)}{n_a + 1:0{len(stem.group(2))}d}{a.suffix}"
            raise InputError(f"{where}: expected consecutive frames {frames[0][1].name} to {frames[-1][1].name}, "
                             f"got no {missing} (frame {n_a + 1} missing after {a.name})")
    return [p for _, p in frames]


def bake_directory_sequence(directory: Path) -> Path | None:
    """The sequence inside a `garment bake` output directory (`<garment>_<motion>/`): its one USD stage (garment
    and body), else its `obj/` frames; None for a directory that holds OBJ frames itself, or neither."""
    if _obj_files(directory):
        return None
    stages = sorted(p for p in directory.iterdir() if p.suffix.lower() in STAGE_SUFFIXES and p.is_file())
    if len(stages) == 1:
        return stages[0]
    if (directory / "obj").is_dir():
        return directory / "obj"
    return None


def bake_batch(directory: Path, frame_folders: bool = False) -> dict[str, Path] | None:
    """The bakes of a `garment bake --out` directory: {name: path} of its subdirectories that are bake outputs
    (`bake_directory_sequence`), in name order; with `frame_folders`, also those holding OBJ frames themselves (two
    or more: another tool's export of each motion into a folder of its name); None when `directory` is not a
    directory, is a sequence itself (OBJ frames, or one bake's output) or holds no bake."""
    directory = Path(directory)
    if not directory.is_dir() or _obj_files(directory) or bake_directory_sequence(directory) is not None:
        return None
    bakes = {d.name: d for d in sorted(directory.iterdir())
             if d.is_dir() and d.name != "obj" and (bake_directory_sequence(d) is not None
                                                   or frame_folders and len(_obj_files(d)) > 1)}
    return bakes or None


def _recorded_number(meta: dict, key: str, meta_path: Path) -> int | None:
    """`meta[key]` as a whole number >= 0, None when absent (or null); an InputError naming the key otherwise."""
    value = meta.get(key)
    if value is None:
        return None
    if isinstance(value, float) and value.is_integer():
        value = int(value)
    if not isinstance(value, int) or isinstance(value, bool) or value < 0:
        raise InputError(f"garment sequence '{meta_path}': expected '{key}' as a whole number >= 0, got {value!r}")
    return value


def _check_recorded_frames(meta_path: Path, meta: dict, files: list[Path]) -> None:
    """Hold the frames (`_frame_files`, consecutive) to what `write_obj_sequence` recorded in `sequence.json`:
    their `prefix`, the first frame's number `start` and their count `frames` (and `up`, the frame they are written
    in: "y" or "z"). Each key is checked only where
    present (other tools write `{"fps": 30}` alone); a mismatch is an InputError naming expected and found files."""
    where = f"garment sequence '{meta_path.parent}'"
    prefix = meta.get("prefix")
    if prefix is not None and not isinstance(prefix, str):
        raise InputError(f"garment sequence '{meta_path}': expected 'prefix' as a string (frame_ of frame_0000.obj), "
                         f"got {prefix!r}")
    _recorded_up(meta, meta_path)
    start = _recorded_number(meta, "start", meta_path)
    written = _recorded_number(meta, "frames", meta_path)
    found = f"{files[0].name} to {files[-1].name}" if len(files) > 1 else files[0].name
    # The found frames' prefix, first number and its digits: the recorded prefix may itself end in digits (f1 of
    # f10000.obj), so it is cut off the name rather than read by _FRAME_NAME.
    stem = files[0].stem
    if prefix is not None and stem.lower().startswith(prefix.lower()) and stem[len(prefix):].isdigit():
        digits = stem[len(prefix):]
        prefixes_match = all(p.stem.lower().startswith(prefix.lower()) and p.stem[len(prefix):].isdigit()
                             for p in files)
    else:
        match = _FRAME_NAME.match(stem)
        digits = match.group(2) if match else ""
        prefixes_match = prefix is None
    first = int(digits) if digits else None
    starts_match = start is None or start == first
    if not (prefixes_match and starts_match):
        n = len(files) if written is None else written
        name_prefix = prefix if prefix is not None else stem[:len(stem) - len(digits)]
        name_start = start if start is not None else (first or 0)
        width = max(len(digits) or 4, len(str(name_start + n - 1)))
        expected = f"{name_prefix}{name_start:0{width}d}{files[0].suffix}"
        if n > 1:
            expected += f" to {name_prefix}{name_start + n - 1:0{width}d}{files[0].suffix}"
        record = " and ".join(([f"prefix {prefix!r}"] if not prefixes_match else [])
                              + ([f"start {start}"] if not starts_match else []))
        # the files end where the record does, so the first ones are gone
        tail = prefixes_match and first is not None and written is not None and first + len(files) == start + written
        hint = "frames missing at the start?" if tail and first > start else \
            "frames renamed or renumbered, or the sequence.json of other frames?"
        raise InputError(f"garment sequence '{meta_path}': expected frames {expected} (it records {record}), got "
                         f"{found}: {hint}")
    if written is not None and written != len(files):
        raise InputError(f"{where}: {SEQUENCE_JSON} says {frames_text(written)} were written, got "
                         f"{frames_text(len(files))} ({found}): frames missing "
                         f"{'at the end' if written > len(files) else 'from the record'}?")


#: Up axes of OBJ frames: "y" (an OBJ's usual frame, turned to this tool's Z-up world as read) or "z".
UP_AXES = ("y", "z")


def _recorded_meta(meta_path: Path) -> dict | None:
    """A frame folder's `sequence.json` as a dict (None where there is none); InputError naming it otherwise."""
    if not meta_path.is_file():
        return None
    try:
        meta = json.loads(meta_path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"garment sequence '{meta_path}': expected JSON like {{\"fps\": 30}}, "
                         f"got unreadable content ({exc})") from None
    if not isinstance(meta, dict):
        raise InputError(f"garment sequence '{meta_path}': expected a JSON object like {{\"fps\": 30}}, "
                         f"got {type(meta).__name__}")
    return meta


def _recorded_up(meta: dict, meta_path: Path) -> str:
    """The up axis a `sequence.json` records; where it records none, "z" for one `garment bake` wrote (its frames
    Z-up before 2026-12-06; it always recorded their `prefix` and count, `frames`), else "y" (another tool's of
    `fps` alone, beside frames written as Blender, Maya and Houdini write them: they were read Z-up, on their
    backs); InputError naming it for another value."""
    recorded = meta.get("up", "z" if "prefix" in meta or "frames" in meta else "y")
    recorded = recorded.lower() if isinstance(recorded, str) else recorded  # ("Y", as another tool may write it)
    if recorded not in UP_AXES:
        raise InputError(f"garment sequence '{meta_path}': expected 'up' as \"y\" (frames written Y-up) or \"z\", "
                         f"got {recorded!r}")
    return recorded


def _obj_up(meta: dict | None, up: str | None, meta_path: Path) -> str:
    """The up axis OBJ frames are read in: `up` where given; else what their `sequence.json` records
    (`_recorded_up`); else, with no sequence.json (frames from Blender, Maya, Houdini), "y", the frame OBJ files
    are written in. An `up` other than one the sequence.json records is warned of (it is taken)."""
    recorded = None if meta is None else _recorded_up(meta, meta_path)
    if up is not None:
        if meta is not None and "up" in meta and up != recorded:
            log.warning("--up %s: garment sequence '%s' records its frames written %s-up (%s): read %s-up", up,
                        meta_path.parent, recorded.upper(), SEQUENCE_JSON, up.upper())
        return up
    return "y" if meta is None else recorded


def _faces_differ(faces: np.ndarray, first: np.ndarray) -> str:
    """How a frame's polygons (P, K, -1 padded) differ from the first frame's: their count, else the first face of
    other corners (1-based, as the file writes them)."""
    if faces.shape != first.shape:
        return (f"{len(faces)} faces of up to {faces.shape[1]} corners, the first frame's {len(first)} of up to "
                f"{first.shape[1]}")
    k = int(np.flatnonzero((faces != first).any(axis=1))[0])
    here, there = (" ".join(str(int(i) + 1) for i in f[k] if i >= 0) for f in (faces, first))
    return f"face {k + 1} is {here}, the first frame's {there}"


def _turned_to_z_up(points: np.ndarray, up: str) -> np.ndarray:
    """Points of frames written `up` in this tool's Z-up world."""
    if up != "y":
        return points
    from core.geometry import Y_UP_TO_Z_UP_MATRIX

    return (points @ Y_UP_TO_Z_UP_MATRIX.T).astype(np.float32)


def _read_obj_directory(directory: Path, up: str | None = None) -> Sequence:
    where = f"garment sequence '{directory}'"
    files = _obj_files(directory)
    if not files:
        raise InputError(f"{where}: expected OBJ frames (frame_0000.obj, ...) or a `garment bake` output (its "
                         f".usd stage or obj/ frames), got a directory with neither")
    meta_path = directory / SEQUENCE_JSON
    meta = _recorded_meta(meta_path)
    fps = None if meta is None else _fps(meta.get("fps"), f"garment sequence '{meta_path}'")
    recorded = meta.get("prefix") if meta is not None else None
    files = _frame_files(directory, files, recorded if isinstance(recorded, str) else None)
    if meta is not None:
        _check_recorded_frames(meta_path, meta, files)

    from core.metrics import same_surface

    first = parse_obj(files[0], label="garment sequence frame", finite=True)
    # Quads are split along frame 0's shorter diagonal in every frame, so all frames share faces.
    faces, _, _ = triangulate(first.vertices, first.polygons)
    points = np.empty((len(files),) + first.vertices.shape, dtype=np.float32)
    points[0] = first.vertices
    other_faces = []  # (frame file, how its faces differ from the first's)
    for t, path in enumerate(files[1:], 1):
        frame = parse_obj(path, label="garment sequence frame", like=first, finite=True)
        if frame.vertices.shape != first.vertices.shape:
            raise InputError(f"{where}: expected every frame to share the vertices of {files[0].name} "
                             f"({first.vertices.shape[0]} vertices, {len(first.polygons)} faces), got "
                             f"{frame.vertices.shape[0]} vertices, {len(frame.polygons)} faces in {path.name}")
        if frame.polygons is not first.polygons and not np.array_equal(frame.polygons, first.polygons):
            how = _faces_differ(frame.polygons, first.polygons)
            if not same_surface(triangulate(frame.vertices, frame.polygons)[0], faces, len(first.vertices)):
                raise InputError(f"{where}: expected every frame to share the faces of {files[0].name} (or to split "
                                 f"its polygons otherwise), got other faces in {path.name} ({how}): its vertices "
                                 "numbered otherwise? export every frame of one mesh")
            other_faces.append((path, how))
        points[t] = frame.vertices
    if other_faces:  # one surface split otherwise (`same_surface`): the first frame's faces are taken for all
        path, how = other_faces[0]
        log.warning("%s: %s of its frames split their polygons otherwise than %s (%s: %s): read with %s's faces "
                    "(triangulated again in each frame? export the polygons, or triangulate once before the "
                    "animation)", where, len(other_faces), files[0].name, path.name, how, files[0].name)
    points = _turned_to_z_up(points, _obj_up(meta, up, meta_path))
    number = re.search(r"(\d+)$", files[0].stem)
    return Sequence(points=points, faces=faces, fps=fps, source=str(directory),
                    first_frame=int(number.group(1)) if number else 0)


def _frame_number_of(stem: str, meta: dict | None) -> str:
    """The frame number of the OBJ named `stem` in a folder whose `sequence.json` is `meta`: its digits after the
    recorded prefix (or, none recorded, after its name), "" where it is not one of the frames recorded."""
    if meta is None:
        return ""
    prefix = meta.get("prefix")
    if isinstance(prefix, str):
        number = stem[len(prefix):] if stem.lower().startswith(prefix.lower()) else ""
    else:
        match = _FRAME_NAME.match(stem)
        number = match.group(2) if match and prefix is None else ""
    return number if number.isdigit() else ""


def _frame_record(path: Path) -> tuple[dict | None, str]:
    """(its folder's `sequence.json`, its frame number) of the OBJ at `path` where that records it, else (None,
    ""): a sequence.json that cannot be read is the folder's to refuse, not a file's beside it."""
    try:
        meta = _recorded_meta(path.parent / SEQUENCE_JSON)
    except InputError:
        return None, ""
    number = _frame_number_of(path.stem, meta)
    return (meta if number else None), number


def recorded_frame(path: str | os.PathLike) -> bool:
    """Whether the OBJ at `path` is one of the frames its folder's `sequence.json` records (a bake's frame)."""
    return bool(_frame_record(Path(path))[1])


def _read_single_obj(path: Path, up: str | None = None) -> Sequence:
    """One OBJ as a one-frame sequence: a frame of a folder whose `sequence.json` records it (its prefix, or none
    recorded and the file numbered) read in the frame, at the rate and with the number that folder is read with;
    another OBJ (a garment, a frame exported alone, an OBJ beside a sequence.json it cannot read) Y-up, frame 0."""
    obj = parse_obj(path, label="garment sequence frame")
    faces, _, _ = triangulate(obj.vertices, obj.polygons)
    meta_path = path.parent / SEQUENCE_JSON
    meta, number = _frame_record(path)
    points = _turned_to_z_up(obj.vertices[None].astype(np.float32), _obj_up(meta, up, meta_path))
    return Sequence(points=points, faces=faces, fps=None if meta is None else _fps(meta.get("fps"), str(meta_path)),
                    source=str(path), first_frame=0 if meta is None else int(number))


def _read_npz(path: Path) -> Sequence:
    where = f"garment sequence '{path}'"
    try:
        with open_npz(path, lambda got: InputError(f"{where}: cannot be read as .npz (a zip of .npy arrays 'points', "
                                                   f"'faces'): it is {got}")) as data:
            arrays = {k: data[k] for k in data.files}
    except InputError:
        raise
    except Exception as exc:  # zipfile/zlib/OS errors all mean "not a readable npz"
        text = str(exc).splitlines()[0][:120] if str(exc) else ""
        raise InputError(f"{where}: cannot be read as .npz ({type(exc).__name__}: {text})") from None
    for key in ("points", "faces"):
        if key not in arrays:
            raise InputError(f"{where}: expected key '{key}', got keys {sorted(arrays)}")
    points = _check_points(arrays["points"], "points", where)
    faces = _check_faces(arrays["faces"], points.shape[1], "faces", where)
    fps = _fps(arrays["fps"], where) if "fps" in arrays else None
    body_points = body_faces = None
    if "body_points" in arrays:
        body_points = _check_points(arrays["body_points"], "body_points", where)
        if body_points.shape[0] != points.shape[0]:
            raise InputError(f"{where}: expected body_points with {frames_text(points.shape[0])} like points, "
                             f"got {body_points.shape[0]}")
    if "body_faces" in arrays:
        if body_points is None:
            raise InputError(f"{where}: expected body_points with body_faces, got body_faces alone")
        body_faces = _check_faces(arrays["body_faces"], body_points.shape[1], "body_faces", where)
    return Sequence(points=points, faces=faces, fps=fps, body_points=body_points,
                    body_faces=body_faces, source=str(path))


def _read_usd_sequence(path: Path, track: str) -> Sequence:
    seq = read_usd(path)
    where = f"garment sequence '{path}'"
    if track in seq.tracks:
        garment = seq.tracks[track]
    elif len(seq.tracks) == 1:
        garment = next(iter(seq.tracks.values()))
    else:
        raise InputError(f"{where}: expected a mesh named '{track}', got meshes {sorted(seq.tracks)}")
    body = seq.tracks.get("body")
    body_points = body_faces = None
    if body is not None and body is not garment:
        if body.points.shape[0] != garment.points.shape[0]:
            raise InputError(f"{where}: expected the body track to have {frames_text(garment.points.shape[0])} "
                             f"like '{garment.name}', got {body.points.shape[0]}")
        body_points, body_faces = body.points.astype(np.float32), body.faces.astype(np.int64)
    return Sequence(points=garment.points.astype(np.float32), faces=garment.faces.astype(np.int64),
                    fps=seq.fps, body_points=body_points, body_faces=body_faces, source=str(path),
                    first_frame=seq.start_frame)


def takes_up(path: str | os.PathLike) -> bool:
    """Whether `read_sequence`'s `up` applies to the sequence at `path`: OBJ frames or one OBJ (a USD stage or an
    npz records its own frame; a bake's folder is read through its stage where it has one)."""
    path = Path(path)
    if path.is_dir():
        inner = bake_directory_sequence(path)
        return inner is None or takes_up(inner)
    return path.suffix.lower() == ".obj"


@warnings_held
def read_sequence(path: str | os.PathLike, track: str = "garment", up: str | None = None) -> Sequence:
    """Read a garment sequence from any supported form.

    path: a directory of OBJ frames (ordered by the number in their names; all
    must share faces; fps from an optional `sequence.json` {"fps": 30}), a `garment bake` output directory
    (its USD stage, else its `obj/` frames: `bake_directory_sequence`), an
    `.npz` with `points (T, V, 3)`, `faces (F, 3)` and optional `fps`,
    `body_points (T, Vb, 3)`, `body_faces (Fb, 3)`, a USD stage
    (`.usd/.usda/.usdc`: the mesh named `track`, else the only mesh, plus a
    mesh named "body" as the body), or one `.obj` (a single frame).
    OBJ frames are turned from the up axis `up` ("y" or "z") to this tool's Z-up world; None: as their
    `sequence.json` records (Z-up where a bake's records none, Y-up where another tool's does), Y-up without one (`_obj_up`).
    Returns a `Sequence` (points float32 metres, faces int64).
    Raises InputError naming the path for a missing path, an unknown suffix, an
    empty directory, OBJ frames with a gap in their numbers or differing topology,
    OBJ frames other than `sequence.json` records (its `prefix`, `start` and
    `frames`, each where present), or wrong array shapes.
    """
    path = Path(path)
    if not path.exists():
        raise InputError(f"garment sequence '{path}': not found")
    if path.is_dir():
        inner = bake_directory_sequence(path)
        return _read_obj_directory(path, up) if inner is None else read_sequence(inner, track, up)
    reason = not_a_file(path)
    if reason:  # a pipe, a device, a socket
        raise InputError(f"garment sequence '{path}': {reason}")
    suffix = path.suffix.lower()
    if suffix == ".npz":
        return _read_npz(path)
    if suffix in STAGE_SUFFIXES:
        return _read_usd_sequence(path, track)
    if suffix == ".obj":
        return _read_single_obj(path, up)
    raise InputError(f"garment sequence '{path}': expected a directory of OBJ frames, .npz, .obj or "
                     f".usd/.usda/.usdc, got '{path.suffix or path.name}'")


def write_obj_sequence(directory: str | os.PathLike, points: np.ndarray, faces: np.ndarray,
                       uvs: np.ndarray | None = None, face_uvs: np.ndarray | None = None,
                       fps: float | None = None, prefix: str = "frame_",
                       materials: np.ndarray | None = None, libraries=(), start: int = 0, up: str = "z",
                       on_frame=None) -> list[Path]:
    """Write one OBJ per frame, `<prefix>0000.obj` ..., and `sequence.json` into `directory`.

    points: (T, V, 3) float, metres, Z-up (this tool's world); faces: (F, 3) int 0-based; uvs (U, 2) and
    face_uvs (F, 3), both or neither (faces (F, K): polygons, as `formats.obj.obj_face_text`); materials: (F,)
    names or None, written as `usemtl` lines; libraries: material library file names (in `directory`) for an
    `mtllib` line; fps: frames per second or None; start: the first frame's number; up: "y" writes the points
    turned to Y-up (-90 degrees about X: an OBJ's usual frame, which Blender's, Houdini's and Maya's imports
    assume), recorded in `sequence.json` so `read_sequence` turns them back; "z" as they are. Frame numbers are
    zero padded to at least 4 digits. The face block is formatted once and shared by every frame. on_frame(1):
    called after each frame is written (a progress bar). Returns the frame paths in order.
    """
    directory = Path(directory)
    points = np.asarray(points)
    if points.ndim != 3 or points.shape[2] != 3:
        raise InputError(f"garment sequence '{directory}': expected points (T, V, 3), got {points.shape}")
    if up not in ("y", "z"):
        raise ValueError(f"up: expected 'y' or 'z', got {up!r}")
    if up == "y":
        from core.geometry import Y_UP_TO_Z_UP_MATRIX

        points = points @ Y_UP_TO_Z_UP_MATRIX  # rows: the inverse (transposed) turn, Z-up to Y-up
    directory.mkdir(parents=True, exist_ok=True)
    n_frames = points.shape[0]
    width = max(4, len(str(max(start + n_frames - 1, 0))))
    face_block = obj_face_text(faces, uvs, face_uvs, materials).encode("utf-8")
    library_line = mtllib_text(libraries).encode("utf-8")
    paths = []
    for t in range(n_frames):
        path = directory / f"{prefix}{start + t:0{width}d}.obj"
        path.write_bytes(f"# frame {start + t}\n".encode("ascii") + library_line + obj_vertex_text(points[t]).encode("ascii")
                         + face_block)
        paths.append(path)
        if on_frame is not None:
            on_frame(1)
    meta = {"fps": None if fps is None else float(fps), "frames": int(n_frames), "prefix": prefix, "start": int(start),
            "up": up}
    (directory / SEQUENCE_JSON).write_text(json.dumps(meta, indent=2) + "\n")
    return paths


def write_npz_sequence(path: str | os.PathLike, points: np.ndarray, faces: np.ndarray, fps: float | None = None,
                       body_points: np.ndarray | None = None, body_faces: np.ndarray | None = None) -> None:
    """Write a sequence file (compressed .npz) that `read_sequence` reads back.

    points: (T, V, 3) float, metres (stored float32); faces: (F, 3) int (int64);
    fps: frames per second or None (then omitted); body_points (T, Vb, 3) and
    body_faces (Fb, 3) optional. Written to exactly `path` (no suffix added).
    """
    arrays = {"points": np.asarray(points, dtype=np.float32), "faces": np.asarray(faces, dtype=np.int64)}
    if fps is not None:
        arrays["fps"] = np.float64(fps)
    if body_points is not None:
        arrays["body_points"] = np.asarray(body_points, dtype=np.float32)
    if body_faces is not None:
        arrays["body_faces"] = np.asarray(body_faces, dtype=np.int64)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "wb") as fh:
        np.savez_compressed(fh, **arrays)
