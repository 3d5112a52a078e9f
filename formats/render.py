"""Off-screen pictures of baked garments: PNG frames, MP4 and contact sheets (PyVista/VTK).

A `Scene` is what is drawn: the garment sequence, the body it moved on and an
optional colouring (a per-vertex scalar such as the error against a ground
truth in mm, or the vertices inside the body in red). `Renderer` draws one
frame of it from a camera preset (`front`, `side`, `back`, `orbit`) framed on
the animated bounds, with a light rig that brings out folds and a ground grid;
`render_outputs` writes PNG frames, an MP4 per camera and a contact sheet.
Everything is in the baked world frame: Z up, metres; "front" looks at a body
facing -Y (the AMASS convention with the usual root rotation), use
`RenderOptions.azimuth_deg` to turn the presets.

No display is needed: VTK opens an EGL context (`VTK_DEFAULT_OPENGL_WINDOW`,
set here unless the user set it). A missing EGL/GL stack raises `RenderError`
naming the Debian packages to install. Renders are deterministic on a given
machine (no anti-aliasing, no random sampling).
"""

from __future__ import annotations

import ctypes.util
import logging
import math
import os
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from core.errors import InputError, check_finite_points, content_kind

log = logging.getLogger(__name__)

# Must be set before VTK creates its first render window; a user's own choice wins.
os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")

#: Debian/Ubuntu packages an off-screen render needs on a bare machine.
APT_PACKAGES = "libegl1 libegl-mesa0 libgl1-mesa-dri"

CAMERAS = ("front", "side", "back", "orbit")
#: Azimuth of each preset, degrees about +Z, measured from the -Y axis (where "front" sits).
_PRESET_AZIMUTH = {"front": 0.0, "side": 90.0, "back": 180.0}
FRAMINGS = ("auto", "fixed", "follow")

GARMENT_COLOR = (0.80, 0.33, 0.25)     # terracotta, as in the USD stage `garment bake` writes
BODY_COLOR = (0.80, 0.82, 0.86)        # cool light grey: never confused with the garment
#: The body's opacity where `--color penetration` colours the garment's vertices inside it.
BODY_OPACITY_PENETRATION = 0.35
PENETRATION_GARMENT_COLOR = (0.36, 0.56, 0.80)  # neutral blue so the red of penetration stands out
PENETRATION_COLOR = (0.92, 0.05, 0.05)
BACKGROUND_COLOR = (0.95, 0.95, 0.96)
GROUND_COLOR = (0.88, 0.88, 0.86)
#: The ground plane's width over that of its grid (which reaches 1.5 m beyond the animation).
GROUND_REACH = 20.0


def ground_scale(extent: float) -> float:
    """The ground grid's scale for a scene whose frames span `extent` at most, a power of ten: 1 for a person or a
    garment in metres (0.54-5.4 units), 100 in centimetres (a centimetre scene was drawn a solid grey plane)."""
    return 10.0 ** round(math.log10(max(extent, 1e-9) / 1.7))
GRID_COLOR = (0.62, 0.62, 0.60)
ERROR_CMAP = "YlOrRd"                  # light = small, so folds stay visible where the error is low


class RenderError(InputError):
    """A render that cannot be made: no OpenGL context, a missing package, an unusable option."""


# ---------------------------------------------------------------------------
# What is drawn
# ---------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class Scene:
    """An animated garment and body with an optional per-vertex colouring.

    garment_points: (T, V, 3) float32, metres, Z-up world. garment_faces: (F, 3) int64.
    body_points: (T, Vb, 3) float32 metres or None; body_faces: (Fb, 3) int64 or None.
    fps: frames per second (None: 30 is used for MP4). frame_numbers: (T,) int, the
    frame number of each row in the source sequence (for labels).
    vertex_values: (T, V) float, a scalar per garment vertex drawn through `value_cmap`
    over `value_range` with a colour bar titled `value_label` (e.g. error in mm), or None.
    inside: (T, V) bool, garment vertices inside the body (drawn red), or None.
    """

    garment_points: np.ndarray
    garment_faces: np.ndarray
    body_points: np.ndarray | None = None
    body_faces: np.ndarray | None = None
    fps: float | None = None
    frame_numbers: np.ndarray | None = None
    vertex_values: np.ndarray | None = None
    value_label: str = ""
    value_range: tuple[float, float] | None = None
    value_cmap: str = ERROR_CMAP
    inside: np.ndarray | None = None

    def __post_init__(self):
        T, V = self.garment_points.shape[:2]
        if self.frame_numbers is None:
            object.__setattr__(self, "frame_numbers", np.arange(T))
        for name in ("vertex_values", "inside"):
            a = getattr(self, name)
            if a is not None and np.shape(a) != (T, V):
                raise InputError(f"render scene: expected {name} of shape ({T}, {V}), got {np.shape(a)}")
        if self.body_points is not None and self.body_points.shape[0] != T:
            raise InputError(f"render scene: expected body_points with {T} frames, got {self.body_points.shape[0]}")

    @property
    def n_frames(self) -> int:
        return int(self.garment_points.shape[0])

    @property
    def has_body(self) -> bool:
        return self.body_points is not None and self.body_faces is not None

    def take(self, frames) -> "Scene":
        """The scene restricted to the given frame indices (an int array or a slice)."""
        idx = np.arange(self.n_frames)[frames]

        def pick(a):
            return None if a is None else a[idx]

        return replace(self, garment_points=self.garment_points[idx], body_points=pick(self.body_points),
                       frame_numbers=self.frame_numbers[idx], vertex_values=pick(self.vertex_values),
                       inside=pick(self.inside))


#: An MP4 plays at least this many frames per second (a bake at --fps 1e-7 handed ffmpeg a rate of 0 and wrote no
#: video): slower rates play as a slide show at this one.
MIN_PLAYBACK_FPS = 1.0


