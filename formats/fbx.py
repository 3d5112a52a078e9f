"""FBX animation of a humanoid skeleton (Mixamo's downloads; Maya, MotionBuilder, 3ds Max, Blender exports in FBX
7.x and 6.x, binary (either byte order) or ASCII), read as the skeleton and motion `core.retarget` turns into SMPL's,
as a BVH is (`formats.bvh`).

The binary format (nodes of typed properties, arrays zlib-compressed or not) and its ASCII form (the same nodes
as text) are read here, with no SDK (FBX 6's objects, named rather than numbered, and its Takes' letter-coded
keys read as FBX 7's, `_from_fbx6`): the skeleton's joints are its Models of type LimbNode (Limb, Root), their
hierarchy from the file's connections; each joint's transform per frame is FBX's whole chain (translation,
rotation offset and pivot, pre-rotation, the Euler rotation in its RotationOrder, post-rotation, scaling offset
and pivot, scaling; the parent's scaling inherited as its InheritType says), its properties over the file's
Model template. Its animation curves are evaluated as the FBX SDK does (`curve_keys`: cubic keys' user, auto and
TCB tangents and weights, linear, constant and constant-next keys; repeated, mirrored or sloped on outside
their keys as their Pre-/Post-Extrapolation says; checked against Maya's and MotionBuilder's own values in
tests/formats/test_fbx_maya.py) at the file's frame rate over one animation stack (a take: the first, or the one
`--take` names; its span, cut to its keys' unless a curve goes on past them), its animation layers combined as
their blend modes and weights say, a value without a curve its property's; key times in FBX 8's ticks where
the header says so (TCDefinition). The rest pose is the file's BindPose where it has one
(the skin's bind matrices), else the joints' own property values. FBX 5 and older and files without a skeleton
are refused in one line. Every node's transform agrees with ufbx's evaluation on the 681 real and synthetic
FBX 6 and 7 files of its test data (`benchmarks/fbx_against_ufbx.py`).
"""

from __future__ import annotations

import hashlib
import logging
import re
import struct
import warnings
import zlib
from pathlib import Path
from typing import NamedTuple

import numpy as np
from scipy.spatial.transform import Rotation

from core.errors import InputError, read_input
from core.retarget import role_names
from formats.bvh import Skeleton

log = logging.getLogger(__name__)

_MAGIC = b"Kaydara FBX Binary  \x00"
#: FBX time units per second (KeyTime, LocalStart, LocalStop).
TICKS_PER_SECOND = 46186158000
#: GlobalSettings' TimeMode -> frames per second (14: CustomFrameRate).
_TIME_MODES = {1: 120.0, 2: 100.0, 3: 60.0, 4: 50.0, 5: 48.0, 6: 30.0, 7: 30.0, 8: 29.97, 9: 29.97, 10: 25.0,
               11: 24.0, 12: 1000.0, 13: 23.976, 15: 96.0, 16: 72.0, 17: 59.94, 18: 119.88}
#: More frames than this (an hour at 1,000 fps) is a damaged time span, refused.
MAX_FRAMES = 3_600_000
#: RotationOrder -> the axes in the order they turn a point (eEulerXYZ: X first, R = Rz Ry Rx).
_ORDERS = {0: "xyz", 1: "xzy", 2: "yzx", 3: "yxz", 4: "zxy", 5: "zyx"}
#: The Model properties curve nodes drive, by the channel's letter.
_LCL = {"Lcl Translation": "T", "Lcl Rotation": "R", "Lcl Scaling": "S"}
_ARRAY_TYPES = {b"f": "f4", b"d": "f8", b"l": "i8", b"i": "i4", b"b": "?", b"c": "u1"}
#: Scalar properties' types (struct's codes, the byte order the file's): 'C' a letter (an extrapolation's Type,
#: an FBX 6 key's kind; read as a one-letter str), 'B' and 'Z' a byte.
_SCALARS = {b"Y": "h", b"C": "c", b"B": "B", b"Z": "B", b"I": "i", b"F": "f", b"D": "d", b"L": "q"}
_STRUCTS = {(endian, kind): struct.Struct(endian + code) for endian in "<>" for kind, code in _SCALARS.items()}


class Node(NamedTuple):
    name: str
    props: list
    children: list

    def child(self, name: str) -> Node | None:
        return next((c for c in self.children if c.name == name), None)

    def all(self, name: str) -> list[Node]:
        return [c for c in self.children if c.name == name]


def read_nodes(data: bytes, src: str) -> tuple[int, list[Node]]:
    """(version, top-level nodes) of an FBX's bytes, binary or ASCII (`_ascii_nodes`); InputError naming `src` for
    a damaged one or another file."""
    if not data.startswith(_MAGIC):
        if data.lstrip()[:1] == b";" or b"FBXHeaderExtension:" in data[:4096]:
            return _ascii_nodes(data.decode("utf-8", "replace"), src)
        raise InputError(f"{src}: expected an FBX file (binary 'Kaydara FBX Binary', or ASCII), got a file that is "
                         f"not one")
    endian = ">" if data[22:23] == b"\x01" else "<"  # a big-endian file's (Maya on PowerPC Macs)
    try:
        version = struct.unpack_from(endian + "I", data, 23)[0]
        nodes, _ = _records(data, 27, len(data), version >= 7500, endian)
    except (struct.error, IndexError, ValueError, zlib.error) as exc:
        raise InputError(f"{src}: its FBX records are damaged or cut short ({type(exc).__name__})") from None
    return version, nodes


def _records(data: bytes, at: int, end: int, wide: bool, endian: str = "<") -> tuple[list[Node], int]:
    head = struct.Struct(endian + ("QQQ" if wide else "III"))
    nodes = []
    while at + head.size + 1 <= end:
        end_offset, n_props, _ = head.unpack_from(data, at)
        if end_offset == 0:  # the null record closing a list
            return nodes, at + head.size + 1
        if end_offset > len(data) or end_offset <= at:
            raise ValueError("record end out of the file")
        name_len = data[at + head.size]
        at += head.size + 1
        name = data[at:at + name_len].decode("latin-1")
        at += name_len
        props = []
        for _ in range(n_props):
            value, at = _property(data, at, endian)
            props.append(value)
        children = []
        if at < end_offset:
            children, at = _records(data, at, end_offset, wide, endian)
        nodes.append(Node(name, props, children))
        at = end_offset
    return nodes, at


#: An ASCII FBX's tokens: a node's name (with its colon), a string, a number, an array's '*N', a brace or a comma,
#: a bare word (a value such as Shading's T); comments (';' to the end of the line) and white space skipped.
_ASCII_TOKEN = re.compile(r'(?:\s|;[^\n]*)*(?:(?P<name>[A-Za-z_][\w|-]*)\s*:(?!:)|"(?P<string>[^"]*)"'
                          r'|(?P<number>[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+|#[A-Z]+\d*)?)|\*(?P<array>\d+)'
                          r'|(?P<punct>[{},])|(?P<word>[A-Za-z_]\w*))')
#: Infinities and NaNs as Microsoft's C library prints them (1.#INF, -1.#IND, 1.#QNAN), which FBX SDKs on Windows
#: wrote.
_MSVC_SPECIAL = re.compile(r"([-+]?)\d*\.?\d*#(INF|IND|QNAN|SNAN|NAN)\d*")
#: An ASCII array's values: '*N {' then 'a:' and N numbers, then '}'.
_ASCII_ARRAY = re.compile(r"\s*\{\s*a\s*:([^}]*)\}")


def _ascii_nodes(text: str, src: str) -> tuple[int, list[Node]]:
    """(version, top-level nodes) of an ASCII FBX (Maya's, MotionBuilder's, the FBX converter's): the binary
    format's nodes written as text (`Name: value, value {` children `}`, arrays `*N { a: ... }`, object names
    'Class::Name'), read into the same Nodes (names as binary FBX writes them: 'Name\\x00\\x01Class'); its
    version FBXHeaderExtension's FBXVersion. InputError naming `src` where its text is not that grammar."""
    at, stack, top = 0, [], []
    current: list = top  # the children list being filled
    node: Node | None = None  # the node whose values are being read
    expect_value = False
    while True:
        m = _ASCII_TOKEN.match(text, at)
        if m is None or m.end() == at:
            if text[at:].strip() == "" or text[at:].lstrip().startswith(";"):
                break
            raise _damaged(text, at, src, f"got {text[at:at + 20].strip()!r}")
        at = m.end()
        kind = m.lastgroup
        if kind == "name":
            node = Node(m.group("name"), [], [])
            current.append(node)
            expect_value = True
        elif kind == "punct" and m.group("punct") == "{":
            if node is None:
                raise _damaged(text, at, src, "a block of no node")
            stack.append(current)
            current, node, expect_value = node.children, None, False
        elif kind == "punct" and m.group("punct") == "}":
            if not stack:
                raise _damaged(text, at, src, "a '}' closing nothing")
            current, node, expect_value = stack.pop(), None, False
        elif kind == "punct":  # ','
            expect_value = True
        elif node is not None and expect_value:
            if kind == "array":
                values = _ASCII_ARRAY.match(text, at)
                if values is None:
                    raise _damaged(text, at, src, f"an array '*{m.group('array')}' without its values")
                node.props.append(_ascii_array(values.group(1), int(m.group("array")), src))
                at = values.end()
            else:
                node.props.append(_ascii_value(m))
            expect_value = False
        else:
            raise _damaged(text, at, src, f"a value {m.group(0).strip()!r} out of place")
    if stack:
        raise InputError(f"{src}: its ASCII FBX is cut short ({len(stack)} block(s) left open)")
    header = next((n for n in top if n.name == "FBXHeaderExtension"), None)
    version = header.child("FBXVersion") if header is not None else None
    return (int(version.props[0]) if version is not None and version.props else 7000), top


