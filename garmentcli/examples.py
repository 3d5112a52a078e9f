"""`garment examples`: regenerate the example garments (OBJ) and motions (AMASS-style npz)."""

from __future__ import annotations

import shutil
from pathlib import Path

import click

from formats.atomic import atomic_dir
from garmentcli.common import MAX_FPS, FiniteFloatRange, OutputPath, input_errors_as_click


@click.command(name="examples")
@click.option("--out", "out_dir", type=OutputPath(file_okay=False), default="examples", show_default=True,
              help="Directory to write the examples into.")
@click.option("--fps", type=FiniteFloatRange(min=1.0, max=MAX_FPS), default=60.0, show_default=True,
              help="Frame rate of the generated motions (1 to 1000).")
@click.option("--overwrite", is_flag=True,
              help="Replace the examples in an existing output directory (its other files are kept).")
@input_errors_as_click
def examples(out_dir, fps, overwrite):
    """Write the example garments, fitted to the default body, and the example motions.

    Deterministic on one machine: the files in the repository's examples/
    were made by `garment examples --out examples --overwrite`. On another
    CPU the t-shirt may differ at up to a few hundred of its 6,698 vertices
    by up to 8 mm (the generator's thresholds decide some of its vertices
    by that CPU's float rounding; on a Zen 4 EPYC: 78 to 167 vertices, 7-8
    mm, depending on the commit), and the trousers' and jumpsuit's UVs may
    differ (an AVX2 Xeon: one face, and the jumpsuit's layout rescaled by
    0.5 %); any garment may differ in its last written digit (an AMD EPYC:
    the dress, skirt, trousers and jumpsuit by 1 um). Each change is a new
    content hash: caches and psd fits made on the shipped files do not
    carry over.
    """
    from core.body import default_body
    from core.garmentgen import generate_example_garments
    from core.motiongen import generate_example_motions
    from formats.motion import save_motion
    from formats.obj import write_obj

    out = Path(out_dir)
    if out.exists() and not overwrite:  # before the generators' seconds of work
        raise click.ClickException(f"output '{out}' exists: pass --overwrite to replace it")
    body = default_body()
    garments = generate_example_garments(body)
    motions = generate_example_motions(fps=fps)
    written = {f"{name}.obj" for name in garments} | {f"{name}.npz" for name in motions}
    listed = list(out.iterdir()) if out.is_dir() else []
    keep = [p for p in listed if p.name not in written]
    blocked = sorted(p.name for p in listed if p.name in written and not p.is_file())
    if blocked:  # a folder of the user's where an example goes is not replaced by it
        raise click.ClickException(f"'{out / blocked[0]}' is a folder where an example file goes: move it, or "
                                   "write the examples elsewhere with --out")
    with atomic_dir(out, overwrite) as tmp:
        for p in keep:  # every file and folder but the examples' own (a README, textures, a garment of the user's)
            if p.is_dir():
                shutil.copytree(p, tmp / p.name, symlinks=True)
            elif p.is_file():
                shutil.copy2(p, tmp / p.name)
        for name, g in garments.items():
            write_obj(tmp / f"{name}.obj", g.vertices, g.faces, g.uvs, g.face_uvs,
                      header=f"garment example '{name}': made by `garment examples`, fitted to the default body")
            click.echo(f"{out / (name + '.obj')}: {g.n_vertices} vertices, {g.n_faces} triangles")
        for name, m in motions.items():
            save_motion(tmp / f"{name}.npz", m)
            click.echo(f"{out / (name + '.npz')}: {m.n_frames} frames at {m.fps:g} fps")
        others = sorted(p.name for p in keep if p.suffix in (".obj", ".npz"))
        if others:
            click.echo(f"{out}: kept {', '.join(others[:5])}{', ...' if len(others) > 5 else ''} (not examples: "
                       "remove them yourself where they are stale ones)")
