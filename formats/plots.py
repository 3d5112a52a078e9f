"""Pictures of a metrics report (`garment metrics --plots`): per-frame curves, error histograms, a report page.

`plot_per_frame` draws one panel per metric of a `core.metrics.MetricsResult`
against the frame number; `plot_error_histograms` draws the distribution of
per-vertex distance (mm), per-vertex normal angle (deg) and per-edge relative
length error (%) pooled over all frames; `write_plot_report` writes both PNGs
and a Markdown and an HTML page that show the tables and the pictures together
(plus any extra images, e.g. an error heatmap render). matplotlib runs on its
Agg backend: no display needed.
"""

from __future__ import annotations

import html
import logging
import os
from pathlib import Path

import numpy as np

from core.metrics import METRICS, MetricsResult

log = logging.getLogger(__name__)

PER_FRAME_PNG = "metrics_per_frame.png"
HISTOGRAMS_PNG = "metrics_histograms.png"
REPORT_MD = "metrics_report.md"
REPORT_HTML = "metrics_report.html"


def _pyplot():
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def _names(result: MetricsResult) -> list[str]:
    return [n for n in METRICS if n in result.per_frame] + [n for n in result.per_frame if n not in METRICS]


def _title(name: str) -> str:
    label, unit = METRICS.get(name, (name, ""))
    return f"{label} ({unit})" if unit else label


def plot_per_frame(result: MetricsResult, path: str | os.PathLike, dpi: int = 100) -> Path:
    """One panel per metric: value (in its unit) against frame, with the mean as a dashed line. Writes a PNG."""
    plt = _pyplot()
    names = _names(result)
    cols = 2 if len(names) > 1 else 1
    rows = (len(names) + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(5.2 * cols, 2.4 * rows), squeeze=False)
    for ax, name in zip(axes.ravel(), names):
        y = np.asarray(result.per_frame[name], dtype=np.float64)
        ax.plot(np.arange(y.size), y, color="#c0503f", lw=1.5, marker="o" if y.size <= 30 else None, ms=3)
        ax.axhline(float(np.mean(y)), color="0.4", ls="--", lw=1, label=f"mean {np.mean(y):.4g}")
        ax.set_title(_title(name), fontsize=10)
        ax.set_xlabel("frame")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="best")
    for ax in axes.ravel()[len(names):]:
        ax.axis("off")
    return _save_figure(plt, fig, path, dpi)


def _save_figure(plt, fig, path: str | os.PathLike, dpi: int) -> Path:
    """Lay out, write and close a figure; returns the path."""
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return path


def per_element_errors(pred: np.ndarray, gt: np.ndarray, faces: np.ndarray) -> dict[str, np.ndarray]:
    """Errors per vertex / edge over all frames, for the histograms.

    pred, gt: (T, V, 3) float, metres; faces: (F, 3) int.
    Returns {"vertex distance (mm)": (T*V,), "vertex normal angle (deg)": (T*V,),
    "edge length error (%)": (T*E,)} float64 (edges of zero ground-truth length left out).
    """
    from core.metrics import edge_relative_error, vertex_distance_mm, vertex_normal_angle_deg

    rel, ok = edge_relative_error(pred, gt, faces)
    return {"vertex distance (mm)": vertex_distance_mm(pred, gt).ravel(),
            "vertex normal angle (deg)": vertex_normal_angle_deg(pred, gt, faces).ravel(),
            "edge length error (%)": 100.0 * rel[ok]}


def plot_error_histograms(errors: dict[str, np.ndarray], path: str | os.PathLike, bins: int = 50,
                          dpi: int = 100) -> Path:
    """One histogram per entry of `errors` (name -> values), with the mean and 95th percentile marked."""
    plt = _pyplot()
    fig, axes = plt.subplots(1, len(errors), figsize=(4.2 * len(errors), 3.0), squeeze=False)
    for ax, (name, values) in zip(axes.ravel(), errors.items()):
        v = np.asarray(values, dtype=np.float64)
        v = v[np.isfinite(v)]
        if v.size:
            ax.hist(v, bins=bins, color="#4a7fb0", edgecolor="white", linewidth=0.3)
            for q, style in ((np.mean(v), "--"), (np.percentile(v, 95), ":")):
                ax.axvline(q, color="0.2", ls=style, lw=1)
            ax.set_title(f"{name}\nmean {np.mean(v):.3g}, p95 {np.percentile(v, 95):.3g}", fontsize=9)
        else:
            ax.set_title(f"{name}\n(no values)", fontsize=9)
        ax.set_xlabel(name)
        ax.set_ylabel("count")
        ax.grid(alpha=0.3)
    return _save_figure(plt, fig, path, dpi)


