"""`garment tradeoff GARMENT MOTION`: every method and configuration on one scene, speed against accuracy.

Writes OUT/<garment>_<motion>/tradeoff.md, tradeoff.csv, tradeoff.json and tradeoff.png (Pareto plot);
the rows are those of `core.tradeoff.configurations`, compared with its reference (the simulator at
the finest substeps with self-contact).
"""

from __future__ import annotations

import csv
import json
import shutil
import tempfile
import time
from pathlib import Path

import click
from tqdm import tqdm

from core.tradeoff import (
    METRIC_COLUMNS,
    SPREAD_JITTER_M,
    compare,
    configurations,
    load_simulation,
    measure,
    memory_needed,
    pareto_front,
    save_simulation,
    sim_file_name,
    simulation_key,
    simulation_scene,
)
from garmentcli.common import (
    OutputPath,
    betas_option,
    beyond_memory,
    body_option,
    check_preroll,
    collected_notes,
    frames_option,
    input_errors_as_click,
    load_body_option,
    read_garment_on,
    motion_up_option,
    person_option,
    take_option,
    parse_device,
    prepare_motion,
    preroll_option,
    require_file,
    source_fps_option,
    option_file,
    FiniteFloatRange,
    MAX_FPS,
)

COLUMNS = ("config", "method", "seconds_per_frame", "frames_per_second", "seconds_prepare", "peak_memory_mb",
           "gpu_peak_memory_mb", *METRIC_COLUMNS, "pareto")


#: Subdirectory of a scene's results holding its simulator rows (points, timings, key) for --reuse-sim.
SIMULATIONS = "simulations"


#: The software a tradeoff run records (tradeoff.json, the calibration's provenance).
SOFTWARE = ("garment", "numpy", "torch", "newton", "warp-lang")


def _model_sha256(path) -> str:
    """sha256 of a model file (None: the shipped model's), as a calibration records which model it measured."""
    from core.model_deform import DEFAULT_MODEL
    from core.provenance import file_sha256

    return file_sha256(path or DEFAULT_MODEL)


def _models(specs: tuple) -> dict:
    return _named_files(specs, "--model", "model") if specs else {"model": None}  # None: the shipped model


def _models_for_body(models: dict, body) -> dict:
    """The models that run on `body`: a --model of another skeleton is refused, the shipped one's rows left out
    with a line saying why (`core.model_deform.model_body`)."""
    from core.model_deform import DEFAULT_MODEL, skeleton_mismatch
    from formats.checkpoint import load_model

    kept = {}
    for name, path in models.items():
        # the network built and its weights loaded, before any row: a model that cannot be (weights not finite,
        # or not of its config) failed row by row while the simulator rows ran on (hours)
        config = load_model(path or DEFAULT_MODEL)[1]["config"]
        what = skeleton_mismatch(str(path or DEFAULT_MODEL), config["n_joints"], body)
        if not what:
            kept[name] = path
        elif path is not None:
            raise click.BadParameter(f"{what} (leave it out, or pass the --body it was made for)", param_hint="--model")
        else:
            click.echo(f"tradeoff: {what}: its rows are left out", err=True)
    return kept


def _refuse_beyond_memory(n_rows: int, garment, body, n_frames: int, source_fps: float, fps: float,
                          motion_path) -> None:
    """A run whose rows' points would not fit in the memory free now stops before its first simulation (hours),
    not after its last. n_frames: at `fps`, of a motion at `source_fps`."""
    beyond = beyond_memory(memory_needed(n_rows, garment, body, 1), n_frames, source_fps, fps)
    if beyond is not None:
        need, free, fit = beyond
        raise click.ClickException(
            f"motion '{motion_path}': {n_rows} configurations of {n_frames} frames of a "
            f"{garment.n_vertices}-vertex garment need about {need / 1e9:.3g} GB, {free / 1e9:.3g} GB is free: "
            + (f"measure a part of at most {fit} source frames with --frames START:STOP" if fit >= 1
               else "not one frame fits"))