def _damaged(text: str, at: int, src: str, what: str) -> InputError:
    return InputError(f"{src}: its ASCII FBX is damaged at line {text.count(chr(10), 0, at) + 1} ({what})")


def _ascii_value(m: re.Match):
    """A value token of an ASCII FBX: a string (an object's 'Class::Name' as binary FBX writes it), an int, a
    float, or a bare word (as a string)."""
    if m.lastgroup == "string":
        value = m.group("string")
        cls, sep, name = value.partition("::")
        return f"{name}\x00\x01{cls}" if sep and cls.isidentifier() else value
    if m.lastgroup == "number":
        number = m.group("number")
        return _number(number) if any(c in number for c in ".eE#") else int(number)
    return m.group("word")


def _number(text: str) -> float:
    """A float of an ASCII FBX (Microsoft's '1.#INF' and '-1.#IND' as infinities and NaN)."""
    return float(_msvc(text) if "#" in text else text)


def _msvc(text: str) -> str:
    """A number's text with Microsoft's infinities and NaNs ('1.#INF', '-1.#IND') written as Python reads them."""
    return _MSVC_SPECIAL.sub(lambda m: m.group(1) + ("inf" if m.group(2) == "INF" else "nan"), text)


def _ascii_array(values: str, n: int, src: str) -> np.ndarray:
    """An ASCII FBX array's `n` comma-separated numbers: int64 where all are integers, else float64."""
    if ";" in values:  # comments between its values
        values = re.sub(r";[^\n]*", "", values)
    items = [v for v in values.replace("\n", " ").split(",") if v.strip()]
    if len(items) != n:
        raise InputError(f"{src}: its ASCII FBX has an array of {len(items)} values where it says {n}")
    integer = not any(c in values for c in ".eE#")
    if "#" in values:
        items = [_msvc(v) for v in items]
    try:
        return np.array(items, dtype=np.int64 if integer else np.float64)
    except ValueError:
        raise InputError(f"{src}: its ASCII FBX has an array of other than numbers") from None


def _property(data: bytes, at: int, endian: str = "<"):
    kind = data[at:at + 1]
    at += 1
    if kind in _SCALARS:
        fmt = _STRUCTS[endian, kind]
        value = fmt.unpack_from(data, at)[0]
        return (value.decode("latin-1") if kind == b"C" else value), at + fmt.size
    if kind in _ARRAY_TYPES:
        length, encoding, size = struct.unpack_from(endian + "III", data, at)
        at += 12
        raw = data[at:at + size]
        if encoding == 1:
            raw = zlib.decompress(raw)
        dtype = np.dtype(_ARRAY_TYPES[kind]).newbyteorder(endian)
        if len(raw) != length * dtype.itemsize:
            raise ValueError("array of another length than it says")
        return np.frombuffer(raw, dtype=dtype).astype(dtype.newbyteorder("=")), at + size
    if kind in (b"S", b"R"):
        size = struct.unpack_from(endian + "I", data, at)[0]
        raw = data[at + 4:at + 4 + size]
        return (raw.decode("utf-8", "replace") if kind == b"S" else raw), at + 4 + size
    raise ValueError(f"unknown property type {kind!r}")


def _props70(node: Node | None) -> dict:
    """{name: values (a list)} of a node's Properties70."""
    block = node.child("Properties70") if node is not None else None
    return {p.props[0]: p.props[4:] for p in (block.all("P") if block is not None else [])}


def _vector(props: dict, name: str, default: float) -> np.ndarray:
    values = props.get(name)
    return np.array(values[:3], dtype=np.float64) if values and len(values) >= 3 else np.full(3, default)


def _euler(degrees: np.ndarray, order: str) -> np.ndarray:
    """(..., 3, 3) the rotation of Euler angles (..., 3) in degrees about x, y, z, turning about `order`'s axes
    in turn (the first axis first: 'xyz' is Rz Ry Rx)."""
    radians = np.radians(np.asarray(degrees, dtype=np.float64))
    R = None
    for axis in order:
        k = "xyz".index(axis)
        i, j = (k + 1) % 3, (k + 2) % 3
        c, s = np.cos(radians[..., k]), np.sin(radians[..., k])
        turn = np.zeros(radians.shape[:-1] + (3, 3))
        turn[..., k, k] = 1.0
        turn[..., i, i], turn[..., i, j], turn[..., j, i], turn[..., j, j] = c, -s, s, c
        R = turn if R is None else turn @ R
    return R


def _name(node: Node) -> str:
    return str(node.props[1]).split("\x00\x01")[0]


class _Layer(NamedTuple):
    """One animation layer of a stack: its curves {(model id, 'T'/'R'/'S'): [per axis: Keys, a default or
    None]}, its BlendMode (0 additive, 1 override, 2 override passthrough), its Weight (0 to 1; `weight_keys`
    where animated), and whether it composes rotations as rotations and multiplies scalings
    (RotationAccumulationMode and ScaleAccumulationMode 0), else adds their Euler angles and scalings."""

    channels: dict
    mode: int = 1
    weight: float = 1.0
    weight_keys: Keys | None = None
    compose_rotation: bool = True
    compose_scale: bool = True


class _Curves(NamedTuple):
    """The animation of one stack: its layers in order (`_Layer`), the first the base, and its span in ticks."""

    layers: list
    start: int
    stop: int


def _animation(objects: Node, links: list[tuple], stack: Node | None, unit: float = 1.0) -> _Curves | None:
    """The curves of the animation stack `stack`, layer by layer (all the file's curve nodes, one layer, where
    it has none); `unit`: FBX 7 ticks per tick of the file's (`time_unit`)."""
    by_id = {n.props[0]: n for n in objects.children if n.props and isinstance(n.props[0], int)}
    up: dict[int, list] = {}  # child -> [(parent, the parent's property it drives, or None)]
    down: dict[int, list] = {}  # parent -> [(child, property)]
    for kind, child, parent, *prop in links:
        up.setdefault(child, []).append((parent, prop[0] if prop else None))
        down.setdefault(parent, []).append((child, prop[0] if prop else None))
    layer_ids: list = [None]
    if stack is not None:
        layer_ids = [c for c, _ in down.get(stack.props[0], []) if c in by_id and by_id[c].name == "AnimationLayer"]
        layer_ids = list(dict.fromkeys(layer_ids)) or [None]
    channels: dict = {layer: {} for layer in layer_ids}
    weights: dict = {}
    times = []
    for node in objects.all("AnimationCurveNode"):
        links_up = up.get(node.props[0], [])
        layer = next((p for p, _ in links_up if p in channels), None)
        if layer is None and layer_ids != [None]:
            continue
        target = next(((p, _LCL[prop]) for p, prop in links_up if prop in _LCL), None)
        weight_of = next((p for p, prop in links_up if prop == "Weight" and p in channels), None)
        if target is None and weight_of is None:
            continue
        defaults = _props70(node)
        names = ["d|X", "d|Y", "d|Z"] if target is not None else ["d|Weight"]
        axes: list = [defaults.get(name, [None])[0] for name in names]
        for curve_id, prop in down.get(node.props[0], []):
            curve = by_id.get(curve_id)
            if prop not in names or curve is None:
                continue
            keys = curve_keys(curve, unit)
            if keys is not None:
                axes[names.index(prop)] = keys
                if target is not None:
                    times += [int(keys.ticks[0]), int(keys.ticks[-1])]
        if target is not None:
            channels[layer][target] = axes
        elif isinstance(axes[0], Keys):
            weights[weight_of] = axes[0]
    if not any(channels.values()):
        return None
    layers = []
    for layer in layer_ids:
        props = _props70(by_id[layer]) if layer is not None else {}
        layers.append(_Layer(channels[layer], int(props.get("BlendMode", [0])[0]),
                             float(np.clip(float(props.get("Weight", [100.0])[0]) / 100.0, 0.0, 1.0)),
                             weights.get(layer), not int(props.get("RotationAccumulationMode", [0])[0]),
                             not int(props.get("ScaleAccumulationMode", [0])[0])))
    # the stack's span, within its keys' (a frame past the last key would hold it) unless a curve goes on there
    span = _props70(stack)
    first, last = min(times, default=0), max(times, default=0)
    keys = [axis for layer in layers for axes in layer.channels.values() for axis in axes if isinstance(axis, Keys)]
    low = int(round(span.get("LocalStart", [first / unit])[0] * unit))
    start = min(max(low, first) if not any(k.extends(False) for k in keys) else low, last)
    high = int(round(span.get("LocalStop", [last / unit])[0] * unit))
    stop = min(high, last) if not any(k.extends(True) for k in keys) else high
    return _Curves(layers, start, max(stop, start))