def playback_fps(scene: Scene) -> float:
    """Frames per second of the scene's rows: its fps (30 if unknown) over the step between kept frames, at least
    MIN_PLAYBACK_FPS."""
    steps = np.diff(scene.frame_numbers)
    step = float(np.median(steps)) if steps.size else 1.0
    return max((scene.fps or 30.0) / max(step, 1.0), MIN_PLAYBACK_FPS)


@dataclass(frozen=True)
class RenderOptions:
    """How a scene is drawn.

    width, height: pixels. cameras: presets from `CAMERAS`. azimuth_deg: turns every
    preset about +Z (0: front looks at a body facing -Y). elevation_deg: camera height
    angle above the horizon. fov_deg: vertical view angle. framing: "fixed" (one camera
    for the whole animation, framed on the animated bounds), "follow" (the camera tracks
    the body at a fixed distance, framed on the largest single-frame bounds), "auto"
    (follow when the animation travels further than its own size). margin: fraction of
    the image kept free at each border. labels: frame number and camera in a corner.
    """

    width: int = 1280
    height: int = 720
    cameras: tuple[str, ...] = ("front",)
    azimuth_deg: float = 0.0
    elevation_deg: float = 12.0
    fov_deg: float = 30.0
    framing: str = "auto"
    margin: float = 0.06
    show_body: bool = True
    ground: bool = True
    labels: bool = True
    garment_color: tuple[float, float, float] = GARMENT_COLOR
    body_color: tuple[float, float, float] = BODY_COLOR

    def __post_init__(self):
        bad = [c for c in self.cameras if c not in CAMERAS]
        if bad or not self.cameras:
            raise InputError(f"--camera: expected one or more of {', '.join(CAMERAS)}, got {bad or 'none'}")
        if self.framing not in FRAMINGS:
            raise InputError(f"--framing: expected one of {', '.join(FRAMINGS)}, got '{self.framing}'")
        if not (16 <= self.width <= 8192 and 16 <= self.height <= 8192):
            raise InputError(f"--size: expected 16..8192 pixels a side, got {self.width}x{self.height}")
        check_azimuth(self.azimuth_deg)
        if not (0.0 <= self.margin < 0.45):
            raise InputError(f"render margin: expected 0 <= margin < 0.45, got {self.margin}")


def check_azimuth(degrees: float) -> None:
    """--azimuth: degrees within one turn either way (NaN or Inf would draw blank frames; 1e300 is no angle: its
    remainder of a turn is rounding)."""
    if not (math.isfinite(degrees) and abs(degrees) <= 360):
        raise InputError(f"--azimuth: expected degrees within -360..360, got {degrees:g}")


def check_value_range(value_range: tuple[float, float]) -> None:
    """--range LO HI: finite, LO < HI (the colour bar's range)."""
    lo, hi = value_range
    if not (math.isfinite(lo) and math.isfinite(hi)):
        raise InputError(f"--range: expected finite LO HI, got {lo} {hi}")
    if not lo < hi:
        raise InputError(f"--range: expected LO < HI, got {lo} {hi}")


def parse_size(text: str) -> tuple[int, int]:
    """'1280x720' -> (1280, 720); raises InputError naming --size otherwise."""
    try:
        w, h = (int(s) for s in text.lower().split("x"))
    except ValueError:
        raise InputError(f"--size: expected WIDTHxHEIGHT like 1280x720, got '{text}'") from None
    if not (16 <= w <= 8192 and 16 <= h <= 8192):
        raise InputError(f"--size: expected 16..8192 pixels a side, got '{text}'")
    return w, h


# ---------------------------------------------------------------------------
# Colourings
# ---------------------------------------------------------------------------

def vertex_error_mm(pred: np.ndarray, gt: np.ndarray) -> np.ndarray:
    """Per-vertex distance between two sequences of one mesh.

    pred, gt: (T, V, 3) float, metres. Returns (T, V) float32, millimetres.
    """
    d = np.asarray(pred, dtype=np.float64) - np.asarray(gt, dtype=np.float64)
    return (1000.0 * np.linalg.norm(d, axis=-1)).astype(np.float32)


def penetration_masks(points: np.ndarray, body_points: np.ndarray, body_faces: np.ndarray,
                      depth_m: float = 0.002) -> np.ndarray:
    """Garment vertices more than `depth_m` inside the body, per frame.

    points: (T, V, 3) metres; body_points: (T, Vb, 3) metres; body_faces: (Fb, 3) int.
    Returns (T, V) bool. Uses `core.geometry.points_inside_mesh` (about a second per
    frame for a 13k-vertex body), so restrict the scene to the frames drawn first.
    """
    from core.geometry import points_inside_mesh

    return np.stack([points_inside_mesh(p, b, body_faces, depth=depth_m) for p, b in zip(points, body_points)])


def load_vertex_scalars(path: str | os.PathLike, key: str | None, n_frames: int, n_vertices: int) -> np.ndarray:
    """A per-vertex scalar array from an .npz, as (n_frames, n_vertices) float32.

    The array under `key` (or the only array in the file when key is None) must be
    (V,) (the same for every frame) or (T, V) with T = n_frames.
    """
    path = Path(path)
    where = f"--scalars '{path}'"
    try:
        with np.load(path, allow_pickle=False) as data:
            keys = list(data.files)
            if key is None:
                if len(keys) != 1:
                    raise InputError(f"{where}: expected one array or FILE.npz:KEY, got keys {keys}")
                key = keys[0]
            if key not in keys:
                raise InputError(f"{where}: expected key '{key}', got keys {keys}")
            values = np.asarray(data[key])
    except InputError:
        raise
    except Exception as exc:
        got = content_kind(path)
        if got:
            raise InputError(f"{where}: expected a .npz of arrays, got {got}") from None
        raise InputError(f"{where}: cannot be read as .npz ({type(exc).__name__}: {exc})") from None
    if not np.issubdtype(values.dtype, np.number) and values.dtype != bool:
        raise InputError(f"{where}: expected numbers under '{key}', got dtype {values.dtype}")
    if values.shape == (n_vertices,):
        values = np.broadcast_to(values, (n_frames, n_vertices))
    if values.shape != (n_frames, n_vertices):
        raise InputError(f"{where}: expected '{key}' of shape ({n_vertices},) or ({n_frames}, {n_vertices}), "
                         f"got {values.shape}")
    values = values.astype(np.float32)
    if not np.isfinite(values).all():
        raise InputError(f"{where}: expected finite values under '{key}', got NaN/Inf")
    return values


