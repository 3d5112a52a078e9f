"""Errors raised by `core` and `formats` for bad input.

The CLI turns every `InputError` into one clear line and a non-zero exit, so the
message must name the file or option, what was expected and what was found.
"""


class InputError(ValueError):
    """Bad user input: a file, an array or an option value that cannot be used."""


def frames_text(n: int) -> str:
    """"1 frame", "5 frames": a frame count for messages."""
    return f"{n} frame" if n == 1 else f"{n} frames"


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