def _html_table(headers: list[str], rows: list[list]) -> str:
    def cell(c):
        return f"{c:.4g}" if isinstance(c, (float, np.floating)) else html.escape(str(c))

    head = "".join(f"<th>{html.escape(h)}</th>" for h in headers)
    body = "".join("<tr>" + "".join(f"<td>{cell(c)}</td>" for c in r) + "</tr>" for r in rows)
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def write_plot_report(result: MetricsResult, out_dir: str | os.PathLike, pred: np.ndarray | None = None,
                      gt: np.ndarray | None = None, faces: np.ndarray | None = None,
                      images: list[tuple[str, Path]] | None = None) -> list[Path]:
    """Write the per-frame PNG, the histogram PNG (when pred, gt, faces are given) and a report page.

    result: the metrics; pred, gt: (T, V, 3) metres and faces (F, 3) for the histograms;
    images: extra (caption, path) pictures already inside out_dir (e.g. a heatmap render).
    Writes metrics_per_frame.png, metrics_histograms.png, metrics_report.md and
    metrics_report.html into out_dir (pictures linked by relative path). Returns the paths.
    """
    from formats.report import _atomic_write_text, markdown_table

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    pictures: list[tuple[str, Path]] = [("Per-frame metrics", plot_per_frame(result, out_dir / PER_FRAME_PNG))]
    if pred is not None and gt is not None and faces is not None:
        pictures.append(("Error distributions over all frames",
                         plot_error_histograms(per_element_errors(pred, gt, faces), out_dir / HISTOGRAMS_PNG)))
    pictures += list(images or [])
    names = _names(result)
    headers = [_title(n) for n in names]
    overall = [[float(result.overall[n]) for n in names]]
    stats = [[s] + [float(f(result.per_frame[n])) for n in names]
             for s, f in (("min", np.min), ("mean", np.mean), ("max", np.max))]
    meta = {**result.metadata, "frames": result.n_frames, "vertices": result.n_vertices}

    md = ["# Garment metrics report\n", "\n".join(f"- {k}: `{v}`" for k, v in meta.items()) + "\n",
          "## Overall (mean over frames)\n", markdown_table(headers, overall),
          f"## Over {result.n_frames} frames\n", markdown_table(["statistic"] + headers, stats)]
    for caption, p in pictures:
        rel = os.path.relpath(p, out_dir)
        md.append(f"## {caption}\n\n![{caption}]({rel})\n")
    md_path = out_dir / REPORT_MD
    _atomic_write_text(md_path, "\n".join(md))

    parts = ["<!DOCTYPE html><html><head><meta charset='utf-8'><title>Garment metrics report</title>",
             "<style>body{font-family:sans-serif;max-width:1100px;margin:2em auto;}"
             "table{border-collapse:collapse;margin:1em 0;}td,th{border:1px solid #bbb;padding:3px 8px;"
             "text-align:right;}th{background:#eee;}img{max-width:100%;}</style></head><body>",
             "<h1>Garment metrics report</h1><ul>"
             + "".join(f"<li>{html.escape(str(k))}: <code>{html.escape(str(v))}</code></li>" for k, v in meta.items())
             + "</ul>", "<h2>Overall (mean over frames)</h2>", _html_table(headers, overall),
             f"<h2>Over {result.n_frames} frames</h2>", _html_table(["statistic"] + headers, stats)]
    for caption, p in pictures:
        rel = html.escape(os.path.relpath(p, out_dir))
        parts.append(f"<h2>{html.escape(caption)}</h2><img src='{rel}' alt='{html.escape(caption)}'>")
    parts.append("</body></html>\n")
    html_path = out_dir / REPORT_HTML
    _atomic_write_text(html_path, "\n".join(parts))
    return [p for _, p in pictures] + [md_path, html_path]


def render_worst_frame_heatmap(pred_seq, gt_seq, result: MetricsResult, path: str | os.PathLike,
                               size: tuple[int, int] = (960, 540)) -> Path | None:
    """A heatmap render (per-vertex error, mm) of the frame with the largest E_verts, or None if no GL.

    pred_seq, gt_seq: `formats.sequence.Sequence` of the same mesh. Rendering problems are
    logged and give None: the plots and report do not depend on a working OpenGL.
    """
    from formats.render import RenderError, RenderOptions, render_image, scene_from_sequence, write_png

    worst = int(np.argmax(result.per_frame["e_verts"])) if "e_verts" in result.per_frame else 0
    try:
        scene = scene_from_sequence(pred_seq, color="error", gt=gt_seq, frames=[worst])
        img = render_image(scene, 0, "front", RenderOptions(width=size[0], height=size[1], framing="fixed"))
    except RenderError as exc:
        log.warning("no heatmap render in the report: %s", exc)
        return None
    return write_png(path, img)