def _layered(curves: _Curves, model: int, key: str, static: np.ndarray, t: np.ndarray, order: str) -> np.ndarray:
    """(T, 3) a model's translation, Euler rotation (in its `order`) or scaling (`key` 'T', 'R', 'S') at times
    `t`, its layers combined as the FBX SDK does: the base layer's curves (else the property's `static`
    value), then each other layer's by its blend mode and weight (additive: added, its rotation turned after
    and its scaling multiplied in; override passthrough: blended by the weight; override: replaced)."""
    out = np.broadcast_to(static, (len(t), 3)).copy()
    for k, layer in enumerate(curves.layers):
        axes = layer.channels.get((model, key))
        if axes is None:
            continue
        value = _sampled(axes, static if k == 0 else np.full(3, 1.0 if key == "S" else 0.0), t)
        if k == 0 or layer.mode not in (0, 2):
            out = value
            continue
        w = layer.weight_keys.at(t) / 100.0 if layer.weight_keys is not None else np.full(len(t), layer.weight)
        w = np.where(w > 0.99999, 1.0, np.clip(w, 0.0, 1.0))[:, None]
        if key == "R" and layer.compose_rotation:
            now = Rotation.from_euler(order, _ordered(out, order), degrees=True)
            more = Rotation.from_euler(order, _ordered(value, order), degrees=True)
            turned = now * _slerp(Rotation.identity(len(t)), more, w[:, 0]) if layer.mode == 0 else \
                _slerp(now, more, w[:, 0])
            with warnings.catch_warnings():  # a gimbal lock's angles are one of its equal answers
                warnings.simplefilter("ignore", UserWarning)
                angles = turned.as_euler(order, degrees=True)
            out = angles[:, [order.index(a) for a in "xyz"]]
        elif key == "S" and layer.compose_scale:
            out = out * _power(value, w) if layer.mode == 0 else _power(out, 1.0 - w) * _power(value, w)
        else:
            out = out + value * w if layer.mode == 0 else out * (1.0 - w) + value * w
    return out


def _ordered(angles: np.ndarray, order: str) -> np.ndarray:
    """Euler angles about x, y, z reordered as `order` turns about them (scipy's extrinsic sequence)."""
    return angles[:, ["xyz".index(a) for a in order]]


def _slerp(a: Rotation, b: Rotation, w: np.ndarray) -> Rotation:
    """Rotations `w` of the way from `a` to `b` (the shorter way), per frame."""
    return a * Rotation.from_rotvec((a.inv() * b).as_rotvec() * w[:, None])


def _power(v: np.ndarray, e: np.ndarray) -> np.ndarray:
    """Scalings raised to weights as the FBX SDK blends them: |v|^e with v's sign, 1 at weight 0."""
    return np.where(e <= 0, 1.0, np.where(e >= 1, v, np.sign(v) * np.abs(v) ** np.clip(e, 1e-12, 1.0)))


def _sampled(axes: list, static: np.ndarray, t: np.ndarray) -> np.ndarray:
    """(T, 3) a channel's values at times `t` (FBX ticks): its curves, else its curve node's defaults, else
    `static`."""
    out = np.broadcast_to(static, (len(t), 3)).copy()
    for k, axis in enumerate(axes):
        if isinstance(axis, Keys):
            out[:, k] = axis.at(t)
        elif axis is not None:
            out[:, k] = float(axis)
    return out


#: KeyAttrFlags' bits (the FBX SDK's FbxAnimCurveDef): interpolation, tangent mode, weights.
_CONSTANT, _LINEAR, _CUBIC = 0x2, 0x4, 0x8
_CONSTANT_NEXT, _TCB, _USER = 0x100, 0x200, 0x400
_CLAMP, _TIME_INDEPENDENT, _CLAMP_PROGRESSIVE = 0x1000, 0x2000, 0x4000
_WEIGHTED_RIGHT, _WEIGHTED_NEXT_LEFT = 0x1000000, 0x2000000
#: A key's interpolation to the next: its value held, the next's held, a straight line, a Bezier curve.
_HOLD, _HOLD_NEXT, _STRAIGHT, _BEZIER = range(4)


class Keys(NamedTuple):
    """An animation curve's keys: `ticks` (K,) FBX time, `values` (K,), each key's interpolation to the next
    (`mode`, `_HOLD`...) and its Bezier handles to the left and right as (time in seconds, value) from the key;
    `before` and `after`, how it goes on outside its keys (its Pre- and Post-Extrapolation: 'C' constant, 'K'
    along its end key's tangent, 'R' repeated, 'M' mirrored, 'A' repeated from where the last repeat ended) and
    how many times (-1: for ever)."""

    ticks: np.ndarray
    values: np.ndarray
    mode: np.ndarray
    left: np.ndarray
    right: np.ndarray
    before: tuple = ("C", -1)
    after: tuple = ("C", -1)

    def extends(self, after: bool) -> bool:
        """Whether the curve moves on after (else before) its keys."""
        mode, count = self.after if after else self.before
        return mode != "C" and count != 0 and len(self.values) > 1

    def at(self, t: np.ndarray) -> np.ndarray:
        """The curve's values at times `t` (ticks), extrapolated outside its keys as the FBX SDK does."""
        t = np.asarray(t, dtype=np.float64)
        first, last = self.ticks[0], self.ticks[-1]
        out = self._between(np.clip(t, first, last))
        for pre, outside in ((True, t < first), (False, t > last)):
            if outside.any():
                out[outside] = self._outside(t[outside], pre)
        return out

    def _between(self, t: np.ndarray) -> np.ndarray:
        v, ticks = self.values, self.ticks
        if not (self.mode[:-1] != _STRAIGHT).any():  # straight lines only (a baked motion's): at once
            return np.interp(t, ticks, v)
        after = np.searchsorted(ticks, t, side="right")
        k = np.clip(after - 1, 0, len(v) - 1)
        n = np.minimum(k + 1, len(v) - 1)
        span = (ticks[n] - ticks[k]).astype(np.float64)
        u = np.divide(t - ticks[k], span, out=np.zeros(len(t)), where=span > 0)
        out = np.where(self.mode[k] == _HOLD_NEXT, v[n], v[k])
        line = self.mode[k] == _STRAIGHT
        out[line] = (v[k] + u * (v[n] - v[k]))[line]
        curve = (self.mode[k] == _BEZIER) & (span > 0)
        if curve.any():
            seconds = span[curve] / TICKS_PER_SECOND
            kc, nc = k[curve], n[curve]
            out[curve] = bezier(u[curve], self.right[kc, 0] / seconds, 1.0 - self.left[nc, 0] / seconds, v[kc],
                                v[kc] + self.right[kc, 1], v[nc] - self.left[nc, 1], v[nc])
        return np.where((after == 0) | (u <= 0), v[k], np.where(after >= len(v), v[-1], out))

    def _outside(self, t: np.ndarray, pre: bool) -> np.ndarray:
        """Values at times before (`pre`) or after the keys."""
        mode, count = self.before if pre else self.after
        end = 0 if pre else -1
        value = np.full(len(t), self.values[end])
        if mode == "K":  # along the end key's tangent
            dx, dy = self.right[0] if pre else self.left[-1]
            if not (self.mode[:-1] != _STRAIGHT).any():  # the end line's
                dx, dy = np.diff(self.ticks[:2] if pre else self.ticks[-2:]) / TICKS_PER_SECOND, \
                    np.diff(self.values[:2] if pre else self.values[-2:])
                dx, dy = float(dx[0]), float(dy[0])
            return value + (dy / dx * (t - self.ticks[end]) / TICKS_PER_SECOND if dx > 0 else 0.0)
        first, last = float(self.ticks[0]), float(self.ticks[-1])
        duration = last - first
        if mode not in "RMA" or count == 0 or duration < 1:
            return value
        delta = first - t if pre else t - last
        repeat = np.floor(delta / duration)
        into = delta - repeat * duration
        if count > 0:  # held where the repeats end
            into = np.where(repeat >= count, duration, into)
            repeat = np.minimum(repeat, count - 1)
        if mode == "M":
            into = np.where(repeat * 0.5 - np.floor(repeat * 0.5) <= 0.25, duration - into, into)
        value = self._between(first + (duration - into if pre else into))
        if mode == "A":
            step = self.values[-1] - self.values[0]
            value = value + (-step if pre else step) * (repeat + 1.0)
        return value


