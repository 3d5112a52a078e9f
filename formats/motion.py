"""Motion files: AMASS-style .npz archives, and the same parameters pickled; read into a `core.motion.Motion`;
written back as .npz.

Accepted layouts: `poses` with 72 (SMPL), 156 (SMPL+H) or 165 (SMPL-X) values per
frame, or 66 (the 22 body joints alone; the SMPL hands are then at rest), or the same
as a (T, J, 3) array or as rotation matrices (T, J, 3, 3), or, when `poses` is absent, the SMPL-X split keys
`root_orient (T,3)`, `pose_body (T,63)` and optional `pose_jaw (T,3)`, `pose_eye (T,6)`,
`pose_hand (T,90)`, or, when neither is there, the `smplx` library's forward arguments
`global_orient` + `body_pose` (23 joints: SMPL; 21: SMPL-X/SMPL+H, with optional `jaw_pose`, `leye_pose`,
`reye_pose`, `left_hand_pose`, `right_hand_pose`), each as axis-angle or rotation matrices (T, K, 3, 3), and
`transl`; or AIST++'s `smpl_poses`, with `smpl_trans` / `smpl_scaling` as the translation. Also read:
`trans (T,3)` metres Z-up (zeros, with a warning, when missing), `betas` (any length; per frame (T, S) as video
fits write them: their mean),
`mocap_framerate` or `mocap_frame_rate` (Hz; or `mocap_fps`, `fps`, `framerate`,
`frame_rate`), `gender`. WHAM's world motion `pose_world`, `trans_world` (or, without them, VIBE's and WHAM's
camera-frame `pose`) where no other poses are there. Pickles (`PICKLE_SUFFIXES`: AIST++'s motions, the results
WHAM and VIBE write with joblib, one dict per tracked person: the longest is read; PHALP's and 4D-Humans', a dict
per video frame of its detections: the person tracked in most frames; 3DPW's sequences, each parameter a list of
the actors': the first; EMDB's, its 'smpl' dict) and PyTorch files
(`TORCH_SUFFIXES`: GVHMR's `hmr4d_results.pt`, its `smpl_params_global`) are read without running code in them;
a single .npy array of Motion-X's SMPL-X parameters (T, 322) too, and Meshcapade's SMPLCodec `.smpl` (an npz of
`bodyPose`, `headPose`, `leftHandPose`, `rightHandPose`, `bodyTranslation`, `shapeParameters`, `frameRate`), and
BVH, FBX (binary or ASCII), glTF, USD (UsdSkel), COLLADA or Xsens MVNX motion capture of SMPL's or another
humanoid's skeleton (`formats.bvh`, `formats.fbx`, `formats.gltf`, `formats.usdskel`, `formats.collada`,
`formats.mvnx`, `core.retarget`).
"""

from __future__ import annotations

import logging
import zipfile
import zlib
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from core.body import LAYOUT_JOINTS, N_BODY_JOINTS
from core.errors import InputError, content_kind, require_input, warnings_held
from core.motion import (MIN_SOURCE_FPS, Motion, check_frame_rate, fill_untracked, validate_motion_values,
                         warn_if_not_metres, warn_if_not_z_up)
from formats.atomic import atomic_file
from formats.bvh import REST_UP_KEY, TAKE_KEY, Skeleton, read_skeleton, skeleton_arrays
from formats.collada import read_collada
from formats.fbx import animation_takes, read_fbx
from formats.gltf import GLTF_SUFFIXES, animation_names, read_gltf
from formats.mvnx import read_mvnx
from formats.obj import USD_SUFFIXES
from formats.pickles import load_npy_pickle, load_pickle, load_torch

log = logging.getLogger(__name__)

#: What a motion file of another format is, for the message refusing it (only SMPL parameters drive the body).
_OTHER_MOTION_FORMATS = {
    **dict.fromkeys((".c3d", ".trc"), "motion capture markers (C3D/TRC), not a skeleton: fit SMPL to them first "
                    "(AMASS's MoSh), then save the npz"),
    ".json": "a JSON file",
}
#: Where a frame rate is found (AMASS's two spellings first, then those of other SMPL pipelines).
FRAMERATE_KEYS = ("mocap_framerate", "mocap_frame_rate", "mocap_fps", "fps", "framerate", "frame_rate")
_VALUES_PER_FRAME = {3 * n: n for n in LAYOUT_JOINTS.values()}  # 72, 156, 165 -> joints
#: The body's 22 joints alone (the SMPL-H / SMPL-X body without hands, as root_orient + pose_body concatenated):
#: read with the two SMPL hand joints at rest.
_BODY_ONLY_JOINTS = N_BODY_JOINTS
#: Poses whose joint rotations exceed 2 pi radians (a full turn) in more than this share of the rotated joints are
#: refused as degrees: axis-angle fits (AMASS, SMPL) stay within pi; in degrees, joints bent past 6.3 do.
DEGREES_SHARE = 0.2
#: A rotation vector longer than this (720 degrees) is refused as degrees whatever the share: a radian fit stays
#: within pi (an unnormalised root within one turn more, 3 pi), while degrees with small joint bends and a 90-degree
#: root turn put only 19 % of the rotated joints past 2 pi.
DEGREES_MAX_NORM = 4 * np.pi
#: Per-frame betas (a shape estimated in every frame, as video-based fits write) further than this from their
#: mean in some frame and coefficient are warned about: the motion is baked with the mean shape.
BETAS_SPREAD_WARN = 0.1
_SPLIT_KEYS = ("root_orient", "pose_body", "pose_jaw", "pose_eye", "pose_hand")
#: The `smplx` library's forward arguments, as pose estimators and fitters save them (SMPLify-X, SMPLer-X, GVHMR,
#: TRAM; 4D-Humans/HMR2 as rotation matrices): read when neither 'poses' nor 'root_orient' is there. (key, joints)
#: after global_orient and body_pose, in SMPL-X's joint order.
_SMPLX_ARG_EXTRAS = (("jaw_pose", 1), ("leye_pose", 1), ("reye_pose", 1), ("left_hand_pose", 15),
                     ("right_hand_pose", 15))
_SMPLX_ARG_KEYS = ("global_orient", "body_pose", *(key for key, _ in _SMPLX_ARG_EXTRAS))
#: AIST++'s keys (its motions: pickles, or .npz with the same names): SMPL poses, and a translation in the
#: units of the body scaled by `smpl_scaling` (about 95-100: centimetres of a body scaled to metres).
_AIST_KEYS = ("smpl_poses", "smpl_trans", "smpl_scaling")
#: Meshcapade's SMPLCodec `.smpl` files (an npz of camelCase keys): the pose by part, the translation, the shape,
#: the frame rate and the model (`smplVersion`; SUPR, SMPL++ and SKEL are refused: no SMPL-family joints).
_CODEC_KEYS = ("smplVersion", "shapeParameters", "frameRate", "bodyTranslation", "bodyPose", "headPose",
               "leftHandPose", "rightHandPose")
