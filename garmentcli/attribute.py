"""`garment attribute MODEL GARMENT MOTION --frame K`: which inputs drive the model's deformation (paper Eq. 16)."""

from __future__ import annotations

import csv
import json
import logging
from pathlib import Path

import click
import numpy as np

from core.errors import InputError
from garmentcli.common import (
    OutputPath,
    betas_option,
    body_option,
    input_errors_as_click,
    load_body_option,
    motion_up_option,
    person_option,
    take_option,
    prepare_motion,
    FiniteFloatRange,
    MAX_FPS,
)


def _read_vertices(path: str) -> np.ndarray:
    try:
        text = Path(path).read_text()
    except OSError as exc:
        raise InputError(f"--vertices '{path}': cannot read it ({exc.strerror or exc})") from None
    except UnicodeDecodeError:
        raise InputError(f"--vertices '{path}': expected whitespace- or comma-separated vertex indices (text), "
                         "got binary content") from None
    try:
        given = [int(tok) for tok in text.replace(",", " ").split()]
    except ValueError:
        raise InputError(f"--vertices '{path}': expected whitespace- or comma-separated vertex indices") from None
    if not given:
        raise InputError(f"--vertices '{path}': expected vertex indices, got none")
    return np.array(list(dict.fromkeys(given)), dtype=np.int64)  # each once: "0 0 0 1" weighed vertex 0 3 times


log = logging.getLogger(__name__)

#: Most --steps: far beyond the nodes a smooth path integral needs (2**31 ran the process out of memory).
MAX_STEPS = 1000
#: The attributions' sum off f(x) - f(x') by more than this share of it plus COMPLETENESS_WARN_M is warned of: 2
#: nodes on two of the skirt's vertices summed to +2.25 mm where the change was -1.25 (the default 50: 0.002 mm).
COMPLETENESS_WARN_SHARE = 0.05
COMPLETENESS_WARN_M = 1e-5


class _ModelPath(click.Path):
    """A model file, or the word 'default' for the shipped one (`core.model_deform.DEFAULT_MODEL`, inside the
    installed package, where a user has no path to it)."""

    def convert(self, value, param, ctx):
        if value == "default":
            from core.model_deform import DEFAULT_MODEL

            value = str(DEFAULT_MODEL)
        return super().convert(value, param, ctx)


@click.command(name="attribute")
@click.argument("model_path", metavar="MODEL", type=_ModelPath(dir_okay=False, exists=True))
@click.argument("garment_path", metavar="GARMENT", type=click.Path(dir_okay=False, exists=True))
@click.argument("motion_path", metavar="MOTION", type=click.Path(dir_okay=False, exists=True))
@click.option("--frame", type=click.IntRange(min=0), required=True, help="Output frame to explain (after --fps).")
@click.option("--steps", type=click.IntRange(min=1, max=MAX_STEPS), default=50, show_default=True,
              help="Gauss-Legendre nodes N_s of the path integral.")
@click.option("--vertices", "vertices_path", type=click.Path(dir_okay=False), default=None,
              help="Explain the mean deformation of these vertices only (text file of indices). Default: all.")
@click.option("--top", type=click.IntRange(min=1), default=15, show_default=True, help="Rows printed.")
@body_option
@betas_option
@click.option("--fps", type=FiniteFloatRange(min=1.0, max=MAX_FPS), default=30.0, show_default=True,
              help="Frame rate the motion is resampled to.")
@motion_up_option
@person_option
@take_option
@click.option("--out", "out_dir", type=OutputPath(file_okay=False), default=None,
              help="Output directory [default: <garment>_<motion>_f<K>_attribution].")
