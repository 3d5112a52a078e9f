"""Read SMPL-format body model files (SMPL, SMPL+H, SMPL-X) into `core.body.Body`.

Two containers: `.npz` (numpy archives, as SMPL-X and AMASS's SMPL+H ship) and
`.pkl` (the official Python-2 pickles, with some arrays stored as chumpy `Ch`
objects and `J_regressor` as a scipy.sparse matrix). chumpy is never imported:
a restricted unpickler maps its classes to a stand-in that keeps the array of
the pickled state, and refuses every global that an SMPL file has no use for.
Keys read: v_template (V,3), shapedirs (V,3,S), posedirs (V,3,9(J-1)),
J_regressor (J,V), weights (V,J), kintree_table (2,J) or parents (J,), f or
faces (F,3); others (gender, landmarks, hand PCA...) are ignored.
"""

from __future__ import annotations

import logging
from dataclasses import replace
from pathlib import Path

import numpy as np

from core.body import LAYOUT_JOINTS, Body, dense_from_sparse, body_from_arrays
from core.errors import InputError, require_input, warnings_held
from formats.motion import NPZ_READ_ERRORS, _starts_with, open_npz
from formats.pickles import ChumpyStandIn, FastRestrictedUnpickler

log = logging.getLogger(__name__)

REQUIRED_KEYS = ("v_template", "shapedirs", "J_regressor", "weights")
#: SMPL-X files carry 300 shape + 100 expression directions in one `shapedirs`.
SMPLX_SHAPE_AND_EXPRESSION = 400
SMPLX_SHAPE = 300
#: SMPL-X 1.0 files carry 10 shape + 10 expression directions.
SMPLX_V1_SHAPE = 10


@warnings_held
def load_body(path: str | Path) -> Body:
    """Load an SMPL-format body file (`.npz` or `.pkl`) as a validated `Body`.

    Arrays come back float32 in the file's rest frame (SMPL: Y-up, T-pose,
    metres); a 400-coefficient SMPL-X `shapedirs` keeps its first 300 (shape)
    coefficients, SMPL-X 1.0's 20 its first 10. Raises InputError (one line naming
    the file) for a missing file, an unknown suffix, an unreadable file, missing
    keys or wrong shapes.
    """
    path = Path(path)
    label = f"body file '{path}'"
    require_input(path, label)
    suffix = path.suffix.lower()
    readers = {".npz": _read_npz, ".pkl": read_pkl}
    if suffix not in readers:
        raise InputError(f"{label}: expected a .npz or .pkl SMPL-format file, got suffix '{path.suffix}'")
    if suffix == ".pkl" and _starts_with(path, b"PK\x03\x04"):  # an .npz saved under a pickle's name (a zip)
        log.info("%s: a numpy .npz archive, read as one", label)
        suffix = ".npz"
    arrays = readers[suffix](path, label)
    return replace(body_from_file_arrays(arrays, name=path.stem, source=str(path)), path=str(path))