def bezier(u, x1, x2, y0, y1, y2, y3) -> np.ndarray:
    """The values of cubic Bezier curves from (0, y0) to (1, y3), their handles at (x1, y1) and (x2, y2), at
    `u` along their spans (the curve's x, the parameter found by Newton's method), as animation curves are."""
    a, b, c = 3.0 * x1 - 3.0 * x2 + 1.0, 3.0 * x2 - 6.0 * x1, 3.0 * x1
    s = np.asarray(u, dtype=np.float64).copy()
    for _ in range(12):
        slope = (3.0 * a * s + 2.0 * b) * s + c
        step = np.divide(((a * s + b) * s + c) * s - u, slope, out=np.zeros_like(s), where=np.abs(slope) > 1e-12)
        s = np.clip(s - step, 0.0, 1.0)
    r = 1.0 - s
    return r ** 3 * y0 + 3.0 * (r * r * s * y1 + r * s * s * y2) + s ** 3 * y3


def curve_keys(curve: Node, unit: float = 1.0) -> Keys | None:
    """The keys of an AnimationCurve (None where it has none, or times and values of other lengths): each key's
    interpolation and tangents from its KeyAttrFlags and KeyAttrDataFloat (run-length coded by KeyAttrRefCount;
    ASCII files write the floats' bits as integers), as the FBX SDK evaluates them: Maya's user tangents and
    weights as written, auto tangents solved from the neighbouring keys (their clamping and bias), TCB ones
    from tension, continuity and bias; a curve without them (or damaged ones) straight from key to key."""
    t, v = curve.child("KeyTime"), curve.child("KeyValueFloat")
    if t is None and curve.child("Key") is not None:  # FBX 6's
        keys = _fbx6_keys(curve, unit)
    elif t is None or v is None or not t.props or not v.props or not 0 < len(t.props[0]) == len(v.props[0]):
        return None
    else:
        keys = _fbx7_keys(t.props[0], v.props[0], curve, unit)
    return keys._replace(before=_extrapolation(curve, "Pre-Extrapolation"),
                         after=_extrapolation(curve, "Post-Extrapolation"))


def _fbx7_keys(times: np.ndarray, values: np.ndarray, curve: Node, unit: float) -> Keys:
    """`curve_keys` of an FBX 7 curve's KeyTime and KeyValueFloat and its key attributes."""
    ticks = np.asarray(times).astype(np.int64)
    if unit != 1.0:  # FBX 8's ticks (`time_unit`) in FBX 7's
        ticks = np.round(ticks * unit).astype(np.int64)
    values = np.asarray(values).astype(np.float64)
    K = len(values)
    unsorted = K > 1 and bool(np.any(np.diff(ticks) < 0))
    if unsorted:  # keys out of order (a damaged file's): sorted, and taken straight from key to key
        order = np.argsort(ticks, kind="stable")
        ticks, values = ticks[order], values[order]
    found = [curve.child(name) for name in ("KeyAttrFlags", "KeyAttrDataFloat", "KeyAttrRefCount")]
    arrays = [np.asarray(node.props[0]) if node is not None and node.props else None for node in found]
    flags_in, data_in, refs_in = arrays
    if (unsorted or flags_in is None or data_in is None or refs_in is None or len(flags_in) != len(refs_in)
            or len(data_in) != 4 * len(refs_in) or np.asarray(refs_in).astype(np.int64).clip(0).sum() < K):
        none = np.broadcast_to(np.zeros(2), (K, 2))  # straight lines need no handles
        return Keys(ticks, values, np.full(K, _STRAIGHT, dtype=np.int8), none, none)
    refs = refs_in.astype(np.int64).clip(0)
    flags = np.repeat(flags_in.astype(np.int64) & 0xFFFFFFFF, refs)[:K]
    if np.issubdtype(data_in.dtype, np.integer):  # ASCII: the floats' bits
        bits = (data_in.astype(np.int64) & 0xFFFFFFFF).astype(np.uint32)
    else:
        bits = data_in.astype(np.float32).view(np.uint32)
    bits = np.repeat(bits.reshape(-1, 4), refs, axis=0)[:K]
    return _tangents(ticks, values, flags, bits.view(np.float32).astype(np.float64), bits)


def _extrapolation(curve: Node, name: str) -> tuple[str, int]:
    """A curve's (mode, repetitions) before or after its keys (`Keys`): its node `name`'s Type (a letter, an
    ASCII file's bare word or a binary one's byte) and Repetition; ('C', -1) where it has none."""
    node = curve.child(name)
    kind = node.child("Type") if node is not None else None
    times = node.child("Repetition") if node is not None else None
    value = kind.props[0] if kind is not None and kind.props else "C"
    mode = chr(int(value)) if isinstance(value, (int, np.integer)) else str(value)[:1]
    count = times.props[0] if times is not None and times.props else -1
    return (mode if mode in ("C", "K", "R", "M", "A") else "C", int(count) if isinstance(count, (int, np.integer))
            else -1)


def _tangents(ticks, values, flags, data, bits) -> Keys:
    """Keys of curves' values and key attributes, each key's flags (K,), its four attribute floats (K, 4) and
    their bits (weights are packed in the third's)."""
    K = len(values)
    seconds = ticks / TICKS_PER_SECOND
    dt_next = np.append(np.diff(seconds), 0.0)
    dt_prev = np.insert(np.diff(seconds), 0, 0.0)
    v_next, v_prev = np.append(values[1:], values[-1]), np.insert(values[:-1], 0, values[0])
    third = 0.333333
    constant = (flags & _CONSTANT) != 0
    cubic = ~constant & ((flags & _CUBIC) != 0)
    straight = ~constant & ~cubic
    weight_right = np.where(cubic & ((flags & _WEIGHTED_RIGHT) != 0), (bits[:, 2] & 0xFFFF) * 1e-4, third)
    next_weight_left = np.where(cubic & ((flags & _WEIGHTED_NEXT_LEFT) != 0), (bits[:, 2] >> 16) * 1e-4, third)
    line = np.divide(v_next - values, dt_next, out=np.zeros(K), where=dt_next > 0)
    slope_right = np.where(cubic, data[:, 0], np.where(straight, line, 0.0))
    tcb = cubic & ((flags & _TCB) != 0)
    next_slope_left = np.where(cubic & ~tcb, data[:, 1], np.where(straight, line, 0.0))
    slope_left = np.insert(next_slope_left[:-1], 0, 0.0)  # a key's left: what the key before it gives
    weight_left = np.insert(next_weight_left[:-1], 0, third)
    has_prev, has_next = dt_prev > 0, dt_next > 0
    left_line = np.divide(values - v_prev, dt_prev, out=np.zeros(K), where=has_prev)
    if tcb.any():
        tension, continuity, bias = data[:, 0], data[:, 1], data[:, 2]
        factor = np.where(has_prev & has_next, 0.5, 1.0) * (1.0 - tension)
        tcb_left = factor * ((1 + bias) * (1 - continuity) * left_line + (1 - bias) * (1 + continuity) * line)
        tcb_right = factor * ((1 + bias) * (1 + continuity) * left_line + (1 - bias) * (1 - continuity) * line)
        slope_left, slope_right = np.where(tcb, tcb_left, slope_left), np.where(tcb, tcb_right, slope_right)
    auto = cubic & ~tcb & ((flags & _USER) == 0)
    if auto.any():
        both = has_prev & has_next
        one = np.abs(slope_left + slope_right) <= 1e-4
        common = _auto_slope(seconds, values, dt_prev, dt_next, weight_left, weight_right, slope_right, flags)
        own_left = _auto_slope(seconds, values, dt_prev, dt_next, weight_left, weight_right, -slope_left, flags)
        edge_left = _edge_slope(left_line, values - v_prev, -slope_left, flags)
        edge_right = _edge_slope(line, v_next - values, slope_right, flags)
        new_left = np.where(both, np.where(one, common, own_left),
                            np.where(has_prev, edge_left, np.where(has_next, edge_right, 0.0)))
        new_right = np.where(both, common, np.where(has_prev, edge_left, np.where(has_next, edge_right, 0.0)))
        slope_left, slope_right = np.where(auto, new_left, slope_left), np.where(auto, new_right, slope_right)
    mode = np.where(constant, np.where((flags & _CONSTANT_NEXT) != 0, _HOLD_NEXT, _HOLD),
                    np.where(cubic, _BEZIER, _STRAIGHT)).astype(np.int8)
    return _handled(ticks, values, mode, slope_left, slope_right, weight_left, np.where(cubic, weight_right, third))