def robust_range(values: np.ndarray, upper_percentile: float = 99.0) -> tuple[float, float]:
    """Colour range (lo, hi) of a scalar array: 0 (or its minimum if negative) to its 99th percentile."""
    v = np.asarray(values, dtype=np.float64)
    lo = min(0.0, float(v.min()))
    hi = float(np.percentile(v, upper_percentile))
    if not hi > lo:
        hi = float(v.max()) if v.max() > lo else lo + 1.0
    return lo, hi


def check_finite_sequence(seq, what: str = "garment sequence") -> None:
    """Raise InputError naming `seq.source` and the first frame and vertex whose coordinates are NaN or Inf.

    Checks the garment points and, when present, the body points (frame numbers of the file, 0-based).
    """
    for points, vertex in ((seq.points, "vertex"), (seq.body_points, "body vertex")):
        if points is not None:
            check_finite_points(points, f"{what} '{seq.source}'", vertex)
    points = np.asarray(seq.points)
    if points.shape[1] > 1 and not np.ptp(points, axis=1).any():
        far = float(np.abs(points).max())
        raise InputError(f"{what} '{seq.source}': expected a garment of some size, got all {points.shape[1]} "
                         f"vertices at one point in every frame"
                         + (f", {far:.3g} m from the origin (too far for float32 to tell its vertices apart: "
                            f"move it near the origin)" if far > 1e4 else ""))


def scene_from_sequence(seq, color: str = "plain", gt=None, scalars: np.ndarray | None = None,
                        scalar_label: str = "value", value_range: tuple[float, float] | None = None,
                        frames=None, depth_m: float = 0.002) -> Scene:
    """A `Scene` from a `formats.sequence.Sequence`.

    color: "plain", "error" (needs `gt`, a Sequence of the same mesh; the per-vertex
    distance in mm), "penetration" (needs a body in `seq`) or "scalar" (needs
    `scalars`, (T, V) for the whole sequence). frames: indices or a slice of the
    frames to keep (applied before the costly penetration test).
    """
    if value_range is not None:
        check_value_range(value_range)
    check_finite_sequence(seq)
    if gt is not None:
        check_finite_sequence(gt, "--gt")
    idx = np.arange(seq.n_frames) if frames is None else np.arange(seq.n_frames)[frames]
    if idx.size == 0:
        numbered = "" if not seq.first_frame else \
            f", numbered {seq.first_frame}-{seq.first_frame + seq.n_frames - 1}: --frames counts them from 0"
        raise InputError(f"--frames: selects no frame of '{seq.source}' ({seq.n_frames} frames{numbered})")
    body_points = None if seq.body_points is None else seq.body_points[idx]
    kwargs = {}
    if color == "error":
        if gt is None:
            raise InputError("--color error: needs --gt, the ground-truth sequence")
        from core.metrics import check_comparable

        check_comparable(seq.points, seq.faces, gt.points, gt.faces, seq.source or "INPUT", gt.source or "--gt")
        if seq.fps is not None and gt.fps is not None and not np.isclose(seq.fps, gt.fps, rtol=1e-6):
            raise InputError(f"--gt: '{gt.source}' is at {gt.fps:g} fps, '{seq.source}' at {seq.fps:g} fps: expected "
                             "the same frame rate (resample one of them to match)")  # as `garment metrics` refuses
        values = vertex_error_mm(seq.points, gt.points)
        # the range over every frame, not only those drawn: a frame is coloured alike whatever --frames says
        kwargs = dict(vertex_values=values[idx], value_label="error (mm)",
                      value_range=value_range or robust_range(values))
    elif color == "penetration":
        if body_points is None or seq.body_faces is None:
            raise InputError(f"--color penetration: '{seq.source}' carries no body mesh "
                             "(render a baked USD or an .npz with body_points/body_faces)")
        kwargs = dict(inside=penetration_masks(seq.points[idx], body_points, seq.body_faces, depth_m))
    elif color == "scalar":
        if scalars is None:
            raise InputError("--color scalar: needs --scalars FILE.npz[:KEY]")
        values = np.asarray(scalars, dtype=np.float32)
        kwargs = dict(vertex_values=values[idx], value_label=scalar_label,
                      value_range=value_range or robust_range(values), value_cmap="viridis")
    elif color != "plain":
        raise InputError(f"--color: expected plain, error, penetration or scalar, got '{color}'")
    return Scene(garment_points=seq.points[idx], garment_faces=seq.faces, body_points=body_points,
                 body_faces=seq.body_faces, fps=seq.fps, frame_numbers=seq.first_frame + idx, **kwargs)


# ---------------------------------------------------------------------------
# Cameras
# ---------------------------------------------------------------------------

def _view_basis(azimuth_deg: float, elevation_deg: float):
    """Unit vectors (to_camera, right, up) for a camera at the given angles; Z up, azimuth 0 on -Y."""
    az, el = math.radians(azimuth_deg), math.radians(elevation_deg)
    horizontal = np.array([math.sin(az), -math.cos(az), 0.0])
    to_cam = math.cos(el) * horizontal + np.array([0.0, 0.0, math.sin(el)])
    right = np.cross(np.array([0.0, 0.0, 1.0]), to_cam)
    right /= np.linalg.norm(right)
    up = np.cross(to_cam, right)
    return to_cam, right, up