def body_from_file_arrays(arrays: dict, name: str, source: str) -> Body:
    """Check keys, convert and validate the arrays read from file `source` (see `load_body`)."""
    label = f"body file '{source}'"
    missing = [k for k in REQUIRED_KEYS if k not in arrays]
    if "kintree_table" not in arrays and "parents" not in arrays:
        missing.append("kintree_table")
    if "f" not in arrays and "faces" not in arrays:
        missing.append("f")
    if missing:
        raise InputError(f"{label}: missing keys {', '.join(missing)} "
                         f"(an SMPL-format file has v_template, shapedirs, J_regressor, weights, kintree_table, f)")
    wanted = REQUIRED_KEYS + ("posedirs", "kintree_table", "parents", "f", "faces")
    out = {}
    for key in wanted:
        if key not in arrays:
            continue
        value = arrays[key]
        if key == "J_regressor" and hasattr(value, "toarray"):
            out[key] = value  # scipy.sparse: body_from_arrays densifies it
            continue
        try:
            value = np.asarray(value)
            if value.dtype == object:
                raise TypeError
            out[key] = value
        except (TypeError, ValueError):
            raise InputError(f"{label}: expected {key} to be a numeric array, "
                             f"got {type(arrays[key]).__name__}") from None
    kt = out.get("parents", out.get("kintree_table"))
    n_joints = kt.shape[-1] if kt.ndim >= 1 else 0
    if n_joints not in LAYOUT_JOINTS.values():
        families = ", ".join(f"{n} ({k})" for k, n in LAYOUT_JOINTS.items())
        raise InputError(f"{label}: expected {families} joints, got {n_joints} "
                         f"(from {'parents' if 'parents' in out else 'kintree_table'} of shape {tuple(kt.shape)})")
    sd = out["shapedirs"]
    if sd.ndim == 3 and sd.shape[2] == SMPLX_SHAPE_AND_EXPRESSION:
        log.info("%s: shapedirs has %d coefficients (SMPL-X shape + expression): keeping the first %d (shape)",
                 label, sd.shape[2], SMPLX_SHAPE)
        out["shapedirs"] = sd[:, :, :SMPLX_SHAPE]
    elif sd.ndim == 3 and n_joints == LAYOUT_JOINTS["smplx"] and sd.shape[2] == 2 * SMPLX_V1_SHAPE:
        # SMPL-X 1.0's files: 10 shape and 10 expression directions (as the smplx library reads them); taken whole,
        # a motion's betas 11-16 moved the face as body shape.
        log.info("%s: shapedirs has %d coefficients (SMPL-X 1.0: %d shape, then expression): keeping the first %d",
                 label, sd.shape[2], SMPLX_V1_SHAPE, SMPLX_V1_SHAPE)
        out["shapedirs"] = sd[:, :, :SMPLX_V1_SHAPE]
    if "joint_names" in arrays:  # a file that names its joints (the embedded body's, `garment make-body`'s)
        names = np.asarray(arrays["joint_names"])
        if names.shape != (n_joints,) or names.dtype.kind not in "US":
            raise InputError(f"{label}: expected joint_names to be {n_joints} strings (one per joint), got "
                             f"{names.dtype} of shape {names.shape}")
        out["joint_names"] = [str(n) for n in names]
    try:
        return body_from_arrays(out, name=name, source=source)
    except InputError:
        raise
    except (ValueError, TypeError, IndexError) as exc:
        raise InputError(f"{label}: arrays do not form an SMPL-format body ({_reason(exc)})") from None


def _read_npz(path: Path, label: str) -> dict:
    try:
        with open_npz(path, lambda got: InputError(f"{label}: cannot read it as a numpy .npz archive (a zip of .npy "
                                                   f"arrays): it is {got}")) as data:
            files = list(data.files)
            arrays = {}
            for key in files:
                if key in ("v_template", "shapedirs", "posedirs", "J_regressor", "weights", "kintree_table",
                           "parents", "f", "faces", "joint_names") or key.endswith(("_indices", "_values", "_shape")):
                    try:
                        arrays[key] = data[key]
                    except ValueError as exc:
                        if "allow_pickle" not in str(exc):
                            raise
                        if key == "joint_names":  # names saved as objects: the layout's are taken
                            continue
                        # np.savez of an official pickle's dict: its scipy.sparse J_regressor a pickled object
                        raise InputError(f"{label}: expected '{key}' as a numeric array, got a pickled object "
                                         f"(numpy's savez of a scipy.sparse matrix?): save it as an array "
                                         f"(.toarray()), or give the original .pkl") from None
    except InputError:
        raise
    except NPZ_READ_ERRORS as exc:
        raise InputError(f"{label}: cannot read it as a numpy .npz archive ({_reason(exc)})") from None
    motion_key = next((k for k in ("poses", "pose_body", "root_orient") if k in files), None)
    if motion_key and "v_template" not in arrays:
        raise InputError(f"{label}: expected an SMPL-format body (v_template, shapedirs, ...), got a motion file (it "
                         f"has '{motion_key}'): give motions as MOTION, the body with --body")
    for key in ("J_regressor", "weights"):
        if key not in arrays and f"{key}_indices" in arrays:
            try:
                arrays[key] = dense_from_sparse(arrays, key)
            except (KeyError, IndexError, ValueError) as exc:
                raise InputError(f"{label}: sparse {key} is malformed ({_reason(exc)})") from None
    return arrays


def read_pkl(path: Path, label: str) -> dict:
    """The arrays of an SMPL-format pickle (chumpy arrays as numpy's); InputError naming `label` where it is none."""
    try:
        with open(path, "rb") as fh:
            data = FastRestrictedUnpickler(fh, label, "an SMPL-format file").load()
    except InputError:
        raise
    except Exception as exc:  # noqa: BLE001 - any failure to unpickle is an unreadable file
        raise InputError(f"{label}: cannot read it as an SMPL-format pickle ({_reason(exc)})") from None
    if not isinstance(data, dict):
        raise InputError(f"{label}: expected a pickled dict of arrays, got {type(data).__name__}")
    return {str(k): (v.array if isinstance(v, ChumpyStandIn) else v) for k, v in data.items()}


def _reason(exc: BaseException) -> str:
    text = str(exc).splitlines()[0] if str(exc) else ""
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


