"""`garment bake GARMENT MOTION...`: deform a garment over motions and write USD, OBJ sequences and summaries."""

from __future__ import annotations

import json
import logging
import os
import time
from contextlib import contextmanager
from dataclasses import dataclass, fields, replace
from pathlib import Path

import click
import numpy as np
from tqdm import tqdm

from core.bake import bake_item
from core.body import Body
from core.deform import DEFORMERS, LBSDeformer, LBSOptions
from core.errors import InputError, counted
from core.motion import parse_frame_range
from core.provenance import file_sha256, software_versions
from core.psd import FEATURE_CONTEXT_FRAMES
from core.quality import DEFAULT_BUDGET_MM
from core.threads import torch_threads
from core.scene import SKIP_METHODS, SKIPS, parse_no_skip
from core.strain import STRAIN_LIMIT
from formats.atomic import atomic_dir
from formats.pointcache import POINT_CACHE_FORMATS
from garmentcli.common import (
    FLOOR_CHOICES,
    FLOOR_HELP,
    PIN_CHOICES,
    PIN_HELP,
    FiniteFloatRange,
    FloatOrOff,
    OutputPath,
    betas_option,
    beyond_memory,
    body_option,
    check_preroll,
    check_retries,
    collected_notes,
    collected_warnings,
    frames_option,
    input_errors_as_click,
    load_body_option,
    read_garment_on,
    motion_files,
    motion_names,
    motion_parts,
    motion_up_option,
    person_option,
    take_option,
    parse_device,
    prepare_motion,
    require_file,
    preroll_option,
    scheduler_options,
    source_fps_option,
    thread_count,
    with_collected_warnings,
    option_file,
    option_given,
    MAX_FPS,
    MAX_WORKERS,
    MAX_SOLVER_STEPS,
    MAX_START_FRAME,
)

log = logging.getLogger(__name__)

#: --lbs-smooth's bound: each pass spreads the weights one ring further, so a few hundred reach across any garment
#: (1,000,000, a typo, took minutes on a 2k-vertex skirt).
MAX_LBS_SMOOTH = 1000


class LbsSmooth(click.ParamType):
    """--lbs-smooth: 'auto' (returned as the string) or passes 0..MAX_LBS_SMOOTH."""

    name = "auto|N"

    def convert(self, value, param, ctx):
        if isinstance(value, int) and not isinstance(value, bool):
            n = value
        elif isinstance(value, str) and value.strip().lower() == "auto":
            return "auto"
        else:
            try:
                n = int(str(value).strip())
            except ValueError:
                n = -1
        if not 0 <= n <= MAX_LBS_SMOOTH:
            self.fail(f"expected 'auto' or passes from 0 to {MAX_LBS_SMOOTH}, got {value!r}", param, ctx)
        return n


def lbs_options(lbs_smooth, strain_limit: float | None = None) -> LBSOptions:
    """LBS's options of --lbs-smooth ('auto': the default's passes with the legs' spread; N: N passes, no spread)."""
    if lbs_smooth == "auto":
        return LBSOptions(strain_limit=strain_limit)
    return LBSOptions(smooth_iterations=int(lbs_smooth), leg_spread_m=None, strain_limit=strain_limit)


#: The methods --strain-limit applies to, and those it is on for by default.
STRAIN_METHODS = ("lbs", "model", "psd")
STRAIN_DEFAULT_METHODS = ("model", "psd")


def strain_limit_of(method: str, option) -> float | None:
    """The strain limit of `method` given --strain-limit's value (None: not given; 'off'; a number)."""
    if option is None:
        return STRAIN_LIMIT if method in STRAIN_DEFAULT_METHODS else None
    return None if option == "off" or method not in STRAIN_METHODS else float(option)


def make_deformer(method: str, lbs_smooth: int | str, material_path=None, self_contact=False, substeps=None,
                  iterations=None, model_path=None, pin=None, precision=None, push_out=False, no_skip=(),
                  contact_guard=True, floor=None, fit_path=None, device=None, strain=None):
    """The deformer of bake's options (`strain`: --strain-limit's value, `strain_limit_of`)."""
    deformer = _method_deformer(method, lbs_smooth, material_path, self_contact, substeps, iterations, model_path, pin,
                                precision, contact_guard, floor, fit_path, device, strain_limit_of(method, strain))
    deformer.skips = parse_no_skip(no_skip)
    if push_out:
        if method == "sim":
            raise click.UsageError("--push-out applies to --method lbs, model or psd (the simulator handles contact)")
        from core.pushout import PushOutDeformer

        deformer = PushOutDeformer(deformer)
    return deformer


def _options_of_other_methods(method: str, no_contact_guard: bool, strain, no_skip) -> list[tuple[str, str]]:
    """(option, why it does not apply) for each option given that applies to other methods than `method` but the
    simulator's (`sim_options_given`): --method refuses the first, --quality auto leaves them out, said."""
    found = []
    if method != "lbs" and option_given("lbs_smooth"):
        found.append(("--lbs-smooth", f"--lbs-smooth applies to --method lbs only (got --method {method})"))
    if no_contact_guard and method not in ("model", "psd"):
        found.append(("--no-contact-guard",
                      f"--no-contact-guard applies to --method model and psd only (got --method {method})"))
    if strain is not None and method not in STRAIN_METHODS:
        found.append(("--strain-limit", f"--strain-limit applies to --method {', '.join(STRAIN_METHODS)} only (got "
                                        f"--method {method}: the simulator's cloth has its own stretch stiffness)"))
    found += [(f"--no-skip {name}", f"--no-skip {name} applies to --method {' and '.join(SKIP_METHODS[name])} only "
                                    f"(got --method {method})")
              for name in no_skip if name != "all" and method not in SKIP_METHODS[name]]
    return found


def sim_options_given(material_path, self_contact, substeps, iterations, pin, floor) -> list[str]:
    """The simulator's options given (not left at their defaults), by name."""
    return [name for name, v in (("--material", material_path), ("--self-contact", self_contact or None),
                                 ("--substeps", substeps), ("--iterations", iterations), ("--pin", pin),
                                 ("--floor", floor))
            if v is not None]


def _method_deformer(method, lbs_smooth, material_path, self_contact, substeps, iterations, model_path, pin,
                     precision, contact_guard=True, floor=None, fit_path=None, device=None, strain_limit=None):
    sim_given = sim_options_given(material_path, self_contact, substeps, iterations, pin, floor)
    if method != "sim" and sim_given:
        raise click.UsageError(f"{sim_given[0]} applies to --method sim only (got --method {method})")
    for name, v in (("--model", model_path), ("--precision", precision), ("--device", device)):
        if method != "model" and v is not None:
            raise click.UsageError(f"{name} applies to --method model only (got --method {method})")
    if method == "psd" and fit_path is None:
        raise click.UsageError("--method psd needs --fit FILE (the garment's blend shapes, made by `garment fit`)")
    if method != "psd" and fit_path is not None:
        raise click.UsageError(f"--fit applies to --method psd only (got --method {method})")
    if method == "psd":
        from formats.psd import psd_deformer

        return psd_deformer(fit_path, contact_guard=contact_guard, strain_limit=strain_limit)
    if method == "lbs":
        return LBSDeformer(lbs_options(lbs_smooth, strain_limit))
    if method == "model":
        from core.model_deform import load_model_deformer
        from formats.cache import default_cache_dir

        # Garment preprocessing is cached (`default_cache_dir`), as `garment preprocess` does.
        return load_model_deformer(model_path, cache_dir=default_cache_dir(), precision=precision or "float32",
                                   contact_guard=contact_guard, device=parse_device(device, auto=True),
                                   strain_limit=strain_limit)
    if method == "sim":
        from core.sim import Material, SimDeformer, SimOptions, load_material, require_simulator

        require_simulator("--method sim")
        material = load_material(material_path) if material_path else Material()
        defaults = SimOptions()
        options = SimOptions(substeps=substeps or defaults.substeps, iterations=iterations or defaults.iterations,
                             self_contact=self_contact, pin=pin or defaults.pin, floor=floor or defaults.floor)
        return SimDeformer(material, options)
    return DEFORMERS[method]()