def _handled(ticks, values, mode, slope_left, slope_right, weight_left, weight_right) -> Keys:
    """Keys of their slopes and weights to the left and right: Bezier handles a weight of the span to the
    neighbouring key long (none at the ends), along the slope."""
    dt = np.diff(ticks / TICKS_PER_SECOND)
    left_dx = np.insert(np.maximum(dt, 0.0), 0, 0.0) * weight_left
    right_dx = np.append(np.maximum(dt, 0.0), 0.0) * weight_right
    return Keys(ticks, values, mode, np.stack([left_dx, left_dx * slope_left], axis=1),
                np.stack([right_dx, right_dx * slope_right], axis=1))


#: The numbers an FBX 6 key may carry after its time and value, as `_fbx6_key` names them.
_FBX6_FIELDS = ("slope_right", "next_left", "weight_right", "next_weight")


def _fbx6_key(tokens: list, at: int, key_ver: int) -> tuple[int, int, dict]:
    """The layout of the FBX 6 key starting at `tokens[at]`: its length in tokens, its interpolation (`_HOLD`...)
    and {field (`_FBX6_FIELDS`, or 'automatic': 1): its offset in the key}. ValueError where it breaks the
    grammar (`_fbx6_keys`)."""
    def letter(k):
        if k >= len(tokens) or not isinstance(tokens[k], str):
            raise ValueError(f"no letter at token {k}")
        return tokens[k]

    def number(k):
        if k >= len(tokens) or isinstance(tokens[k], str):
            raise ValueError(f"no number at token {k}")
        return k - at

    number(at), number(at + 1)
    kind, k, fields = letter(at + 2), at + 3, {}
    if kind == "U":
        slope_mode, weights = letter(k), 1
        k += 1
        if slope_mode in ("s", "b"):
            fields.update(slope_right=number(k), next_left=number(k + 1))
            k, weights = k + 2, 0 if key_ver == 4003 else 1
        elif slope_mode in ("a", "p", "q", "t", "d"):
            fields["automatic"] = 1
            k += {"a": 0, "p": 2, "q": 2, "t": 3, "d": 1}[slope_mode]
            weights = {"a": 0 if key_ver <= 4004 else 1, "p": 1 if key_ver <= 4004 else 2,
                       "q": 1 if key_ver <= 4004 else 2, "t": 0, "d": 1}[slope_mode]
        else:
            raise ValueError(f"a slope mode {slope_mode!r}")
        for _ in range(weights):
            weight_mode = letter(k)
            k += 1
            if weight_mode == "a":
                fields.update(weight_right=number(k), next_weight=number(k + 1))
                k += 2
            elif weight_mode in ("l", "r"):
                fields["next_weight" if weight_mode == "l" else "weight_right"] = number(k)
                k += 1
            elif weight_mode not in ("n", "c"):
                raise ValueError(f"a weight mode {weight_mode!r}")
        return k - at, _BEZIER, fields
    if kind == "C":
        if key_ver >= 4004:
            return k + 1 - at, _HOLD_NEXT if letter(k) == "n" else _HOLD, fields
        return k - at, _HOLD, fields
    if kind == "L":
        return k - at, _STRAIGHT, fields
    raise ValueError(f"a key kind {kind!r}")


def _fbx6_keys(curve: Node, unit: float = 1.0) -> Keys:
    """The keys of an FBX 6 channel: its 'Key' a run of time, value and interpolation letter, then that letter's
    parameters ('U' cubic: its slope mode ('s'/'b' two slopes; 'a', 'p', 'q', 't', 'd' automatic) and weight
    modes; 'L' linear; 'C' constant, its 'n' the next key's value), as the FBX SDK wrote them by KeyVer
    (4003 to 4005); automatic slopes solved from the neighbouring keys, as ufbx does; its times `unit` FBX 7
    ticks each (`time_unit`). ValueError where the run breaks that grammar."""
    tokens = list(curve.child("Key").props)
    if len(tokens) == 1 and isinstance(tokens[0], np.ndarray):
        tokens = tokens[0].tolist()
    version = curve.child("KeyVer")
    key_ver = int(version.props[0]) if version is not None and version.props else 4005
    third = 0.333333
    size, mode, fields = _fbx6_key(tokens, 0, key_ver)
    # a run of keys all laid out as the first (a baked motion's): read at once
    grid = np.array(tokens, dtype=object).reshape(-1, size) if len(tokens) % size == 0 else None
    letters = [j for j in range(size) if isinstance(tokens[j], str)]
    if grid is not None and all((grid[:, j] == tokens[j]).all() for j in letters) and not any(
            isinstance(x, str) for j in range(size) if j not in letters for x in grid[:, j]):
        table = np.zeros((len(grid), 8))
        table[:, 5:7] = third
        table[:, 2], table[:, 7] = mode, fields.pop("automatic", 0)
        for column, at in ((0, 0), (1, 1)) + tuple((_FBX6_FIELDS.index(f) + 3, j) for f, j in fields.items()):
            table[:, column] = grid[:, at].astype(np.float64)
    else:
        rows, at = [], 0  # time, value, mode, right slope, next left slope, right weight, next left weight, auto
        while at < len(tokens):
            size, mode, fields = _fbx6_key(tokens, at, key_ver)
            row = [float(tokens[at]), float(tokens[at + 1]), mode, 0.0, 0.0, third, third, fields.pop("automatic", 0)]
            for field, offset in fields.items():
                row[_FBX6_FIELDS.index(field) + 3] = float(tokens[at + offset])
            rows.append(row)
            at += size
        table = np.array(rows, dtype=np.float64)
    order = np.argsort(table[:, 0], kind="stable")
    table = table[order]
    ticks, values, mode = np.round(table[:, 0] * unit).astype(np.int64), table[:, 1], table[:, 2].astype(np.int64)
    slope_right, next_left, weight_right, next_weight = table[:, 3], table[:, 4], table[:, 5], table[:, 6]
    automatic = table[:, 7] > 0
    seconds = ticks / TICKS_PER_SECOND
    dt = np.diff(seconds)
    line = np.divide(np.diff(values), dt, out=np.zeros(len(dt)), where=dt > 0)
    straight = mode[:-1] == _STRAIGHT
    slope_right[:-1] = np.where(straight, line, slope_right[:-1])
    next_left[:-1] = np.where(straight, line, next_left[:-1])
    slope_left = np.insert(next_left[:-1], 0, 0.0)
    weight_left = np.insert(next_weight[:-1], 0, third)
    if automatic.any():
        dt_prev, dt_next = np.insert(dt, 0, 0.0), np.append(dt, 0.0)
        solved = _auto_slope(seconds, values, dt_prev, dt_next, weight_left, weight_right, np.zeros(len(values)),
                             _CLAMP_PROGRESSIVE | _TIME_INDEPENDENT)
        solved[0] = 0.0
        slope_left, slope_right = np.where(automatic, solved, slope_left), np.where(automatic, solved, slope_right)
    return _handled(ticks, values, mode, slope_left, slope_right, weight_left, weight_right)


def _auto_slope(seconds, values, dt_prev, dt_next, weight_left, weight_right, bias, flags) -> np.ndarray:
    """Auto tangents' slopes at keys between two others (as the FBX SDK solves them: clamped flat at a key of
    its neighbour's value; the mean slope, blended with the sides' unless time-independent, leaning to the side
    `bias` (percent) says; progressive clamping against overshoot)."""
    v_prev, v_next = np.insert(values[:-1], 0, values[0]), np.append(values[1:], values[-1])
    with np.errstate(divide="ignore", invalid="ignore"):
        span = dt_prev + dt_next
        slope = np.where(span > 0, (v_next - v_prev) / span, 0.0)
        left, right = (values - v_prev) / dt_prev, (v_next - values) / dt_next
        delta = np.where(span > 0, dt_prev / span, 0.0)
        blended = slope * 0.5 + (left * (1.0 - delta) + right * delta) * 0.5
        weight = np.abs(bias) / 100.0
        target = np.where(bias > 0, right, left)
        biased = blended * (1.0 - weight) + target * weight
        sign = np.where(np.abs(target - blended) > 1e-5, target - blended, bias) > 0
        biased = biased + np.where(weight > 5.0, (weight - 5.0) ** 2 * np.where(sign, 40.0, -40.0), 0.0)
        biased = np.where(weight > 1e-4, biased, blended)
        slope = np.where((flags & _TIME_INDEPENDENT) != 0, slope, biased)
        sign = np.where(slope >= 0, 1.0, -1.0)
        max_left = sign * (values - v_prev) / (weight_left * dt_prev)
        max_right = sign * (v_next - values) / (weight_right * dt_next)
        limit = np.minimum(np.where(max_left > 0, max_left, 0.0), np.where(max_right > 0, max_right, 0.0))
    slope = np.where((flags & _CLAMP_PROGRESSIVE) != 0, sign * np.minimum(np.abs(slope), limit), slope)
    flat = np.minimum(np.abs(v_prev - values), np.abs(v_next - values)) <= 0
    return np.where(((flags & _CLAMP) != 0) & flat, 0.0, np.nan_to_num(slope))


