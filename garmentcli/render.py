"""`garment render INPUT`: off-screen PNG frames, MP4 and a contact sheet of a baked sequence."""

from __future__ import annotations

import logging
from dataclasses import replace
from pathlib import Path

import click
from tqdm import tqdm

from core.errors import InputError, counted, require_input
from formats.atomic import atomic_dir, refuse_replacing
from formats.render import check_azimuth, check_value_range
from garmentcli.common import (MAX_FPS, FiniteFloatRange, OutputPath, checked_by, input_errors_as_click, obj_up_option,
                               warn_up_unused)

log = logging.getLogger(__name__)

COLORS = ("plain", "error", "penetration", "scalar")
CAMERA_CHOICES = ("front", "side", "back", "orbit")


def _frame_slice(frames: str | None, every: int) -> slice:
    """--frames START:STOP[:STEP] (Python slice, STOP exclusive, STEP >= 1) and --every N as one slice."""
    from core.motion import parse_frame_range

    step = every
    if frames and frames.count(":") == 2:
        frames, text = frames.rsplit(":", 1)
        try:
            step = int(text) if text.strip() else 1
        except ValueError:
            step = 0
        if step < 1:
            raise InputError(f"--frames: expected a positive integer STEP in START:STOP:STEP, got '{text}'")
        if every != 1 and step != 1:
            raise InputError(f"--frames ...:{step} and --every {every}: expected one step, got both")
        step = max(step, every)
    start, stop = parse_frame_range(frames) if frames else (None, None)
    if start is not None and stop is not None and (start < 0) == (stop < 0) and stop <= start:
        raise InputError(f"--frames: expected STOP after START (STOP exclusive), got {start}:{stop}")
    return slice(start, stop, step)


def _at_rates(seq, gt, fps: float | None):
    """INPUT `seq` and --gt `gt` (or None) at their rates: INPUT at --fps where given (warned where it records
    another: overridden), else its own, else GT's, else 30 (said); GT at its own, else INPUT's (its recorded rate
    is never overridden: a GT of another rate is refused as `metrics` refuses it)."""
    if seq.fps is not None and fps is not None and fps != seq.fps:
        log.warning("--fps %g: '%s' records %g fps: rendered at %g", fps, seq.source, seq.fps, fps)
        seq = replace(seq, fps=fps)
    elif seq.fps is None:
        rate = fps or (gt.fps if gt is not None else None)
        if rate is None:
            click.echo(f"note: '{seq.source}' records no frame rate: played at 30 fps (--fps sets it)")
        seq = replace(seq, fps=rate or 30.0)
    if gt is not None and gt.fps is None:
        gt = replace(gt, fps=seq.fps)
    return seq, gt


@click.command(name="render")
@click.argument("input_path", metavar="INPUT", type=click.Path(exists=True, path_type=Path))
@click.option("--out", "out_dir", type=OutputPath(file_okay=False, path_type=Path), default=None,
              help="Output directory [default: <INPUT stem>_render beside INPUT].")
@click.option("--camera", "cameras", type=click.Choice(CAMERA_CHOICES), multiple=True,
              help="Camera preset, repeatable [default: front]. 'orbit' turns once around over the frames.")
@click.option("--color", type=click.Choice(COLORS), default="plain", show_default=True,
              help="plain; error: distance to --gt per vertex (mm); penetration: vertices inside the body in red, the "
                   "body see-through; "
                   "scalar: the per-vertex array of --scalars. --gt alone colours the error, --scalars alone the "
                   "scalar.")
@click.option("--gt", "gt_path", type=click.Path(exists=True, path_type=Path), default=None,
              help="Ground-truth sequence for --color error (same mesh and frame count as INPUT).")
@click.option("--scalars", "scalars_spec", metavar="FILE.npz[:KEY]", default=None,
              help="Per-vertex values (V,) or (T, V) for --color scalar.")
@click.option("--range", "value_range", type=(float, float), default=None, metavar="LO HI", callback=checked_by(check_value_range),
              help="Colour-bar range for error/scalar [default: 0 to the 99th percentile over every frame].")
@click.option("--frames", default=None, metavar="START:STOP[:STEP]",
              help="Frames to render (Python slice, STOP exclusive; ::2 is every 2nd frame).")
@click.option("--every", type=click.IntRange(min=1), default=1, show_default=True, help="Render every N-th frame.")
@click.option("--size", default="1280x720", show_default=True, metavar="WxH", help="Image size in pixels.")
@click.option("--azimuth", type=float, default=0.0, show_default=True, callback=checked_by(check_azimuth),
              help="Turn every camera preset by this many degrees about the up axis (Z), -360 to 360.")
@click.option("--framing", type=click.Choice(("auto", "fixed", "follow")), default="auto", show_default=True,
              help="fixed: one view of the whole animation; follow: track the body; auto: follow when it travels.")
@obj_up_option
@click.option("--fps", type=FiniteFloatRange(min=1.0, max=MAX_FPS), default=None,
              help="Frames per second of INPUT (OBJ frames without a sequence.json, another tool's npz record "
                   "none; a recorded rate is overridden, warned) [default: its recorded rate, else --gt's, else 30]: "
                   "the MP4's rate and the follow camera's half-second smoothing.")