def _named_files(specs: tuple, option: str, what: str) -> dict:
    """NAME=PATH specs of `option` -> {name: path}; BadParameter for a malformed one or a missing file."""
    out = {}
    for spec in specs:
        name, sep, path = spec.partition("=")
        if not sep or not name or not path:
            raise click.BadParameter(f"expected NAME=PATH, got {spec!r}", param_hint=option)
        if name in out:  # one row each: the second would replace the first's
            raise click.BadParameter(f"expected distinct names, got {name!r} twice ('{out[name]}', '{path}')",
                                     param_hint=option)
        option_file(path, option, what)
        out[name] = path
    return out


@click.command(name="tradeoff")
@click.argument("garment_path", metavar="GARMENT", type=click.Path(dir_okay=False))
@click.argument("motion_path", metavar="MOTION", type=click.Path(dir_okay=False))
@click.option("--out", "out_dir", type=OutputPath(file_okay=False), default="garment_tradeoff", show_default=True,
              help="Output directory; the scene's results go to OUT/<garment>_<motion>/.")
@body_option
@betas_option
@source_fps_option
@motion_up_option
@person_option
@take_option
@click.option("--fps", type=FiniteFloatRange(min=1.0, max=MAX_FPS), default=30.0, show_default=True,
              help="Frame rate the scene is baked at.")
@frames_option
@preroll_option
@click.option("--model", "model_specs", multiple=True, metavar="NAME=PATH",
              help="Model checkpoints to compare (repeatable). Default: the shipped model.")
@click.option("--fit", "fit_specs", multiple=True, metavar="NAME=PATH",
              help="The garment's fitted blend shapes (`garment fit`) to compare as `psd NAME` rows (repeatable; "
                   "left out of --calibrate: a fit belongs to one garment).")
@click.option("--device", default=None, metavar="DEVICE",
              help="Where the model rows' network runs: cpu, cuda or cuda:N [default: auto, as bake's].")
@click.option("--repeats", type=click.IntRange(min=1), default=3, show_default=True,
              help="Timed runs per configuration after a warm-up (the median counts); the simulator runs once.")
@click.option("--overwrite", is_flag=True, help="Replace an existing result directory.")
@click.option("--reuse-sim", is_flag=True,
              help="Take the simulator rows from the earlier run in the result directory where it simulated the same "
                   "scene (garment, body, motion, frames, fps, simulator settings), so adding a model re-simulates "
                   "nothing; replaces that directory. Also takes the rows an interrupted run finished.")
@click.option("--calibrate", "calibration_path", type=OutputPath(dir_okay=False), default=None, metavar="FILE",
              help="Also add this scene to the --quality auto calibration FILE (created if missing), e.g. "
                   "<model>.calibration.json beside the model.")
@click.option("--spread", is_flag=True,
              help="Also run the reference once more from starting positions moved by 1 um (seeded): how far apart "
                   "two equally valid simulations of the scene end up (cloth is chaotic), the floor under every "
                   "row's error. A row of the table and a dashed line in the plot; one more reference run of time.")