#: smplVersion -> (the model, the pose's parts after bodyPose: (key, joints)), as the codec writes them.
_CODEC_MODELS = {0: ("SMPL", ()), 1: ("SMPL-H", (("leftHandPose", 15), ("rightHandPose", 15))),
                 2: ("SMPL-X", (("headPose", 3), ("leftHandPose", 15), ("rightHandPose", 15)))}
_CODEC_OTHER_MODELS = {3: "SUPR", 4: "SMPL++", 5: "SKEL"}
_CODEC_GENDERS = ("neutral", "male", "female")
#: A pose estimator's keys (`_from_estimator`): WHAM's world motion, VIBE's and WHAM's camera-frame 'pose', TRAM's
#: camera-frame ones, a track's video frames.
_ESTIMATOR_KEYS = ("pose_world", "trans_world", "pose", "pred_rotmat", "pred_trans", "pred_shape", "frame",
                   "frame_ids", "poses_root", "poses_body")
#: The keys read; the others (dmpls, marker data, AMASS SMPL-X's markers_latent_vids, a pickled dict that
#: needs allow_pickle, a face's expression) are left unread. `transl` is the smplx arguments' `trans`.
_READ_KEYS = ("poses", *_SPLIT_KEYS, *_SMPLX_ARG_KEYS, "trans", "transl", "betas", *FRAMERATE_KEYS, "gender",
              *_AIST_KEYS, *_ESTIMATOR_KEYS, *_CODEC_KEYS)
#: Pickled motions, read through a restricted unpickler (`formats.pickles`: no code in them runs): AIST++'s motion
#: pickles; pose estimators' results saved with pickle or joblib (WHAM, VIBE: a dict per tracked person; PHALP,
#: 4D-Humans: a dict per video frame).
PICKLE_SUFFIXES = (".pkl", ".pickle", ".joblib")
#: PyTorch files, read with torch.load(weights_only=True) (tensors, containers, numpy arrays: `formats.pickles`):
#: GVHMR's hmr4d_results.pt.
TORCH_SUFFIXES = (".pt", ".pth")
#: A dict in a pickled motion that holds it: GVHMR's world parameters (preferred) or its camera-frame ones; EMDB's
#: 'smpl' (its file's other values, such as its 'gender', kept beside).
_NESTED_KEYS = ("smpl_params_global", "smpl_params_incam", "smpl")
#: Motion files that may hold several animations (takes), one read (`--take`).
TAKE_SUFFIXES = (".fbx", *GLTF_SUFFIXES, *USD_SUFFIXES)
#: Motion capture files of a rig's skeleton, retargeted onto SMPL's (`read_rig`).
SKELETON_SUFFIXES = (".bvh", ".mvnx", ".dae", *TAKE_SUFFIXES)
#: The key under which `_pickled_arrays` passes the id of the track read (of a file of tracked people) on.
PERSON_KEY = "garment_person"
#: Keys whose length is a tracked person's number of frames.
_POSE_KEYS = ("poses", "pose", "pose_world", "smpl_poses", "global_orient", "root_orient", "body_pose",
              "pred_rotmat")
#: Motion-X's SMPL-X parameters, one row of 322 values per frame (a .npy array): the columns of those read.
MOTION_X_VALUES = 322
MOTION_X_COLUMNS = {"root_orient": (0, 3), "pose_body": (3, 66), "pose_hand": (66, 156), "pose_jaw": (156, 159),
                    "trans": (309, 312), "betas": (312, 322)}
#: A track's frames filled in where it was not tracked (`_fill_untracked`) at the most: an hour at 30 fps.
MAX_FILLED_FRAMES = 108_000
#: What a motion file's name ends with (the case aside).
MOTION_SUFFIXES = (".npz", ".smpl", ".npy", ".bvh", ".fbx", *GLTF_SUFFIXES, *USD_SUFFIXES, ".dae", ".mvnx",
                   *PICKLE_SUFFIXES,
                   *TORCH_SUFFIXES)
#: A rotation matrix further than this from orthonormal (max |R R^T - I|), or with a negative determinant, is refused.
ROTATION_MATRIX_TOL = 1e-3
_EXPECTED = "72 (SMPL), 156 (SMPL+H), 165 (SMPL-X) or 66 (the 22 body joints alone)"
#: What reading an archive or one of its arrays raises for a damaged, truncated or unusual file: a corrupt deflate
#: stream (zlib.error), an encrypted member (RuntimeError), a compression zipfile lacks (NotImplementedError), an
#: array header declaring more values than memory holds (MemoryError).
NPZ_READ_ERRORS = (zipfile.BadZipFile, zlib.error, ValueError, OSError, EOFError, KeyError, RuntimeError,
                   NotImplementedError, MemoryError)
#: How a zip archive (an .npz) starts: a local file header, or the end record of an empty archive. A file starting
#: "PK" otherwise (a truncated or spanned zip) is none: numpy would try to unpickle it.
ZIP_MAGIC = (b"PK\x03\x04", b"PK\x05\x06")


@contextmanager
def open_npz(path: Path, refuse):
    """The NpzFile of `path` (no pickles), the file opened here so that a failed load leaves none open; a file
    that is no zip archive (numpy would read an .npy, or try to unpickle anything else) raises refuse(what it is:
    "a single .npy array", "a damaged or incomplete zip archive" or "no zip archive"), an InputError naming the
    file."""
    with open(path, "rb") as fh:
        head = fh.read(6)
        if not head.startswith(ZIP_MAGIC):
            raise refuse("a single .npy array" if head == b"\x93NUMPY" else
                         "a damaged or incomplete zip archive" if head.startswith(b"PK") else "no zip archive")
        fh.seek(0)
        with np.load(fh, allow_pickle=False) as data:
            yield data