def fit_distance(lo: np.ndarray, hi: np.ndarray, target: np.ndarray, azimuth_deg: float, elevation_deg: float,
                 fov_deg: float, aspect: float, margin: float) -> float:
    """Smallest camera distance from `target` at which the box [lo, hi] fits the image.

    lo, hi: (3,) box corners, metres; target: (3,) the point looked at; aspect: width / height;
    margin: fraction of the image left free at each border. Every box corner projects
    inside the image (exact for a perspective camera), so nothing of the box is clipped.
    """
    to_cam, right, up = _view_basis(azimuth_deg, elevation_deg)
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    rel = corners - target
    tan_v = math.tan(math.radians(fov_deg) / 2.0) * (1.0 - 2.0 * margin)
    tan_h = math.tan(math.radians(fov_deg) / 2.0) * aspect * (1.0 - 2.0 * margin)
    depth = rel @ to_cam
    need = np.maximum(np.abs(rel @ right) / tan_h, np.abs(rel @ up) / tan_v) + depth
    return float(max(need.max(), 1e-3))


def _smooth(track: np.ndarray, width: int) -> np.ndarray:
    """Moving average of (T, 3) over `width` frames, so a follow camera does not jitter; the ends padded by the
    track mirrored through its first and last points, so a steady traveller stays where it is in the picture
    (padded with the end points repeated, the camera fell behind an 8 m run at its start and end: 0.55 -> 0.44 of
    the width; 0.83 -> 0.17 on frames farther apart)."""
    if width <= 1 or track.shape[0] < 3:
        return track
    pad = width // 2
    padded = np.pad(track, ((pad, pad), (0, 0)), mode="reflect", reflect_type="odd")
    kernel = np.ones(width) / width
    return np.stack([np.convolve(padded[:, k], kernel, mode="valid")[: track.shape[0]] for k in range(3)], axis=1)