@input_errors_as_click
def tradeoff(garment_path, motion_path, out_dir, body_path, fps, frames, model_specs, repeats, overwrite,
             reuse_sim=False, calibration_path=None, spread=False, betas="auto", source_fps=None, fit_specs=(),
             preroll_frames=0, device=None, motion_up="z", person=None, take=None):
    """Run every method and configuration on GARMENT over MOTION and measure speed against accuracy.

    Rows: lbs, and lbs with --strain-limit 1.5; each --fit (psd); each model in float32 and bfloat16, with and
    without penetration push-out; the
    simulator at two substep settings with and without self-contact. The finest simulation with
    self-contact is the reference the errors are measured against.
    """
    for p in (garment_path, motion_path):
        require_file(p)
    check_preroll(preroll_frames, frames)
    device = str(parse_device(device, auto=True))
    models = _models(model_specs)
    fits = _named_files(fit_specs, "--fit", "fit")
    if fits:
        from formats.psd import load_fit

        for path in fits.values():  # a file that is no fit stops the run now (it became a failed row, exit 0)
            load_fit(path)
    if calibration_path and Path(calibration_path).is_file():
        from core.quality import Calibration

        Calibration.load(calibration_path)  # one that is no calibration stops the run now, not after its hours
    from core.sim import require_simulator

    require_simulator("tradeoff")  # its reference rows
    target = Path(out_dir) / f"{Path(garment_path).stem}_{Path(motion_path).stem}"
    if target.exists() and not target.is_dir():  # --overwrite replaces a result folder, not another file
        raise click.ClickException(f"output '{target}' is a file: expected the scene's result folder there (remove "
                                   "it, or choose another --out)")
    if target.exists() and not (overwrite or reuse_sim):
        raise click.ClickException(f"output '{target}' exists: pass --overwrite to replace it (or --reuse-sim to "
                                   "keep its simulations)")
    # Every simulator row is kept here as soon as it is done, so an interrupted run loses none (--reuse-sim).
    staged = target.parent / f".{target.name}.{SIMULATIONS}"
    if reuse_sim and not ((target / SIMULATIONS).is_dir() or staged.is_dir()):
        raise click.ClickException(f"--reuse-sim: '{target / SIMULATIONS}' does not exist: no earlier run to reuse")
    if not reuse_sim and staged.is_dir():
        click.echo(f"tradeoff: discarding the simulator rows an interrupted run left in '{staged}' (--reuse-sim "
                   "would take them)", err=True)
        shutil.rmtree(staged)
    body = load_body_option(body_path)
    garment = read_garment_on(garment_path, body)
    models = _models_for_body(models, body)
    rows = configurations(models, spread=spread, fits=fits)

    def prepared(context: int = 0):  # the motion, with `context` frames either side of --frames (psd's)
        return prepare_motion(motion_path, fps, frames, 0, betas, source_fps, preroll_frames, body=body,
                              check_frames=lambda n, src_fps: _refuse_beyond_memory(len(rows), garment, body, n,
                                                                                    src_fps, fps, motion_path),
                              motion_up=motion_up, person=person, take=take, context_frames=context)[0]

    motion = prepared()
    psd_motion = motion  # the psd rows' (their context frames either side of --frames, as bake's)
    if fits and frames:
        from core.psd import FEATURE_CONTEXT_FRAMES

        with collected_notes():  # (said when first read)
            psd_motion = prepared(FEATURE_CONTEXT_FRAMES)
    from formats.cache import default_cache_dir

    scene = simulation_scene(garment, body, motion)
    results, failed, reused = [], [], []
    bar = tqdm(rows, desc="tradeoff", unit="config", disable=None)
    for i, config in enumerate(bar, 1):
        key = simulation_key(config, scene) if config.method == "sim" else None
        if key is not None and reuse_sim:
            stored = (load_simulation(target / SIMULATIONS / sim_file_name(config), config, key)
                      or load_simulation(staged / sim_file_name(config), config, key))
            if stored is not None:
                results.append(stored)
                reused.append(config.name)
                continue
        try:
            results.append(measure(config, garment, body, psd_motion if config.method == "psd" else motion, repeats,
                                   cache_dir=default_cache_dir(), device=device))
            if key is not None:
                staged.mkdir(parents=True, exist_ok=True)
                save_simulation(staged / sim_file_name(config), results[-1], key, garment.faces, motion.fps)
            if bar.disable:  # no terminal (a log file, a batch job): one line per configuration
                click.echo(f"tradeoff: {i}/{len(rows)} {config.name}: "
                           f"{results[-1].seconds_per_frame:.4g} s/frame", err=True)
        except Exception as exc:  # an unstable configuration (e.g. too few substeps) is a result too, and one row
            # failing otherwise (out of memory, a device error) must not throw away the hours of the others
            reason = str(exc) if isinstance(exc, FloatingPointError) else f"{type(exc).__name__}: {exc}"
            if config.reference:
                kept = (f" (the finished simulator rows are kept in '{staged}' for --reuse-sim)"
                        if staged.is_dir() else "")
                raise click.ClickException(f"tradeoff: the reference configuration '{config.name}' failed: "
                                           f"{reason}{kept}") from exc
            click.echo(f"{config.name}: failed ({reason})", err=True)
            failed.append((config, reason))
    compare(results, garment, body, motion)
    # The spread row is the reference again, not a configuration to choose: outside the front and the calibration.
    front = iter(pareto_front([(m.seconds_per_frame, m.metrics["e_verts"]) for m in results if not m.config.spread]))
    table = []
    for m in results:
        on = False if m.config.spread else next(front)
        table.append({"config": m.config.name, "method": m.config.method, "seconds_per_frame": m.seconds_per_frame,
                      "frames_per_second": 1.0 / m.seconds_per_frame, "seconds_prepare": m.seconds_prepare,
                      "peak_memory_mb": m.peak_memory_mb, "gpu_peak_memory_mb": m.gpu_peak_memory_mb, **m.metrics,
                      "pareto": on,
                      "reference": m.config.reference, "spread": m.config.spread, "runs": m.runs, "failed": "",
                      "retries": m.retries, "self_contact_skipped": m.self_contact_skipped})
    for config, reason in failed:
        table.append({"config": config.name, "method": config.method, "pareto": False, "reference": False,
                      "spread": config.spread, "runs": 0, "failed": reason})
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{target.name}.", dir=target.parent))
    try:
        _write(tmp, table, garment_path, motion_path, motion, garment, device,
               {"frames": frames, "repeats": repeats, "preroll": preroll_frames, "source_fps": source_fps,
                "betas": betas, "body": str(body_path) if body_path else "embedded default"})
        (tmp / SIMULATIONS).mkdir()
        for m in results:
            if m.config.method == "sim":
                save_simulation(tmp / SIMULATIONS / sim_file_name(m.config), m, simulation_key(m.config, scene),
                                garment.faces, motion.fps)
        if target.exists():
            shutil.rmtree(target)
        tmp.rename(target)
        shutil.rmtree(staged, ignore_errors=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    if calibration_path:
        from core.provenance import software_versions
        from core.quality import Calibration, add_scene, scene_features

        # read again (not the copy checked above): another run may have added its scene meanwhile
        cal = Calibration.load(calibration_path) if Path(calibration_path).is_file() else Calibration({})
        features = scene_features(garment, body, motion)
        add_scene(cal, features, [{**r, "options": {k: v for k, v in m.config.options.items() if k != "path"},
                                   **({"model_sha256": _model_sha256(m.config.options.get("path"))}
                                      if m.config.method == "model" else {})}
                                  for r, m in zip(table, results) if not m.config.spread and m.config.method != "psd"])
        cal.provenance = {"updated": time.strftime("%Y-%m-%d"), "software": software_versions(*SOFTWARE)}
        cal.save(calibration_path)
        click.echo(f"{calibration_path}: added the scene (looseness {features['looseness_m'] * 100:.1f} cm, "
                   f"speed {features['speed_m_s']:.2f} m/s)")
    if reuse_sim:
        click.echo(f"--reuse-sim: {len(reused)} of {sum(c.method == 'sim' for c in rows)} simulator rows taken from "
                   f"the earlier run" + (f" ({', '.join(reused)})" if reused else ""))
    best = min((r for r in table if r["method"] == "model" and not r["failed"]), key=lambda r: r["e_verts"], default=None)
    lbs = next(r for r in table if r["method"] == "lbs")
    click.echo(f"{target}: {len(table)} configurations on {motion.n_written} frames; lbs "
               + ("failed" if lbs["failed"] else
                  f"{lbs['e_verts']:.1f} mm at {lbs['seconds_per_frame'] * 1e3:.2f} ms/frame")
               + (f", best model row '{best['config']}' {best['e_verts']:.1f} mm at "
                  f"{best['seconds_per_frame'] * 1e3:.1f} ms/frame" if best else "")
               + "".join(f"; the reference's spread {r['e_verts']:.1f} mm" for r in table
                         if r["spread"] and not r["failed"]))


def _retried(row: dict) -> str:
    """The frames a simulator row ran again with more substeps, in words ("" where none)."""
    return "; ".join(f"frame {r['frame']} run again at {r['kept_substeps']} substeps (try {r['tries']})"
                     for r in row.get("retries") or [])


def _or_dash(value):
    return "-" if value is None else value


def _write(directory: Path, table: list[dict], garment_path, motion_path, motion, garment, device: str,
           options: dict) -> None:
    from formats.plots import plot_pareto
    from formats.report import markdown_table

    with open(directory / "tradeoff.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=[*COLUMNS, "reference", "spread", "runs", "failed", "retries",
                                            "self_contact_skipped"])
        w.writeheader()
        w.writerows([{**r, "retries": _retried(r)} for r in table])
    from core.provenance import software_versions
    from core.sim import SIMULATOR_VERSION

    (directory / "tradeoff.json").write_text(json.dumps(
        {"garment": str(garment_path), "motion": str(motion_path), "frames": motion.n_written,
         "preroll_frames": motion.n_lead, "fps": motion.fps,
         "vertices": garment.n_vertices, "model_device": device, "options": options,
         "simulator_version": SIMULATOR_VERSION,
         "software": software_versions(*SOFTWARE), "rows": table}, indent=1))
    ref = next(r["config"] for r in table if r["reference"])
    done = [r for r in table if not r["failed"]]
    spread = next((r for r in done if r["spread"]), None)
    gpu = any(r.get("gpu_peak_memory_mb") is not None for r in done)  # a column of its own where any row has one
    md = [f"# Speed against accuracy: `{Path(garment_path).name}` on `{Path(motion_path).name}`", "",
          (f"{motion.n_written} frames at {motion.fps:g} fps"
           + (f" after {motion.n_lead} pre-roll frames" if motion.n_lead else "")
           + f", {garment.n_vertices} garment vertices, the model rows on {device}. Errors against "
           f"the reference `{ref}`; seconds per frame: median of the timed runs after a warm-up (simulator: one "
           "run); preparation (binding, preprocessing, simulator build) apart; peak memory: the largest rise of "
           "resident memory during the timed runs"
           + ("; GPU peak: the largest rise of the GPU memory torch allocated (the model rows)" if gpu else "")
           + ". E_verts mm, E_vnorm / E_fnorm degrees, E_edge %, penetration: "
           "% of vertices > 2 mm inside the body.")
          + (f" `{spread['config']}`: the reference run again from starting positions moved by a seeded "
             f"{SPREAD_JITTER_M * 1e6:g} um; its error, {spread['e_verts']:.1f} mm, is how far two equally valid "
             "simulations of this scene end up apart, the floor under every row's error." if spread else ""), "",
          markdown_table(["config", "s/frame", "fps", "prepare s", "memory rise MB", *(["GPU peak MB"] if gpu else []),
                          *METRIC_COLUMNS, "Pareto"],
                         [[r["config"], r["seconds_per_frame"], r["frames_per_second"], r["seconds_prepare"],
                           r["peak_memory_mb"], *([_or_dash(r["gpu_peak_memory_mb"])] if gpu else []),
                           *[r[k] for k in METRIC_COLUMNS], "yes" if r["pareto"] else ""] for r in done])]
    md += [f"\n`{r['config']}` failed: {r['failed']}" for r in table if r["failed"]]
    md += [f"\n`{r['config']}`: {_retried(r)}" for r in done if r.get("retries")]
    md += [f"\n`{r['config']}`: self-contact skipped by the scene analysis (no two distant parts of the garment "
           "come near on this motion): measured as the row without it" for r in done if r.get("self_contact_skipped")]
    (directory / "tradeoff.md").write_text("\n".join(md))
    rows = [r for r in done if not r["spread"]]
    plot_pareto([r["config"] for r in rows], [r["seconds_per_frame"] for r in rows],
                [r["e_verts"] for r in rows], [r["pareto"] for r in rows], directory / "tradeoff.png",
                title=f"{Path(garment_path).stem} on {Path(motion_path).stem}: error against time per frame",
                floor=(spread["e_verts"], f"reference's spread (started {SPREAD_JITTER_M * 1e6:g} um apart)")
                if spread else None)