@warnings_held
def load_motion(path, fps: float | None = None, world_checks: bool = True, person: str | None = None,
                take: str | None = None) -> Motion:
    """Read a motion: an AMASS-style .npz, or a pickle or PyTorch file of the same parameters (module docstring).

    path: file path. fps: frame rate in Hz that overrides (or replaces a missing)
    `mocap_framerate` / `mocap_frame_rate`. world_checks: warn when the motion looks Y-up (or -Y) or its
    translation not in metres (off for a file read for its joint rotations only). person: of a file of several
    tracked people (WHAM, VIBE, PHALP), the track id to read (else the one tracked longest); a file of one
    person is read as it is. take: of an FBX or glTF of several animations, the one to read (else the first).
    Returns a Motion: poses (T, 24|52|55, 3) float32 axis-angle radians, trans
    (T, 3) float32 metres (Z-up world), fps, betas (S,) float32 or None, gender.
    Raises InputError (one line naming the file) for any unreadable or invalid content.
    """
    path = Path(path)
    src = f"motion '{path}'"
    require_input(path, src)
    if path.suffix.lower() in PICKLE_SUFFIXES + TORCH_SUFFIXES:
        arrays, files = _pickled_arrays(path, src, person=person)
    elif path.suffix.lower() in SKELETON_SUFFIXES:
        arrays = skeleton_arrays(read_rig(path, src, take), src)
        files = list(arrays)
    elif _starts_with(path, b"\x93NUMPY"):
        arrays, files = _npy_arrays(path, src, person)
    else:
        arrays, files = _npz_arrays(path, src)
    if take is not None and path.suffix.lower() not in TAKE_SUFFIXES:
        log.info("%s: no FBX or glTF, no animations: --take %s left aside", src, take)
    _from_smpl_codec(arrays, src)
    _from_aist(arrays, src)
    _from_estimator(arrays, src)
    poses = _read_poses(arrays, src, files)
    T = poses.shape[0]
    if T < 1:
        raise InputError(f"{src}: expected at least 1 frame, got 0")
    _refuse_degrees(poses, src)

    trans_key = next((k for k in ("trans", "transl") if k in arrays), None)
    if trans_key is not None:
        trans = _float_array(arrays[trans_key], trans_key, src)
        if trans.ndim == 1 and trans.shape == (3,) and T == 1:
            trans = trans[None]
        if trans.ndim != 2 or trans.shape[1] != 3:
            raise InputError(f"{src}: expected {trans_key} of shape ({T}, 3), got {tuple(trans.shape)}")
        if trans.shape[0] != T:
            raise InputError(f"{src}: expected {trans_key} of shape ({T}, 3), one row per frame of poses, got "
                             f"{tuple(trans.shape)}")
    else:
        log.warning("%s: no 'trans' (or 'transl') key, using zero translation", src)
        trans = np.zeros((T, 3), dtype=np.float32)

    poses, trans = _fill_untracked(poses, trans, arrays.get("frame_ids"), src)
    betas = _read_betas(arrays["betas"], T, src) if "betas" in arrays else None

    if fps is None:
        key = next((k for k in FRAMERATE_KEYS if k in arrays), None)
        if key is None:
            raise InputError(f"{src}: expected a frame rate under 'mocap_framerate' or 'mocap_frame_rate' (or "
                             f"{', '.join(repr(k) for k in FRAMERATE_KEYS[2:])}), found none: pass the motion's "
                             f"frame rate with --source-fps")
        fps = _read_frame_rate(arrays[key], key, src)
        what = f"'{key}'"
        if path.suffix.lower() == ".bvh" and 0 < fps < MIN_SOURCE_FPS:
            raise InputError(f"{src}: expected its Frame Time in seconds per frame (0.0333333 at 30 fps), got "
                             f"{1 / fps:g}: milliseconds ({1000 * fps:.4g} fps)? pass the motion's frame rate with "
                             f"--source-fps")
    else:
        what = "the fps override"
    check_frame_rate(fps, f"{src}, {what}", "; pass the motion's frame rate with --source-fps")

    gender = _read_gender(arrays.get("gender"))
    rest_up = str(arrays[REST_UP_KEY]) if REST_UP_KEY in arrays else None
    motion = Motion(poses=poses, trans=trans, fps=float(fps), betas=betas, gender=gender, name=path.stem,
                    rest_up=rest_up, person=str(arrays[PERSON_KEY]) if PERSON_KEY in arrays else None,
                    take=str(arrays[TAKE_KEY]) if TAKE_KEY in arrays else None)
    validate_motion_values(motion, str(path))
    if world_checks:
        warn_if_not_z_up(motion, str(path))
        warn_if_not_metres(motion, str(path))
    return motion


def _npz_arrays(path: Path, src: str) -> tuple[dict, list[str]]:
    """(the arrays load_motion reads, every key) of the .npz `path`; InputError naming `src` otherwise."""
    def refuse(got: str) -> InputError:
        kind = _OTHER_MOTION_FORMATS.get(path.suffix.lower(), "a file that is not one" if got == "no zip archive"
                                         else got)
        return InputError(f"{src}: expected an AMASS-style .npz archive (a zip of .npy arrays: SMPL joint rotations "
                          f"'poses', 'trans', a frame rate), got {kind}")

    arrays = {}
    try:
        with open_npz(path, refuse) as data:
            files = list(data.files)
            for key in files:
                if key not in _READ_KEYS:  # e.g. AMASS SMPL-X's markers_latent_vids, a pickled dict: never read
                    continue
                try:
                    arrays[key] = data[key]
                except NPZ_READ_ERRORS as exc:
                    if key == "gender":  # e.g. an object array: not needed
                        log.warning("%s: skipping unreadable key '%s' (%s)", src, key, _short(exc))
                        continue
                    raise InputError(f"{src}: could not read array '{key}' ({_short(exc)})") from None
    except InputError:
        raise
    except NPZ_READ_ERRORS as exc:
        if isinstance(exc, OSError) and exc.errno is not None:  # the system's (e.g. /proc/self/mem: EIO)
            raise InputError(f"{src}: cannot read it ({exc.strerror or exc})") from None
        raise InputError(f"{src}: expected an AMASS-style .npz archive, could not read it ({_short(exc)})") from None
    return arrays, files


def _starts_with(path: Path, magic: bytes) -> bool:
    """Whether `path` starts with `magic` (False where it cannot be read: the reader that follows says why)."""
    try:
        with open(path, "rb") as fh:
            return fh.read(len(magic)) == magic
    except OSError:
        return False


def _npy_arrays(path: Path, src: str, person: str | None = None) -> tuple[dict, list[str]]:
    """(the arrays load_motion reads, their keys) of a single .npy array: Motion-X's SMPL-X parameters, (T, 322)
    (`MOTION_X_COLUMNS`; its face's expression and shape left unread), or a pickled dict (TRAM's
    hps_track_K.npy: `formats.pickles.load_npy_pickle`); InputError naming `src` otherwise."""
    expected = (f"{src}: expected an .npz archive of named arrays, or Motion-X's SMPL-X parameters as one .npy "
                f"array of shape (T, {MOTION_X_VALUES}), got")
    try:
        values = np.load(path, allow_pickle=False)
    except ValueError as exc:  # a pickled object (a dict saved with np.save): through the restricted unpickler
        if "allow_pickle" not in str(exc):
            raise InputError(f"{src}: cannot read it as a .npy array ({_short(exc)})") from None
        return _pickled_arrays(path, src, npy=True, person=person)
    except (OSError, EOFError) as exc:
        raise InputError(f"{src}: cannot read it as a .npy array ({_short(exc)})") from None
    if values.ndim != 2 or values.shape[1] != MOTION_X_VALUES:
        raise InputError(f"{expected} a single .npy array of shape {tuple(values.shape)}")
    arrays = {key: values[:, a:b] for key, (a, b) in MOTION_X_COLUMNS.items()}
    return arrays, list(arrays)