def camera_track(frame_lo: np.ndarray, frame_hi: np.ndarray, preset: str, options: RenderOptions,
                 fps: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Camera positions and focal points for every frame.

    frame_lo, frame_hi: (T, 3) per-frame bounds of what is drawn, metres, Z-up.
    preset: one of `CAMERAS` ("orbit" turns 360 degrees over the T frames).
    Returns position (T, 3) and focal point (T, 3), metres. With "fixed" framing
    every frame sees the whole animated box; with "follow" the focal point tracks
    the (smoothed) per-frame box centre and each frame's box fits the image.
    """
    T = frame_lo.shape[0]
    aspect = options.width / options.height
    if preset == "orbit":
        azimuths = options.azimuth_deg + 360.0 * np.arange(T) / max(T, 1)
    else:
        azimuths = np.full(T, options.azimuth_deg + _PRESET_AZIMUTH[preset])
    lo_all, hi_all = frame_lo.min(0), frame_hi.max(0)
    framing = options.framing
    if framing == "auto":
        travel = np.linalg.norm((hi_all - lo_all)[:2])
        own = np.linalg.norm((frame_hi - frame_lo)[:, :2], axis=1).max()
        framing = "follow" if travel > 1.5 * own else "fixed"
    el = options.elevation_deg
    if framing == "fixed":
        target = np.repeat(((lo_all + hi_all) / 2.0)[None], T, 0)
        dist = max(fit_distance(lo_all, hi_all, target[0], a, el, options.fov_deg, aspect, options.margin)
                   for a in np.unique(azimuths))
        dists = np.full(T, dist)
    else:
        centre = (frame_lo + frame_hi) / 2.0
        target = _smooth(centre, int(round((fps or 30.0) * 0.5)) | 1)
        # Smoothing lags behind a fast traveller (metres a frame): keep the target within the figure's own
        # size of its centre, or the one distance below backs off until the figure is a speck.
        own_size = np.linalg.norm(frame_hi - frame_lo, axis=1).max()
        target = centre + np.clip(target - centre, -own_size, own_size)
        dists = np.array([fit_distance(frame_lo[t], frame_hi[t], target[t], azimuths[t], el, options.fov_deg,
                                       aspect, options.margin) for t in range(T)])
        dists = np.full(T, dists.max())  # one distance: the figure keeps its size on screen
    pos = np.stack([target[t] + dists[t] * _view_basis(azimuths[t], el)[0] for t in range(T)])
    return pos, target


def garment_out_of_view(points: np.ndarray, pos: np.ndarray, focal: np.ndarray, options: RenderOptions,
                        min_fraction: float = 0.02) -> np.ndarray:
    """Frames whose garment is outside the picture, or spans under `min_fraction` of its width and height.

    points: (T, V, 3) metres; pos, focal: (T, 3) camera positions and focal points (`camera_track`).
    Returns (T,) bool. Each frame's garment box is projected through a pinhole camera (Z up).
    """
    lo, hi = points.min(axis=1).astype(np.float64), points.max(axis=1).astype(np.float64)
    tan_v = math.tan(math.radians(options.fov_deg) / 2.0)
    tan_h = tan_v * options.width / options.height
    lost = np.zeros(points.shape[0], dtype=bool)
    for t in range(points.shape[0]):
        fwd = focal[t] - pos[t]
        fwd /= max(np.linalg.norm(fwd), 1e-12)
        right = np.cross(fwd, [0.0, 0.0, 1.0])
        right /= max(np.linalg.norm(right), 1e-12)
        up = np.cross(right, fwd)
        corners = np.array([[x, y, z] for x in (lo[t, 0], hi[t, 0]) for y in (lo[t, 1], hi[t, 1])
                            for z in (lo[t, 2], hi[t, 2])]) - pos[t]
        depth = corners @ fwd
        if (depth <= 0).any():
            lost[t] = bool((depth <= 0).all())
            continue
        u = np.clip(corners @ right / (depth * tan_h), -1.0, 1.0)  # image coordinates in [-1, 1]
        v = np.clip(corners @ up / (depth * tan_v), -1.0, 1.0)
        lost[t] = bool(np.ptp(u) < 2 * min_fraction and np.ptp(v) < 2 * min_fraction)
    return lost


# ---------------------------------------------------------------------------
# Rendering
# ---------------------------------------------------------------------------

def _import_pyvista():
    try:
        import pyvista as pv
    except ImportError as exc:
        raise RenderError(f"rendering needs pyvista (pip install pyvista): {exc}") from None
    return pv


def _x_display_opens() -> bool:
    """Whether libX11 can open the display named by $DISPLAY (VTK's X window crashes when it cannot)."""
    lib = _find_library("X11")
    if lib is None:
        return False
    try:
        x11 = ctypes.CDLL(lib)
        x11.XOpenDisplay.restype = ctypes.c_void_p
        x11.XOpenDisplay.argtypes = [ctypes.c_char_p]
        x11.XCloseDisplay.argtypes = [ctypes.c_void_p]
        display = x11.XOpenDisplay(None)
    except (OSError, AttributeError):
        return False
    if not display:
        return False
    x11.XCloseDisplay(display)
    return True


def _check_gl_libraries() -> None:
    """Raise RenderError (one line) when the window VTK will open cannot be: its libraries or display are absent.

    vtkEGLRenderWindow (the default): libEGL and libGL. A user's VTK_DEFAULT_OPENGL_WINDOW is checked
    for what it needs first, as VTK crashes (segfault) rather than report it: vtkXOpenGLRenderWindow a
    DISPLAY that opens, vtkOSOpenGLRenderWindow libOSMesa. Other windows (Win32, Cocoa) are left to VTK.
    """
    window = os.environ.get("VTK_DEFAULT_OPENGL_WINDOW", "")
    where = f"VTK_DEFAULT_OPENGL_WINDOW={window}"
    egl = "unset VTK_DEFAULT_OPENGL_WINDOW to render off-screen with EGL"
    if window == "vtkXOpenGLRenderWindow":
        display = os.environ.get("DISPLAY", "")
        if not display:
            raise RenderError(f"{where}: expected an X display in DISPLAY, got DISPLAY unset; {egl}")
        if not _x_display_opens():
            raise RenderError(f"{where}: expected an X display that opens, got DISPLAY={display} that does not; "
                              f"{egl}")
        return
    if window == "vtkOSOpenGLRenderWindow":
        if _find_library("OSMesa") is None:
            raise RenderError(f"{where}: expected the OSMesa library, found no libOSMesa (on Debian/Ubuntu: "
                              f"apt-get install libosmesa6); {egl}")
        return
    if window != "vtkEGLRenderWindow":
        return  # another platform's window: let VTK speak for it
    missing = [lib for lib in ("EGL", "GL") if _find_library(lib) is None]
    if missing:
        raise RenderError(f"no OpenGL context for off-screen rendering: library lib{missing[0]} not found "
                          f"(on Debian/Ubuntu: apt-get install {APT_PACKAGES})")


def check_render_window() -> None:
    """Raise RenderError when no off-screen window can be opened (`_check_gl_libraries`); call before any output."""
    _check_gl_libraries()


def _find_library(name: str):
    return ctypes.util.find_library(name)


def _no_context(exc: Exception) -> RenderError:
    """The one-line RenderError for a window or OpenGL context that VTK could not make."""
    return RenderError(f"no OpenGL context for off-screen rendering ({type(exc).__name__}: {exc}); "
                       f"on Debian/Ubuntu: apt-get install {APT_PACKAGES}")


def _vertex_normals(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    from core.geometry import vertex_normals

    return np.asarray(vertex_normals(points, faces), dtype=np.float32)


def _faces_vtk(faces: np.ndarray) -> np.ndarray:
    faces = np.asarray(faces, dtype=np.int64)
    return np.hstack([np.full((faces.shape[0], 1), 3, dtype=np.int64), faces]).ravel()


def _rgb_u8(color) -> np.ndarray:
    return (np.clip(np.asarray(color, dtype=np.float64), 0, 1) * 255 + 0.5).astype(np.uint8)


@dataclass
class _Track:
    """One mesh in the plotter whose points (and normals, colours) change per frame."""

    poly: object
    faces: np.ndarray
    points: np.ndarray
    colors: np.ndarray | None = None
    extra: dict = field(default_factory=dict)


class Renderer:
    """Draws the frames of one `Scene`; a context manager around one off-screen VTK window.

    The meshes are built once; each `image(t, camera)` call updates their points,
    normals and colours in place, places the camera and reads the pixels back:
    (height, width, 3) uint8 RGB.
    """

    def __init__(self, scene: Scene, options: RenderOptions = RenderOptions()):
        self.scene = scene
        self.options = options
        pv = _import_pyvista()
        _check_gl_libraries()
        # Only the window and its context are blamed on OpenGL; an error building the scene is what it is.
        try:
            self.plotter = pv.Plotter(off_screen=True, window_size=(options.width, options.height),
                                      lighting="none")
            self.plotter.disable_anti_aliasing()
        except Exception as exc:  # VTK raises plain RuntimeErrors when no context can be made
            raise _no_context(exc) from None
        try:
            self._build(pv)
        except BaseException:
            self.plotter.close()
            raise
        try:
            self.plotter.render()  # the first render opens the context
        except Exception as exc:
            self.plotter.close()
            raise _no_context(exc) from None
        if not self.plotter.render_window.SupportsOpenGL():
            raise RenderError(f"no OpenGL context for off-screen rendering: VTK's {type(self.plotter.render_window).__name__} "
                              f"found no usable OpenGL (on Debian/Ubuntu: apt-get install {APT_PACKAGES})")
        self._cameras = {}
        self._warned_view = False

    # -- scene set-up --------------------------------------------------------

    def _bounds(self):
        s, o = self.scene, self.options
        lo, hi = s.garment_points.min(axis=1), s.garment_points.max(axis=1)
        if s.has_body and o.show_body:
            lo = np.minimum(lo, s.body_points.min(axis=1))
            hi = np.maximum(hi, s.body_points.max(axis=1))
        return lo.astype(np.float64), hi.astype(np.float64)

    def _build(self, pv) -> None:
        s, o, p = self.scene, self.options, self.plotter
        p.set_background(BACKGROUND_COLOR)
        self.frame_lo, self.frame_hi = self._bounds()
        material = dict(ambient=0.18, diffuse=0.78, specular=0.18, specular_power=24.0)
        self.tracks = {}
        if s.has_body and o.show_body:
            body = pv.PolyData(s.body_points[0].astype(np.float32), _faces_vtk(s.body_faces))
            # see-through where the cloth's vertices inside it are coloured: opaque, it hid them (7-8 % of the
            # dress inside on a crouch, 0-1 red pixels a frame)
            actor = p.add_mesh(body, color=o.body_color, opacity=BODY_OPACITY_PENETRATION if s.inside is not None
                               else 1.0, **material)
            actor.prop.interpolation = "gouraud"
            self.tracks["body"] = _Track(body, np.asarray(s.body_faces), s.body_points)
        garment = pv.PolyData(s.garment_points[0].astype(np.float32), _faces_vtk(s.garment_faces))
        track = _Track(garment, np.asarray(s.garment_faces), s.garment_points)
        if s.vertex_values is not None:
            garment.point_data["values"] = s.vertex_values[0].astype(np.float32)
            h = o.height
            bar = dict(title=s.value_label, vertical=True, position_x=0.84, position_y=0.06, width=0.12,
                       height=0.7, n_labels=5, fmt="%.3g", color="black", title_font_size=max(8, h // 40),
                       label_font_size=max(8, h // 48), font_family="arial")
            actor = p.add_mesh(garment, scalars="values", cmap=s.value_cmap, clim=s.value_range,
                               scalar_bar_args=bar, **material)
            actor.mapper.interpolate_before_map = True
            p.scalar_bar.SetBarRatio(0.3)
            p.scalar_bar.SetTextPositionToPrecedeScalarBar()  # labels left of the bar, inside the image
            p.scalar_bar.SetVerticalTitleSeparation(max(6, h // 40))  # the title above the top label, not on it
        elif s.inside is not None:
            rgb = np.empty((s.garment_points.shape[1], 3), dtype=np.uint8)
            garment.point_data["rgb"] = rgb
            track.colors = rgb
            actor = p.add_mesh(garment, scalars="rgb", rgb=True, **material)
        else:
            actor = p.add_mesh(garment, color=o.garment_color, **material)
        actor.prop.interpolation = "gouraud"
        self.tracks["garment"] = track
        if o.ground:
            self._add_ground(pv)
        self._add_lights(pv)
        self._label = None

    def _add_ground(self, pv) -> None:
        """A ground plane under the lowest point of the animation with a grid on it: 25 cm squares 1.5 m beyond
        where the animation goes, for a scene of a person in metres (`ground_scale`: 25 units in centimetres),
        on a plane GROUND_REACH times wider, so that its far edge, the horizon, stays put as a camera follows."""
        lo, hi = self.frame_lo.min(0), self.frame_hi.max(0)
        scale = ground_scale(float((self.frame_hi - self.frame_lo).max(initial=0.0)))
        z = float(lo[2]) - 0.002 * scale
        size = float(max(hi[0] - lo[0], hi[1] - lo[1])) + 3.0 * scale
        cx, cy = (lo[:2] + hi[:2]) / 2.0
        step = 0.25 * scale
        half = math.ceil(size / 2.0 / step) * step
        x0, x1 = math.floor((cx - half) / step) * step, math.ceil((cx + half) / step) * step
        y0, y1 = math.floor((cy - half) / step) * step, math.ceil((cy + half) / step) * step
        plane = pv.Plane(center=((x0 + x1) / 2, (y0 + y1) / 2, z), direction=(0, 0, 1),
                         i_size=GROUND_REACH * (x1 - x0), j_size=GROUND_REACH * (y1 - y0), i_resolution=1,
                         j_resolution=1)
        self.plotter.add_mesh(plane, color=GROUND_COLOR, ambient=0.35, diffuse=0.65, specular=0.0)
        xs = np.arange(x0, x1 + step / 2, step)
        ys = np.arange(y0, y1 + step / 2, step)
        zl = z + 0.003 * scale
        pts, lines = [], []
        for x in xs:
            pts += [(x, y0, zl), (x, y1, zl)]
        for y in ys:
            pts += [(x0, y, zl), (x1, y, zl)]
        n = len(pts) // 2
        lines = np.hstack([np.full((n, 1), 2), np.arange(2 * n).reshape(n, 2)]).ravel()
        grid = pv.PolyData(np.asarray(pts, dtype=np.float32), lines=lines)
        self.plotter.add_mesh(grid, color=GRID_COLOR, line_width=1, lighting=False)

    def _add_lights(self, pv) -> None:
        """Key light high on one side, a weaker fill on the other and a rim light from behind.

        Camera lights (they turn with an orbiting camera); the raking key light is
        what brings out folds, the fill keeps the shadowed side readable.
        """
        for position, intensity in (((-1.0, 1.4, 1.0), 0.75), ((1.3, 0.3, 1.0), 0.35), ((0.2, 1.0, -1.2), 0.25)):
            self.plotter.add_light(pv.Light(position=position, focal_point=(0, 0, 0), intensity=intensity,
                                            light_type="camera light"))

    # -- frames --------------------------------------------------------------

    def camera(self, preset: str) -> tuple[np.ndarray, np.ndarray]:
        """(positions (T, 3), focal points (T, 3)) of a preset for this scene, cached."""
        if preset not in self._cameras:
            if preset not in CAMERAS:
                raise InputError(f"--camera: expected one of {', '.join(CAMERAS)}, got '{preset}'")
            self._cameras[preset] = camera_track(self.frame_lo, self.frame_hi, preset, self.options,
                                                 playback_fps(self.scene))
            self._warn_if_out_of_view(preset, *self._cameras[preset])
        return self._cameras[preset]

    def _warn_if_out_of_view(self, preset: str, pos: np.ndarray, focal: np.ndarray) -> None:
        """Warn once per renderer when the garment leaves the picture, or shrinks under 2 % of it, in some frames."""
        if self._warned_view:
            return
        lost = garment_out_of_view(self.scene.garment_points, pos, focal, self.options)
        if lost.any():
            self._warned_view = True
            g = self.scene.garment_points
            travel = float(np.linalg.norm(np.ptp(g.mean(axis=1), axis=0)))
            far = float(np.abs(g).max())
            log.warning("render: the garment is out of view or under 2%% of the picture in %d of %d frames "
                        "(first: frame %d, %s camera); it travels %.3g m and reaches %.3g m from the origin%s",
                        int(lost.sum()), lost.size, int(self.scene.frame_numbers[np.argmax(lost)]), preset, travel,
                        far, "; try --framing follow" if self.options.framing == "fixed" else "")

    def _set_frame(self, t: int) -> None:
        s = self.scene
        for name, track in self.tracks.items():
            pts = track.points[t].astype(np.float32)
            track.poly.points = pts
            track.poly.point_data.active_normals = _vertex_normals(pts, track.faces)
        g = self.tracks["garment"]
        if s.vertex_values is not None:
            g.poly.point_data["values"] = s.vertex_values[t].astype(np.float32)
        elif s.inside is not None:
            colors = np.where(s.inside[t][:, None], _rgb_u8(PENETRATION_COLOR), _rgb_u8(PENETRATION_GARMENT_COLOR))
            g.poly.point_data["rgb"] = colors.astype(np.uint8)

    def image(self, t: int, camera: str = "front") -> np.ndarray:
        """Frame `t` (row of the scene) seen from `camera`: (height, width, 3) uint8 RGB."""
        if not 0 <= t < self.scene.n_frames:
            raise InputError(f"render frame: expected 0..{self.scene.n_frames - 1}, got {t}")
        pos, focal = self.camera(camera)
        self._set_frame(t)
        cam = self.plotter.camera
        cam.position = tuple(pos[t])
        cam.focal_point = tuple(focal[t])
        cam.up = (0.0, 0.0, 1.0)
        cam.view_angle = self.options.fov_deg
        self.plotter.reset_camera_clipping_range()
        if self.options.labels:
            text = f"frame {int(self.scene.frame_numbers[t])}  {camera}"
            if self._label is None:
                self._label = self.plotter.add_text(text, position="upper_left",
                                                    font_size=max(6, self.options.height // 60), color="black")
            else:
                self._label.set_text("upper_left", text)
        self.plotter.render()
        img = self.plotter.screenshot(return_img=True)
        return np.ascontiguousarray(img[:, :, :3])

    def close(self) -> None:
        self.plotter.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def render_image(scene: Scene, frame: int = 0, camera: str = "front",
                 options: RenderOptions = RenderOptions()) -> np.ndarray:
    """One frame of `scene` from `camera`: (height, width, 3) uint8 RGB (opens and closes a window)."""
    with Renderer(scene, options) as r:
        return r.image(frame, camera)


# ---------------------------------------------------------------------------
# Files: PNG, MP4, contact sheet
# ---------------------------------------------------------------------------

def write_png(path: str | os.PathLike, image: np.ndarray) -> Path:
    """Write an (H, W, 3) uint8 image as PNG."""
    import imageio.v2 as iio

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    iio.imwrite(path, np.asarray(image, dtype=np.uint8))
    return path


def read_png(path: str | os.PathLike) -> np.ndarray:
    """Read a PNG as (H, W, 3) uint8 RGB (alpha dropped)."""
    import imageio.v2 as iio

    img = np.asarray(iio.imread(path))
    if img.ndim == 2:
        img = np.repeat(img[:, :, None], 3, axis=2)
    return img[:, :, :3].astype(np.uint8)


class Mp4Writer:
    """H.264 MP4 through imageio-ffmpeg (no system ffmpeg needed); odd sizes are padded to even.

    quality: imageio's 0-10 scale (higher: larger file, fewer artefacts).
    """

    def __init__(self, path: str | os.PathLike, fps: float, quality: float = 7.0):
        try:
            import imageio.v2 as iio
            import imageio_ffmpeg  # noqa: F401  (imageio's ffmpeg plugin needs it)
        except ImportError as exc:
            raise RenderError(f"MP4 output needs imageio and imageio-ffmpeg (pip install imageio imageio-ffmpeg): "
                              f"{exc}") from None
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._writer = iio.get_writer(self.path, format="FFMPEG", mode="I", fps=float(fps), codec="libx264",
                                      pixelformat="yuv420p", quality=quality, macro_block_size=1,
                                      ffmpeg_log_level="error")

    def append(self, image: np.ndarray) -> None:
        h, w = image.shape[:2]
        if h % 2 or w % 2:
            image = np.pad(image, ((0, h % 2), (0, w % 2), (0, 0)), mode="edge")
        self._writer.append_data(np.asarray(image, dtype=np.uint8))

    def close(self, check: bool = True) -> None:
        """Finish the file; `check`: RenderError where ffmpeg wrote none (its failure was counted as a video)."""
        self._writer.close()
        if check and (not self.path.is_file() or self.path.stat().st_size == 0):
            raise RenderError(f"MP4 '{self.path.name}': ffmpeg wrote no video (its messages above say why)")


def contact_sheet(rows: list[list[np.ndarray]], labels: list[list[str]] | None = None,
                  thumb_width: int = 320, gap: int = 4) -> np.ndarray:
    """A grid of images in one picture: rows[r][c] is (H, W, 3) uint8; each is scaled to `thumb_width`.

    labels: the same nesting of short strings drawn in each tile's corner, or None.
    Returns (H', W', 3) uint8 on a white background.
    """
    from PIL import Image, ImageDraw

    h0, w0 = rows[0][0].shape[:2]
    tw = min(thumb_width, w0)
    th = max(1, round(h0 * tw / w0))
    n_cols = max(len(r) for r in rows)
    sheet = Image.new("RGB", (n_cols * tw + (n_cols + 1) * gap, len(rows) * th + (len(rows) + 1) * gap),
                      (255, 255, 255))
    draw = ImageDraw.Draw(sheet)
    for r, row in enumerate(rows):
        for c, img in enumerate(row):
            tile = Image.fromarray(np.asarray(img, dtype=np.uint8)).resize((tw, th), Image.LANCZOS)
            x, y = gap + c * (tw + gap), gap + r * (th + gap)
            sheet.paste(tile, (x, y))
            if labels is not None:
                draw.text((x + 4, y + th - 14), labels[r][c], fill=(0, 0, 0))
    return np.asarray(sheet)


def render_outputs(scene: Scene, out_dir: str | os.PathLike, options: RenderOptions = RenderOptions(),
                   png_frames: bool = True, mp4: bool = True, sheet: bool = True,
                   sheet_frames: int = 6, progress=None) -> dict[str, list[Path]]:
    """Render every frame of `scene` from each of `options.cameras` into `out_dir`.

    Writes frames/<camera>/frame_NNNN.png (png_frames), <camera>.mp4 (mp4, at the
    scene's `playback_fps`) and contact_sheet.png (sheet: `sheet_frames` evenly spaced
    frames per camera, one row per camera). progress: optional callable(n) called
    after each frame. Returns {"png": [...], "mp4": [...], "sheet": [...]} paths.
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    T = scene.n_frames
    width = max(4, len(str(int(scene.frame_numbers.max()))))
    sheet_idx = set(np.unique(np.linspace(0, T - 1, min(T, sheet_frames)).round().astype(int)).tolist())
    written = {"png": [], "mp4": [], "sheet": []}
    rows, labels = [], []
    with Renderer(scene, options) as r:
        for cam in options.cameras:
            video = Mp4Writer(out_dir / f"{cam}.mp4", playback_fps(scene)) if mp4 else None
            row, row_labels = [], []
            try:
                for t in range(T):
                    img = r.image(t, cam)
                    if png_frames:
                        written["png"].append(write_png(
                            out_dir / "frames" / cam / f"frame_{int(scene.frame_numbers[t]):0{width}d}.png", img))
                    if video is not None:
                        video.append(img)
                    if t in sheet_idx:
                        row.append(img)
                        row_labels.append(f"{cam} {int(scene.frame_numbers[t])}")
                    if progress is not None:
                        progress(1)
            except BaseException:
                if video is not None:
                    video.close(check=False)
                raise
            if video is not None:
                video.close()
                written["mp4"].append(video.path)
            rows.append(row)
            labels.append(row_labels)
    if sheet:
        sheet_img = contact_sheet(rows, None if options.labels else labels)  # frames carry their own labels
        written["sheet"].append(write_png(out_dir / "contact_sheet.png", sheet_img))
    return written


def render_bake(directory: str | os.PathLike, garment_points: np.ndarray, garment_faces: np.ndarray,
                body_points: np.ndarray | None, body_faces: np.ndarray | None, fps: float | None,
                options: RenderOptions = RenderOptions(cameras=("front", "side")), first_frame: int = 0
                ) -> dict[str, list[Path]]:
    """What `garment bake --render` writes into its output: an MP4 per camera and a contact sheet.

    garment_points: (T, V, 3) float32 metres, Z-up; garment_faces: (F, 3) int; body_points
    (T, Vb, 3) and body_faces (Fb, 3) or None; fps: frames per second; first_frame: the number of the first (the
    bake's --start-frame), as the sheet labels it. No PNG frames (`garment render` writes those on demand).
    """
    scene = Scene(garment_points=np.asarray(garment_points, dtype=np.float32),
                  garment_faces=np.asarray(garment_faces, dtype=np.int64),
                  body_points=None if body_points is None else np.asarray(body_points, dtype=np.float32),
                  body_faces=None if body_faces is None else np.asarray(body_faces, dtype=np.int64), fps=fps,
                  frame_numbers=first_frame + np.arange(len(garment_points)))
    return render_outputs(scene, directory, options, png_frames=False, mp4=True, sheet=True)


# ---------------------------------------------------------------------------
# Image comparison (regression renders)
# ---------------------------------------------------------------------------

@dataclass(frozen=True)
class ImageDiff:
    """How two images differ: share of pixels off by more than the threshold, mean and max difference."""

    differing_fraction: float
    mean_abs: float
    max_abs: int
    shape_mismatch: bool = False


def compare_images(actual: np.ndarray, expected: np.ndarray, pixel_threshold: int = 24) -> ImageDiff:
    """Compare two (H, W, 3) uint8 images.

    A pixel differs when any channel is off by more than `pixel_threshold` (0-255);
    small shading noise between software renderers stays under it, a moved edge does not.
    """
    if actual.shape != expected.shape:
        return ImageDiff(1.0, 255.0, 255, shape_mismatch=True)
    d = np.abs(actual.astype(np.int16) - expected.astype(np.int16))
    return ImageDiff(float((d.max(axis=2) > pixel_threshold).mean()), float(d.mean()), int(d.max()))


def diff_image(actual: np.ndarray, expected: np.ndarray) -> np.ndarray:
    """Expected | actual | amplified difference side by side, (H, 3W, 3) uint8 (for a failing test)."""
    if actual.shape != expected.shape:
        h = max(actual.shape[0], expected.shape[0])
        w = max(actual.shape[1], expected.shape[1])
        pad = lambda a: np.pad(a, ((0, h - a.shape[0]), (0, w - a.shape[1]), (0, 0)))  # noqa: E731
        actual, expected = pad(actual), pad(expected)
    d = np.abs(actual.astype(np.int16) - expected.astype(np.int16)).max(axis=2)
    heat = np.zeros_like(actual)
    heat[..., 0] = np.clip(d * 4, 0, 255)
    heat[..., 1] = np.clip(d * 4 - 255, 0, 255)
    return np.concatenate([expected, actual, heat], axis=1).astype(np.uint8)