@click.option("--no-body", is_flag=True, help="Draw the garment alone.")
@click.option("--no-ground", is_flag=True, help="Leave out the ground grid.")
@click.option("--no-png", is_flag=True, help="Skip the PNG frames.")
@click.option("--no-mp4", is_flag=True, help="Skip the MP4.")
@click.option("--no-sheet", is_flag=True, help="Skip the contact sheet.")
@click.option("--overwrite", is_flag=True, help="Replace an existing output directory.")
@input_errors_as_click
def render(input_path, out_dir, cameras, color, gt_path, scalars_spec, value_range, frames, every, size, azimuth,
           framing, up, fps, no_body, no_ground, no_png, no_mp4, no_sheet, overwrite):
    """Render INPUT (a baked USD, an OBJ-sequence directory or a sequence .npz) off-screen.

    Draws the garment with the body it moved on (when INPUT carries one) on a
    ground grid and writes OUT/frames/<camera>/frame_NNNN.png, OUT/<camera>.mp4
    and OUT/contact_sheet.png. Needs no display (EGL).
    """
    from formats.render import (RenderOptions, check_render_window, load_vertex_scalars, parse_size, render_outputs,
                                scene_from_sequence)
    from formats.sequence import read_sequence

    try:  # their errors before any work, as click's (exit 2)
        width, height = parse_size(size)
    except InputError as exc:
        raise click.BadParameter(str(exc).removeprefix("--size: "), param_hint="--size") from None
    try:
        frame_slice = _frame_slice(frames, every)
    except InputError as exc:
        raise click.BadParameter(str(exc).removeprefix("--frames: "), param_hint="--frames") from None
    if color == "error" and gt_path is None:
        raise click.BadParameter("--color error needs --gt", param_hint="--gt")
    if color == "scalar" and scalars_spec is None:
        raise click.BadParameter("--color scalar needs --scalars FILE.npz[:KEY]", param_hint="--scalars")
    if gt_path is not None and color not in ("plain", "error"):  # it replaced --color penetration without a word
        raise click.BadParameter(f"colours the error (--color error), got --color {color} as well: leave out one",
                                 param_hint="--gt")
    if scalars_spec is not None and color not in ("plain", "scalar"):
        raise click.BadParameter(f"colours by its values (--color scalar), got --color {color} as well: leave out "
                                 "one", param_hint="--scalars")
    if gt_path is not None:
        color = "error"  # --gt alone means: show the error
    if scalars_spec is not None:
        color = "scalar"
    if value_range is not None and color not in ("error", "scalar"):
        raise click.BadParameter(f"applies to --color error or scalar (the colour bar's range), got --color {color}",
                                 param_hint="--range")
    options = RenderOptions(width=width, height=height, cameras=tuple(dict.fromkeys(cameras)) or ("front",),
                            azimuth_deg=azimuth, framing=framing, show_body=not no_body, ground=not no_ground)
    if out_dir is None:  # beside INPUT; for '.' or '..' beside the folder they name, never inside it
        src = input_path.resolve() if input_path.name in ("", "..") else input_path
        out_dir = src.parent / f"{src.stem}_render"
    refuse_replacing(out_dir, (input_path, gt_path))
    if out_dir.exists() and not overwrite:
        raise click.ClickException(f"output '{out_dir}' exists: pass --overwrite to replace it")
    if no_png and no_mp4 and no_sheet:
        raise click.BadParameter("nothing to write: drop one of --no-png, --no-mp4, --no-sheet", param_hint="--no-png")
    check_render_window()  # before any work or output: VTK crashes on a window it cannot open

    seq = read_sequence(input_path, up=up)
    gt = read_sequence(gt_path, up=up) if gt_path is not None else None
    seq, gt = _at_rates(seq, gt, fps)
    warn_up_unused(up, input_path, gt_path)
    scalars, label = None, "value"
    if scalars_spec is not None:
        file, key = scalars_spec, ""
        if not Path(file).exists() and ":" in scalars_spec:
            file, key = scalars_spec.rsplit(":", 1)
        require_input(file, f"--scalars: file '{file}'")
        scalars = load_vertex_scalars(file, key or None, seq.n_frames, seq.points.shape[1])
        label = key or Path(file).stem
    scene = scene_from_sequence(seq, color=color, gt=gt, scalars=scalars, scalar_label=label,
                                value_range=value_range, frames=frame_slice)
    total = scene.n_frames * len(options.cameras)
    with atomic_dir(out_dir, overwrite, (input_path, gt_path)) as tmp:
        with tqdm(total=total, unit="frame", desc="render", disable=None, leave=False) as bar:
            written = render_outputs(scene, tmp, options, png_frames=not no_png, mp4=not no_mp4, sheet=not no_sheet,
                                     progress=bar.update)
    n_png = len(written["png"])
    click.echo(f"{out_dir}: {counted(scene.n_frames, 'frame')} x {len(options.cameras)} camera(s) at {width}x{height}"
               + (f", {n_png} PNG" if n_png else "") + (f", {len(written['mp4'])} MP4" if written["mp4"] else "")
               + (", contact_sheet.png" if written["sheet"] else ""))
    if written["mp4"] and (width % 2 or height % 2):  # H.264's 4:2:0 colour takes even sizes only
        click.echo(f"note: the MP4 is {width + width % 2}x{height + height % 2} (H.264 needs even sizes: the last "
                   f"{'column' if width % 2 else 'row'}{' and row' if width % 2 and height % 2 else ''} repeated); "
                   "an even --size gives it the PNGs' size", err=True)