def _pickled_arrays(path: Path, src: str, npy: bool = False, person: str | None = None) -> tuple[dict, list[str]]:
    """(the arrays load_motion reads, every key of the dict read) of a pickled motion (`PICKLE_SUFFIXES`,
    `TORCH_SUFFIXES`; npy: a .npy of a pickled object): its one person's SMPL parameters (`_motion_dict`; `person`
    as load_motion takes it); InputError naming `src` otherwise."""
    data, track = _motion_dict(_unpickled(path, src, npy), src, person=person)
    arrays = {str(k): _plain(v) for k, v in data.items() if str(k) in _READ_KEYS}
    if track is not None:
        arrays[PERSON_KEY] = np.str_(track)
    return arrays, [str(k) for k in data]


def read_rig(path, src: str | None = None, take: str | None = None) -> Skeleton:
    """The skeleton and motion of a motion capture file of a rig (`SKELETON_SUFFIXES`: BVH, FBX, glTF, USD, COLLADA,
    MVNX) as
    its reader gives it, before any retargeting; of an FBX or glTF of several animations, the one named `take`.
    InputError naming `src` (default: the file) where it cannot be read."""
    path = Path(path)
    src = src or f"motion '{path}'"
    suffix = path.suffix.lower()
    if suffix == ".bvh":
        return read_skeleton(path, src)
    if suffix == ".mvnx":
        return read_mvnx(path, src)
    if suffix == ".dae":
        return read_collada(path, src)
    if suffix in USD_SUFFIXES:
        from formats.usdskel import read_usdskel  # pxr: loaded where a USD is read

        return read_usdskel(path, src, take)
    return (read_fbx if suffix == ".fbx" else read_gltf)(path, src, take)


def motion_takes(path) -> list[str]:
    """The names of the animations (takes: FBX's stacks, glTF's animations) of a motion file where it holds
    several (`--take`), else []; InputError naming the file where it cannot be read."""
    suffix = Path(path).suffix.lower()
    if suffix == ".fbx":
        return animation_takes(Path(path))
    if suffix in USD_SUFFIXES:
        from formats.usdskel import animation_names as usd_animations

        return usd_animations(Path(path))
    return animation_names(Path(path)) if suffix in GLTF_SUFFIXES else []


def tracked_people(path) -> dict[str, int]:
    """{track id (as `--person` reads it): frames tracked} of a motion file of several tracked people (WHAM's,
    VIBE's, PHALP's, 4D-Humans' results), the longest tracked first; {} for any other file (one person's, an .npz,
    a BVH). InputError naming the file where a pickle cannot be read."""
    path = Path(path)
    if path.suffix.lower() not in PICKLE_SUFFIXES + TORCH_SUFFIXES:
        return {}
    src = f"motion '{path}'"
    try:
        frames = _tracks(_unpickled(path, src))[1]
    except (AttributeError, TypeError, KeyError, IndexError, ValueError) as exc:
        if isinstance(exc, InputError):
            raise
        return {}  # not tracked people's structure: load_motion says what it is
    if not frames or len(frames) < 2:
        return {}
    return {str(k): int(frames[k]) for k in sorted(frames, key=lambda k: -frames[k])}


def pickled_motion_keys(path: Path) -> list[str]:
    """The keys of the one person's SMPL parameters in the pickled motion `path` (`_motion_dict`); InputError
    where it cannot be read or holds no dict."""
    src = f"motion '{path}'"
    return [str(k) for k in _motion_dict(_unpickled(path, src, _starts_with(path, b"\x93NUMPY")), src, quiet=True)[0]]


def _unpickled(path: Path, src: str, npy: bool = False):
    """What the pickled motion `path` holds (a PyTorch file through torch.load(weights_only=True), a .npy of a
    pickled object (npy) through `formats.pickles.load_npy_pickle`, another through `formats.pickles.load_pickle`);
    InputError naming `src` where it cannot be read."""
    torch_file = path.suffix.lower() in TORCH_SUFFIXES
    kind = "a .npy array's pickled object" if npy else "a PyTorch file" if torch_file else "a Python pickle"
    try:
        if npy:
            return load_npy_pickle(path, src, "a motion file")
        if torch_file:
            return load_torch(path, src, "a motion file")
        return load_pickle(path, src, "a motion file")
    except InputError:
        raise
    except Exception as exc:  # noqa: BLE001 - any failure to unpickle is an unreadable file
        got = content_kind(path)  # an OBJ or a CSV renamed, an empty file; not a text pickle (protocol 0)
        if got and not got.startswith(tuple(f"text ({q}{c}" for q in "'\"" for c in "(c}]ISVFLN")):
            raise InputError(f"{src}: expected {kind}, got {got}") from None
        raise InputError(f"{src}: cannot read it as {kind} ({type(exc).__name__}: {_short(exc)})") from None


def _motion_dict(data, src: str, quiet: bool = False, person: str | None = None) -> tuple[dict, object]:
    """`_person` of `data`; InputError naming `src` where its structure is not the one expected (a PHALP frame's
    detection of no dict, a track that is no list: what a pickle holds is anybody's)."""
    try:
        return _person(data, src, quiet, person)
    except (AttributeError, TypeError, KeyError, IndexError, ValueError) as exc:
        if isinstance(exc, InputError):
            raise
        raise InputError(f"{src}: expected a pickled dict of SMPL parameters ('poses', 'trans', ...; or one such "
                         f"dict per tracked person or video frame), got another structure ({type(exc).__name__}: "
                         f"{_short(exc)})") from None


def _person(data, src: str, quiet: bool, person: str | None = None) -> tuple[dict, object]:
    """One person's SMPL parameters in the pickled `data`, and the id of its track (None where `data` holds no
    tracked people): the dict itself; GVHMR's `smpl_params_global` in it (`_NESTED_KEYS`); of a dict of tracked
    people (WHAM, VIBE: {track id: dict}; PHALP), the track `person` where given, else the person tracked
    longest, warned about where there are others (quiet: not)."""
    if not isinstance(data, dict):
        raise InputError(f"{src}: expected a pickled dict of SMPL parameters ('poses', 'trans', ...; or one such "
                         f"dict per tracked person), got {type(data).__name__}")
    data, frames, kind = _tracks(data)
    if frames is None:
        if person is not None and not quiet:
            log.info("%s: the parameters of one person: --person %s left aside", src, person)
        return data, None
    if kind == "phalp" and not frames:
        raise InputError(f"{src}: expected PHALP's tracked people ('tid', 'smpl' per detection), found none tracked")
    track = _chosen(frames, src, quiet, person)
    if kind == "phalp":
        return _phalp_person(data, track, src), track
    return (_actor(data, track, len(frames)) if kind == "actors" else data[track]), track


