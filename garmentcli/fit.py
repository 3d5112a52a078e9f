"""`garment fit GARMENT --data DIR`: fit the garment's blend shapes to its simulations (`bake --method psd`)."""

from __future__ import annotations

from pathlib import Path

import click
import numpy as np

from core.errors import counted
from garmentcli.common import (
    FiniteFloatRange,
    OutputPath,
    body_option,
    check_dataset_body,
    input_errors_as_click,
    load_body_option,
    require_file,
)


def _is(template, garment) -> bool:
    """Whether a dataset's garment `template` is `garment`: the same bytes, or the same mesh through a unit round
    trip, an export or faces starting at another corner (`core.psd.same_mesh`, as `bake --method psd` takes a fit)."""
    from core.psd import same_mesh

    return template.content_hash() == garment.content_hash() or same_mesh(template.vertices, template.faces,
                                                                           garment.vertices, garment.faces)


@click.command(name="fit")
@click.argument("garment_path", metavar="GARMENT", type=click.Path(dir_okay=False))
@click.option("--data", "data_dir", required=True, type=click.Path(file_okay=False),
              help="A `garment dataset` directory that simulated GARMENT (the same mesh).")
@click.option("--out", "out_path", type=OutputPath(dir_okay=False), default=None,
              help="Fit file to write [default: <garment>.psd.npz beside GARMENT].")
@click.option("--rank", type=click.IntRange(min=1), default=None, help="Principal offsets kept [default: 64].")
@click.option("--ridge", type=FiniteFloatRange(min=0), default=None, help="Ridge weight [default: 10].")
@body_option
@click.option("--overwrite", is_flag=True, help="Replace an existing fit file.")
@input_errors_as_click
def fit(garment_path, data_dir, out_path, rank, ridge, body_path, overwrite):
    """Fit GARMENT's blend shapes to its simulations in a `garment dataset` directory: LBS plus rest-frame
    offsets linear in the pose, its rate, the root's motion and the body shape (pose-space deformation), fitted
    on the training split and measured on the others. `bake --method psd --fit FILE` then bakes it at about
    LBS's speed, near the simulator on motions like those of the dataset. The sequences simulated so far are
    used (a dataset still running can be fitted)."""
    from core.deform import LBSDeformer
    from core.model_data import manifest_items
    from core.motion import sequence_motion
    from core.psd import DEFAULT_RANK, DEFAULT_RIDGE, PSDDeformer, fit_psd
    from formats.dataset import MANIFEST, read_manifest, read_sequence, sequence_path
    from formats.obj import read_garment, read_obj
    from formats.psd import save_fit

    source = Path(garment_path)
    require_file(source)
    out = Path(out_path) if out_path else source.with_name(f"{source.stem}.psd.npz")
    if out.suffix.lower() != ".npz":
        raise click.BadParameter(f"expected a .npz fit file (what is written), got '{out}'", param_hint="--out")
    if out.exists() and not overwrite:
        raise click.ClickException(f"output '{out}' exists: pass --overwrite to replace it")
    data = Path(data_dir)
    manifest = read_manifest(data)
    if manifest is None:
        raise click.BadParameter(f"'{data}': expected a `garment dataset` directory (with manifest.json)",
                                 param_hint="--data")
    garment = read_garment(source)
    body = load_body_option(body_path)
    check_dataset_body(data, manifest, body_path)
    templates = sorted((data / "garments").glob("*.obj"))
    names = [t.stem for t in templates if _is(read_obj(t), garment)]
    if not names:
        raise click.BadParameter(f"'{data}' did not simulate '{source.name}' (its garments: "
                                 f"{', '.join(t.stem for t in templates) or 'none'}; the mesh must be the same)",
                                 param_hint="--data")
    splits: dict[str, list] = {"train": [], "val": [], "test": []}
    for item_id, it in manifest_items(manifest, str(data / MANIFEST)).items():  # each checked as train checks it
        path = sequence_path(data, item_id)
        if it.get("garment") in names and it.get("split") in splits and path.is_file():
            seq = read_sequence(path)
            splits[it["split"]].append((sequence_motion(seq, item_id, drop_settle=True),
                                        seq.positions[seq.n_settle:]))
    if not splits["train"]:
        raise click.BadParameter(f"'{data}': expected simulated training sequences of '{names[0]}', found none",
                                 param_hint="--data")
    ridge = DEFAULT_RIDGE if ridge is None else ridge
    try:
        result = fit_psd(garment, body, splits["train"], rank or DEFAULT_RANK, ridge)
    except np.linalg.LinAlgError:  # no ridge and fewer independent frames than regressors: no unique fit
        frames = sum(len(gt) for _, gt in splits["train"])
        raise click.BadParameter(f"expected a weight that makes the fit unique, got {ridge:g}: the "
                                 f"{frames} training frames do not determine the blend shapes alone (the "
                                 f"default is {DEFAULT_RIDGE:g})", param_hint="--ridge") from None
    errors = {}
    psd, lbs = PSDDeformer(result), LBSDeformer()  # each binds the garment once, for every split
    for split in ("val", "test"):
        if splits[split]:
            e = {motion.name: [float(np.linalg.norm(d.deform(garment, body, motion) - gt, axis=-1).mean() * 1e3)
                               for d in (psd, lbs)] for motion, gt in splits[split]}
            errors[split] = {"sequences": len(e), "psd_mm": float(np.mean([a for a, _ in e.values()])),
                             "lbs_mm": float(np.mean([b for _, b in e.values()])),
                             # the motions the fit does not carry over to (a split's mean can hide them)
                             "worse_than_lbs": {k: {"psd_mm": a, "lbs_mm": b} for k, (a, b) in e.items() if a > b}}
    result.meta.update({"data": str(data.resolve()), "garment": names[0], "errors": errors})
    save_fit(out, result)
    measured = "; ".join(f"{split} ({counted(v['sequences'], 'sequence')}): {v['psd_mm']:.1f} mm from the "
                         f"simulator, LBS {v['lbs_mm']:.1f} mm" + _worse(v, ridge)
                         for split, v in errors.items()) or "no validation sequences yet"
    asked = rank or DEFAULT_RANK
    cut = (f" (--rank {asked} asked: at most one fewer than the {result.meta['frames']} training frames)"
           if result.rank < asked else "")
    click.echo(f"{out}: {counted(result.rank, 'blend shape')}{cut} of '{source.name}' fitted to "
               f"{counted(result.meta['sequences'], 'sequence')} ({result.meta['frames']} frames) of '{data}'; "
               f"{measured}")


#: `fit` advises a larger --ridge where the fit came out worse than LBS only below this (at 1e12 the fit is the
#: mean offset alone, and a larger one was still advised).
RIDGE_ADVICE_MAX = 1e6


def _worse(errors: dict, ridge: float) -> str:
    """What `fit` says of a split's motions worse than LBS (`errors`: a split's record) fitted at --ridge `ridge`,
    or ''."""
    worse = errors["worse_than_lbs"]
    if not worse:
        return ""
    # a ridge far above the frames' own weight leaves the mean offset alone: a larger one changes nothing
    advice = "fit on more of them" + (", or a larger --ridge" if ridge < RIDGE_ADVICE_MAX else "")
    listed = ", ".join(f"'{k}' {v['psd_mm']:.1f} against {v['lbs_mm']:.1f} mm" for k, v in list(worse.items())[:3])
    more = f" and {len(worse) - 3} more" if len(worse) > 3 else ""
    return (f" (worse than LBS on {counted(len(worse), 'motion')}: {listed}{more}: the fit does not carry "
            f"over to these motions; {advice})")
