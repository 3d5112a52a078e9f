"""One bake item: a garment, a body and a prepared motion through a Deformer, plus its statistics.

Pure computation (no files): `bake_item` returns the garment and body sequences
and the summary that `garment bake` writes next to them. Batch runners (the
CLI now, a cluster later) call it once per (garment, motion, body) item.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass

import numpy as np

from core.body import Body
from core.deform import Deformer
from core.garment import Garment
from core.geometry import penetration_per_frame
from core.motion import Motion, motion_cuts, poses_for_body, written

log = logging.getLogger(__name__)

#: Depth below the body surface at which a garment vertex counts as penetrating.
PENETRATION_DEPTH_M = 0.002
#: Beyond the strain limit's tolerance (1 mm) an edge may stay longer than the limit where its passes run out; a
#: bake warns where one stays longer by more than this (metres): an extreme pose stretching the cloth further than
#: the limit undoes (the trousers' crotch on the side splits: 5.6 mm left in 38 of 61 frames; the dress's 120-degree
#: kick 2.5 mm in 4 of 46). The audits' bakes of the example and library walks, runs, jumps, kicks and crouches
#: leave none over.
STRAIN_LEFT_WARN_M = 0.002
#: Penetration statistics are computed on at most this many frames (evenly spaced).
MAX_CHECKED_FRAMES = 60
#: ... and at most this many vertex-frames, but at least MIN_CHECKED_FRAMES frames: each garment vertex of a checked
#: frame is a closest-point query on the body (60 frames of a 53k-vertex garment took 23 s, the LBS bake 0.4 s).
MAX_CHECKED_VERTEX_FRAMES = 1_000_000
MIN_CHECKED_FRAMES = 4


@dataclass(frozen=True, eq=False)
class BakeResult:
    """garment_points: (T, V, 3) float32 metres, Z-up world; body_points: (T, Vb, 3) float32 or None."""

    garment_points: np.ndarray
    body_points: np.ndarray | None
    summary: dict


def checked_frames(n_frames: int, n_vertices: int, max_frames: int = MAX_CHECKED_FRAMES) -> np.ndarray:
    """The frames `penetration_stats` checks of a sequence of `n_frames` frames of `n_vertices` vertices: at most
    `max_frames` evenly spaced, fewer for a garment of more than MAX_CHECKED_VERTEX_FRAMES / max_frames vertices
    (MIN_CHECKED_FRAMES at least)."""
    max_frames = min(max_frames, max(MIN_CHECKED_FRAMES, MAX_CHECKED_VERTEX_FRAMES // max(n_vertices, 1)))
    return np.unique(np.linspace(0, n_frames - 1, min(n_frames, max_frames)).round().astype(int))


def penetration_stats(garment_points: np.ndarray, body_points: np.ndarray, body_faces: np.ndarray,
                      max_frames: int = MAX_CHECKED_FRAMES, depth: float = PENETRATION_DEPTH_M) -> dict:
    """Share of garment vertices more than `depth` inside the body on the `checked_frames`.

    garment_points: (T, V, 3); body_points: (T, Vb, 3), or the body at the checked frames only (fewer rows: a bake
    that writes no body poses no more); body_faces: (Fb, 3).
    Returns a JSON-ready dict (percentages, the frames checked).
    """
    frames = checked_frames(*garment_points.shape[:2], max_frames)
    at = frames if len(body_points) == len(garment_points) else np.arange(len(frames))
    share = penetration_per_frame(garment_points[frames], body_points[at], body_faces, depth) * 100.0
    return {
        "depth_mm": depth * 1e3,
        "frames_checked": frames.tolist(),
        "percent_per_checked_frame": [round(float(s), 4) for s in share],
        "mean_percent": float(share.mean()),
        "max_percent": float(share.max()),
        "worst_frame": int(frames[int(np.argmax(share))]),
    }


def bake_item(garment: Garment, body: Body, motion: Motion, deformer: Deformer, with_body: bool = True,
              check_penetration: bool = True) -> BakeResult:
    """Deform `garment` on `body` over `motion` and measure it.

    Returns the garment sequence (T, V, 3), the posed body (T, Vb, 3) when `with_body` (else None; both without
    the motion's lead and tail frames, `Motion.n_lead` and `n_tail`, which are deformed and dropped), and a
    summary dict: method, frames, fps, seconds per frame of the deformation, penetration statistics, the deformer's
    report.
    """
    shown = written(motion)
    cuts = motion_cuts(shown, body)
    if cuts:
        frame, what = cuts[0]
        more = f" (and at {len(cuts) - 1} more frames)" if len(cuts) > 1 else ""
        log.warning(f"motion '{motion.name}': the body jumps at written frame {frame}{more}: {what}, a teleport or "
                    "a cut or flip in the capture? The garment follows it in one frame; bake the parts apart with "
                    "--frames (`garment info` names the jump's source frame)")
    t0 = time.perf_counter()
    points = deformer.deform(garment, body, motion)
    t_deform = time.perf_counter() - t0
    points = points[motion.n_lead:motion.n_lead + shown.n_frames]  # a pre-roll and a tail are deformed, not kept
    body_points = None
    if with_body:
        body_points, _ = body.pose(poses_for_body(shown, body.n_joints), shown.trans, shown.betas)
    elif check_penetration:  # the body of the frames checked only: 160 kB a frame of a long motion otherwise
        at = checked_frames(len(points), points.shape[1])
        body_points, _ = body.pose(poses_for_body(shown, body.n_joints)[at], shown.trans[at], shown.betas)
    summary = {
        "method": deformer.name,
        "frames": int(shown.n_frames),
        "fps": float(motion.fps),
        "settle_frames": int(motion.n_settle),
        "preroll_frames": int(motion.n_lead),
        "tail_frames": int(motion.n_tail),
        "garment": {"name": garment.name, "vertices": garment.n_vertices, "faces": garment.n_faces,
                    "sha256": garment.content_hash(),
                    # The outputs are written in the file's own mesh where it differs from the one deformed.
                    "written_as_file": None if garment.source is None else {
                        "vertices": garment.source.n_vertices, "polygons": int(len(garment.source.polygons))}},
        "body": {"name": body.name, "vertices": body.n_vertices, "joints": body.n_joints,
                 "betas": body.fit_betas(motion.betas).round(6).tolist()},
        "seconds_deform": t_deform,
        "seconds_per_frame": t_deform / motion.n_frames,  # per frame deformed, the pre-roll's included
        "deformer": deformer.report,
        "scene": deformer.scene,
    }
    _warn_strain_left(deformer.report, deformer.name, motion.n_frames)
    if not np.all(np.isfinite(points)):
        bad = int(np.argmax(~np.isfinite(points).reshape(points.shape[0], -1).all(axis=1)))
        raise FloatingPointError(f"method '{deformer.name}' produced NaN/Inf at frame {bad}")
    if check_penetration:
        t1 = time.perf_counter()
        summary["penetration"] = penetration_stats(points, body_points, body.faces)
        summary["seconds_penetration_check"] = time.perf_counter() - t1
    return BakeResult(points, body_points if with_body else None, summary)


def _warn_strain_left(report: dict, method: str, n_frames: int) -> None:
    """Warn where the strain limit of a deformer's `report` (over `n_frames` frames deformed) left an edge longer
    than it by more than STRAIN_LEFT_WARN_M."""
    r = report.get("strain_limit")
    if not r or not r.get("frames_still_over") or r["excess_left_max_mm"] <= STRAIN_LEFT_WARN_M * 1e3:
        return
    log.warning(f"method '{method}': the strain limit ({r['limit']:g}x an edge's rest length) left edges longer than "
                f"it in {r['frames_still_over']} of {n_frames} frames deformed (up to {r['edges_still_over_per_frame_max']} a frame, "
                f"{r['excess_left_max_mm']:.1f} mm beyond it) after its {r['passes_max']} passes: the pose stretches "
                "the cloth further than the limit undoes")