def _tracks(data: dict) -> tuple[dict, dict | None, str]:
    """(`data` with GVHMR's nesting taken off; {track id: frames tracked, in the order first seen} where it holds
    tracked people, else None; how it holds them: 'phalp' (PHALP's per-frame detections), 'tracks' (a dict per
    track: WHAM, VIBE), 'actors' (each parameter a list of the actors', or along a first axis: 3DPW), or '')."""
    nested = next((k for k in _NESTED_KEYS if isinstance(data.get(k), dict)), None)
    if nested:
        data = {**{k: v for k, v in data.items() if not isinstance(v, dict)}, **data[nested]}
    if data and all(isinstance(v, dict) and "smpl" in v and "tid" in v for v in data.values()):
        counts: dict = {}
        for tid in (t for frame_tids in _phalp_frames(data)[1] for t in frame_tids):
            counts[tid] = counts.get(tid, 0) + 1
        return data, counts, "phalp"
    if data and all(isinstance(v, dict) for v in data.values()):
        return data, {k: max((len(v[p]) for p in _POSE_KEYS if hasattr(v.get(p), "__len__")), default=0)
                      for k, v in data.items()}, "tracks"
    poses = next((data[k] for k in ("poses", "pose") if k in data), None)
    if isinstance(poses, (list, tuple)) and poses and all(len(getattr(p, "shape", ())) == 2 for p in poses):
        return data, {i: len(p) for i, p in enumerate(poses)}, "actors"
    if len(getattr(poses, "shape", ())) == 3 and poses.shape[-1] in (66, 72, 156, 165):
        return data, {i: poses.shape[1] for i in range(poses.shape[0])}, "actors"
    return data, None, ""


#: 3DPW's frame rate: its 'poses' follow the video's frames (its 'poses_60Hz' twice as many).
THREEDPW_FPS = 30.0


def _actor(data: dict, i: int, n: int) -> dict:
    """Actor `i`'s parameters of a file of `n` actors' (3DPW's: a list of the actors' per parameter; or arrays
    along a first axis of `n`): each such value's `i`th, its 'genders' its 'gender'; 3DPW's frame rate where the
    file names none."""
    out = {}
    for key, value in data.items():
        if isinstance(value, (list, tuple)) and len(value) == n:
            value = value[i]
        elif len(getattr(value, "shape", ())) >= 2 and value.shape[0] == n and str(key) in _READ_KEYS:
            value = value[i]
        out[key] = value
    if "genders" in out and "gender" not in out:
        out["gender"] = out["genders"]
    if "poses_60Hz" in data and not any(k in data for k in FRAMERATE_KEYS):
        out["mocap_framerate"] = THREEDPW_FPS
    return out


def _chosen(frames: dict, src: str, quiet: bool, person: str | None = None):
    """The person of `frames` ({id: frames tracked}) whose id reads as `person` where given (InputError naming
    `src` and the ids where none does), else the one tracked longest (the first of them), the others warned about
    (quiet: not)."""
    def listed():
        return ", ".join(f"'{k}' {n} frames" for k, n in list(frames.items())[:6]) + (", ..." if len(frames) > 6
                                                                                       else "")

    if person is not None:
        chosen = next((k for k in frames if str(k) == str(person)), None)
        if chosen is None:
            raise InputError(f"{src}: expected --person one of its {len(frames)} tracked people ({listed()}), got "
                             f"'{person}'")
        return chosen
    chosen = max(frames, key=frames.get)
    if len(frames) > 1 and not quiet:
        log.warning("%s: holds %d tracked people (%s): reading '%s', tracked longest (--person ID reads another)",
                    src, len(frames), listed(), chosen)
    return chosen


def _phalp_frames(data: dict) -> tuple[list, list]:
    """PHALP's frames ((key, frame) in time order) and each one's track ids (per detection)."""
    frames = sorted(data.items(), key=lambda kv: (_plain(kv[1].get("time", -1)).reshape(-1)[:1].tolist(),
                                                  str(kv[0])))
    return frames, [[_plain(t).item() for t in frame["tid"]] for _, frame in frames]


def _phalp_person(data: dict, person, src: str) -> dict:
    """The track `person`'s smplx arguments (global_orient, body_pose, betas, transl: its 'camera' translation;
    frame_ids: the frames' 'time') from PHALP's and 4D-Humans' results: {frame: {'time', 'tid': [track id per
    detection], 'smpl': [{'global_orient', 'body_pose', 'betas'} per detection], 'camera': [(3,) per detection],
    ...}}."""
    frames, tids = _phalp_frames(data)
    parts: dict = {"global_orient": [], "body_pose": [], "betas": [], "transl": [], "frame_ids": []}
    for k, ((_, frame), frame_tids) in enumerate(zip(frames, tids)):
        if person not in frame_tids:
            continue
        i = frame_tids.index(person)
        smpl, cameras = frame["smpl"][i], list(frame.get("camera", ()))
        for key in ("global_orient", "body_pose", "betas"):
            parts[key].append(_plain(smpl.get(key)))
        parts["transl"].append(_plain(cameras[i]).reshape(-1) if i < len(cameras) else None)
        time = _plain(frame.get("time", k)).reshape(-1)
        parts["frame_ids"].append(time[0] if time.size == 1 else k)
    if any(t is None for t in parts["transl"]):
        del parts["transl"]
    try:
        stacked = {key: np.stack(values) for key, values in parts.items()}
    except ValueError as exc:
        raise InputError(f"{src}: expected PHALP's SMPL parameters of one shape in every frame ({_short(exc)})") \
            from None
    stacked["global_orient"] = stacked["global_orient"].reshape(len(stacked["frame_ids"]), 1, 3, 3) \
        if stacked["global_orient"].size == 9 * len(stacked["frame_ids"]) else stacked["global_orient"]
    return stacked


def _plain(value) -> np.ndarray:
    """A pickled value as a numpy array (a tensor's values; an object array where it is no array of numbers)."""
    if hasattr(value, "detach"):  # a torch tensor
        value = value.detach().cpu()
        return (value.float() if value.is_floating_point() else value).numpy()
    try:
        return np.asarray(value)
    except (ValueError, TypeError):  # ragged lists
        return np.array(None, dtype=object)


def save_motion(path, motion: Motion) -> None:
    """Write `motion` as an AMASS-style .npz (atomically: temp file, then rename).

    Keys: poses (T, J*3) float32, trans (T, 3) float32, betas (S,) float32 (16 zeros
    when the motion has none), mocap_framerate float64, gender str ('neutral' if None).
    """
    path = Path(path)
    T, J, _ = motion.poses.shape
    arrays = {
        "poses": np.asarray(motion.poses, dtype=np.float32).reshape(T, J * 3),
        "trans": np.asarray(motion.trans, dtype=np.float32),
        "betas": (np.zeros(16, dtype=np.float32) if motion.betas is None
                  else np.asarray(motion.betas, dtype=np.float32).reshape(-1)),
        "mocap_framerate": np.float64(motion.fps),
        "gender": np.array(motion.gender if motion.gender is not None else "neutral"),
    }
    with atomic_file(path) as tmp, open(tmp, "wb") as f:
        np.savez(f, **arrays)


