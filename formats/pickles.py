"""Python pickles read without running their code: SMPL body files and pose estimators' motion files.

A restricted unpickler resolves only the globals such files need (numpy arrays and dtypes, scipy.sparse matrices,
a few builtins and collections, torch tensors rebuilt through torch.load(weights_only=True)) and refuses every
other with an InputError naming the file; chumpy `Ch` objects (the official SMPL pickles) become `ChumpyStandIn`,
holding their array. `load_pickle` also reads joblib's files (WHAM, VIBE and other estimators save their results
with `joblib.dump`: the arrays follow their pickled header in the stream, optionally compressed) without
importing joblib; `load_npy_pickle` a .npy of a pickled object (np.save of a dict); `load_torch` a PyTorch file.
"""

from __future__ import annotations

import _compat_pickle
import bz2
import gzip
import importlib
import io
import lzma
import pickle
import zlib
from pathlib import Path

import numpy as np

from core.errors import InputError

_NUMPY_NAMES = {"_reconstruct", "ndarray", "dtype", "scalar", "_frombuffer"}
_BUILTIN_NAMES = {"object", "set", "frozenset", "slice", "complex", "bytearray", "list", "dict", "tuple",
                  "int", "float", "str", "bytes", "bool"}
_OTHER_GLOBALS = {("copyreg", "_reconstructor"), ("_codecs", "encode"), ("collections", "OrderedDict"),
                  ("collections", "defaultdict")}
#: The modules of joblib's array wrapper (joblib itself; scikit-learn's copy of it, which older VIBE used).
_JOBLIB_MODULES = ("joblib.numpy_pickle", "sklearn.externals.joblib.numpy_pickle")
#: How the compressed files `joblib.dump(..., compress=...)` writes start (lz4 needs a package: not read).
_COMPRESSED = ((b"\x1f\x8b", lambda fh: gzip.GzipFile(fileobj=fh)), (b"BZh", bz2.BZ2File),
               (b"\xfd7zXZ", lzma.LZMAFile), (b"\x5d\x00", lzma.LZMAFile), (b"\x78", None))  # None: a zlib stream
#: Bytes read at a time from a joblib array's data.
_CHUNK = 1 << 24
#: A joblib array larger than this (bytes) is read only when asked for (`LazyArray`).
LAZY_BYTES = 1 << 24


class ChumpyStandIn:
    """Takes the place of a chumpy `Ch` while unpickling; `.array` is its value.

    A pickled `Ch` stores its value under 'x' of its state dict (other entries
    are chumpy bookkeeping).
    """

    array = None

    def __init__(self, *args, **kwargs):
        if args:
            self.array = np.asarray(args[0])

    def __setstate__(self, state):
        if isinstance(state, tuple):  # (dict, slots) from objects with __slots__
            state = next((s for s in state if isinstance(s, dict)), {})
        if not isinstance(state, dict):
            return
        value = state.get("x")
        if value is None:
            value = next((v for v in state.values() if isinstance(v, np.ndarray)), None)
        if isinstance(value, ChumpyStandIn):
            value = value.array
        self.array = None if value is None else np.asarray(value)


class _JoblibArray:
    """Takes the place of joblib's `NumpyArrayWrapper`: its pickled state (dtype, shape, order, alignment) says
    how the array's bytes that follow it in the file are laid out; `read` reads them."""

    def __setstate__(self, state):
        self.state = state if isinstance(state, dict) else {}

    def read(self, unpickler) -> np.ndarray:
        fh = unpickler.file_handle
        dtype, shape = np.dtype(self.state.get("dtype")), tuple(int(n) for n in self.state.get("shape", ()))
        if dtype.hasobject:  # joblib pickles object arrays after the wrapper: refused or read as any pickle
            return _RestrictedUnpickler(fh, unpickler.label, unpickler.what).load()
        if self.state.get("numpy_array_alignment_bytes") is not None:  # a byte giving the padding, the padding
            fh.read(int.from_bytes(fh.read(1), "little"))
        size = int(np.prod(shape, dtype=np.int64)) * dtype.itemsize
        fortran = self.state.get("order") == "F"
        if unpickler.path is not None and size > LAZY_BYTES:  # left in the file until asked for
            offset = fh.tell()
            if fh.seek(size, io.SEEK_CUR) > unpickler.path.stat().st_size:
                raise EOFError(f"the file ends inside an array of {size} bytes")
            return LazyArray(unpickler.path, offset, dtype, shape, fortran)
        data = np.empty(size, dtype=np.uint8)  # read into in place: a video's vertices may be most of the file
        view, got = memoryview(data), 0
        while got < size:
            n = fh.readinto(view[got:got + _CHUNK])
            if not n:
                raise EOFError(f"the file ends inside an array ({got} of its {size} bytes)")
            got += n
        return _shaped(data.view(dtype), shape, fortran)