def write_bake_outputs(directory: Path, stem: str, result, garment, body: Body, write_obj: bool,
                       start_frame: int = 0, point_caches: tuple = (), on_written=None) -> None:
    """USD stage (garment + body), the OBJ sequence and the point caches (`formats.pointcache`: 'pc2', 'mdd')
    into `directory`. The garment is written as its file has it (`garment.source`: its point numbering, quads and
    UV seams), where that differs from the mesh deformed. on_written(n): n OBJ frames written (0 as the writing
    starts: a progress bar)."""
    from formats.mtl import output_libraries
    from formats.sequence import write_obj_sequence
    from formats.usd import MeshTrack, garment_track, write_usd_stage

    if on_written is not None:
        on_written(0)
    fps = result.summary["fps"]
    written = garment.written(result.garment_points)  # the points in the file's numbering: made once
    tracks = [garment_track(garment, written)]
    if result.body_points is not None:
        tracks.append(MeshTrack("body", result.body_points, body.faces, uvs=None, color=(0.75, 0.75, 0.78)))
    write_usd_stage(directory / f"{stem}.usd", tracks, fps=fps, start_frame=start_frame,
                    metadata={"garment_method": result.summary["method"], "garment_settle_frames": result.summary["settle_frames"]})
    if write_obj:  # the material libraries copied beside the frames, their textures' paths leading to them
        points, faces, uvs, face_uvs, materials = written
        write_obj_sequence(directory / "obj", points, faces, uvs, face_uvs, fps=fps, materials=materials,
                           libraries=output_libraries(garment.source, directory / "obj", stem), start=start_frame, up="y",
                           on_frame=on_written)
    for kind in point_caches:  # in the garment file's own frame (Y-up): Blender keeps an imported OBJ's points so
        from core.geometry import Y_UP_TO_Z_UP_MATRIX
        from formats.pointcache import write_point_cache

        write_point_cache(directory / f"{stem}.{kind}", written[0] @ Y_UP_TO_Z_UP_MATRIX, fps, start_frame)


@dataclass(frozen=True)
class BakeSpec:
    """Everything one bake task needs besides its motion (picklable, hashable: the per-process cache key)."""

    garment_path: str
    body_path: str | None
    method: str
    lbs_smooth: int | str
    material_path: str | None
    self_contact: bool
    substeps: int | None
    iterations: int | None
    model_path: str | None
    pin: str | None
    fps: float
    frames: str | None
    settle_frames: int
    write_obj: bool
    with_body: bool
    render_video: bool
    overwrite: bool
    precision: str | None = None
    push_out: bool = False
    quality: str = ""  # JSON of the --quality auto choice, recorded in summary.json
    no_skip: tuple = ()
    threads: int = 0  # torch threads of a process (0: torch's default; a --workers process: the cores shared out)
    threads_fixed: bool = False  # --threads N: that count throughout (no ThreadTuner), recorded in summary.json
    fallback: str = ""  # JSON: why the default model gave way to lbs, recorded in summary.json
    contact_guard: bool = True  # model, psd: keep vertices outside the body faces they rest on
    strain: float | str | None = None  # --strain-limit as given (None: the method's default; 'off')
    betas: str = "auto"  # --betas as given (the motions arrive with it applied), recorded in summary.json
    floor: str | None = None  # sim: --floor (None: the default)
    start_frame: int = 0  # --start-frame: the number of the first frame written (USD time code, OBJ file)
    preroll_frames: int = 0  # --preroll: source frames before --frames START deformed, not written
    fit_path: str | None = None  # psd: --fit
    motion_up: str | None = "z"  # --motion-up (None: left out; the motions arrive turned), recorded in summary.json
    person: str | None = None  # --person (the track read of a file of tracked people), recorded in summary.json
    take: str | None = None  # --take (the animation read of an FBX or glTF of several), recorded in summary.json
    point_caches: tuple = ()  # --point-cache: the point cache formats written beside the USD ('pc2', 'mdd')
    device: str | None = None  # model: --device as given (None: auto, resolved where the deformer is made)
    #: ((motion path, (warning, ...)), ...): what reading the inputs warned about, per motion (`_warnings_of`)
    warnings: tuple = ()
    settings: str = ""  # JSON of `_bake_settings`, recorded in summary.json (what --skip-existing compares)


def _model_input(spec: BakeSpec) -> dict:
    """summary.json's inputs of the model's checkpoint where the model bakes: its path (absolute) and sha256 (a
    bake traced to its checkpoint, the shipped one's too)."""
    if spec.method != "model":
        return {}
    from core.model_deform import DEFAULT_MODEL

    path = Path(spec.model_path or DEFAULT_MODEL).resolve()
    return {"model": str(path), "model_sha256": file_sha256(path)}


# Per process: (garment, body, prepared deformer) of the last spec, so a worker prepares once for many motions.
_CONTEXT: dict = {}


def _context(spec: BakeSpec):
    if spec not in _CONTEXT:
        from formats.obj import read_garment

        _CONTEXT.clear()
        if spec.threads:  # a worker process's count, for good
            import torch

            torch.set_num_threads(spec.threads)
        deformer = make_deformer(spec.method, spec.lbs_smooth, spec.material_path, spec.self_contact, spec.substeps,
                                 spec.iterations, spec.model_path, spec.pin, spec.precision, spec.push_out,
                                 spec.no_skip, spec.contact_guard, spec.floor, spec.fit_path, spec.device, spec.strain)
        _fix_threads(deformer, spec.threads_fixed)
        garment = read_garment(spec.garment_path)
        body = load_body_option(spec.body_path)
        deformer.prepare(garment, body, source=spec.garment_path)
        _CONTEXT[spec] = (garment, body, deformer)
    return _CONTEXT[spec]


def bake_task(spec: BakeSpec, motion_path: str, target: str | Path, prepared, on_written=None) -> dict | None:
    """Bake one motion into `target` (atomically) and return its summary; the task of every engine.

    prepared: (Motion, source fps) from `prepare_motion`. Returns None without writing when `target`
    exists and not `spec.overwrite` (an earlier attempt finished it: a retry rewrites nothing finished).
    on_written: `write_bake_outputs`' progress callback.
    """
    target = Path(target)
    if target.exists() and not spec.overwrite:
        return None
    garment, body, deformer = _context(spec)
    motion, source_fps = prepared
    t0 = time.perf_counter()
    with collected_warnings() as warned:
        result = bake_item(garment, body, motion, deformer, with_body=spec.with_body)
    result.summary.update({
        # absolute, however the command named them (a batch on workers named the garment so, the motion not)
        "inputs": {"garment": str(Path(spec.garment_path).resolve()), "motion": str(Path(motion_path).resolve()),
                   "body": str(Path(spec.body_path).resolve()) if spec.body_path else "embedded default (anny)",
                   **({"fit": str(Path(spec.fit_path).resolve()), "fit_sha256": file_sha256(spec.fit_path)}
                      if spec.fit_path else {}), **_model_input(spec)},
        "source_fps": source_fps,
        "options": {"fps": spec.fps, "frames": spec.frames, "preroll": spec.preroll_frames, "settle": spec.settle_frames,
                    "betas": spec.betas, "start_frame": spec.start_frame, "motion_up": spec.motion_up,
                    "motion_up_as_read": motion.up, "person": spec.person, "person_read": motion.person,
                    "take": spec.take, "take_read": motion.take,
                    "threads": spec.threads if spec.threads_fixed else "auto",
                    "strain_limit": strain_limit_of(spec.method, spec.strain),
                    "point_caches": list(spec.point_caches), "no_skip": sorted(spec.no_skip)},
        "software": software_versions("garment", "numpy", "scipy", "torch", "usd-core",
                                      *(("newton", "warp-lang") if spec.method == "sim" else ())),
        "warnings": [*dict(spec.warnings).get(str(motion_path), ()), *warned],
    })
    if spec.quality:
        result.summary["quality"] = json.loads(spec.quality)
    if spec.fallback:
        result.summary["method_fallback"] = json.loads(spec.fallback)
    if spec.push_out:
        result.summary["push_out"] = True
    if spec.settings:
        result.summary["settings"] = json.loads(spec.settings)
    with atomic_dir(target, spec.overwrite) as tmp:
        write_bake_outputs(tmp, target.name, result, garment, body, write_obj=spec.write_obj,
                           start_frame=spec.start_frame, point_caches=spec.point_caches, on_written=on_written)
        result.summary["seconds_total"] = time.perf_counter() - t0
        (tmp / "summary.json").write_text(json.dumps(result.summary, indent=2))
        if spec.render_video:  # inside the temporary directory: a failed render leaves nothing behind
            from formats.render import render_bake

            render_bake(tmp / "render", result.garment_points, garment.faces, result.body_points,
                        body.faces, spec.fps, first_frame=spec.start_frame)
    return result.summary