def _read_betas(raw, n_frames: int, src: str) -> np.ndarray:
    """(S,) float32 betas from (S,), (1, S) or per-frame (T, S) (their mean, warned about when the frames
    disagree by more than BETAS_SPREAD_WARN)."""
    betas = _float_array(raw, "betas", src)
    if betas.size and not np.all(np.isfinite(betas)):
        raise InputError(f"{src}: betas contain NaN or Inf")
    if betas.ndim == 2 and betas.shape[0] == n_frames and n_frames > 1:
        spread = float(np.abs(betas - betas.mean(axis=0)).max(initial=0.0))
        if spread > BETAS_SPREAD_WARN:
            log.warning("%s: betas are given per frame and differ by up to %.2f from their mean: the body's shape "
                        "is held at their mean over the %d frames", src, spread, n_frames)
        return betas.mean(axis=0).astype(np.float32)
    if betas.ndim > 1 and (betas.ndim > 2 or betas.shape[0] != 1):
        raise InputError(f"{src}: expected betas of shape (S,), (1, S) or one row per frame ({n_frames}, S), "
                         f"got {tuple(betas.shape)}")
    return betas.reshape(-1)


def _refuse_degrees(poses: np.ndarray, src: str) -> None:
    """InputError when the (T, J, 3) axis-angle `poses` look like degrees (`DEGREES_SHARE`, `DEGREES_MAX_NORM`)."""
    angle = np.linalg.norm(np.asarray(poses, dtype=np.float64), axis=-1)
    angle = angle[np.isfinite(angle) & (angle > 1e-6)]
    over = float(np.mean(angle > 2 * np.pi)) if angle.size else 0.0
    if over > DEGREES_SHARE or (angle.size and angle.max() > DEGREES_MAX_NORM):
        raise InputError(f"{src}: expected joint rotations as axis-angle radians, got {over:.0%} of them over a full "
                         f"turn (2 pi; the largest {angle.max():.1f}): in degrees? multiply poses by pi / 180 (radians "
                         "wound past a full turn: reduce each rotation to within pi)")


def _body_only(poses: np.ndarray) -> np.ndarray:
    """(T, 24, 3): 22-joint body poses with the SMPL hand joints (22, 23) at rest."""
    return np.concatenate([poses, np.zeros((poses.shape[0], 2, 3), dtype=poses.dtype)], axis=1)


def _from_smpl_codec(arrays: dict, src: str) -> None:
    """An SMPLCodec file's keys (`_CODEC_KEYS`) as load_motion's, in place, where it has a 'bodyPose' and no
    'poses': the parts of the pose (`_CODEC_MODELS`; missing ones at rest) as 'poses', 'bodyTranslation' as
    'trans', 'shapeParameters' as 'betas', 'frameRate', and its gender's number as its name."""
    if "bodyPose" not in arrays or "poses" in arrays:
        return
    version = np.asarray(arrays.pop("smplVersion", 2)).reshape(-1)
    version = int(version[0]) if version.size and version.dtype.kind in "iu" else -1
    if version not in _CODEC_MODELS:
        raise InputError(f"{src}: expected an SMPL, SMPL-H or SMPL-X pose (smplVersion 0, 1 or 2), got smplVersion "
                         f"{version}" + (f" ({_CODEC_OTHER_MODELS[version]}: its pose is no rotations of SMPL's "
                                          f"joints)" if version in _CODEC_OTHER_MODELS else ""))
    body = _float_array(arrays.pop("bodyPose"), "bodyPose", src)
    body = body[None] if body.ndim == 2 and body.shape[1] == 3 else body  # one pose without a frame axis
    if body.ndim != 3 or body.shape[2] != 3:
        raise InputError(f"{src}: expected bodyPose of shape (T, J, 3), got {tuple(body.shape)}")
    T = body.shape[0]
    parts = [body]
    for key, n in _CODEC_MODELS[version][1]:
        part = _float_array(arrays.pop(key), key, src) if key in arrays else np.zeros((T, n, 3), np.float32)
        part = part[None] if part.ndim == 2 else part
        if part.shape != (T, n, 3):
            raise InputError(f"{src}: expected {key} of shape ({T}, {n}, 3), got {tuple(part.shape)}")
        parts.append(part)
    arrays["poses"] = np.concatenate(parts, axis=1)
    for key, new in (("bodyTranslation", "trans"), ("shapeParameters", "betas"), ("frameRate", "mocap_framerate")):
        if key in arrays:
            arrays[new] = arrays.pop(key)
    gender = np.asarray(arrays.get("gender", "")).reshape(-1)
    if gender.size == 1 and gender.dtype.kind in "iu" and 0 <= int(gender[0]) < len(_CODEC_GENDERS):
        arrays["gender"] = _CODEC_GENDERS[int(gender[0])]


def _from_aist(arrays: dict, src: str) -> None:
    """AIST++'s `smpl_poses` and `smpl_trans` / `smpl_scaling` (metres) as `poses` and `trans`, in place, where
    the file has no `poses` or translation of its own. Its world is Y-up and it records no frame rate (60 Hz):
    the Y-up warning and --source-fps say so."""
    if "smpl_poses" in arrays and "poses" not in arrays:
        arrays["poses"] = arrays.pop("smpl_poses")
    if "smpl_trans" in arrays and not {"trans", "transl"} & arrays.keys():
        trans = _float_array(arrays.pop("smpl_trans"), "smpl_trans", src)
        if "smpl_scaling" in arrays:
            scale = _float_array(arrays.pop("smpl_scaling"), "smpl_scaling", src).ravel()
            if scale.size != 1 or not np.isfinite(scale[0]) or scale[0] <= 0:
                raise InputError(f"{src}: expected smpl_scaling to be one finite number > 0, got "
                                 f"{scale.size} value(s) {scale[:3].tolist()}")
            trans = trans / scale[0]
        arrays["trans"] = trans


def _from_estimator(arrays: dict, src: str) -> None:
    """A pose estimator's keys as load_motion's, in place, where the file has no poses of another name: WHAM's
    world motion ('pose_world', 'trans_world'; without the latter, no translation: its 'trans' is the camera's view)
    in place of its camera-frame one, else a 'pose' (VIBE's, WHAM's in the camera's frame: SMPL's 72 values per
    frame) as 'poses', else EMDB's 'poses_root' and 'poses_body', else TRAM's 'pred_rotmat', 'pred_trans',
    'pred_shape' and 'frame'."""
    if not {"poses", "root_orient", "global_orient"} & arrays.keys():
        if "pose_world" in arrays:
            arrays["poses"] = arrays.pop("pose_world")
            arrays.pop("trans", None)
            if "trans_world" in arrays:
                arrays["trans"] = arrays.pop("trans_world")
        elif "pose" in arrays:
            arrays["poses"] = arrays.pop("pose")
        elif "poses_root" in arrays and "poses_body" in arrays:  # EMDB's: (T, 3) and SMPL's other 23 joints
            arrays["global_orient"], arrays["body_pose"] = arrays.pop("poses_root"), arrays.pop("poses_body")
        elif "pred_rotmat" in arrays:  # TRAM's: rotation matrices (T, 24, 3, 3), trans (T, 1, 3)
            arrays["poses"] = arrays.pop("pred_rotmat")
            for key, new in (("pred_trans", "trans"), ("pred_shape", "betas"), ("frame", "frame_ids")):
                if key in arrays and new not in arrays:
                    value = np.asarray(arrays.pop(key))
                    flat = new == "trans" and value.ndim and value.size == 3 * len(value)  # (T, 1, 3) -> (T, 3)
                    arrays[new] = value.reshape(len(value), 3) if flat else value


