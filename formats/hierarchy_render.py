"""PNG of a garment's pooling hierarchy, levels side by side (like paper Fig. 7), rendered off-screen.

Each panel shows the rest mesh as a faint surface with the level's graph on
it: its edges as lines and its vertices as points, seen from the front (+Z,
Y up). Rendering is off-screen through PyVista with an EGL window, so no
display is needed (a bare Debian machine needs libegl1 libegl-mesa0
libgl1-mesa-dri).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from core.errors import InputError
from core.hierarchy import Hierarchy
from formats.atomic import atomic_file

_LEVEL_COLOURS = ["#2b6cb0", "#c05621", "#2f855a", "#6b46c1", "#b7791f", "#c53030", "#319795", "#4a5568", "#805ad5"]


def _pyvista():
    os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    import pyvista as pv

    return pv


def render_hierarchy(path: str | os.PathLike, vertices: np.ndarray, faces: np.ndarray, hierarchy: Hierarchy,
                     title: str = "", panel_size: tuple[int, int] = (300, 400)) -> Path:
    """Write a PNG with one panel per hierarchy level (level 0 = the mesh) to `path`; returns the path.

    vertices: (V, 3) rest positions, metres (Y-up, facing +Z); faces: (F, 3) int;
    hierarchy: from `core.hierarchy.build_hierarchy` over these vertices.
    panel_size: pixels (width, height) per level. Written to a temporary file and renamed.
    """
    from core.geometry import vertex_normals

    pv = _pyvista()
    path = Path(path)
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    # Lines and points sit just off the opaque surface so the far side is hidden, without z-fighting.
    scale = float(np.ptp(v, axis=0).max()) if len(v) else 1.0
    lifted = v + 0.004 * scale * vertex_normals(v, f)
    n = hierarchy.n_levels + 1
    surface = pv.PolyData(v, np.hstack([np.full((len(f), 1), 3), f]).ravel())
    plotter = pv.Plotter(off_screen=True, shape=(1, n), window_size=(panel_size[0] * n, panel_size[1]),
                         border=False)
    try:
        plotter.enable_anti_aliasing = None
        for level in range(n):
            plotter.subplot(0, level)
            plotter.set_background("white")
            idx = hierarchy.vertex_index[level]
            e = hierarchy.edges[level]
            pts = lifted[idx]
            colour = _LEVEL_COLOURS[level % len(_LEVEL_COLOURS)]
            plotter.add_mesh(surface, color="#f2f2f2", lighting=True)
            if len(e):
                lines = pv.PolyData(pts, lines=np.hstack([np.full((len(e), 1), 2), e]).ravel())
                plotter.add_mesh(lines, color=colour, line_width=1.0 if level == 0 else 1.5)
            plotter.add_mesh(pv.PolyData(pts), color=colour, point_size=2.0 if level == 0 else 4.0,
                             render_points_as_spheres=False)
            label = f"level {level}: {len(idx)} vertices, {len(e)} edges"
            plotter.add_text(label if not (title and level == 0) else f"{title}\n{label}", font_size=8,
                             color="black", position="upper_left")
            plotter.view_xy()
            plotter.camera.Elevation(10)
            plotter.camera.zoom(1.2)
        plotter.render()
        with atomic_file(path) as tmp:
            plotter.screenshot(str(tmp))
    except OSError as exc:
        raise InputError(f"render '{path}': cannot be written ({exc.strerror or exc})") from None
    finally:
        plotter.close()
    return path
