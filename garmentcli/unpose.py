"""`garment unpose GARMENT --pose tpose|apose|MOTION [--betas B0,...] [--scale S] [--turn T] [--move DX,DY,DZ]`:
move a garment authored on a posed, shaped or otherwise placed body, or written in other units, to the rest pose
and mean shape."""

from __future__ import annotations

import logging
from dataclasses import replace
from pathlib import Path

import click
import numpy as np

from core.skinning import TURNS, turn_matrix
from core.unpose import A_POSE_ARM_DEGREES
from formats.obj import STAGE_SUFFIXES
from garmentcli.common import (
    _check_betas_range,
    FiniteFloatRange,
    OutputPath,
    body_option,
    foreign_betas,
    collected_notes,
    input_errors_as_click,
    load_body_option,
    parse_betas,
    parse_numbers,
    require_file,
    option_file,
)


class _AboutTheInput(logging.Filter):
    """Rewrites the rest-fit warning of `bind_garment` on the unposed result: it names GARMENT (the input), not
    the output file, and asks about the pose and shape given instead of advising `garment unpose`."""

    def __init__(self, source: Path, what: str):
        super().__init__()
        self.source, self.what = source, what

    def filter(self, record: logging.LogRecord) -> bool:
        args = record.args
        if isinstance(args, tuple) and args and str(record.msg).startswith("garment mesh '%s'"):
            cause = args[-1]
            if isinstance(cause, str) and "garment unpose" in cause:
                cause = (f"unposed from {self.what}: was '{self.source.name}' authored in that pose and shape? "
                         f"check --pose and --betas")
            record.args = (f"{self.source}", *args[1:-1], cause)
        return True


def _check_shape(ctx, param, value):
    return None if value is None else parse_betas(value)


#: --move: at most this far (metres) on each axis; a garment further off is not on the body (a unit mix-up?).
MAX_MOVE_M = 10.0


def _check_move(ctx, param, value):
    if value is None:
        return None
    move = parse_numbers(value, "--move", count=3)
    if np.abs(move).max() > MAX_MOVE_M:
        raise click.BadParameter(f"expected metres, at most {MAX_MOVE_M:g} on each axis, got '{value}'",
                                 param_hint="--move")
    return move


#: --scale: a file's metres per unit lie within these (a garment in micrometres or kilometres is no unit mix-up).
SCALE_RANGE = (1e-4, 1e3)


def _check_scale(ctx, param, value):
    if value is None:
        return None
    if not SCALE_RANGE[0] <= value <= SCALE_RANGE[1]:
        raise click.BadParameter(f"expected metres per unit of the file, {SCALE_RANGE[0]:g} to {SCALE_RANGE[1]:g} "
                                 f"(0.01: centimetres, 0.001: millimetres, 0.0254: inches), got {value:g}",
                                 param_hint="--scale")
    return value


def _write_obj(out: Path, garment, rest_points: np.ndarray, header: str, overwrite: bool) -> None:
    """`garment` at `rest_points` as its file has it (its points in order, its quads, UVs and materials), as bake
    writes its outputs; its material libraries beside it (where it is written elsewhere than GARMENT's folder)."""
    from formats.atomic import atomic_file
    from formats.mtl import copy_material_libraries, write_mtl
    from formats.obj import write_obj

    *mesh, materials = garment.written(rest_points)
    libraries = () if garment.source is None else garment.source.libraries
    looks = None if garment.source is None or libraries else garment.source.looks  # a USD's preview materials
    copies = [lib for lib in libraries if (out.parent / Path(lib).name).resolve() != Path(lib).resolve()]
    taken = [out.parent / Path(lib).name for lib in copies if (out.parent / Path(lib).name).exists()]
    if looks and out.with_suffix(".mtl").exists():
        taken.append(out.with_suffix(".mtl"))
    if taken and not overwrite:
        raise click.ClickException(f"output '{taken[0]}' (GARMENT's material library, written beside the result) "
                                   f"exists: pass --overwrite to replace it")
    names = [Path(lib).name for lib in libraries if lib not in copies]
    names += copy_material_libraries(copies, out.parent)
    if looks:
        write_mtl(out.with_suffix(".mtl"), looks)
        names.append(out.with_suffix(".mtl").name)
    with atomic_file(out) as tmp:
        write_obj(tmp, *mesh, header=header, materials=materials, libraries=names)