def _edge_slope(line, step, bias, flags) -> np.ndarray:
    """Auto tangents' slopes at a curve's first or last key: the line to its one neighbour (`line`, the values'
    `step` to it), flat where clamped to an equal value or clamped progressively."""
    weight = np.abs(bias) / 100.0 - 5.0
    slope = line + np.where(((flags & _TIME_INDEPENDENT) == 0) & (weight > 0),
                            weight ** 2 * np.where(bias > 0, 40.0, -40.0), 0.0)
    flat = ((flags & _CLAMP_PROGRESSIVE) != 0) | (((flags & _CLAMP) != 0) & (np.abs(step) <= 0))
    return np.where(flat, 0.0, slope)


def read_fbx(path: Path, src: str, take: str | None = None) -> Skeleton:
    """The skeleton and motion of the FBX `path` (module docstring), as `formats.bvh.read_skeleton` gives a
    BVH's: its joints' frames turned to the world's at rest (the rest its zero pose), so `core.retarget` reads it
    as a BVH; of a file of several animation stacks, the one named `take` (`chosen_take`; default: the first).
    InputError naming `src` for a file that is no FBX, a damaged one, or one without a skeleton."""
    parsed = parsed_file(path, src)
    try:
        return _read(parsed, src, take)
    except InputError:
        raise
    except (IndexError, KeyError, TypeError, ValueError, AttributeError) as exc:
        raise InputError(f"{src}: its FBX objects are not as FBX writes them ({type(exc).__name__}: "
                         f"{str(exc)[:80]})") from None


class Scene(NamedTuple):
    """An FBX 7's objects as its readers take them: its top-level nodes by name, its Objects, its connections
    (tuples), its Models by id, each Model's parent Model, the Models parents first, its frame rate, its
    animation stacks, the one read (None: none) and that one's curves (None: no curve)."""

    top: dict
    objects: Node
    links: list
    models: dict
    parent: dict
    order: list
    fps: float
    stacks: list
    stack: Node | None
    curves: _Curves | None


def read_scene(data: bytes | tuple, src: str, take: str | None = None) -> Scene:
    """The `Scene` of an FBX's bytes, or of its (version, nodes) as `read_nodes` gives them (FBX 6's as FBX 7's,
    `_from_fbx6`), its animation the stack named `take` (`chosen_take`); InputError naming `src` for FBX 5 and
    older or a frame rate that is none."""
    version, nodes = read_nodes(data, src) if isinstance(data, bytes) else data
    header = next((n.child("FBXVersion") for n in nodes if n.name == "FBXHeaderExtension"), None)
    if header is not None and header.props and isinstance(header.props[0], (int, np.integer)):
        version = int(header.props[0])  # a binary FBX 5's header says 3000
    if version < 6000:
        raise InputError(f"{src}: expected FBX 6 or 7 (2006 and later), got FBX {version // 1000}."
                         f"{version % 1000 // 100}: export it again as a newer FBX, or as a BVH")
    if version < 7000:
        nodes = _from_fbx6(nodes)
    top = {n.name: n for n in nodes}
    objects = top.get("Objects", Node("Objects", [], []))
    links = [tuple(c.props) for c in top.get("Connections", Node("Connections", [], [])).all("C") if len(c.props) >= 3]
    models = {m.props[0]: m for m in objects.all("Model") if len(m.props) >= 3}
    model_parent = {child: parent for kind, child, parent, *_ in links if kind == "OO" and child in models
                    and parent in models}
    depth = node_depths(list(models), model_parent)
    model_parent = {c: p for c, p in model_parent.items() if depth[p] < depth[c]}  # a damaged file's cycle cut
    order = sorted(models, key=lambda i: depth[i])
    settings = _props70(top.get("GlobalSettings"))
    mode = int(settings.get("TimeMode", [0])[0])
    fps = float(settings.get("CustomFrameRate", [30.0])[0]) if mode == 14 else _TIME_MODES.get(mode, 30.0)
    if not (np.isfinite(fps) and fps > 0):
        raise InputError(f"{src}: expected a frame rate over 0 in its CustomFrameRate, got {fps:g}")
    stacks = objects.all("AnimationStack")
    chosen = chosen_take([_name(s) for s in stacks], take, src)
    stack = stacks[chosen] if chosen is not None else None
    return Scene(top, objects, links, models, model_parent, order, fps, stacks, stack,
                 _animation(objects, links, stack, time_unit(top)))


def time_unit(top: dict) -> float:
    """FBX 7 ticks (`TICKS_PER_SECOND`) per tick of a file's key times: 1, but for files of FBX 8's ticks
    (141,120,000 a second), which a header of version 1004 or later opts into by a TCDefinition other than 127
    (FBX 8 files by default)."""
    header = top.get("FBXHeaderExtension", Node("FBXHeaderExtension", [], []))
    version, header_version = header.child("FBXVersion"), header.child("FBXHeaderVersion")
    flags = header.child("OtherFlags")
    tc = flags.child("TCDefinition") if flags is not None else None
    new = bool(version is not None and version.props and int(version.props[0]) >= 8000)
    if tc is not None and tc.props and header_version is not None and header_version.props \
            and int(header_version.props[0]) >= 1004:
        new = int(tc.props[0]) != 127
    return TICKS_PER_SECOND / 141_120_000 if new else 1.0


def _from_fbx6(nodes: list[Node]) -> list[Node]:
    """FBX 6's nodes as FBX 7 holds the same (ids for the names FBX 6 links objects by, Properties70 for its
    Properties60, an animation stack, layer, curve nodes and curves for each Take's channels, the GlobalSettings
    of its Objects or its Version5 Settings' frame rate), for the FBX 7 reading to take as they are."""
    top = {n.name: n for n in nodes}
    objects = top.get("Objects", Node("Objects", [], []))
    ids: dict = {}

    def identity(name) -> int:
        return ids.setdefault(name, 1_000_000 + len(ids))

    def props70(node: Node) -> Node:  # Property: name, type, flags, values -> P: name, type, label, flags, values
        block = node.child("Properties60")
        entries = [Node("P", [e.props[0], e.props[1], "", *e.props[2:]], []) for e in
                   (block.all("Property") if block is not None else []) if len(e.props) >= 3]
        return Node("Properties70", [], entries)

    out: list[Node] = []
    for node in objects.children:
        if node.name == "Model" and len(node.props) >= 2:
            out.append(Node("Model", [identity(node.props[0]), node.props[0], node.props[1]],
                            [props70(node)] + [c for c in node.children if c.name != "Properties60"]))
        elif node.name == "Pose" and len(node.props) >= 2:
            poses = []
            for pose in node.all("PoseNode"):
                at, matrix = pose.child("Node"), pose.child("Matrix")
                if at is not None and matrix is not None and at.props:
                    values = matrix.props[0] if len(matrix.props) == 1 else np.array(matrix.props, dtype=np.float64)
                    poses.append(Node("PoseNode", [], [Node("Node", [identity(at.props[0])], []),
                                                       Node("Matrix", [values], [])]))
            out.append(Node("Pose", [identity(node.props[0]), node.props[0], node.props[1]], poses))
    settings = objects.child("GlobalSettings") or top.get("GlobalSettings")
    rate = next((s.child("FrameRate") for v in [top.get("Version5")] if v is not None
                 for s in [v.child("Settings")] if s is not None), None)
    if settings is not None and settings.child("Properties60") is not None:
        settings = Node("GlobalSettings", [], [props70(settings)])
    elif rate is not None and rate.props and float(rate.props[0]) > 0:
        settings = Node("GlobalSettings", [], [Node("Properties70", [], [
            Node("P", ["TimeMode", "enum", "", "", 14], []),
            Node("P", ["CustomFrameRate", "double", "", "", float(rate.props[0])], [])])])
    links = [Node("C", [c.props[0], identity(c.props[1]), identity(c.props[2])], [])
             for c in top.get("Connections", Node("Connections", [], [])).all("Connect")
             if len(c.props) >= 3 and c.props[1] in ids and c.props[2] in ids]
    takes = top.get("Takes", Node("Takes", [], []))
    for take in takes.all("Take"):
        stack, layer = identity(("stack", take.props[0])), identity(("layer", take.props[0]))
        span = take.child("LocalTime")
        span_props = [Node("P", [name, "KTime", "", "", value], []) for name, value in
                      zip(("LocalStart", "LocalStop"), span.props if span is not None else [])]
        out += [Node("AnimationStack", [stack, f"{take.props[0]}\x00\x01AnimStack", ""],
                     [Node("Properties70", [], span_props)]),
                Node("AnimationLayer", [layer, "BaseLayer\x00\x01AnimLayer", ""], [])]
        links.append(Node("C", ["OO", layer, stack], []))
        for model in take.all("Model"):
            if not model.props or model.props[0] not in ids:
                continue
            transform = next((c for c in model.all("Channel") if c.props[:1] == ["Transform"]), None)
            for channel in transform.all("Channel") if transform is not None else []:
                prop = {"T": "Lcl Translation", "R": "Lcl Rotation", "S": "Lcl Scaling"}.get(channel.props[0])
                if prop is None:
                    continue
                curve_node = identity((take.props[0], model.props[0], prop))
                axes = [a for a in channel.all("Channel") if a.props[:1] in (["X"], ["Y"], ["Z"])]
                defaults = [Node("P", [f"d|{a.props[0]}", "Number", "", "A", a.child("Default").props[0]], [])
                            for a in axes if a.child("Default") is not None and a.child("Default").props]
                out.append(Node("AnimationCurveNode", [curve_node, f"{channel.props[0]}\x00\x01AnimCurveNode", ""],
                                [Node("Properties70", [], defaults)]))
                links += [Node("C", ["OO", curve_node, layer], []),
                          Node("C", ["OP", curve_node, ids[model.props[0]], prop], [])]
                for axis in axes:
                    if axis.child("Key") is not None:
                        curve = identity((take.props[0], model.props[0], prop, axis.props[0]))
                        out.append(Node("AnimationCurve", [curve, "\x00\x01AnimCurve", ""], axis.children))
                        links.append(Node("C", ["OP", curve, curve_node, f"d|{axis.props[0]}"], []))
    kept = [n for n in nodes if n.name not in ("Objects", "Connections", "Takes", "GlobalSettings")]
    return kept + ([settings] if settings is not None else []) + [Node("Objects", [], out),
                                                                   Node("Connections", [], links)]