def _shaped(flat: np.ndarray, shape: tuple, fortran: bool) -> np.ndarray:
    return flat.reshape(shape[::-1]).T if fortran else flat.reshape(shape)


class LazyArray:
    """A joblib array over `LAZY_BYTES` left in its (uncompressed) file until np.asarray asks for it: the vertices
    a pose estimator writes per frame are most of its file, and never read here."""

    def __init__(self, path: Path, offset: int, dtype: np.dtype, shape: tuple, fortran: bool):
        self.path, self.offset, self.dtype, self.shape, self.fortran = path, offset, dtype, shape, fortran

    def __len__(self) -> int:
        return self.shape[0] if self.shape else 0

    def __array__(self, dtype=None, copy=None):
        count = int(np.prod(self.shape, dtype=np.int64))
        flat = np.fromfile(self.path, dtype=self.dtype, count=count, offset=self.offset)
        if flat.size < count:
            raise EOFError(f"'{self.path}' ends inside an array ({flat.size} of its {count} values)")
        array = _shaped(flat, self.shape, self.fortran)
        return array if dtype is None else array.astype(dtype)


class _Restricted:
    """find_class for the restricted unpicklers (see the module's docstring); `label` names the file and `what` is
    the kind of file whose needs decide (the refusal: "which an SMPL-format file does not use")."""

    label = what = ""

    def find_class(self, module: str, name: str):
        # Python-2 names (__builtin__, copy_reg), as the default find_class maps them.
        if (module, name) in _compat_pickle.NAME_MAPPING:
            module, name = _compat_pickle.NAME_MAPPING[(module, name)]
        module = _compat_pickle.IMPORT_MAPPING.get(module, module)
        if module == "chumpy" or module.startswith("chumpy."):
            return ChumpyStandIn
        if module in _JOBLIB_MODULES and name == "NumpyArrayWrapper":
            return _JoblibArray
        if module.startswith("scipy.sparse") and name.endswith(("_matrix", "_array")):
            import scipy.sparse

            if hasattr(scipy.sparse, name):
                return getattr(scipy.sparse, name)
        if module.split(".")[0] == "numpy" and (name in _NUMPY_NAMES or name.endswith("DType")):
            # numpy 2 moved numpy.core to numpy._core; old pickles name the former.
            for mod in (module.replace("numpy.core", "numpy._core", 1), module):
                try:
                    return getattr(importlib.import_module(mod), name)
                except (ImportError, AttributeError):
                    continue
        if (module, name) == ("torch._utils", "_rebuild_tensor_v2"):  # a tensor pickled (TRAM's results)
            import torch._utils

            return torch._utils._rebuild_tensor_v2
        if (module, name) == ("torch.storage", "_load_from_bytes"):  # its storage, through torch's own restrictions
            return _storage_from_bytes
        if (module, name) in _OTHER_GLOBALS or (module == "builtins" and name in _BUILTIN_NAMES):
            return getattr(importlib.import_module(module), name)
        raise InputError(f"{self.label}: the pickle refers to '{module}.{name}', which {self.what} does not use "
                         f"(refused)")