class TurnType(click.ParamType):
    """--turn: a name in `core.skinning.TURNS` or an axis and degrees (`core.skinning.turn_matrix`: y-15)."""

    name = "turn"
    choices = tuple(TURNS)

    def convert(self, value, param, ctx):
        try:
            turn_matrix(str(value))
        except ValueError as exc:
            self.fail(str(exc), param, ctx)
        return value


@click.command(name="unpose")
@click.argument("garment_path", metavar="GARMENT", type=click.Path(dir_okay=False))
@click.option("--pose", "pose_spec", required=True, metavar="tpose|apose|MOTION",
              help="The pose the garment was authored in: 'tpose' (the rest pose: only --betas is taken off), "
                   "'apose' (the arms lowered by --arm-angle), or a motion file of any format bake reads (AMASS-style "
                   ".npz, BVH, FBX, glTF, USD, ...: its --frame's joint rotations and betas; its root and trans are "
                   "ignored: the garment is in the body's frame).")
@click.option("--betas", "betas_text", default=None, callback=_check_shape, metavar="B0,B1,...",
              help="The body shape the garment was authored on (coefficients of the body's own basis, missing ones "
                   "0), taken off as well: the result fits the mean shape that bake shapes to each motion's "
                   "betas [default: a motion file's betas on a --body, else the mean shape: a motion's betas belong to the "
                   "body model it was fitted to].")
@click.option("--scale", type=float, default=None, callback=_check_scale, metavar="S",
              help="Metres per unit of GARMENT, multiplied in first, about the origin: 0.01 for a file in "
                   "centimetres, 0.001 millimetres, 0.0254 inches (bake names it for a garment in other units).")
@click.option("--turn", "turns", type=TurnType(), multiple=True,
              help="Turn the garment first (after --scale), as bake names it for a garment written in another frame: "
                   "z-up (-90 degrees about X: authored Z-up), x+90 (+90 degrees about X), backwards (180 degrees "
                   "about Y), x+180, y+90, y-90, z+90, z-90, z+180, or an axis and degrees (y-15: -15 degrees "
                   "about Y, right-handed); given several times, each in turn (Unreal's Z-up facing +Y: --turn z-up "
                   "--turn backwards).")
@click.option("--move", "move", default=None, callback=_check_move, metavar="DX,DY,DZ",
              help="Metres to move the garment by first, in the body's frame (Y up): for a garment authored on a "
                   "body whose origin stands elsewhere (bake names the move).")
@click.option("--arm-angle", type=FiniteFloatRange(min=-90.0, max=90.0), default=None,
              help=f"apose: degrees each arm is lowered from the T-pose, -90 to 90 [default: {A_POSE_ARM_DEGREES:g}].")
@click.option("--frame", type=click.IntRange(min=0), default=None, help="--pose MOTION: the frame to use [default: 0].")
@body_option
@click.option("--out", "out_path", type=OutputPath(dir_okay=False), default=None,
              help="Output OBJ, or USD (.usd/.usda/.usdc: one static mesh, Y-up metres, its materials as "
                   "UsdPreviewSurface) [default: <garment>_rest.obj beside GARMENT].")