def model_transforms(scene: Scene, t: np.ndarray) -> tuple[dict, dict]:
    """({Model id: (T, 4, 4) its transform in the world at times `t`, FBX ticks}, {Model id: (4, 4) at rest,
    its properties' own values}) of every Model of `scene` (`placed`: its properties over the file's template,
    its curves sampled)."""
    template = model_template(scene.top)
    curves = scene.curves
    world: dict = {}
    rest: dict = {}
    props_of = {i: {**template, **_props70(scene.models[i])} for i in scene.order}
    compensated = {scene.parent.get(i) for i, props in props_of.items()  # parents whose unscaled transforms count
                   if int(props.get("InheritType", [1])[0]) in (0, 2)}
    for i in scene.order:
        props = props_of[i]
        static = [_vector(props, "Lcl Translation", 0.0), _vector(props, "Lcl Rotation", 0.0),
                  _vector(props, "Lcl Scaling", 1.0)]
        p = scene.parent.get(i)
        rest[i] = placed(props, [s[None] for s in static], rest.get(p), i in compensated)
        world[i] = rest[i] if curves is None else placed(
            props, [_layered(curves, i, key, s, t, _rotation_order(props)) for key, s in zip("TRS", static)],
            world.get(p), i in compensated)
    return {i: w.matrix for i, w in world.items()}, {i: w.matrix[0] for i, w in rest.items()}


def _read(data: bytes | tuple, src: str, take: str | None = None) -> Skeleton:
    scene = read_scene(data, src, take)
    models, curves, fps = scene.models, scene.curves, scene.fps
    joints = [i for i, m in models.items() if m.props[2] in ("LimbNode", "Limb", "Root")]
    if not joints:
        raise InputError(f"{src}: expected an FBX of a skeleton (Models of type LimbNode), found "
                         f"{len(models)} Model(s) and no joint: export the character's skeleton with its animation")
    if curves is None:
        log.warning("%s: no animation curves: its one frame is the skeleton as it stands", src)
        t = np.zeros(1)
    else:
        n = int(round((curves.stop - curves.start) / TICKS_PER_SECOND * fps)) + 1
        if n > MAX_FRAMES:
            raise InputError(f"{src}: expected an animation of at most {MAX_FRAMES:,} frames, got {n:,} at {fps:g} "
                             f"fps (its keys span {(curves.stop - curves.start) / TICKS_PER_SECOND:,.0f} s)")
        t = curves.start + np.arange(n) * (TICKS_PER_SECOND / fps)
    world, rest = model_transforms(scene, t)
    bound = _bind_pose(scene.objects, rest)
    rest = bound_rest(rest, bound, scene.order, scene.parent)
    creator = str(scene.top["Creator"].props[:1]) if "Creator" in scene.top else ""
    posed = not bound and curves is not None and "Blender" in creator
    if posed:
        log.warning("%s: an armature Blender wrote without its mesh holds no rest pose (no BindPose): its joints' "
                    "values are the pose of the frame it was exported at (read as below); export the rig with its "
                    "mesh, or as USD or BVH", src)
    skeleton = skeleton_of(joints, {i: _name(models[i]) for i in joints}, scene.parent, scene.order, world, rest,
                           1.0 / fps)._replace(rest_posed=posed)
    return skeleton._replace(take=_name(scene.stack)) if len(scene.stacks) > 1 else skeleton


def chosen_take(names: list[str], take: str | None, src: str, what: str = "animation stacks") -> int | None:
    """The index among a file's animations (`names`; FBX's stacks, glTF's animations) of the one named `take`
    (its case aside where none matches exactly; InputError naming `src` and the animations where none does),
    else the first, the others named in a warning; None where there is none. A file of one is read as it is, a
    `take` of another name warned about."""
    listed = ", ".join(f"'{n}'" for n in names[:6]) + (", ..." if len(names) > 6 else "")
    if take is not None and len(names) > 1:
        found = [i for i, n in enumerate(names) if n == take] or [i for i, n in enumerate(names)
                                                                  if n.lower() == take.lower()]
        if not found:
            raise InputError(f"{src}: expected --take one of its {len(names)} {what} ({listed}), got '{take}'")
        return found[0]
    if take is not None and names != [take]:
        log.warning("%s: holds %s: --take %s left aside", src,
                    f"only {listed}" if names else f"no {what}", take)
    elif len(names) > 1:
        log.warning("%s: holds %d %s (%s): reading '%s', the first (--take NAME reads another)", src,
                    len(names), what, listed, names[0])
    return 0 if names else None


#: The last FBX file parsed: (its bytes' digest, (version, nodes)), so that reading its takes one after another
#: (`garment info`, `bake --take all`) parses it once.
_LAST_PARSED: list = [None, None]


def parsed_file(path: Path, src: str) -> tuple[int, list[Node]]:
    """`read_nodes` of the FBX `path`, parsed again only where its bytes are not the last file's parsed (their
    digest); InputError naming `src` as `read_input` and `read_nodes` give it."""
    data = read_input(path, src)
    key = hashlib.blake2b(data, digest_size=16).digest()
    if _LAST_PARSED[0] == key:
        return _LAST_PARSED[1]
    parsed = read_nodes(data, src)
    _LAST_PARSED[:] = [key, parsed]
    return parsed


def forget_parsed() -> None:
    """Drops the last file parsed (`parsed_file`): the next read parses again (a benchmark's cold reads)."""
    _LAST_PARSED[:] = [None, None]


def animation_takes(path: Path) -> list[str]:
    """The names of the animation stacks of the FBX `path` where it holds several (`--take`), else []; InputError
    naming the file where it is no FBX `read_fbx` reads."""
    src = f"motion '{path}'"
    version, nodes = parsed_file(path, src)
    if 6000 <= version < 7000:
        nodes = _from_fbx6(nodes)
    objects = next((n for n in nodes if n.name == "Objects"), None)
    names = [_name(s) for s in objects.all("AnimationStack")] if objects is not None else []
    return names if len(names) > 1 else []


def node_depths(ids: list, parent: dict) -> dict:
    """{id: its number of ancestors} (going up a cycle stops where it comes round)."""
    depth = {}
    for i in ids:
        d, j, seen = 0, i, {i}
        while j in parent and parent[j] not in seen:
            j = parent[j]
            seen.add(j)
            d += 1
        depth[i] = d
    return depth