@click.option("--overwrite", is_flag=True, help="Replace an existing output directory.")
@click.option("--no-render", is_flag=True, help="Skip the heatmap renders.")
@input_errors_as_click
def attribute(model_path, garment_path, motion_path, frame, steps, vertices_path, top, body_path, fps, out_dir,
              overwrite, no_render, motion_up="z", person=None, take=None, betas="auto"):
    """Attribute the model's deformation of GARMENT at frame K of MOTION to its inputs.

    MODEL: a model file (.pt), or `default` for the model shipped with garment.

    Path-integrated gradients (Aumann-Shapley values) from a baseline (the body still in
    the rest pose, mean shape, zero garment features) with Gauss-Legendre quadrature.
    Writes OUT/attributions.md and .csv (input groups: joint rotations, body velocities,
    body shape, garment features), attributions.npz (every attribution, f values) and
    heatmaps of the deformation and of the garment-feature attributions per vertex.
    """
    import torch

    from core.attribution import DeformationTarget, attribution_table, integrated_gradients
    from core.model_data import prepare_garment
    from core.model_deform import model_body, skeleton_mismatch
    from formats.atomic import atomic_dir, refuse_replacing
    from core.model_deform import trained_betas
    from formats.checkpoint import load_model
    from formats.obj import read_garment

    if not np.isfinite(fps) or fps <= 0:
        raise click.BadParameter(f"expected a positive frame rate, got {fps}", param_hint="--fps")
    vertices = _read_vertices(vertices_path) if vertices_path else None
    model, data = load_model(model_path)
    garment = read_garment(garment_path)
    body = load_body_option(body_path)
    view = model_body(body, model.config.n_joints)
    if view is None:
        raise click.ClickException(f"{skeleton_mismatch(str(model_path), model.config.n_joints, body)}: pass the "
                                   "--body it was made for")
    motion, _ = prepare_motion(motion_path, fps, None, 0, betas, body=body, motion_up=motion_up, person=person,
                               take=take)
    out = Path(out_dir or f"{Path(garment_path).stem}_{Path(motion_path).stem}_f{frame}_attribution")
    inputs = (model_path, garment_path, motion_path, vertices_path, body_path)
    refuse_replacing(out, inputs)
    if out.exists() and not overwrite:
        raise click.ClickException(f"output '{out}' exists: pass --overwrite to replace it")
    g = prepare_garment(garment, view, model.config, source=garment_path, near=False).inputs
    target = DeformationTarget(model, g, view, motion, frame, vertices, trained_betas(data["meta"]),
                               vertices_from=f"--vertices '{vertices_path}'")
    with click.progressbar(length=1, label=f"attribute ({steps} nodes)") as bar:
        att = integrated_gradients(target, target.input, target.baseline, steps)
        bar.update(1)
    rows = attribution_table(att, model.config.n_joints, model.config.window)
    gap = att.f_input - att.f_baseline
    lines = [f"# Attribution of the deformation of {Path(garment_path).name} at frame {frame} of "
             f"{Path(motion_path).name}",
             "", f"Model `{model_path}`; f = mean |x - x_lbs| over {len(target.vertices)} vertices; "
             f"f(input) = {att.f_input * 1e3:.3f} mm, f(baseline) = {att.f_baseline * 1e3:.3f} mm; "
             f"sum of attributions {att.total * 1e3:.3f} mm (completeness error "
             f"{att.completeness_error * 1e3:.4f} mm, {steps} Gauss-Legendre nodes).", "",
             "| input | attribution (mm) | share of f(x) - f(x') |", "|---|---:|---:|"]
    for name, value in rows:
        share = value / gap if gap else float("nan")
        lines.append(f"| {name} | {value * 1e3:.4f} | {share:.3f} |")
    with torch.no_grad():
        verts = target.verts(target.input)
        per_vertex = torch.linalg.norm(verts - target.lbs, dim=-1).numpy()
        verts = verts.numpy()
    feature_map = att.phi.garment.abs().sum(1).numpy()
    with atomic_dir(out, overwrite, inputs) as tmp:
        (tmp / "attributions.md").write_text("\n".join(lines) + "\n")
        with open(tmp / "attributions.csv", "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["input", "attribution_m"])
            w.writerows(rows)
        np.savez_compressed(tmp / "attributions.npz", **{f"phi_{k}": v.numpy() for k, v in zip(att.phi.NAMES,
                                                                                              att.phi.as_tuple())},
                            f_input=att.f_input, f_baseline=att.f_baseline, deformation_m=per_vertex,
                            garment_feature_attribution=feature_map, vertices=target.vertices)
        (tmp / "summary.json").write_text(json.dumps({
            "model": str(model_path), "garment": str(garment_path), "motion": str(motion_path), "frame": frame,
            "steps": steps, "f_input_m": att.f_input, "f_baseline_m": att.f_baseline, "sum_m": att.total,
            "completeness_error_m": att.completeness_error, "top": rows[:top]}, indent=2))
        if not no_render:
            _render_heatmaps(tmp, g, verts, per_vertex, feature_map, body, motion, frame)
    click.echo("\n".join([lines[2], ""] + lines[4:6 + top]))
    if abs(att.completeness_error) > COMPLETENESS_WARN_SHARE * abs(gap) + COMPLETENESS_WARN_M:
        log.warning(f"attribute: the attributions sum to {att.total * 1e3:.3f} mm where f(x) - f(x') is "
                    f"{gap * 1e3:.3f} mm (completeness error {att.completeness_error * 1e3:.3f} mm): too few nodes for "
                    f"this path; pass more --steps (now {steps})")
    click.echo(f"wrote {out}")


def _render_heatmaps(directory: Path, g, verts, deformation, feature_map, body, motion, frame) -> None:
    """heatmap_deformation.png and heatmap_garment_features.png on the posed garment `verts` (front camera)."""
    from core.motion import poses_for_body
    from formats.render import RenderError, RenderOptions, Scene, render_image, robust_range, write_png

    body_pts, _ = body.pose(poses_for_body(motion, body.n_joints)[frame:frame + 1], motion.trans[frame:frame + 1],
                            motion.betas)
    for name, values, label in (("deformation", deformation * 1e3, "|x - x_lbs| (mm)"),
                                ("garment_features", feature_map * 1e3, "|attribution| (mm)")):
        scene = Scene(garment_points=verts[None].astype(np.float32), garment_faces=g.faces.numpy(),
                      frame_numbers=np.array([frame]),
                      body_points=body_pts, body_faces=body.faces, vertex_values=values[None], value_label=label,
                      value_range=robust_range(values), value_cmap="viridis")
        try:
            write_png(directory / f"heatmap_{name}.png",
                      render_image(scene, 0, "front", RenderOptions(width=960, height=720, framing="fixed")))
        except RenderError as exc:
            click.echo(f"warning: no heatmap render ({exc})", err=True)
            return
