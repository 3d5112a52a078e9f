"""Render speed: seconds per frame of `formats.render` at 1280x720 (off-screen, EGL), written as a table.

Scene: an example garment baked with lbs on examples/walk.npz (default body),
or, without the examples, a synthetic garment/body pair of similar size. Times
the window set-up once, then per frame: points/normals update + render +
pixel read-back ("render"), PNG encoding, and MP4 encoding, for each camera
preset. Writes benchmarks/results/render_speed.md.

    python benchmarks/render_speed.py [--garment examples/dress.obj] [--frames 60]
"""

from __future__ import annotations

import argparse
import os
import platform
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def example_scene(garment_path: Path, motion_path: Path, n_frames: int):
    from core.body import default_body
    from core.deform import LBSDeformer
    from core.motion import poses_for_body, resample, select_frames
    from formats.motion import load_motion
    from formats.obj import read_obj
    from formats.render import Scene

    body = default_body()
    motion = select_frames(resample(load_motion(motion_path), 30.0), 0, n_frames)
    garment = read_obj(garment_path)
    points = LBSDeformer().deform(garment, body, motion)
    body_points, _ = body.pose(poses_for_body(motion, body.n_joints), motion.trans, motion.betas)
    return Scene(points, garment.faces, body_points.astype(np.float32), body.faces, fps=30.0), garment_path.name


def synthetic_scene(n_frames: int):
    from formats.render import Scene
    from tests.meshes import icosphere

    vb, fb = icosphere(5, radius=0.25)   # 10k vertices, like a body
    vg, fg = icosphere(4, radius=0.3)    # 2.5k vertices
    shift = np.array([[0.0, -0.02 * t, 0.9] for t in range(n_frames)])[:, None]
    return (Scene((vg[None] + shift).astype(np.float32), fg, (vb[None] * [1, 1, 3] + shift).astype(np.float32), fb,
                  fps=30.0), "synthetic spheres")


def main() -> None:
    from formats.report import write_markdown

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--garment", type=Path, default=ROOT / "examples" / "dress.obj")
    ap.add_argument("--motion", type=Path, default=ROOT / "examples" / "walk.npz")
    ap.add_argument("--frames", type=int, default=60)
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "render_speed.md")
    args = ap.parse_args()

    from formats.render import Mp4Writer, RenderOptions, Renderer, write_png

    if args.garment.is_file() and args.motion.is_file():
        scene, label = example_scene(args.garment, args.motion, args.frames)
    else:
        scene, label = synthetic_scene(args.frames)
    options = RenderOptions(width=1280, height=720, cameras=("front", "side", "orbit"))
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        renderer = Renderer(scene, options)
        setup = time.perf_counter() - t0
        with renderer:
            renderer.image(0, "front")  # warm-up (shader compilation)
            for cam in options.cameras:
                t_render = t_png = 0.0
                video = Mp4Writer(Path(tmp) / f"{cam}.mp4", 30.0)
                t_mp4 = 0.0
                for t in range(scene.n_frames):
                    a = time.perf_counter()
                    img = renderer.image(t, cam)
                    b = time.perf_counter()
                    write_png(Path(tmp) / f"{cam}_{t:04d}.png", img)
                    c = time.perf_counter()
                    video.append(img)
                    d = time.perf_counter()
                    t_render += b - a
                    t_png += c - b
                    t_mp4 += d - c
                a = time.perf_counter()
                video.close()
                t_mp4 += time.perf_counter() - a
                n = scene.n_frames
                rows.append((cam, t_render / n, t_png / n, t_mp4 / n, (t_render + t_png + t_mp4) / n))
    import pyvista
    import vtk

    gl = "EGL (" + os.environ.get("VTK_DEFAULT_OPENGL_WINDOW", "?") + ")"
    lines = [
        "# Render speed (formats/render.py, 1280x720, off-screen)\n",
        f"- scene: {label} on the walk, {scene.n_frames} frames; garment {scene.garment_points.shape[1]} vertices, "
        f"body {0 if scene.body_points is None else scene.body_points.shape[1]} vertices",
        f"- machine: {platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, software OpenGL via {gl}; "
        f"pyvista {pyvista.__version__}, vtk {vtk.vtkVersion.GetVTKVersion()}",
        f"- window set-up (once per scene): {setup:.2f} s",
        "- render = update points and normals, draw, read pixels back; PNG/MP4 = encoding that image\n",
        "| camera | render s/frame | PNG s/frame | MP4 s/frame | total s/frame | frames/s |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    lines += [f"| {c} | {r:.4f} | {p:.4f} | {m:.4f} | {tot:.4f} | {1 / tot:.1f} |" for c, r, p, m, tot in rows]
    write_markdown(args.out, lines, show=True)


if __name__ == "__main__":
    main()