def model_template(top: dict) -> dict:
    """{name: values} of the Model template in a file's Definitions (the values a Model leaves out takes)."""
    for kind in top.get("Definitions", Node("Definitions", [], [])).all("ObjectType"):
        if kind.props[:1] == ["Model"]:
            return {k: v for t in kind.all("PropertyTemplate") for k, v in _props70(t).items()}
    return {}


class Placed(NamedTuple):
    """A model's transforms in the world per frame (F, 4, 4): `matrix`; `unscaled`, its scaling left out; `scale`
    (F, 3), the scaling its children inherit where they take it component by component (FBX's InheritType)."""

    matrix: np.ndarray
    unscaled: np.ndarray
    scale: np.ndarray
    scale_from: Placed | None  # the model whose `scale` a child ignoring its parent's scaling takes instead


def placed(props: dict, frames: list, parent: Placed | None, unscaled: bool = True) -> Placed:
    """A model's transforms in the world (`Placed`) from its properties (Properties70 over the file's template)
    and its translation, Euler rotation and scaling per frame (`frames`, each (F, 3)), below `parent`'s (None: at
    the root): FBX's chain T Roff Rp Rpre R Rpost^-1 Rp^-1 Soff Sp S Sp^-1 (pre- and post-rotation and the
    RotationOrder where RotationActive is on, as the FBX SDK reads them), and the parent's scaling inherited
    as the InheritType says: 1 (Maya's transforms, the SDK's default) through the parent's whole matrix; 0 (RrSs)
    component by component, without shear; 2 (Rrs, a Maya joint's segment scale compensation) not the parent's
    own, its translation still scaled by it. unscaled: whether its transform without its scaling is kept (for
    children of InheritType 0 and 2; else `Placed.unscaled` is its `matrix`)."""
    T, R, S = (np.asarray(f, dtype=np.float64) for f in frames)
    rotation_space = bool(int(props.get("RotationActive", [1])[0])) and not int(
        props.get("RotationSpaceForLimitOnly", [0])[0])
    if rotation_space:
        turn = (_euler(_vector(props, "PreRotation", 0.0), "xyz")
                @ _euler(R, _rotation_order(props))
                @ _euler(_vector(props, "PostRotation", 0.0), "xyz").T)
    else:
        turn = _euler(R, "xyz")
    pivot, scale_pivot = _vector(props, "RotationPivot", 0.0), _vector(props, "ScalingPivot", 0.0)
    inner = _vector(props, "ScalingOffset", 0.0) + scale_pivot - pivot - S * scale_pivot
    move = T + _vector(props, "RotationOffset", 0.0) + pivot + (turn @ inner[..., None])[..., 0]
    inherit = int(props.get("InheritType", [1])[0])
    scale_from = None
    if parent is not None and inherit in (0, 2):
        scale_from = parent if inherit == 0 else parent.scale_from
        if scale_from is not None:
            S = S * scale_from.scale
        move = move * parent.scale
    matrix = _matrix(turn * S[..., None, :], move)
    without = _matrix(turn, move) if unscaled else None
    if parent is not None:
        above = parent.matrix if inherit not in (0, 2) else parent.unscaled
        matrix = above @ matrix
        without = above @ without if unscaled else None
    return Placed(matrix, matrix if without is None else without, np.broadcast_to(S, move.shape), scale_from)


def _rotation_order(props: dict) -> str:
    """The axes a Model's Euler rotation turns about, in turn (its RotationOrder; `_euler`'s order)."""
    return _ORDERS.get(int(props.get("RotationOrder", [0])[0]), "xyz")


def _matrix(linear: np.ndarray, move: np.ndarray) -> np.ndarray:
    M = np.zeros(move.shape[:-1] + (4, 4))
    M[..., :3, :3] = linear
    M[..., :3, 3] = move
    M[..., 3, 3] = 1.0
    return M


def bound_rest(rest: dict, bound: dict, order: list, parent: dict) -> dict:
    """{id: (4, 4)} the rest of every node: its bind pose's where it has one (`bound`), else its own transform
    from its parent's (in `rest`, as its properties hold them) below its parent's rest, so the joints a
    BindPose leaves out (end joints, IK controls: no skin weights) keep their places along their bound parents;
    order: the ids, parents first."""
    out = dict(rest)
    out.update(bound)
    for i in order:
        p = parent.get(i)
        if i not in bound and p is not None and p in out and out[p] is not rest[p]:
            if abs(np.linalg.det(rest[p][:3, :3])) > 1e-12:
                out[i] = out[p] @ np.linalg.solve(rest[p], rest[i])
    return out


def _bind_pose(objects: Node, rest: dict) -> dict:
    """{model id: (4, 4) its world matrix} of the file's BindPose, where it has one."""
    for pose in objects.all("Pose"):
        if len(pose.props) >= 3 and pose.props[2] == "BindPose":
            out = {}
            for node in pose.all("PoseNode"):
                i, m = node.child("Node"), node.child("Matrix")
                if i is not None and m is not None and i.props[0] in rest and len(m.props[0]) == 16:
                    out[i.props[0]] = np.asarray(m.props[0], dtype=np.float64).reshape(4, 4).T
            return out
    return {}


def skeleton_of(joints: list, names: dict, parent: dict, order: list, world: dict, rest: dict,
                frame_time: float) -> Skeleton:
    """`joints` (ids of a file's nodes) as a Skeleton whose zero pose is the rest (its frames the world's there):
    names {id: joint name}; parent {id: its parent node's id} over all nodes (an Armature above the joints too);
    order: every id, parents first; world {id: (T, 4, 4)} each joint's transform in the world per frame; rest
    {id: (4, 4)} at rest; frame_time in seconds. Scalings are taken out of the rotations. The largest tree of
    joints is the skeleton's; the others (a foot under an IK control, a deforming skeleton beside a larger rig of
    controls) hang from its root, each joint's tree in `trees`. Where joints' places move from their rest offsets
    (those trees; hips animated under a root joint), their places per frame are in `moving`."""
    joint_set = set(joints)
    up = {}  # each joint's nearest joint above it (through nodes that are no joints: an Armature), or None
    for i in joints:
        p = parent.get(i)
        while p is not None and p not in joint_set:
            p = parent.get(p)
        up[i] = p
    roots = {}
    for i in joints:
        r = i
        while up[r] is not None:
            r = up[r]
        roots.setdefault(r, []).append(i)
    # the body's tree: the one of the most humanoid joint names (a deforming skeleton beside a larger control rig),
    # then of the most joints
    main = max(roots, key=lambda r: (role_names([names[i] for i in roots[r]]), len(roots[r])))
    for r in roots:  # the other trees hang from the main one's root
        if r != main:
            up[r] = main
    # the main tree first (a joint named as one of another tree, a second character's, is matched in it), each
    # tree's parents before their children
    ids = [i for i in order if i in roots[main]] + [i for i in order if i in joint_set and i not in roots[main]]
    index = {i: k for k, i in enumerate(ids)}
    parents = [index[up[i]] if up[i] is not None else -1 for i in ids]
    tree_of = {i: index[r] for r, tree in roots.items() for i in tree}
    trees = tuple(tree_of[i] for i in ids) if len(roots) > 1 else ()

    def rotation(M):  # the rotation of a transform, its scaling taken out
        R = M[..., :3, :3]
        return R / np.linalg.norm(R, axis=-2, keepdims=True)

    rest_R = {i: rotation(rest[i]) for i in ids}
    turned = {i: rotation(world[i]) @ rest_R[i].T for i in ids}  # each joint's rotation from its rest, in the world
    rotations = np.stack([turned[i] if up[i] is None else np.swapaxes(turned[up[i]], -1, -2) @ turned[i]
                          for i in ids], axis=1)
    offsets = np.array([rest[i][:3, 3] - (rest[up[i]][:3, 3] if up[i] is not None else 0.0) for i in ids])
    root = world[ids[0]][:, :3, 3]
    # each joint's place from its parent's per frame, in the parent's frame turned back to its rest: kept where
    # it moves (hips animated under a root joint at the floor, as game engines' rigs are; the trees hung above)
    moving = np.stack([offsets[0] + np.zeros_like(root) if up[i] is None else
                       (np.swapaxes(turned[up[i]], -1, -2)
                        @ (world[i][:, :3, 3] - world[up[i]][:, :3, 3])[..., None])[..., 0] for i in ids], axis=1)
    size = max(float(np.ptp(offsets[1:], axis=0).max()) if len(ids) > 1 else 0.0, 1e-12)
    if not trees and np.abs(moving - offsets).max() <= 1e-6 * size:
        moving = None
    return Skeleton([names[i] for i in ids], parents, offsets, rotations, root, frame_time, moving=moving,
                    trees=trees)