def _fill_untracked(poses: np.ndarray, trans: np.ndarray, raw, src: str) -> tuple[np.ndarray, np.ndarray]:
    """`poses`, `trans` on every video frame from the first to the last a person was tracked in, where 'frame_ids'
    (`raw`, None where absent: a pose estimator's track) skip some: those filled in (`core.motion.fill_untracked`)
    and warned about; ids that are not one increasing frame number per frame are warned about and left unused."""
    if raw is None:
        return poses, trans
    ids = np.asarray(raw)
    T = len(poses)
    if not (ids.shape == (T,) and ids.dtype.kind in "iu" and np.all(np.diff(ids.astype(np.int64)) > 0)):
        log.warning("%s: its frame numbers ('frame_ids') left unused: expected %d increasing frame numbers, one per "
                    "frame, got %s of dtype %s", src, T, tuple(ids.shape), ids.dtype)
        return poses, trans
    span = int(ids[-1]) - int(ids[0]) + 1
    if span == T:
        return poses, trans
    if span > MAX_FILLED_FRAMES:
        raise InputError(f"{src}: expected the frame numbers of a track in one video, got frames {int(ids[0])} to "
                         f"{int(ids[-1])} for {T} tracked (over {MAX_FILLED_FRAMES} frames to fill in)")
    gap = int(np.diff(ids.astype(np.int64)).max()) - 1
    log.warning("%s: the person is not tracked in %d of the video's %d frames from its first to its last "
                "(its frame numbers; %d in a row at the most): filled in, joint rotations slerped and the translation "
                "interpolated between the frames around them", src, span - T, span, gap)
    return fill_untracked(poses, trans, ids)


def _read_poses(arrays: dict, src: str, files: list[str]) -> np.ndarray:
    """(T, J, 3) float32 poses from `poses` or the SMPL-X split keys; files: every key of the archive."""
    if "poses" in arrays:
        poses = _float_array(arrays["poses"], "poses", src)
        if poses.ndim == 1:  # a single frame stored flat
            poses = poses[None]
        if poses.ndim == 4:  # rotation matrices (T, J, 3, 3)
            poses = _rotations(poses, "poses", src)
        if poses.ndim == 3:
            if poses.shape[2] == 3 and poses.shape[1] == _BODY_ONLY_JOINTS:
                return _body_only(poses)
            if poses.shape[2] != 3 or poses.shape[1] * 3 not in _VALUES_PER_FRAME:
                raise InputError(f"{src}: expected poses of shape (T, 22|24|52|55, 3), got {tuple(poses.shape)}")
            return poses
        if poses.ndim != 2:
            raise InputError(f"{src}: expected poses of shape (T, 72|156|165), got {tuple(poses.shape)}")
        n = poses.shape[1]
        if n == 3 * _BODY_ONLY_JOINTS:
            return _body_only(poses.reshape(poses.shape[0], _BODY_ONLY_JOINTS, 3))
        if n not in _VALUES_PER_FRAME:
            raise InputError(f"{src}: expected {_EXPECTED} pose values per frame, got {n}")
        return poses.reshape(poses.shape[0], _VALUES_PER_FRAME[n], 3)
    if "root_orient" in arrays and "pose_body" in arrays:
        return _split_poses(arrays, src)
    if "global_orient" in arrays and "body_pose" in arrays:
        return _smplx_arg_poses(arrays, src)
    if "v_template" in files:
        raise InputError(f"{src}: an SMPL-format body file (v_template, shapedirs, ...), not a motion: give it with "
                         "--body")
    raise InputError(f"{src}: expected a 'poses' array, SMPL-X 'root_orient' + 'pose_body' or the smplx arguments "
                     f"'global_orient' + 'body_pose', found keys {sorted(files)}")


#: Shapes of a global_orient of one frame: a file holding one image's estimate, whose other arrays may have no
#: frame axis.
_ONE_FRAME_ROOT = ((3,), (1, 3), (1, 1, 3), (1, 3, 3), (1, 1, 3, 3))


def _smplx_arg_poses(arrays: dict, src: str) -> np.ndarray:
    """(T, 24|55, 3) poses from the smplx forward arguments (`_SMPLX_ARG_KEYS`): a body_pose of 23 joints is SMPL's
    (global_orient first), one of 21 SMPL-X's (or SMPL+H's) body, followed by the jaw, the eyes and the hands where
    given (at rest where not; hands given as PCA coefficients of the body model's own basis are warned about and
    left at rest)."""
    one = np.shape(arrays["global_orient"]) in _ONE_FRAME_ROOT  # a per-image estimate: no frame axis elsewhere?

    def frames(raw, joints):
        """`raw` given a frame axis where it is one frame's `joints` rotations without one (a per-image
        estimator's file, SMPLer-X's: body_pose (21, 3), the hands (15, 3))."""
        shape = np.shape(raw)
        return np.asarray(raw)[None] if one and shape[:1] in [(j,) for j in joints] and shape[1:] in ((3,), (3, 3)) \
            else raw

    glob = _rotations(arrays["global_orient"], "global_orient", src)
    body = _rotations(frames(arrays["body_pose"], (21, 23)), "body_pose", src)
    T, K = body.shape[:2]
    if K not in (21, 23):
        raise InputError(f"{src}: expected body_pose of 23 (SMPL) or 21 (SMPL-X, SMPL+H) joints (69 or 63 values "
                         f"per frame), got {K} joints")
    if glob.shape[1] != 1:
        raise InputError(f"{src}: expected global_orient of one joint (3 values per frame), got {glob.shape[1]}")
    parts = {"global_orient": glob, "body_pose": body}
    for key, n in _SMPLX_ARG_EXTRAS if K == 21 else ():
        raw = arrays.get(key)
        raw = None if raw is None else frames(raw, (n,))
        if raw is not None and key.endswith("hand_pose") and np.ndim(raw) == 2 and np.shape(raw)[1] != 3 * n:
            log.warning("%s: %s has %d values per frame, not %d: PCA coefficients of the body model's hand basis? "
                        "the hands are left at rest (save them as axis-angle: smplx's use_pca=False)",
                        src, key, np.shape(raw)[1], 3 * n)
            raw = None
        parts[key] = np.zeros((T, n, 3), dtype=np.float32) if raw is None else _rotations(raw, key, src)
        if parts[key].shape[1] != n:
            raise InputError(f"{src}: expected {key} of {n} joint(s) ({3 * n} values per frame), got "
                             f"{parts[key].shape[1]}")
    for key, a in parts.items():
        if a.shape[0] != T:
            raise InputError(f"{src}: {key} has {a.shape[0]} frames but body_pose has {T}")
    return np.concatenate(list(parts.values()), axis=1)