#: Mean share (%) of garment vertices inside the body above which `bake` suggests --push-out (the model's contact
#: guard leaves 0-0.75 % on the example dress, skirt and trousers, 1-3 % on the t-shirt and jumpsuit:
#: benchmarks/results/contact_guard.md).
PUSH_OUT_HINT_PERCENT = 1.0


def _echo_done(target, summary: dict, method: str, fps: float) -> None:
    pen = summary.get("penetration", {})
    mean = pen.get("mean_percent", float("nan"))
    hint = ""
    if mean > PUSH_OUT_HINT_PERCENT and method in ("model", "lbs") and not summary.get("push_out"):
        hint = " (--push-out moves them outside)"
    device = summary.get("deformer", {}).get("device", "cpu")
    where = method if device == "cpu" else f"{method} on {device}"
    click.echo(f"{target}: {counted(summary['frames'], 'frame')} at {fps:g} fps, "
               f"{summary['seconds_per_frame'] * 1e3:.2f} ms/frame ({where}), "
               f"penetration mean {mean:.2f}% max {pen.get('max_percent', float('nan')):.2f}%{hint}")


@click.command(name="bake")
@click.argument("garment_path", metavar="GARMENT", type=click.Path(dir_okay=False))
@click.argument("motion_paths", metavar="MOTION...", nargs=-1, required=True, type=click.Path())
@click.option("--method", type=click.Choice(sorted(DEFORMERS)), default=None,
              help="Deformation method: model (the learned network; the default), lbs (linear blend skinning: "
                   "fastest, no cloth dynamics), psd (LBS plus this garment's blend shapes fitted to its "
                   "simulations: --fit) or sim (reference physics: slowest).")
@click.option("--fit", "fit_path", type=click.Path(dir_okay=False), default=None, metavar="FILE",
              help="psd: the garment's fitted blend shapes (`garment fit`).")
@click.option("--quality", type=click.Choice(["auto"]), default=None,
              help="auto: choose the cheapest method expected within --budget-mm from the scene (garment looseness, "
                   "motion speed) and the model's calibration; the choice is printed and kept in summary.json.")
@click.option("--budget-mm", type=FiniteFloatRange(min=0, min_open=True), default=None,
              help=f"--quality auto: error budget, mean vertex distance to the simulator in mm [default: "
                   f"{DEFAULT_BUDGET_MM:g}].")
@click.option("--calibration", "calibration_path", type=click.Path(dir_okay=False), default=None,
              help="--quality auto: calibration JSON (`garment tradeoff --calibrate`). Default: the model's own.")
@click.option("--precision", type=click.Choice(["float32", "bfloat16"]), default=None,
              help="model: arithmetic of the network [default: float32].")
@click.option("--device", default=None, metavar="DEVICE",
              help="model: where the network runs: cpu, cuda or cuda:N [default: auto, the first CUDA GPU torch sees, "
                   "else the CPU].")
@click.option("--push-out", is_flag=True, help="lbs, model, psd: move vertices inside the body to just outside it.")
@click.option("--no-contact-guard", is_flag=True,
              help="model, psd: leave out the contact guard (on by default, about 0.6-3 ms/frame on 2k-7k vertices), "
                   "which keeps each vertex outside the body face it rests on; the network's or the fit's raw output.")
@click.option("--strain-limit", "strain", type=FloatOrOff(1, "an edge's longest, as a multiple of its rest length"),
              default=None, metavar="RATIO|off",
              help=f"lbs, model, psd: no edge of the garment longer than RATIO times its rest length (undoes the tears "
                   f"skinning makes between a dress's legs, at a knee, in an armpit; on 2k-7k vertices up to about "
                   f"11 ms a frame where a wide tear is, 0.2-0.6 where none; 0.19 s on 203k) [default: "
                   f"{STRAIN_LIMIT:g} for model and psd, off for lbs].")
@click.option("--no-skip", "no_skip", multiple=True, type=click.Choice([*SKIPS, "all"]),
              help="Do this work even where the scene analysis finds it unneeded (repeatable): joints without weight "
                   "on the garment, body faces out of its reach (sim), self-contact where distant parts never meet, "
                   "self-contact checks between points of one stretch of cloth (sim), and the ground where the garment "
                   "never comes near it (sim). Every skip is reported in "
                   "summary.json under 'scene'.")
@click.option("--out", "out_dir", type=OutputPath(file_okay=False), default="garment_bake", show_default=True,
              help="Output directory; one sub-directory per motion.")
@body_option
@betas_option
@source_fps_option
@motion_up_option
@person_option(every=True)
@take_option(every=True)
@click.option("--fps", type=FiniteFloatRange(min=1.0, max=MAX_FPS), default=30.0, show_default=True,
              help="Output frame rate (any ratio to the source).")
@frames_option
@click.option("--settle", "settle_frames", type=click.IntRange(min=0), default=0, show_default=True, metavar="K",
              help="Frames blending from the rest pose into the first frame, prepended to the output.")
@preroll_option
@click.option("--lbs-smooth", type=LbsSmooth(), default="auto", show_default=True,
              help="lbs: smoothing of the transferred skinning weights over the garment: auto (10 passes, and the "
                   "weights of cloth skinned to the legs spread over about 10 cm, so that a skirt or dress between "
                   "the legs follows both thighs and tears less at a stride), or N passes over the whole garment, no "
                   "spread (10: LBS before 2026-12-06).")
@click.option("--material", "material_path", type=click.Path(dir_okay=False, exists=True), default=None,
              help="sim: cloth material JSON (fields of core.sim.Material; unknown keys are rejected).")
@click.option("--self-contact", is_flag=True, help="sim: cloth-cloth contact (about 3-10x slower).")
@click.option("--substeps", type=click.IntRange(1, MAX_SOLVER_STEPS), default=None,
              help="sim: solver steps per frame [default: 10]; a frame that fails the simulator's checks is run "
                   "again at 2x, then 4x them.")
@click.option("--iterations", type=click.IntRange(1, MAX_SOLVER_STEPS), default=None,
              help="sim: VBD iterations per substep [default: 10].")
@click.option("--pin", type=click.Choice(PIN_CHOICES), default=None, help=f"sim: {PIN_HELP} [default: auto]")
@click.option("--floor", type=click.Choice(FLOOR_CHOICES), default=None, help=f"sim: {FLOOR_HELP} [default: auto]")
@click.option("--model", "model_path", type=click.Path(dir_okay=False), default=None,
              help="model: trained model checkpoint (from `garment train`). Default: the shipped model.")
@click.option("--start-frame", type=click.IntRange(0, MAX_START_FRAME), default=0, show_default=True, metavar="N",
              help="Number of the first frame written (USD time codes, OBJ frame files): e.g. 1 for Blender, 1001 "
                   "for a VFX shot; with --settle S the motion's first frame is N + S.")