class _RestrictedUnpickler(_Restricted, pickle._Unpickler):
    """The pure-Python unpickler, as joblib's own: its BUILD reads a joblib array's bytes from the file."""

    dispatch = pickle._Unpickler.dispatch.copy()

    def __init__(self, fh, label: str, what: str, path: Path | None = None):
        super().__init__(fh, encoding="latin1")
        self.file_handle, self.label, self.what, self.path = fh, label, what, path

    def load(self):
        try:
            return super().load()
        except KeyError as exc:  # an unknown opcode: not a pickle, or a damaged one (the C unpickler's words)
            if exc.args and isinstance(exc.args[0], int):
                raise pickle.UnpicklingError(f"invalid load key, {bytes(exc.args[:1])!r}") from None
            raise

    def load_build(self):
        pickle._Unpickler.load_build(self)
        if isinstance(self.stack[-1], _JoblibArray):
            self.stack.append(self.stack.pop().read(self))

    dispatch[pickle.BUILD[0]] = load_build


class FastRestrictedUnpickler(_Restricted, pickle.Unpickler):
    """The C unpickler, restricted: for large plain pickles (an SMPL body's); no joblib arrays."""

    def __init__(self, fh, label: str, what: str):
        super().__init__(fh, encoding="latin1")
        self.label, self.what = label, what


def _storage_from_bytes(data: bytes):
    """A pickled tensor's storage: torch.load(weights_only=True) of its bytes (torch's own `_load_from_bytes` loads
    them with weights_only=False: any code)."""
    import torch

    return torch.load(io.BytesIO(data), weights_only=True)


def load_torch(path: Path, label: str, what: str):
    """torch.load(weights_only=True) of `path` (tensors and containers only), with the numpy arrays and scalars it
    holds (GVHMR's results may) and every other global the restricted unpickler allows: any it refuses raises
    InputError naming `label`."""
    import torch

    resolver = _Restricted()
    resolver.label, resolver.what = label, what
    try:
        unsafe = torch.serialization.get_unsafe_globals_in_checkpoint(path)
    except Exception:  # noqa: BLE001 - not a zip-format file (a legacy one): torch.load says what it is
        unsafe = []
    allowed = [resolver.find_class(*name.rsplit(".", 1)) for name in sorted(unsafe)]
    if np.dtype in allowed:  # a dtype unpickled is an instance of its own class (numpy.dtypes.Float32DType, ...)
        allowed += [getattr(np.dtypes, n) for n in dir(np.dtypes) if n.endswith("DType")]
    with torch.serialization.safe_globals(allowed):
        return torch.load(path, map_location="cpu", weights_only=True)


def load_npy_pickle(path: Path, label: str, what: str):
    """The object a .npy file of a pickled object array holds (`np.save` of a dict: its 0-d array's item),
    through the restricted unpickler; ValueError where the file holds no object array."""
    with open(path, "rb") as fh:
        version = np.lib.format.read_magic(fh)
        read_header = np.lib.format.read_array_header_1_0 if version == (1, 0) else \
            np.lib.format.read_array_header_2_0
        _, _, dtype = read_header(fh)
        if not dtype.hasobject:
            raise ValueError(f"a .npy array of {dtype}, not of pickled objects")
        array = _RestrictedUnpickler(fh, label, what).load()
    return array.item() if isinstance(array, np.ndarray) and array.shape == () else array


def load_pickle(path: Path, label: str, what: str):
    """The object pickled in `path` (a plain pickle, or a joblib file, compressed or not) through the restricted
    unpickler; an uncompressed joblib file's large arrays come as `LazyArray`s. Raises InputError naming `label`
    for a global `what` does not use; other failures (a truncated or damaged file) propagate as the unpickler
    raises them."""
    with open(path, "rb") as raw:
        head = raw.read(6)
        raw.seek(0)
        opener = next((o for magic, o in _COMPRESSED if head.startswith(magic)), False)
        if opener is False:
            return _RestrictedUnpickler(raw, label, what, Path(path)).load()
        if opener is None:  # joblib's zlib: one raw stream
            return _RestrictedUnpickler(io.BytesIO(zlib.decompress(raw.read())), label, what).load()
        with opener(raw) as fh:
            return _RestrictedUnpickler(fh, label, what).load()
