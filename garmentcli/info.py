"""`garment info PATH...`: what `garment` reads in each file, before any bake: a garment's mesh and how it rests on
the body (or why it would be refused); a motion's frames, rate, joints, world, the parts a file holds (tracked
people, animations) and what reading it said (a rig retargeted, a world turned)."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import click
import numpy as np

from core.errors import InputError, counted
from garmentcli.common import (
    bake_summary_path,
    body_option,
    collected_notes,
    input_errors_as_click,
    load_body_option,
    read_garment_on,
    motion_files,
    person_option,
    resolved_up,
    source_fps_option,
    take_option,
)


def garment_info(path: str, body) -> dict:
    """A garment file's mesh (vertices, triangles, extent in metres) and its rest on `body`: the median distance
    of its vertices to the body's surface, the share more than `REST_INSIDE_DEPTH_M` inside, and the refusal a
    bake would give ('refused': its line, or None)."""
    from core.geometry import TriangleMesh
    from core.skinning import REST_INSIDE_DEPTH_M, check_rest_fit

    with collected_notes() as notes:
        garment = read_garment_on(path, body)
        mesh = TriangleMesh(body.v_template, body.faces)
        _, signed = mesh.signed_closest(garment.vertices)
        try:
            check_rest_fit(garment, body, mesh, signed, str(path))
            refused = None
        except InputError as exc:
            refused = str(exc)
    span = np.ptp(garment.vertices, axis=0)
    return {"path": str(path), "kind": "garment", "vertices": garment.n_vertices, "triangles": garment.n_faces,
            "extent_m": [round(float(x), 4) for x in span],
            "median_distance_mm": round(float(np.median(np.abs(signed))) * 1e3, 2),
            "inside_percent": round(float(np.mean(signed < -REST_INSIDE_DEPTH_M)) * 100, 2),
            "refused": refused, "notes": notes}


def bake_info(path: Path) -> dict:
    """A `garment bake` output (its folder, its USD stage, its OBJ frames or one of them): the sequence it holds
    (frames, rate, vertices) and, from its `summary.json` where there is one, how it was made (method, inputs)."""
    from formats.sequence import read_sequence

    seq = read_sequence(path)
    summary_path = bake_summary_path(path)
    summary = json.loads(summary_path.read_text()) if summary_path is not None else {}
    return {"path": str(path), "kind": "bake", "frames": seq.n_frames, "fps": seq.fps,
            "vertices": int(seq.points.shape[1]), "first_frame": seq.first_frame,
            "method": summary.get("method"), "inputs": summary.get("inputs"), "notes": []}


def body_info(path: Path) -> dict:
    """An SMPL-format body file: its vertices, joints, shape coefficients, layout and content hash."""
    from formats.body import load_body

    with collected_notes() as notes:
        body = load_body(path)
    return {"path": str(path), "kind": "body", "vertices": body.n_vertices, "joints": body.n_joints,
            "betas": body.n_betas, "layout": body.layout, "sha256": body.content_hash(), "notes": notes}


def fit_info(path: Path) -> dict:
    """A `garment fit` file: the garment and body it was fitted to, its shapes and how well it fitted."""
    from formats.psd import load_fit

    fit = load_fit(path)
    return {"path": str(path), "kind": "fit", "body": fit.body, "shapes": int(fit.basis.shape[0]),
            "vertices": int(fit.mean.size // 3), "meta": fit.meta, "notes": []}


#: The suffixes of `garment train`'s model and resume-state files (a motion may be a `.pt` too).
MODEL_SUFFIXES = (".pt", ".pth", ".ckpt")


def model_info(path: Path) -> dict:
    """A model checkpoint of `garment train` (or its resume state, MODEL.ckpt): what it was trained on."""
    from core.model_deform import trained_betas, trained_body
    from formats.checkpoint import load_checkpoint

    data = load_checkpoint(path)
    meta, cfg = data.get("meta") or {}, data.get("config") or {}
    body = trained_body(meta)
    least, largest = trained_betas(meta)
    return {"path": str(path), "kind": "model", "resume_state": "train" in data,
            "steps": meta.get("steps", (data.get("train") or {}).get("step")), "phase": meta.get("phase"),
            "body": None if body is None else body["name"], "body_sha256": None if body is None else body["sha256"],
            "garments": meta.get("garments"), "val_verts_mm": meta.get("val_verts_mm"),
            # the shapes the network is given within (core.model_deform.trained_betas; recorded or the default)
            "trained_betas": {"min": least.round(6).tolist(), "max": largest.round(6).tolist(),
                              "recorded": "trained_betas" in meta},
            "levels": cfg.get("levels"), "joints": cfg.get("n_joints"), "notes": []}


def _kind_of(path: Path) -> str:
    """What `info` reads `path` as: "bake" (a bake's folder, stage or OBJ frames), "bakes" (a `bake --out` folder
    of several), "body", "fit", "model", "garment", "motion" or "model or motion" (a `.pt` that PyTorch cannot
    load: read as a motion, its error naming both)."""
    from formats.obj import USD_SUFFIXES
    from formats.sequence import SEQUENCE_JSON, bake_batch, bake_directory_sequence, recorded_frame
    from formats.usdskel import holds_skeleton

    suffix = path.suffix.lower()
    if path.is_dir():
        if bake_batch(path) is not None:
            return "bakes"
        baked = (path / "summary.json").is_file() or (path / SEQUENCE_JSON).is_file() or \
            bake_directory_sequence(path) is not None
        return "bake" if baked else "motion"
    if suffix == ".obj":
        return "bake" if recorded_frame(path) else "garment"
    if suffix in USD_SUFFIXES:
        if holds_skeleton(path):
            return "motion"
        return "bake" if (path.parent / "summary.json").is_file() else "garment"
    if suffix in MODEL_SUFFIXES and path.is_file():
        import torch

        from formats.checkpoint import FORMAT
        from formats.motion import TORCH_SUFFIXES

        try:  # a checkpoint by its format field, whatever its version (`model_info` says what is wrong with it)
            data = torch.load(path, map_location="cpu", weights_only=True)
        except Exception:  # damaged, or no torch file: a `.ckpt` is a model's; a `.pt` may be either (both told)
            return "model or motion" if suffix in TORCH_SUFFIXES else "model"
        return "model" if isinstance(data, dict) and data.get("format") == FORMAT else "motion"
    if suffix == ".npz" and path.is_file():
        try:
            with np.load(path, allow_pickle=False) as d:
                keys = set(d.files)
        except Exception:  # not an npz: the motion reader says what it is
            return "motion"
        if "v_template" in keys:
            return "body"
        if "format" in keys and "basis" in keys:
            return "fit"
        if {"points", "faces"} <= keys:
            return "bake"
    if suffix in (".pkl", ".pickle") and path.is_file():  # SMPL's own bodies are pickles of chumpy arrays
        from formats.body import read_pkl

        try:
            return "body" if "v_template" in read_pkl(path, str(path)) else "motion"
        except Exception:  # noqa: BLE001 - no body's pickle: the motion reader says what it is
            return "motion"
    return "motion"


def motion_info(path: str, person: str | None = None, take: str | None = None,
                source_fps: float | None = None, body=None) -> dict:
    """A motion file as `garment bake` reads it (with --person, --take, --source-fps; --motion-up left out): its
    frames, rate,
    joints, betas, the world axis read as up, the root's path, where the body jumps between two frames on `body`
    (`core.motion.motion_cuts`; the embedded body where None), the tracked people or animations it holds
    (frames of each) and the part read, and what reading it said."""
    from core.body import default_body
    from core.motion import motion_cuts
    from formats.motion import load_motion, motion_takes, tracked_people

    with collected_notes() as notes:
        motion = load_motion(path, fps=source_fps, world_checks=False, person=person, take=take)
        up = resolved_up(motion, path, None)
    takes = {}
    for name in motion_takes(path):
        with collected_notes():
            takes[name] = load_motion(path, fps=source_fps, world_checks=False, take=name).n_frames
    speed = np.linalg.norm(np.diff(motion.trans.astype(np.float64), axis=0), axis=1) * motion.fps
    # posed as `bake` poses it: on the embedded body at its mean shape (a motion's betas are another model's), on
    # another at the motion's betas fitted to it (warned of by bake; a count the body lacks was warned of here, twice)
    body = body or default_body()
    shaped = replace(motion, betas=None if body is default_body() or motion.betas is None else
                     body.fit_betas(motion.betas, warn=False))
    return {"path": str(path), "kind": "motion", "frames": motion.n_frames, "fps": motion.fps,
            "seconds": round(motion.duration_s, 3), "joints": int(motion.poses.shape[1]),
            "betas": None if motion.betas is None else int(motion.betas.size), "gender": motion.gender, "up": up,
            "person": motion.person, "people": tracked_people(path), "take": motion.take, "takes": takes,
            "root_travel_m": round(float(speed.sum() / motion.fps), 3),
            "root_speed_m_s_p99": round(float(np.percentile(speed, 99)), 3) if speed.size else 0.0,
            "jumps": [{"frame": k, "what": what} for k, what in motion_cuts(shaped, body)],
            "notes": notes}


def _parts(word: str, chosen, parts: dict, option: str) -> str:
    listed = ", ".join(f"'{k}' {counted(n, 'frame')}" for k, n in list(parts.items())[:6])
    listed += ", ..." if len(parts) > 6 else ""
    return f"; {word} '{chosen}' of {len(parts)} ({listed}: {option})"


def _text(record: dict, body_name: str) -> str:
    """One report line (and its notes) of a record of `garment_info` or `motion_info`."""
    if "error" in record:
        return f"{record['path']}: error: {record['error']}"
    if record["kind"] == "bake":
        made = f", baked with {record['method']}" if record["method"] else ""
        inputs = record["inputs"] or {}
        of = f" of '{Path(inputs['garment']).name}' on '{Path(inputs['motion']).name}'" if {"garment", "motion"} <= \
            set(inputs) else ""
        rate = f" at {record['fps']:g} fps" if record["fps"] else ""
        line = (f"{record['path']}: a baked garment sequence{of}{made}, {counted(record['frames'], 'frame')}{rate} "
                f"from frame {record['first_frame']}, {record['vertices']:,} vertices (garment metrics and render read "
                "it; not a garment to bake)")
    elif record["kind"] == "body":
        line = (f"{record['path']}: body ({record['layout']}), {record['vertices']:,} vertices, {record['joints']} "
                f"joints, {record['betas']} betas, sha256 {record['sha256'][:12]} (give it to bake with --body)")
    elif record["kind"] == "fit":
        line = (f"{record['path']}: psd fit of a {record['vertices']:,}-vertex garment on body '{record['body']}', "
                f"{record['shapes']} shape{'' if record['shapes'] == 1 else 's'} (give it to bake with --method psd "
                "--fit)")
    elif record["kind"] == "model":
        trained = ", ".join(filter(None, [
            f"{record['steps']} steps" if record["steps"] is not None else "",
            f"phase {record['phase']}" if record["phase"] is not None else "",
            f"on body '{record['body']}' (sha256 {record['body_sha256'][:12]})" if record["body"] else "",
            f"garments {', '.join(record['garments'])}" if record["garments"] else "",
            f"validation E_verts {float(record['val_verts_mm']):.1f} mm" if record["val_verts_mm"] is not None
            else ""]))
        line = (f"{record['path']}: " + ("training state of a garment model (`garment train --resume` continues it)"
                                         if record["resume_state"] else
                                         "garment model (give it to bake with --method model --model)")
                + f", {record['levels']} pooling level{'' if record['levels'] == 1 else 's'}, {record['joints']} joints"
                + (f"; {trained}" if trained else ""))
    elif record["kind"] == "garment":
        x, y, z = record["extent_m"]
        verdict = f"refused: {record['refused']}" if record["refused"] else "bakes as it is"
        line = (f"{record['path']}: garment, {record['vertices']:,} vertices, {record['triangles']:,} triangles, "
                f"{x:.2f} x {y:.2f} x {z:.2f} m; on {body_name}: {record['median_distance_mm']:.0f} mm from it "
                f"(median), {record['inside_percent']:.1f} % inside: {verdict}")
    else:
        line = (f"{record['path']}: motion, {counted(record['frames'], 'frame')} at {record['fps']:g} fps "
                f"({record['seconds']:.1f} s), {record['joints']} joints, read {record['up']}-up")
        if record["betas"]:
            line += f", {record['betas']} betas"
        if record["people"]:
            line += _parts("person", record["person"], record["people"], "--person")
        if record["takes"]:
            line += _parts("take", record["take"], record["takes"], "--take")
        line += (f"; the root travels {record['root_travel_m']:.1f} m, up to {record['root_speed_m_s_p99']:.1f} "
                 f"m/s")
        if record["jumps"]:
            first, more = record["jumps"][0], len(record["jumps"]) - 1
            line += (f"; the body jumps at frame {first['frame']}{f' (and at {more} more)' if more else ''}: "
                     f"{first['what']}")
    own = (f"motion '{record['path']}': ", f"garment mesh '{record['path']}': ")
    notes = [next((note[len(o):] for o in own if note.startswith(o)), note) for note in record["notes"]]
    return "\n".join([line, *(f"  - {note}" for note in notes)])


@click.command(name="info")
@click.argument("paths", nargs=-1, required=True, metavar="PATH...")
@body_option
@person_option
@take_option
@source_fps_option
@click.option("--format", "fmt", type=click.Choice(["text", "json"]), default="text", show_default=True,
              help="text: a line per file (and what reading it said); json: a list of records.")
@input_errors_as_click
def info(paths, body_path, person, take, source_fps, fmt):
    """Tell what `garment bake` reads in each PATH, before any bake: a garment (OBJ or USD) and how it rests on
    the body, or a motion (any format bake reads, a USD of a skeleton too; a directory: its motion files) and the
    tracked people or animations (takes) it holds. A bake's output, a body, a psd fit and a model checkpoint are
    told for what they are.

    Exits with 1 where a file cannot be read or its garment would be refused (each told), else 0.
    """
    body = load_body_option(body_path)
    body_name = f"the body '{body_path}'" if body_path else "the embedded default body"
    records = []
    readers = {"bake": bake_info, "body": body_info, "fit": fit_info, "model": model_info,
               "garment": lambda p: garment_info(str(p), body)}
    for arg in paths:
        kind = _kind_of(Path(arg))
        if kind == "bakes":
            from formats.sequence import bake_batch

            kind, found = "bake", list(bake_batch(Path(arg)).values())
        else:
            found = [Path(arg)] if kind != "motion" else motion_files([arg], hint="PATH")
        for path in found:
            try:
                records.append(readers[kind](path) if kind not in ("motion", "model or motion")
                               else motion_info(path, person, take, source_fps, body))
            except InputError as exc:
                said = str(exc) if kind != "model or motion" else (
                    f"'{path}': expected a model checkpoint of `garment train` or a motion of PyTorch's format, "
                    f"could read it as neither ({exc})")
                records.append({"path": str(path), "error": said})
    if fmt == "json":
        click.echo(json.dumps(records, indent=2))
    else:
        for record in records:
            click.echo(_text(record, body_name))
    if any("error" in r or r.get("refused") for r in records):
        raise click.exceptions.Exit(1)