def _rotations(raw, key: str, src: str) -> np.ndarray:
    """(T, K, 3) float32 axis-angle joint rotations from axis-angle (K*3,), (T, K*3) or (T, K, 3), or from rotation
    matrices (T, 3, 3) (one joint) or (T, K, 3, 3), as pose estimators write them."""
    a = _float_array(raw, key, src)
    if a.ndim == 4 or (a.ndim == 3 and a.shape[1:] == (3, 3)):
        if a.shape[-2:] != (3, 3):
            raise InputError(f"{src}: expected {key} as rotation matrices (T, K, 3, 3), got {tuple(a.shape)}")
        m = a.reshape(a.shape[0], int(np.prod(a.shape[1:-2])), 3, 3).astype(np.float64)  # (T, 3, 3): one joint
        if not np.isfinite(m).all():
            raise InputError(f"{src}: {key} contains NaN or Inf")
        off = float(np.abs(m @ np.swapaxes(m, -1, -2) - np.eye(3)).max(initial=0.0))
        if off > ROTATION_MATRIX_TOL or (m.size and np.linalg.det(m).min() < 0):
            raise InputError(f"{src}: expected {key} as rotation matrices (orthonormal, determinant +1), got "
                             f"matrices {off:.3g} from orthonormal or mirroring")
        from core.rotations import matrix_to_axis_angle

        return matrix_to_axis_angle(m).astype(np.float32)
    if a.ndim == 1:
        a = a[None]
    if a.ndim == 3 and a.shape[2] == 3:
        return a
    if a.ndim != 2 or a.shape[1] % 3:
        raise InputError(f"{src}: expected {key} as axis-angle (T, K*3) or (T, K, 3), or rotation matrices "
                         f"(T, K, 3, 3), got {tuple(a.shape)}")
    return a.reshape(a.shape[0], a.shape[1] // 3, 3)  # explicit: an empty array has no -1 to infer


def _split_poses(arrays: dict, src: str) -> np.ndarray:
    """Assemble (T, 22|55, 3) poses from SMPL-X split keys (no hands/jaw/eyes -> SMPL-X with zeros)."""
    widths = dict(zip(_SPLIT_KEYS, (3, 63, 3, 6, 90)))
    parts = {}
    for key, width in widths.items():
        if key not in arrays:
            continue
        a = _float_array(arrays[key], key, src)
        if a.ndim == 1:
            a = a[None]
        a = a.reshape(a.shape[0], -1)
        if a.shape[1] != width:
            raise InputError(f"{src}: expected {key} with {width} values per frame, got {a.shape[1]}")
        parts[key] = a
    T = parts["root_orient"].shape[0]
    for key, a in parts.items():
        if a.shape[0] != T:
            raise InputError(f"{src}: {key} has {a.shape[0]} frames but root_orient has {T}")
    zeros = lambda w: np.zeros((T, w), dtype=np.float32)  # noqa: E731
    flat = np.concatenate([parts["root_orient"], parts["pose_body"], parts.get("pose_jaw", zeros(3)),
                           parts.get("pose_eye", zeros(6)), parts.get("pose_hand", zeros(90))], axis=1)
    return flat.reshape(T, 55, 3)


def _read_frame_rate(raw, key: str, src: str) -> float:
    """The one frame rate stored under `key` (a 0-d or 1-element array, or one value repeated per frame)."""
    values = np.asarray(raw)
    try:
        if values.dtype.kind not in _NUMBER_KINDS:
            raise TypeError
        rates = np.asarray(values, dtype=np.float64).reshape(-1)
    except (ValueError, TypeError):
        raise InputError(f"{src}: expected a number under '{key}', got {_value_text(values)}") from None
    if rates.size == 0:
        raise InputError(f"{src}: expected a number under '{key}', got an empty array")
    if rates.size > 1 and not (rates == rates[0]).all():
        raise InputError(f"{src}: expected one frame rate under '{key}', got {rates.size} different values "
                         f"({_value_text(rates)}{', ...' if rates.size > 4 else ''})")
    return float(rates[0])


#: numpy dtype kinds read as numbers: floats, integers and text of numbers ('60'); not bool (True is no rotation or
#: rate), complex (the imaginary part would be dropped), dates or durations.
_NUMBER_KINDS = frozenset("fiuUS")


def _value_text(values) -> str:
    """The first values of an array as a message quotes them (`60.0, 30.0, 120.0`; `abc (dtype <U3)`)."""
    a = np.asarray(values)
    items = ", ".join(str(v) for v in a.reshape(-1)[:4].tolist())[:80]
    return items if a.dtype.kind in "fiu" else f"{items} (dtype {a.dtype})"


def _float_array(a, key: str, src: str) -> np.ndarray:
    """`a` as float32 (integers and text of numbers too; integers other than 0 warned about: angles in whole
    radians, positions in whole metres are a file's writer truncating them); InputError naming `key` otherwise."""
    dtype = np.asarray(a).dtype
    try:
        if dtype.kind not in _NUMBER_KINDS:
            raise TypeError
        with np.errstate(over="ignore"):  # float64 beyond float32's range becomes Inf: refused below
            out = np.asarray(a, dtype=np.float32)
    except (ValueError, TypeError):
        raise InputError(f"{src}: expected numbers in '{key}', got dtype {dtype}") from None
    if dtype.kind == "f" and dtype.itemsize > 4:
        source = np.asarray(a)
        beyond = np.isinf(out) & np.isfinite(source)
        if beyond.any():  # it was called NaN or Inf, which the file does not hold
            at = np.unravel_index(int(np.argmax(beyond)), beyond.shape)
            raise InputError(f"{src}: expected '{key}' within float32's range (3.4e+38), got {source[at]:.3g} at "
                             f"index {tuple(int(i) for i in at)}: no angle or position of a motion (a damaged file?)")
    if dtype.kind in "iu" and out.any():
        log.warning("%s: '%s' holds integers (dtype %s), not floating-point values: read as whole radians or metres, "
                    "as given (a writer that truncated them?)", src, key, dtype)
    return out


def _read_gender(raw) -> str | None:
    """bytes / str / 0-d or 1-element array -> str, or None."""
    if raw is None:
        return None
    a = np.asarray(raw)
    if a.size == 0:
        return None
    v = a.reshape(-1)[0]
    if isinstance(v, bytes):
        v = v.decode("utf-8", errors="replace")
    return str(v).strip() or None


def _short(exc: BaseException, limit: int = 120) -> str:
    """An exception's first line, cut at a word before `limit` characters ('...'; it ended mid-word: 'If yo')."""
    text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    return text if len(text) <= limit else text[:limit].rsplit(" ", 1)[0].rstrip(".,;:") + " ..."