#: Candidate places of a point's number, in points from the point (lower-left corner of the text), nearest first.
#: The first four touch the point (above or below, right or left); the others step away 9 points at a time.
LABEL_OFFSETS = [(3, 3), (3, -10), (-4, 3), (-4, -10)] + [
    (dx, dy) for r in (1, 2, 3, 4) for dy in (9 * r + 3, -9 * r - 10) for dx in (3, -4)]


def label_offsets(points: np.ndarray, n_chars: list[int], char_w: float = 4.5, height: float = 7.0,
                  crowd: float = 12.0):
    """Where to write each point's label so no two labels overlap: ((dx, dy) in points, moved_far) per point.

    points: (N, 2) point positions in points. Labels are boxes n_chars * char_w wide and `height` tall with
    their lower-left corner at point + offset (offsets left of the point are shifted by the label's width).
    Greedy, the point with most neighbours within `crowd` points first; each takes the nearest offset of
    LABEL_OFFSETS whose box overlaps no label placed so far, or the last one when all do. moved_far:
    beyond the first four places (draw a leader line).
    """
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    if len(pts) == 0:
        return []
    d = np.linalg.norm(pts[:, None] - pts[None], axis=-1)
    order = np.argsort(-(d < crowd).sum(1), kind="stable")
    boxes, out = [], [None] * len(pts)
    for i in order:
        w = n_chars[i] * char_w
        for k, (dx, dy) in enumerate(LABEL_OFFSETS):
            dx = dx - w if dx < 0 else dx
            x0, y0 = pts[i, 0] + dx, pts[i, 1] + dy
            if all(x0 + w <= bx0 or bx1 <= x0 or y0 + height <= by0 or by1 <= y0 for bx0, by0, bx1, by1 in boxes):
                break
        boxes.append((x0, y0, x0 + w, y0 + height))
        out[i] = ((dx, dy), k >= 4)
    return out


def plot_pareto(names: list[str], seconds_per_frame: list[float], errors_mm: list[float], front: list[bool],
                path: str | os.PathLike, title: str = "", dpi: int = 100,
                floor: tuple[float, str] | None = None) -> Path:
    """Error (mm, linear) against seconds per frame (log scale), one numbered point per configuration with its
    name in a key beside the axes (names written at the points overlap where configurations cluster), the
    Pareto front joined by a line. The reference (error 0) sits on the x axis. floor: (mm, label) of a dashed
    horizontal line (the reference's own spread). Writes a PNG."""
    plt = _pyplot()
    fig, (ax, key_ax) = plt.subplots(1, 2, figsize=(10.5, max(4.8, 0.16 * len(names) + 1.2)),
                                     gridspec_kw={"width_ratios": [2.2, 1]})
    x = np.maximum(np.asarray(seconds_per_frame, dtype=np.float64), 1e-7)
    y = np.asarray(errors_mm, dtype=np.float64)
    on = np.asarray(front, dtype=bool)
    ax.scatter(x[~on], y[~on], color="0.55", s=28, label="dominated", zorder=3)
    ax.scatter(x[on], y[on], color="#c0503f", s=36, label="Pareto front", zorder=4)
    order = np.argsort(x[on])
    ax.plot(x[on][order], y[on][order], color="#c0503f", lw=1, zorder=2)
    if floor is not None:
        ax.axhline(floor[0], color="#3f6fc0", ls="--", lw=1, label=f"{floor[1]}: {floor[0]:.1f} mm", zorder=1)
    ax.set_xscale("log")
    ax.autoscale_view()
    points_px = ax.transData.transform(np.c_[x, y]) * 72.0 / fig.dpi  # display pixels -> points
    for i, (off, far) in enumerate(label_offsets(points_px, [len(str(i + 1)) for i in range(len(x))])):
        ax.annotate(str(i + 1), (x[i], y[i]), textcoords="offset points", xytext=off, fontsize=7,
                    arrowprops={"arrowstyle": "-", "lw": 0.4, "color": "0.5"} if far else None)
    key = "\n".join(f"{i + 1:>2}  {n}" + ("  *" if f else "") for i, (n, f) in enumerate(zip(names, on)))
    key_ax.axis("off")
    key_ax.text(0.0, 0.5, key + "\n\n* on the Pareto front", fontsize=7, family="monospace", va="center",
                transform=key_ax.transAxes)
    ax.set_xlabel("seconds per frame (log scale)")
    ax.set_ylabel("E_verts against the reference (mm)")
    ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8, loc="lower left")
    return _save_figure(plt, fig, path, dpi)