@click.option("--overwrite", is_flag=True, help="Replace an existing output file.")
@input_errors_as_click
def unpose(garment_path, pose_spec, arm_angle, frame, body_path, out_path, overwrite, betas_text=None, move=None,
           turns=(), scale=None):
    """Move GARMENT (OBJ or USD), authored on the body in another pose, shape or place, to the body's rest pose
    (T-pose) and mean shape.

    Each vertex follows the body part it lies on, by the inverse of the linear blend skinning that
    `bake --method lbs` applies. Writes an OBJ or USD (UVs and materials kept) that `bake` and the other
    commands accept.
    """
    from core.motion import poses_for_body
    from core.skinning import Placement, bind_garment
    from core.unpose import a_pose, unpose_garment
    from formats.motion import MOTION_SUFFIXES, load_motion
    from formats.obj import read_garment

    source = Path(garment_path)
    require_file(source)
    if source.suffix.lower() == ".npz":  # a motion given as GARMENT: said first, not what its options lack
        read_garment(source)
    out = Path(out_path) if out_path else source.with_name(f"{source.stem}_rest.obj")
    if out.suffix.lower() not in (".obj", *STAGE_SUFFIXES):
        raise click.BadParameter(f"expected an .obj, .usd, .usda or .usdc file, got '{out}'", param_hint="--out")
    if out.resolve() == source.resolve():
        raise click.BadParameter(f"'{out}' is GARMENT itself: write the result elsewhere", param_hint="--out")
    body = load_body_option(body_path)
    betas = None
    if arm_angle is not None and pose_spec != "apose":
        raise click.UsageError(f"--arm-angle applies to --pose apose only (got --pose {pose_spec})")
    if pose_spec == "tpose":
        if frame is not None:
            raise click.UsageError("--frame applies to a motion file only (got --pose tpose)")
        if betas_text is None and move is None and not turns and scale is None:
            raise click.UsageError("--pose tpose takes off the body shape, place, frame and units only: give them "
                                   "with --betas B0,B1,..., --move DX,DY,DZ, --turn or --scale")
        pose = np.zeros((body.n_joints, 3), dtype=np.float32)
        what = "the rest pose"
    elif pose_spec == "apose":
        if frame is not None:
            raise click.UsageError("--frame applies to a motion file only (got --pose apose)")
        pose = a_pose(body, A_POSE_ARM_DEGREES if arm_angle is None else arm_angle)
        what = f"A-pose, arms lowered {A_POSE_ARM_DEGREES if arm_angle is None else arm_angle:g} degrees"
    elif pose_spec.lower().endswith(MOTION_SUFFIXES):  # POSE.NPZ too, as every other command reads a motion
        option_file(pose_spec, "--pose")
        motion = load_motion(pose_spec, fps=30.0, world_checks=False)  # rotations only: no fps, root or trans
        k = frame or 0
        if k >= motion.n_frames:
            raise click.BadParameter(f"expected a frame in 0..{motion.n_frames - 1} of '{pose_spec}', got {k}",
                                     param_hint="--frame")
        pose, betas = poses_for_body(motion, body.n_joints)[k], motion.betas
        what = f"frame {k} of '{pose_spec}'"
        if body_path is None and betas is not None and np.any(betas != 0) and betas_text is None:
            # fitted to SMPL's (or SMPL+H's, SMPL-X's) shape basis, not the embedded body's own: as bake does
            click.echo("warning: " + foreign_betas(f"pose '{pose_spec}'", "taken off as its mean shape (pass --body "
                                                   "with the model the pose was fitted to, or --betas the embedded "
                                                   "body's coefficients)"), err=True)
            betas = None
    else:
        raise click.BadParameter(f"expected 'tpose', 'apose' or a motion file ({', '.join(MOTION_SUFFIXES)}), got "
                                 f"'{pose_spec}'", param_hint="--pose")
    if betas_text is not None:  # fewer than the body has: the rest are 0, as --help says (no warning)
        betas = betas_text if len(betas_text) >= body.n_betas else body.fit_betas(betas_text, warn=False)
    if betas is not None:  # as bake checks them: 1e30 overflowed, 50 wrote the garment 27 % inside the body
        _check_betas_range(betas, "--betas" if betas_text is not None else f"pose '{pose_spec}'")
    if betas_text is not None:
        shown = ",".join(f"{b:g}" for b in betas_text[:10]) + (f",... ({len(betas_text)} betas)"
                                                                if len(betas_text) > 10 else "")
        what += f", shape {shown}"
    moved_by = ", ".join(([f"scaled by {scale:g}"] if scale is not None else [])
                         + [f"turned {turn}" for turn in turns]
                         + ([] if move is None else ["moved by " + ",".join(f"{m:g}" for m in move) + " m"]))
    if moved_by:
        what += ", " + moved_by
    if out.exists() and not overwrite:
        raise click.ClickException(f"output '{out}' exists: pass --overwrite to replace it")
    # What this command does to the file before the pose and shape are taken off: a fix named on its result
    # follows it, in one command (`core.skinning.unpose_command`).
    given = Placement(1.0 if scale is None else scale, tuple(turns), (0.0, 0.0, 0.0) if move is None else tuple(move),
                      "".join((f" --pose {pose_spec}", "" if arm_angle is None else f" --arm-angle {arm_angle:g}",
                               "" if frame is None else f" --frame {frame}",
                               "" if betas_text is None else " --betas " + ",".join(f"{b:g}" for b in betas_text))),
                      "" if body_path is None else f" --body {body_path}")
    garment = read_garment(source, given.scale)  # scaled as read: the seams are welded in metres
    authored = garment.vertices  # as scaled: the largest move reported is in metres
    if turns or move is not None:
        garment = replace(garment, vertices=replace(given, scale=1.0).apply(garment.vertices).astype(np.float32))
    rest, report = unpose_garment(garment, body, pose, betas, source=str(source))
    report["max_move_m"] = float(np.linalg.norm(rest.vertices - authored, axis=1).max(initial=0.0))
    # The result must be what bake accepts: refused or warned here, naming GARMENT (what the user can fix).
    about_input = _AboutTheInput(source, what)
    skinning_log = logging.getLogger("core.skinning")
    skinning_log.addFilter(about_input)
    try:
        bind_garment(rest, body, source=f"{source}", placed=given)
    finally:
        skinning_log.removeFilter(about_input)
    header = f"'{source.name}' unposed from {what} by `garment unpose` onto body '{body.name}'"
    if out.suffix.lower() in STAGE_SUFFIXES:  # one static mesh in the rest frame (Y-up, metres), its looks inside
        from formats.usd import garment_track, write_usd_stage

        write_usd_stage(out, [garment_track(garment, garment.written(rest.vertices[None]))], fps=30.0, up_axis="Y",
                        metadata={"garment_note": header})
    else:
        _write_obj(out, garment, rest.vertices, header, overwrite)
    # The round trip as bake makes it of the file written (its polygons split again, at the rest positions): the
    # in-memory figure was 1.8 mm where bake's was 4.5 (an A-posed t-shirt's quads split the other way at rest).
    from core.unpose import baked_back_error

    with collected_notes():  # what reading GARMENT and binding its rest said was said, naming the input
        written_back = read_garment(out)
        if written_back.n_vertices == rest.n_vertices:
            report["reposed_max_error_m"] = baked_back_error(written_back, body, pose, betas, garment.vertices)
    shaped = betas is not None and bool(np.any(np.asarray(betas) != 0))  # (a pose file's zero betas take none off)
    target = "the rest pose" + (" and mean shape" if shaped else "")
    moved = f"moved to {target} from {what}" if pose_spec != "tpose" or betas is not None else moved_by
    written = rest.n_vertices if garment.source is None else len(garment.source.vertex_of)  # the file's, unwelded
    if report["edges_torn"]:
        from core.unpose import UNPOSE_TEAR_RATIO, UNPOSE_TEAR_SLACK_M

        if garment.source is not None:  # the file's numbering (its seams welded in the garment's)
            report["torn_at_vertex"] = int(np.flatnonzero(garment.source.vertex_of == report["torn_at_vertex"])[0])

        click.echo(f"warning: garment '{source}': {report['edges_torn']} of its edges came out over "
                   f"{UNPOSE_TEAR_RATIO:g}x their length as authored, plus {UNPOSE_TEAR_SLACK_M * 100:g} cm (the "
                   f"worst {report['max_edge_stretch']:.3g}x, at vertex {report['torn_at_vertex']}): that part took the weights of a body part it does not lie "
                   f"on (cloth pressed against another part in the pose?); look at it before baking it (garment "
                   f"render {out})", err=True)
    after = " after the scale" if given.scale != 1.0 else ""  # (a file in millimetres shrinks 1000 times: no move)
    click.echo(f"{out}: {written} vertices {moved} (largest move{after} "
               f"{report['max_move_m'] * 100:.1f} cm; skinned back into the pose, {report['reposed_max_error_m'] * 1e3:.1f} "
               f"mm from the input at most; on the posed body: median distance "
               f"{report['posed_median_distance_m'] * 100:.1f} cm, {report['posed_inside_share']:.1%} inside)")