@click.option("--no-obj", is_flag=True, help="Skip the OBJ sequence (USD and summary only).")
@click.option("--point-cache", "point_caches", type=click.Choice(POINT_CACHE_FORMATS), multiple=True,
              help="Also write the garment's points per frame as a point cache, <garment>_<motion>.pc2 or .mdd "
                   "(repeatable): pc2 (3ds Max's Point Cache; Blender's Mesh Cache modifier) or mdd (LightWave's; "
                   "Blender, Cinema 4D, Houdini), its points in the garment file's order and frame (metres, Y-up): "
                   "it plays on the garment file as Blender imports it (the Mesh Cache's Frame Start set to "
                   "--start-frame).")
@click.option("--no-body", is_flag=True, help="Leave the body out of the USD stage.")
@click.option("--render", "render_video", is_flag=True,
              help="Also render render/front.mp4, render/side.mp4 and render/contact_sheet.png (off-screen).")
@click.option("--overwrite", is_flag=True, help="Replace existing output directories.")
@click.option("--skip-existing", is_flag=True,
              help="Leave motions whose output directory exists and bake the others (resume a batch); a bake "
                   "made with other options (but --workers, --scheduler, --retries, --threads, --device) is "
                   "refused.")
@click.option("--workers", type=click.IntRange(1, MAX_WORKERS), default=1, show_default=True,
              help="Local processes baking motions side by side, 1 to 256, no more started than there are motions "
                   "(each prepares the garment and loads the method once; the cores are shared out among them).")
@click.option("--threads", default=None, metavar="N|auto",
              help="CPU threads of torch's work in each process (the model's network) [default: auto: chosen while "
                   "the model bakes, from a thread per core, or the cores shared out among --workers]. N: that many "
                   "throughout, so that a bake repeats bit for bit on one machine (auto's counts change a batch's "
                   "float rounding: its bakes agree to float32 rounding, but where the strain limit undoes a tear, "
                   "by up to a few mm at a few vertices), at auto's speed where no other work "
                   "holds the cores.")
@scheduler_options("motion", note=" --workers is then ignored.")
@input_errors_as_click
@with_collected_warnings
def bake(garment_path, motion_paths, method, out_dir, body_path, fps, frames, settle_frames, lbs_smooth,
         no_obj, no_body, overwrite, render_video=False, material_path=None, self_contact=False, substeps=None,
         iterations=None, model_path=None, skip_existing=False, scheduler=None, retries=2, pin=None, quality=None,
         budget_mm=None, calibration_path=None, precision=None, push_out=False, no_skip=(), workers=1,
         no_contact_guard=False, betas="auto", source_fps=None, floor=None, start_frame=0, fit_path=None,
         preroll_frames=0, device=None, motion_up="z", person=None, take=None, threads=None, point_caches=(),
         strain=None, warned=()):
    """Bake GARMENT (OBJ or USD, on the body's rest pose) over each MOTION (AMASS-style .npz; another tool's .pkl,
    .pt, .npy, .smpl, .bvh, .fbx, .glb, .gltf, .usd of a skeleton, .dae or .mvnx, README "Inputs"; or a
    directory: every motion .npz, .smpl, .pkl, .npy, .bvh, .fbx, .glb, .gltf, .usd, .dae and .mvnx under it).

    Writes OUT/<garment>_<motion>/ with <garment>_<motion>.usd (garment and body,
    time-sampled, Z-up, metres), obj/frame_NNNN.obj and summary.json. Motions of one file name in different
    folders are told apart by their folders' names (<garment>_<folder>_<motion>), files of one stem in one folder
    by their suffixes (`motion_names`).
    """
    if not np.isfinite(fps) or fps <= 0:
        raise click.BadParameter(f"expected a positive frame rate, got {fps}", param_hint="--fps")
    if frames:
        parse_frame_range(frames)  # reject a bad --frames before any work
    check_preroll(preroll_frames, frames, settle_frames)
    threads = thread_count(threads)
    if device is not None:  # a cluster's workers have their own devices
        parse_device(device, auto=True, check=not scheduler)
    if quality is None:
        for name, v in (("--budget-mm", budget_mm), ("--calibration", calibration_path)):
            if v is not None:
                raise click.UsageError(f"{name} applies to --quality auto only")
        explicit = method is not None
        method = method or "model"
        other = _options_of_other_methods(method, no_contact_guard, strain, no_skip)
        if other:
            raise click.UsageError(other[0][1])
        deformer = make_deformer(method, lbs_smooth, material_path, self_contact, substeps, iterations, model_path, pin,
                                 precision, push_out, no_skip, not no_contact_guard, floor, fit_path, device, strain)
    elif method is not None or precision is not None:
        raise click.UsageError("--quality auto chooses the method and precision: leave out --method and --precision")
    require_file(garment_path)
    motion_paths = motion_files(motion_paths)
    body = load_body_option(body_path)
    garment = read_garment_on(garment_path, body)
    out_dir = Path(out_dir)
    targets = [(m, out_dir / f"{Path(garment_path).stem}_{name}{suffix}", part)
               for m, name in zip(motion_paths, motion_names(motion_paths))
               for part, suffix in motion_parts(m, person, take)]
    _refuse_shared_targets(targets)
    if overwrite and skip_existing:
        raise click.UsageError("--overwrite and --skip-existing exclude each other")
    settings = _bake_settings(method, quality, garment)
    check_retries(scheduler)
    if skip_existing:
        other = next((t for _, t, _ in targets if t.exists() and not (t / "summary.json").is_file()), None)
        if other is not None:  # a file or an empty folder by the bake's name was taken for a finished bake
            raise click.ClickException(f"output '{other}' exists and is no finished bake (no summary.json in it): "
                                       f"remove it, or pass --overwrite instead of --skip-existing")
        done = [t for _, t, _ in targets if t.exists()]
        for t in done:
            otherwise = _baked_otherwise(t, settings)
            if otherwise:
                raise click.ClickException(f"output '{t}' was baked with {otherwise}: pass --overwrite to bake "
                                           "it again, or that bake's options to resume it")
        targets = [item for item in targets if not item[1].exists()]
        click.echo(f"{out_dir}: {len(done)} of {len(done) + len(targets)} motions already baked, skipped")
        if not targets:
            return
    if not overwrite:
        existing = [str(t) for _, t, _ in targets if t.exists()]
        if existing:
            raise click.ClickException(f"output '{existing[0]}' exists: pass --overwrite to replace it")
    if render_video:  # a window that cannot open stops the bake before any work, not after its other outputs
        from formats.render import check_render_window

        check_render_window()
    # Read every motion before baking any, so a bad file fails fast and writes nothing; one that --fps would
    # resample to more frames than fit (the cheapest method's copies, one at a time) is refused before it is.
    def check_frames(path):
        return lambda n, src_fps: _refuse_beyond_memory(garment, body, path, n, src_fps, fps,
                                                        min(BAKE_COPIES.values()), 1, settle_frames, not no_body)

    def prepared(context: int) -> list:  # context: the method's frames either side of --frames (psd's)
        return [(prepare_motion(m, fps, frames, settle_frames, betas, source_fps, preroll_frames, body=body,
                                check_frames=check_frames(m), motion_up=motion_up, context_frames=context, **part),
                 m, target)
                for m, target, part in targets]

    motions = prepared(FEATURE_CONTEXT_FRAMES if method == "psd" else 0)
    choice, fallback = "", ""
    if quality == "auto":
        pick = _choose_quality(garment, body, [(mo, m) for (mo, _), m, _ in motions], model_path, calibration_path,
                               DEFAULT_BUDGET_MM if budget_mm is None else budget_mm, fit_path, garment_path)
        method, opts = pick["method"], pick["options"]
        # --push-out asked for: after the chosen method, where it is not the simulator (which handles contact)
        wanted_push_out = push_out
        asked_push_out = push_out and method != "sim" and not opts.get("push_out")
        precision, push_out = opts.get("precision"), bool(opts.get("push_out", False)) or asked_push_out
        strain = opts.get("strain_limit", strain)  # a configuration measured with a limit (lbs +strain-limit)
        replaced = [f"--substeps {substeps}"] if substeps is not None and opts.get("substeps") not in (None,
                                                                                                  substeps) else []
        substeps = opts.get("substeps", substeps)
        self_contact = bool(opts.get("self_contact", self_contact))
        if method != "model":
            model_path, precision, device = None, None, None
        if method != "psd":
            fit_path = None  # a fit given to --quality auto is one candidate; another method was chosen
        # Options of other methods than the one chosen are left out, said (an explicit --method refuses them).
        left = [name for name, _ in _options_of_other_methods(method, no_contact_guard,
                                                                  None if "strain_limit" in opts else strain, no_skip)]
        if method != "sim":
            left += sim_options_given(material_path, self_contact, substeps, iterations, pin, floor)
            material_path, self_contact, substeps, iterations, pin, floor = None, False, None, None, None, None
        if "--lbs-smooth" in left:
            lbs_smooth = "auto"
        no_contact_guard = no_contact_guard and "--no-contact-guard" not in left
        strain = None if "--strain-limit" in left else strain
        no_skip = tuple(n for n in no_skip if f"--no-skip {n}" not in left)
        deformer = make_deformer(method, lbs_smooth, material_path, self_contact, substeps, iterations, model_path, pin,
                                 precision, push_out, no_skip, not no_contact_guard, floor, fit_path, device, strain)
        choice = json.dumps({k: pick[k] for k in ("config", "method", "options", "expected_mm", "budget_mm",
                                                   "motion", "features", "reason", "candidates",
                                                   "outside_calibration", "outside_motions")})
        click.echo(f"quality auto: {pick['config']}{' +push-out (--push-out)' if asked_push_out else ''} "
                   f"({pick['reason']})")
        if wanted_push_out and method == "sim":
            click.echo("quality auto: --push-out left out: the simulator handles contact itself", err=True)
        if left:
            click.echo(f"quality auto: {', '.join(left)} left out: {'it applies' if len(left) == 1 else 'they apply'}"
                       f" to other methods than the {method} chosen", err=True)
        if replaced and method == "sim":
            click.echo(f"quality auto: {', '.join(replaced)} replaced by the configuration chosen ({pick['config']}; "
                       "--method sim keeps yours)", err=True)
        if pick["outside_motions"]:
            outside = pick["outside_paths"]
            log.warning("--quality auto: %s %s beyond the calibration's scenes: expected errors there are "
                        "extrapolated (the learned methods taken as no better than lbs); `garment tradeoff` on "
                        "such a motion measures them", "motion" if len(outside) == 1 else "motions",
                        ", ".join(f"'{m}'" for m in outside) + (" is" if len(outside) == 1 else " are"))
        explicit = False
        if method == "psd" and frames:  # read again with psd's context frames
            with collected_notes():  # (said when first read)
                motions = prepared(FEATURE_CONTEXT_FRAMES)
    # The method is known (--quality auto has chosen), no deformer has prepared anything yet.
    # LBS deforms each frame on its own: the frames before START unused. (psd's blend shapes read the joints' rates
    # and the root's acceleration, taken from the frames around each: its context frames, FEATURE_CONTEXT_FRAMES.)
    if preroll_frames and method == "lbs":
        click.echo(f"note: --preroll {preroll_frames}: {method} deforms each frame on its own, so the frames before "
                   "START change nothing (it is for sim, model and psd, whose cloth carries the motion on)", err=True)
    _check_memory(garment, body, [(mo, src_fps, m) for (mo, src_fps), m, _ in motions], method,
                  workers if not scheduler else 1, settle_frames, not no_body)
    if method == "psd":
        _warn_beyond_fit(getattr(deformer, "inner", deformer).fit, body, [(mo, m) for (mo, _), m, _ in motions],
                         fit_path)
    if method == "model":
        fallback = _body_joints_guard(deformer, body, explicit)
        prepared = not fallback
        if prepared:
            deformer.prepare(garment, body, source=garment_path)
            fallback = _training_range_guard(deformer, garment, body, garment_path, explicit)
        if fallback:
            method, model_path, precision, device = "lbs", None, None, None
            deformer = make_deformer(method, lbs_smooth, push_out=push_out, no_skip=no_skip, strain=strain)
            if prepared:
                _prepare_unwarned(deformer, garment, body, garment_path)
        elif quality != "auto":  # --quality auto has said so in its choice
            _warn_beyond_calibration(garment, body, [(mo, m) for (mo, _), m, _ in motions], model_path)
    if (method == "model" and precision == "bfloat16"
            and parse_device(device, auto=True, check=not scheduler).type == "cpu"):
        from core.model_deform import native_bfloat16

        if native_bfloat16() is False:
            click.echo("warning: --precision bfloat16: this CPU has no native bfloat16 arithmetic (no avx512_bf16, "
                       "amx_bf16 or bf16 flag), so the network runs emulated and slower than in float32 (2-5x on an "
                       "AVX2-only CPU)", err=True)
    spec = BakeSpec(str(garment_path), body_path, method, lbs_smooth, material_path, self_contact, substeps, iterations,
                    model_path, pin, fps, frames, settle_frames, not no_obj, not no_body, render_video, overwrite,
                    precision, push_out, choice, tuple(sorted(set(no_skip))), fallback=fallback,
                    contact_guard=not no_contact_guard, strain=strain, betas=betas, floor=floor, start_frame=start_frame,
                    fit_path=fit_path, preroll_frames=preroll_frames, device=device, motion_up=motion_up,
                    person=person, take=take, threads=threads or 0, threads_fixed=threads is not None,
                    point_caches=tuple(dict.fromkeys(point_caches)), settings=json.dumps(settings))
    _fix_threads(deformer, spec.threads_fixed)
    if method in ("sim", "model"):
        _note_rest_start(frames, preroll_frames, [(mo, path) for (mo, _), path, _ in motions], method)
    deformer.prepare(garment, body, source=garment_path)  # once for all motions; validates the pair
    spec = replace(spec, warnings=_warnings_of(warned, [m for _, m, _ in motions]))
    t_start = time.perf_counter()
    total_frames = sum(mo.n_frames for (mo, _), _, _ in motions)  # deformed (the bar's)
    written_frames = sum(mo.n_written for (mo, _), _, _ in motions)  # without --preroll's and psd's context
    if workers > 1 and len(motions) == 1 and not scheduler:
        click.echo(f"note: --workers {workers}: one motion, baked in this process (the workers share out motions)",
                   err=True)
    if scheduler or (workers > 1 and len(motions) > 1):  # the workers prepare their own copy (once per process)
        if not scheduler and not spec.threads_fixed:
            spec = replace(spec, threads=max(1, (os.cpu_count() or 1) // min(workers, len(motions))))
        _bake_in_workers(spec, motions, scheduler, retries, workers)
        _echo_throughput(written_frames, len(motions), time.perf_counter() - t_start)
        return
    _CONTEXT.clear()
    _CONTEXT[spec] = (garment, body, deformer)
    # Frames counted in shares where a method passes over them more than once (the model on a CPU: its network,
    # contact guard and strain limit), shown whole.
    with tqdm(total=total_frames, unit="frame", desc="bake", disable=None, leave=False,
              bar_format="{desc}: {percentage:3.0f}%|{bar}| {n:.0f}/{total_fmt} frames [{elapsed}<{remaining}]") as bar:
        ticked = [0]

        def on_frames(n: float) -> None:
            ticked[0] += n
            bar.update(n)

        deformer.on_frames = on_frames
        try:
            with torch_threads(spec.threads):
                _bake_locally(spec, motions, bar, ticked, method, fps)
        finally:
            _CONTEXT.clear()
            deformer.on_frames = None
    _echo_throughput(written_frames, len(motions), time.perf_counter() - t_start)


def _refuse_shared_targets(targets) -> None:
    """Refuse, before any work, two motions (or two parts of one: --person all, --take all) that would be written
    to one output (`motion_names` tells files apart; a part's suffix can meet another file's name), and an output
    whose name its file system cannot take (`formats.atomic.check_name_fits`). targets: [(motion path, output,
    part)]."""
    from formats.atomic import check_name_fits

    seen: dict = {}
    for motion, target, part in targets:
        check_name_fits(target)
        first = seen.setdefault(str(target).casefold(), (motion, part))  # (as a case-insensitive file system)
        if first != (motion, part):
            raise click.ClickException(f"motions '{first[0]}' and '{motion}' would both be written to '{target}': "
                                       "rename one of them, or bake them into other --out folders")


#: bake's parameters that change nothing it writes (--threads and --device: float rounding at most) or where it
#: writes, and those `_bake_settings` records otherwise (the method; the garment by its mesh's content).
_NOT_SETTINGS = {"garment_path", "motion_paths", "out_dir", "overwrite", "skip_existing", "workers", "scheduler",
                 "retries", "threads", "device", "method", "quality"}
#: bake's parameters naming a file: recorded by its content's sha256 (a model retrained in place is another).
_FILE_SETTINGS = {"body_path", "material_path", "model_path", "calibration_path", "fit_path"}
#: What summary.json recorded before its "settings" (`_baked_otherwise` compares those of an earlier version's
#: bake): options' keys -> bake's parameters.
_RECORDED_OPTIONS = {"fps": "fps", "frames": "frames", "preroll": "preroll_frames", "settle": "settle_frames",
                     "betas": "betas", "start_frame": "start_frame"}


def _bake_settings(method: str | None, quality: str | None, garment) -> dict:
    """What this bake's outputs are made with, as summary.json's "settings" records it and `--skip-existing`
    compares (`_baked_otherwise`): the method asked for ('--method M', '--quality auto'), the garment's mesh
    (sha256 of its content), every option given or defaulted but those of `_NOT_SETTINGS`, a file by its bytes'
    sha256 (`_FILE_SETTINGS`). As JSON reads it back (lists for tuples)."""
    settings = {"method": f"--quality {quality}" if quality else f"--method {method}",
                "garment": garment.content_hash()}
    for name, value in click.get_current_context().params.items():
        if name in _FILE_SETTINGS and value is not None and Path(value).is_file():
            value = f"sha256:{file_sha256(value)}"
        if name not in _NOT_SETTINGS:
            settings[name] = value
    return _spelled_out(json.loads(json.dumps(settings)))


def _spelled_out(settings: dict) -> dict:
    """`settings` (`_bake_settings`, or an earlier run's record of them) with the defaults that options stand for
    written out: no --model is the shipped model's file (by sha256), no --precision float32 with --method model, no
    --body the embedded body's file, and --frames in one spelling ('0:', ':' and none alike, ':5' as '0:5'); so a
    bake made with either spelling resumes under the other (`--model` naming the shipped checkpoint was refused as
    another file)."""
    out = dict(settings)
    if "body_path" in out and out["body_path"] is None:
        from core.body import default_body_sha256

        out["body_path"] = f"sha256:{default_body_sha256()}"
    if isinstance(out.get("frames"), str):
        out["frames"] = _frames_spelled(out["frames"])
    if out.get("method") in ("--method model", "--quality auto") and "model_path" in out \
            and out["model_path"] is None:
        from core.model_deform import DEFAULT_MODEL

        out["model_path"] = f"sha256:{file_sha256(DEFAULT_MODEL)}" if Path(DEFAULT_MODEL).is_file() else None
    if out.get("method") == "--method model" and "precision" in out and out["precision"] is None:
        out["precision"] = "float32"
    return out


def _frames_spelled(text: str) -> str | None:
    """A --frames range in one spelling: None for the whole motion ('0:', ':'), 'START:STOP' otherwise; as it is
    where it does not parse (refused before it is compared)."""
    try:
        start, stop = parse_frame_range(text)
    except InputError:
        return text
    if not start and stop is None:
        return None
    return f"{start or 0}:{'' if stop is None else stop}"


def _baked_otherwise(target: Path, settings: dict) -> str:
    """What the finished bake in `target` was made with other than this run's `settings` (`_bake_settings`), as
    "--fps 30 (this run: 24)"; '' where the same. A bake of an earlier version, whose summary.json records no
    "settings", is compared by what it records (the method, garment and `_RECORDED_OPTIONS`)."""
    try:
        summary = json.loads((target / "summary.json").read_text())
        baked = summary.get("settings")
        if baked is None:
            options = summary.get("options", {})
            method = summary.get("method_fallback", {}).get("from") or summary["method"]  # what was asked
            baked = {"method": "--quality auto" if "quality" in summary else f"--method {method}",
                     "garment": summary.get("garment", {}).get("sha256"),
                     **{name: options[k] for k, name in _RECORDED_OPTIONS.items() if k in options}}
        if not isinstance(baked, dict):
            raise TypeError("settings")
        baked = _spelled_out(baked)
    except (OSError, ValueError, KeyError, AttributeError, TypeError) as exc:
        return f"a summary.json that cannot be read ({type(exc).__name__})"
    flags = {p.name: max(p.opts, key=len) for p in click.get_current_context().command.params}
    for key, now in settings.items():
        then = baked.get(key)
        if key not in baked or then == now or then is None and key == "garment":
            continue
        if key == "method":
            return f"{then} (this run: {now})"
        if key == "garment":
            return "a garment of other content (this run's garment file changed since)"
        return f"{flags.get(key, key)} {_setting_text(key, then)} (this run: {_setting_text(key, now)})"
    return ""


def _setting_text(name: str, value) -> str:
    """An option's value as `_baked_otherwise` says it."""
    if value is None or value == []:
        return "left out"
    if isinstance(value, bool):
        return "on" if value else "off"
    if name in _FILE_SETTINGS and str(value).startswith("sha256:"):
        return f"a file of sha256 {value[7:19]}"
    if isinstance(value, list):
        return " ".join(map(str, value))
    return f"{value:g}" if isinstance(value, float) else str(value)


def _fix_threads(deformer, fixed: bool) -> None:
    """--threads N: the model's batches on that count throughout, not chosen by timing them."""
    if fixed and hasattr(deformer, "tune_threads"):
        deformer.tune_threads = False


def _warnings_of(messages, motion_paths) -> tuple:
    """((motion path, (message, ...)), ...): per motion, the messages naming it or no motion of the batch."""
    quoted = {str(m): f"'{m}'" for m in motion_paths}
    return tuple((m, tuple(dict.fromkeys(w for w in messages if q in w or not any(o in w for o in quoted.values()))))
                 for m, q in quoted.items())


#: Bytes a bake holds per frame and vertex, as copies of float32 points (x 12 bytes): garment and body points
#: and their copies while measured and written (measured: the 3,240-vertex dress on the 13,348-vertex body, 2,000
#: and 5,000 frames, peak memory's growth per frame: LBS 430 kB, 2.16 copies; the model 370 kB, 1.86; with
#: --no-body, where only the garment counts and the body is posed at the frames checked for penetration only, 1.7
#: and 1.1 copies of the garment); the simulator keeps two more of the body (its moving collider, float64),
#: written or not.
BAKE_COPIES = {"lbs": 2.25, "model": 2.0, "psd": 2.25, "sim": 4.0}


def _check_memory(garment, body, motions, method, parallel: int, settle_frames: int = 0,
                  with_body: bool = True) -> None:
    """Refuse, before any work, a bake whose longest motion would not fit in the memory free now (`parallel`
    motions at once), naming the motion and the --frames that fit; a crash for want of memory writes nothing
    either, but says nothing. motions: (prepared motion, its source fps, path)."""
    if not motions:  # --skip-existing found every one baked
        return
    motion, source_fps, path = max(motions, key=lambda x: x[0].n_frames)
    _refuse_beyond_memory(garment, body, path, motion.n_frames, source_fps, motion.fps, BAKE_COPIES[method],
                          max(1, min(parallel, len(motions))), settle_frames, with_body or method == "sim")


def _refuse_beyond_memory(garment, body, path, n_frames: int, source_fps: float, fps: float, copies: float,
                          at_once: int, settle_frames: int = 0, with_body: bool = True) -> None:
    """The click error of `_check_memory` where `n_frames` frames at `fps` (of a motion at `source_fps`; the first
    `settle_frames` of them --settle's), `at_once` motions at a time with `copies` (BAKE_COPIES) of the garment and,
    `with_body`, the body, would not fit in the memory free now."""
    per_frame = (garment.n_vertices + (body.n_vertices if with_body else 0)) * 12 * copies * at_once
    beyond = beyond_memory(per_frame, n_frames, source_fps, fps, settle_frames)
    if beyond is None:
        return
    need, free, fit = beyond
    if settle_frames and fit < 1:  # the settle blend alone does not fit
        raise click.ClickException(
            f"--settle {settle_frames}: {settle_frames} frames of a {garment.n_vertices}-vertex garment on a "
            f"{body.n_vertices}-vertex body need about {settle_frames * per_frame / 1e9:.3g} GB, "
            f"{free / 1e9:.3g} GB is free: lower --settle (a few frames blend the rest pose into the motion)")
    parts = f"bake it in parts of at most {fit} source frames with --frames START:STOP" if fit >= 1 else ""
    if fps > source_fps:  # --fps multiplies the frames
        lower = f"lower --fps {fps:g} (it makes {fps / source_fps:.3g} frames of each at {source_fps:g} fps)"
        what = f"{parts}, or {lower}" if parts else lower
    else:
        what = parts or "not one frame fits"
    raise click.ClickException(
        f"motion '{path}': {n_frames} frames of a {garment.n_vertices}-vertex garment on a {body.n_vertices}-vertex "
        f"body need about {need / 1e9:.3g} GB, {free / 1e9:.3g} GB is free: {what}")


#: Root speed (m/s) in a simulated motion's first frame above which `bake` notes the jolt of a cloth starting at
#: rest (a brisk walk: 2 m/s; the example trousers trail where skinning puts them by 35 mm at its second frame).
START_SPEED_NOTE_M_S = 0.5


def _note_rest_start(frames: str | None, preroll_frames: int, motions: list, method: str = "sim") -> None:
    """sim, model: say where the cloth starts at rest on a moving body (a --frames range after the motion's start
    without --preroll, or a motion already moving in its first frame) and how to leave that start out of the
    output. The model learned its start from the simulator's: the dress on the example walk moves more than 30 mm
    against the body in 567 of its 3,240 vertices from frame 0 to 1, against 15-257 a frame after frame 4."""
    cloth = "the simulated cloth" if method == "sim" else "the model's cloth (as the simulator's it learned from)"
    if frames and not preroll_frames and (parse_frame_range(frames)[0] or 0) > 0:
        verb = "simulates" if method == "sim" else "deforms"
        click.echo(f"note: --frames {frames}: the cloth starts at rest on the body at START; --preroll N {verb} "
                   "N frames before it (not written) so that it arrives there moving", err=True)
        return
    moving = []
    for motion, path in motions:
        k = motion.n_settle  # the settle blend holds the root still: the motion's own first frame
        if motion.n_lead == 0 and motion.n_frames > k + 1:
            speed = float(np.linalg.norm(motion.trans[k + 1] - motion.trans[k]) * motion.fps)
            if speed > START_SPEED_NOTE_M_S:
                moving.append((speed, path))
    if moving:
        speed, path = max(moving)
        others = f" (and {counted(len(moving) - 1, 'more motion')})" if len(moving) > 1 else ""
        click.echo(f"note: motion '{path}'{others} moves at {speed:.1f} m/s from its first frame: {cloth} starts "
                   "at rest and trails the body for a few frames; `--frames K: --preroll K` leaves the first K source "
                   "frames out of the output", err=True)


def _echo_throughput(frames: int, motions: int, seconds: float) -> None:
    if motions > 1:
        click.echo(f"baked {frames} frames of {motions} motions in {seconds:.1f} s: {frames / max(seconds, 1e-9):.1f} "
                   "frames/s (writing included)")


def _body_joints_guard(deformer, body, explicit: bool) -> str:
    """A body whose skeleton is not the model's (`core.model_deform.model_body`: SMPL's 24 joints for a model of
    SMPL+H's 52; an SMPL+H or SMPL-X body is read on SMPL's joints by a model of them): the JSON of a fall-back
    to lbs when the model was not asked for by name, else a click error naming both."""
    from core.model_deform import skeleton_mismatch

    inner = getattr(deformer, "inner", deformer)  # under --push-out
    want = inner.model.config.n_joints
    what = skeleton_mismatch(inner.model_name, want, body)
    if not what:
        return ""
    if explicit:
        raise click.ClickException(f"{what}: bake with --method lbs (or psd), or train a model on this body "
                                   "(garment dataset/train --body)")
    click.echo(f"{what}: baking with lbs instead", err=True)
    return json.dumps({"from": "model", "to": "lbs", "model": inner.model_name, "reason": "body joints",
                       "model_joints": want, "body_joints": body.n_joints})


def _prepare_unwarned(deformer, garment, body, garment_path) -> None:
    """The lbs that the model gave way to, prepared without the binding's warnings: the model's preparation bound
    the same garment and gave them (a garment partly inside the body was warned about twice)."""
    log = logging.getLogger("core.skinning")
    quiet = logging.Filter("nothing")  # passes no record of core.skinning
    log.addFilter(quiet)
    try:
        deformer.prepare(garment, body, source=garment_path)
    finally:
        log.removeFilter(quiet)


def _training_range_guard(deformer, garment, body, garment_path, explicit: bool) -> str:
    """Warn when the garment lies outside the model's training garments; returns the JSON of a fall-back to
    lbs when the model was not asked for by name (--method model), else ""."""
    inner = getattr(deformer, "inner", deformer)  # under --push-out
    rng = inner.training_range(garment, body)
    edges = (rng or {}).get("edges")
    if edges is not None and not edges["within"] and (explicit or rng["within"]):  # (not where lbs bakes it)
        (least, largest), edge = edges["trained_edge_m"], edges["median_edge_m"]
        click.echo(f"warning: garment '{garment_path}' has edges of {edge * 1e3:.1f} mm (median), "
                   f"{'finer' if edge < least else 'coarser'} than model '{inner.model_name}' was trained on "
                   f"({least * 1e3:.1f}-{largest * 1e3:.1f} mm): its result may be worse than lbs (`garment "
                   f"tradeoff` measures both on this scene); a mesh remeshed to about their size bakes as they do",
                   err=True)
    if rng is None or rng["within"]:
        return ""
    joints = ", ".join(rng["uncovered_joints"][:4])
    what = (f"garment '{garment_path}' puts {rng['uncovered_share']:.0%} of its skinning weight on joints no training "
            f"garment of model '{inner.model_name}' covered ({joints})")
    if explicit:
        click.echo(f"warning: {what}: its result may be worse than lbs", err=True)
        return ""
    click.echo(f"{what}: baking with lbs instead (--method model uses the model anyway)", err=True)
    return json.dumps({"from": "model", "to": "lbs", "model": inner.model_name, **rng})


def _calibration_beside(model_path) -> Path:
    """`<model>.calibration.json` beside the model (the shipped one where `model_path` is None)."""
    from core.model_deform import DEFAULT_MODEL

    model = Path(model_path) if model_path else DEFAULT_MODEL
    return model.with_name(model.stem + ".calibration.json")


def _warn_beyond_fit(fit, body, motions, fit_path) -> None:
    """Warn about each motion (motions: [(Motion, path)]) beyond the sequences a psd fit was fitted on
    (`core.psd.beyond_fit`): there its blend shapes answer poses and speeds they never saw (a run at six times its
    speed on betas +5: 22 mm against LBS's 15)."""
    from core.psd import beyond_fit

    for motion, motion_path in motions:
        beyond = beyond_fit(fit, body, motion)
        if beyond:
            log.warning("motion '%s': beyond the sequences the fit '%s' was fitted on (%s): psd can do worse than "
                        "lbs there; `garment tradeoff --fit` measures it on this motion", motion_path, fit_path,
                        beyond)


def _warn_beyond_calibration(garment, body, motions, model_path) -> None:
    """Warn, for the model, about each motion (motions: [(Motion, path)]) beyond the scenes of its calibration
    (`<model>.calibration.json`, where there is one: `core.quality.Calibration.outside`), where its gain over lbs
    is not known."""
    from core.quality import OUTSIDE_MEASURED, Calibration, describe_outside, scene_features

    path = _calibration_beside(model_path)
    if not path.is_file():
        return
    calibration = Calibration.load(path)
    for motion, motion_path in motions:
        outside = calibration.outside(scene_features(garment, body, motion))
        if outside:
            log.warning("motion '%s': beyond the scenes the model's calibration measured (%s): expect little gain "
                        "over lbs (%s); `garment tradeoff` measures it on this motion", motion_path,
                        "; ".join(describe_outside(o) for o in outside),
                        OUTSIDE_MEASURED if model_path is None else "unmeasured for this model")


def _choose_quality(garment, body, motions, model_path, calibration_path, budget_mm, fit_path=None,
                    garment_path=None) -> dict:
    """--quality auto: the choice for the most demanding motion of the batch (motions: [(Motion, path)]): the
    costliest of their choices; with --fit, the garment's fitted blend shapes are a candidate too
    (`core.quality.psd_candidate`)."""
    from core.model_deform import DEFAULT_MODEL
    from core.quality import Calibration, choose, psd_candidate, scene_features

    if model_path:  # before its calibration, which is named after it
        option_file(model_path, "--model")
    if calibration_path is None:
        calibration_path = _calibration_beside(model_path)
        if not calibration_path.is_file():
            raise click.ClickException(f"--quality auto: model '{model_path or DEFAULT_MODEL}' has no calibration "
                                       f"'{calibration_path.name}' beside it: make one with `garment tradeoff "
                                       "--calibrate`, or pass --calibration or --method")
    else:
        option_file(calibration_path, "--calibration")
    calibration = Calibration.load(calibration_path)
    measured = calibration.models()
    if measured:  # which model's errors its model configurations are (a calibration of before 2026-12-06: unknown)
        from core.provenance import file_sha256

        used = file_sha256(model_path or DEFAULT_MODEL)
        if used not in measured:
            log.warning("--quality auto: calibration '%s' measured model %s on its scenes, not '%s' (sha256 %s): "
                        "its expected errors for the model are another model's (`garment tradeoff --calibrate` "
                        "measures this one)", calibration_path, " and ".join(sorted(m[:8] for m in measured)),
                        model_path or DEFAULT_MODEL, used[:8])
    if fit_path is not None:
        from formats.psd import psd_deformer

        psd = psd_deformer(fit_path)
        psd.check(garment, body, source=str(garment_path))  # before it is offered as a candidate
    picks = []
    for motion, path in motions:
        features = scene_features(garment, body, motion)
        extra = [] if fit_path is None else [psd_candidate(calibration, features, psd.fit.meta)]
        picks.append({**choose(calibration, features, budget_mm, extra), "motion": Path(path).name})
    # One method for the batch: the one the most demanding motion needs (the costliest pick, then the largest
    # expected error); a motion beyond the calibration is named whichever motion the choice came from.
    pick = max(picks, key=lambda p: (p["ms_per_frame"], p["expected_mm"]))
    pick["outside_motions"] = [p["motion"] for p in picks if p["outside_calibration"]]
    # as given: the warning naming them is kept in those motions' summaries only (`_warnings_of`)
    pick["outside_paths"] = [str(path) for p, (_, path) in zip(picks, motions) if p["outside_calibration"]]
    if pick["method"] == "model" and model_path:
        pick["options"] = {**pick["options"], "path": str(model_path)}
    return pick


def _bake_locally(spec: BakeSpec, motions, bar, ticked, method: str, fps: float) -> None:
    """Each motion in turn in this process; one that fails is said at once and the others go on, as on workers
    (`_failed`); a write out of room stops the batch."""
    from formats.atomic import OutOfRoom

    failures = []
    for prepared, motion_path, target in motions:
        ticked[0] = 0
        try:
            with _writing_bar(prepared[0].n_frames if spec.write_obj else 0) as on_written:
                summary = bake_task(spec, motion_path, target, prepared, on_written)
        except OutOfRoom:
            raise
        except (InputError, FloatingPointError) as exc:
            if len(motions) == 1:
                if isinstance(exc, InputError):
                    raise
                raise click.ClickException(_failed([(motion_path, exc)], 1)) from None
            click.echo(f"error: bake of '{motion_path}': {_cause(exc)}", err=True)
            failures.append((motion_path, exc))
            continue
        finally:
            bar.update(prepared[0].n_frames - ticked[0])
        if summary is None:  # its output was checked not to be there before the batch
            click.echo(f"{target}: written by another run while this one worked, left as it is", err=True)
        else:
            _echo_done(target, summary, method, fps)
    if failures:
        raise click.ClickException(_failed(failures, len(motions)))


def _cause(exc: BaseException) -> str:
    """An exception's first line, its type named where it is none of ours (a worker's OSError, a bug's)."""
    line = str(exc).splitlines()[0] if str(exc) else ""
    ours = isinstance(exc, (InputError, FloatingPointError))  # (the simulator's divergence: a sentence)
    return line if ours and line else f"{type(exc).__name__}: {line}".rstrip(": ")


def _failed(failures: list, total: int) -> str:
    """The error line of a batch whose motions `failures` [(motion path, exception)] failed, of `total`."""
    path, exc = failures[0]
    if total == 1:
        return f"bake of '{path}': {_cause(exc)}"
    more = f" (and {counted(len(failures) - 1, 'other')})" if len(failures) > 1 else ""
    return (f"bake: {len(failures)} of {total} motions failed, the others are written; '{path}'{more}: "
            f"{_cause(exc)}; rerun with --skip-existing to bake what failed")


@contextmanager
def _writing_bar(frames: int):
    """on_written(n) for `bake_task`: a second bar, "write", over a motion's `frames` OBJ frames, shown once the
    writing starts (a 203k-vertex garment's 1.3 GB of frames took a minute after the bake bar's 100 %); None
    for no frames (--no-obj)."""
    held = []

    def on_written(n: int) -> None:
        if not held:
            held.append(tqdm(total=frames, unit="frame", desc="write", disable=None, leave=False))
        held[0].update(n)

    try:
        yield on_written if frames else None
    finally:
        for bar in held:
            bar.close()


def _bake_in_workers(spec: BakeSpec, motions, scheduler: str | None, retries: int, workers: int) -> None:
    """One task per motion on a Dask cluster (`scheduler`) or in `workers` local processes; outputs written by
    the workers; progress as motions finish."""
    from core.distributed import ItemsFailed, connect, run_items

    absolute = lambda p: str(Path(p).resolve()) if p else None  # noqa: E731 - workers run elsewhere
    # Every input file (a field `*_path`) named absolutely: a worker opened the --fit it was given relative to its
    # own folder (a cluster's: "file not found", or silently another fit of that name there).
    spec = replace(spec, **{f.name: absolute(getattr(spec, f.name)) for f in fields(spec) if f.name.endswith("_path")},
                   warnings=tuple((absolute(m), w) for m, w in spec.warnings))
    client = connect(scheduler) if scheduler else None
    # m: read here (`prepared`), named to the workers as the client's path
    calls = [(spec, absolute(m), target.resolve(), prepared) for prepared, m, target in motions]
    names = [target.name for _, _, target in motions]
    target_of = {target.name: target for _, _, target in motions}
    try:
        with tqdm(total=len(calls), unit="motion", desc="bake", disable=None, leave=False) as bar:
            for name, summary in run_items(bake_task, calls, names, retries=retries, client=client, workers=workers):
                bar.update(1)
                if summary is not None:
                    _echo_done(target_of[name], summary, spec.method, spec.fps)
    except ItemsFailed as exc:
        motion_of = {target.name: m for _, m, target in motions}
        raise click.ClickException(_failed([(motion_of.get(name, name), e) for name, e in exc.failures],
                                           exc.total)) from None
    finally:
        if client is not None:
            client.close()

