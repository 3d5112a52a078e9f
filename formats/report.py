"""Metric reports: a `core.metrics.MetricsResult` as JSON, CSV and Markdown files.

JSON carries everything (metadata such as the input paths, units, overall
values and per-frame lists) and reads back with `read_json_report`; CSV is one
row per frame under a header and nothing else; Markdown is for people: the
overall values with units in the layout of the paper's tables, then per-frame
rows for short sequences or min/mean/max for long ones. `markdown_table`,
`write_csv_rows` and `write_json` are generic and serve other tables too
(benchmarks). Every file is written to a temporary name beside it and renamed
on success, so nothing half-written is left.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
from pathlib import Path
from typing import Any, Iterable, Sequence

import numpy as np

from core.errors import InputError
from core.metrics import METRICS, MetricsResult
from formats.atomic import atomic_files

REPORT_FORMATS = ("json", "csv", "md")
#: File names written into a report directory.
REPORT_NAMES = {"json": "metrics.json", "csv": "metrics.csv", "md": "metrics.md"}
#: Sequences with at most this many frames get a per-frame Markdown table.
MAX_FRAMES_TABLE = 30


# ---------------------------------------------------------------------------
# Generic helpers
# ---------------------------------------------------------------------------

def format_value(value: Any, digits: int = 4) -> str:
    """A table cell: floats with `digits` significant decimals (fixed notation unless tiny/huge)."""
    if isinstance(value, (float, np.floating)):
        v = float(value)
        if not math.isfinite(v):
            return str(v)
        if v != 0 and (abs(v) < 10 ** -(digits - 1) or abs(v) >= 1e7):
            return f"{v:.{digits - 1}e}"
        return f"{v:.{digits}f}"
    if isinstance(value, np.integer):
        return str(int(value))
    return str(value)


def markdown_table(headers: Sequence[str], rows: Iterable[Sequence[Any]], digits: int = 4) -> str:
    """A GitHub-flavoured Markdown table; numbers right-aligned, text left-aligned.

    headers: column titles. rows: sequences of cells (str, int or float), each
    as long as `headers`. Pipes in cells are escaped. Returns the table text
    ending in a newline.
    """
    headers = [str(h) for h in headers]
    rows = [list(r) for r in rows]
    for i, r in enumerate(rows):
        if len(r) != len(headers):
            raise ValueError(f"markdown_table: row {i} has {len(r)} cells, expected {len(headers)}")
    numeric = [all(isinstance(r[c], (int, float, np.integer, np.floating)) and not isinstance(r[c], bool)
                   for r in rows) and bool(rows) for c in range(len(headers))]
    cells = [[format_value(c, digits).replace("|", "\\|") for c in r] for r in rows]
    head = [h.replace("|", "\\|") for h in headers]
    width = [max([len(head[c])] + [len(r[c]) for r in cells] + [3]) for c in range(len(headers))]

    def line(values: Sequence[str]) -> str:
        out = [v.rjust(width[c]) if numeric[c] else v.ljust(width[c]) for c, v in enumerate(values)]
        return "| " + " | ".join(out) + " |"

    rule = "| " + " | ".join(("-" * (width[c] - 1) + ":") if numeric[c] else "-" * width[c]
                              for c in range(len(headers))) + " |"
    return "\n".join([line(head), rule] + [line(r) for r in cells]) + "\n"


def _atomic_write_text(path: Path, text: str) -> None:
    _atomic_write_texts({path: text})


def _atomic_write_texts(texts: dict) -> None:
    """Each {path: text} written as UTF-8, all replacing their files together (`formats.atomic.atomic_files`)."""
    with atomic_files(list(texts)) as tmps:
        for tmp, text in zip(tmps, texts.values()):
            tmp.write_text(text, encoding="utf-8", newline="")


def write_markdown(path: str | os.PathLike, lines: Sequence[str], show: bool = False) -> Path:
    """A benchmark's Markdown report: `lines` written to `path` (its folder made, atomically), printed first
    where `show`, then where it went. Returns the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    text = "\n".join(lines) + "\n"
    _atomic_write_text(path, text)
    if show:
        print(text, end="")
    print(f"wrote {path}")
    return path


def write_json(path: str | os.PathLike, obj: Any) -> Path:
    """Write `obj` (JSON-serialisable; numpy scalars/arrays allowed) as indented JSON; returns the path."""
    _atomic_write_text(Path(path), _json_text(obj))
    return Path(path)


def _json_text(obj: Any) -> str:
    def default(o):
        if isinstance(o, np.ndarray):
            return o.tolist()
        if isinstance(o, (np.integer, np.floating, np.bool_)):
            return o.item()
        if isinstance(o, os.PathLike):
            return os.fspath(o)
        raise TypeError(f"cannot write {type(o).__name__} as JSON")

    return json.dumps(obj, indent=2, default=default, allow_nan=False) + "\n"


def write_csv_rows(path: str | os.PathLike, headers: Sequence[str], rows: Iterable[Sequence[Any]]) -> Path:
    """Write a CSV file: one header line, then one line per row (floats at full precision)."""
    _atomic_write_text(Path(path), _csv_text(headers, rows))
    return Path(path)


def _csv_text(headers: Sequence[str], rows: Iterable[Sequence[Any]]) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(headers)
    for r in rows:
        w.writerow([repr(float(c)) if isinstance(c, (float, np.floating)) else c for c in r])
    return buf.getvalue()


# ---------------------------------------------------------------------------
# Metrics reports
# ---------------------------------------------------------------------------

def _names(result: MetricsResult) -> list[str]:
    """Metric names of `result` in report order (known ones first, then any others)."""
    known = [n for n in METRICS if n in result.per_frame]
    return known + [n for n in result.per_frame if n not in METRICS]


def _title(name: str) -> str:
    label, unit = METRICS.get(name, (name, ""))
    return f"{label} ({unit})" if unit else label


def result_to_dict(result: MetricsResult, metadata: dict | None = None) -> dict:
    """The JSON document of a report: metadata, sizes, units, overall values and per-frame lists."""
    names = _names(result)
    return {
        "metadata": {**result.metadata, **(metadata or {})},
        "n_frames": result.n_frames,
        "n_vertices": result.n_vertices,
        "n_faces": result.n_faces,
        "units": {n: METRICS.get(n, (n, ""))[1] for n in names},
        "overall": {n: float(result.overall[n]) for n in names},
        "per_frame": {n: [float(x) for x in np.asarray(result.per_frame[n])] for n in names},
    }


def read_json_report(path: str | os.PathLike) -> MetricsResult:
    """Read back a report written by `write_report` (format json)."""
    path = Path(path)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
        per_frame = {k: np.asarray(v, dtype=np.float64) for k, v in doc["per_frame"].items()}
        return MetricsResult(per_frame=per_frame, overall={k: float(v) for k, v in doc["overall"].items()},
                             n_frames=int(doc["n_frames"]), n_vertices=int(doc["n_vertices"]),
                             n_faces=int(doc.get("n_faces", 0)), metadata=dict(doc.get("metadata", {})))
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise InputError(f"metrics report '{path}': expected a JSON report written by garment, "
                         f"got an unreadable file ({type(exc).__name__}: {exc})") from None


#: The summary files of a batch comparison (`garment metrics PRED_DIR GT_DIR`), beside each bake's own reports.
BATCH_REPORT_NAMES = {"json": "metrics_batch.json", "csv": "metrics_batch.csv", "md": "metrics_batch.md"}
#: The last row of a batch table: every frame of every bake.
BATCH_ALL = "all (mean over every frame)"


def batch_rows(results: dict[str, MetricsResult]) -> tuple[list[str], list[str], list[list]]:
    """(metric names, column titles, rows): one row per bake (name, frames, overall values), then `BATCH_ALL`,
    the mean over every frame of every bake (each bake's overall weighted by its frames). Every result must
    have the same metrics (a metric some bakes lack is left out)."""
    names = [n for n in _names(next(iter(results.values()))) if all(n in r.overall for r in results.values())]
    rows = [[name, r.n_frames] + [r.overall[n] for n in names] for name, r in results.items()]
    frames = np.array([r.n_frames for r in results.values()], dtype=np.float64)
    rows.append([BATCH_ALL, int(frames.sum())]
                + [float(np.average([r.overall[n] for r in results.values()], weights=frames)) for n in names])
    return names, ["bake", "frames"] + [_title(n) for n in names], rows


def write_batch_report(results: dict[str, MetricsResult], directory: str | os.PathLike,
                       formats: Sequence[str] = REPORT_FORMATS, metadata: dict | None = None,
                       failed: Sequence[str] = ()) -> list[Path]:
    """Write the batch table (`batch_rows`) into `directory` as BATCH_REPORT_NAMES, all files together (as
    `write_report`); the bakes `failed` (not compared) are rows of their own in the CSV and Markdown tables, after
    the mean over the others; returns the paths."""
    names, titles, rows = batch_rows(results)
    table = rows + [[name, "not compared"] + [""] * len(names) for name in failed]
    texts = {}
    for f in dict.fromkeys(formats):
        path = Path(directory) / BATCH_REPORT_NAMES[f]
        if f == "json":
            texts[path] = _json_text({
                "metadata": dict(metadata or {}), "units": {n: METRICS.get(n, (n, ""))[1] for n in names},
                "bakes": {row[0]: {"frames": row[1], **dict(zip(names, map(float, row[2:])))} for row in rows}})
        elif f == "csv":
            texts[path] = _csv_text(["bake", "frames"] + names, table)
        else:
            texts[path] = ("# Garment metrics, bake by bake\n\n"
                           + "".join(f"- {k}: `{v}`\n" for k, v in (metadata or {}).items())
                           + "\n" + markdown_table(titles, table))
    _atomic_write_texts(texts)
    return list(texts)


def overall_markdown(result: MetricsResult) -> str:
    """One-row Markdown table of the overall values, columns titled with units (paper Table 1 layout)."""
    names = _names(result)
    return markdown_table([_title(n) for n in names], [[result.overall[n] for n in names]])


def result_to_markdown(result: MetricsResult, metadata: dict | None = None,
                       max_frames_table: int = MAX_FRAMES_TABLE) -> str:
    """The Markdown report: metadata, overall table, then per-frame rows or a min/mean/max summary."""
    names = _names(result)
    meta = {**result.metadata, **(metadata or {})}
    parts = ["# Garment metrics\n"]
    info = [f"- {k}: `{v}`" for k, v in meta.items()]
    info += [f"- frames: {result.n_frames}", f"- vertices: {result.n_vertices}"]
    if result.n_faces:
        info.append(f"- faces: {result.n_faces}")
    parts.append("\n".join(info) + "\n")
    parts.append("## Overall (mean over frames)\n")
    parts.append(overall_markdown(result))
    headers = [_title(n) for n in names]
    if result.n_frames <= max_frames_table:
        parts.append("## Per frame\n")
        rows = [[t] + [float(result.per_frame[n][t]) for n in names] for t in range(result.n_frames)]
        parts.append(markdown_table(["frame"] + headers, rows))
    else:
        parts.append(f"## Over {result.n_frames} frames\n")
        rows = [[stat] + [float(fn(result.per_frame[n])) for n in names]
                for stat, fn in (("min", np.min), ("mean", np.mean), ("max", np.max))]
        parts.append(markdown_table(["statistic"] + headers, rows))
    return "\n".join(parts)


def report_paths(path_or_dir: str | os.PathLike, formats: Sequence[str]) -> dict[str, Path]:
    """Where `write_report` puts each format.

    A directory (existing, or a path without a suffix) gets metrics.json/.csv/.md;
    a path with a suffix is a stem: `out/run1.json` -> out/run1.json, out/run1.csv, ...
    """
    p = Path(path_or_dir)
    if p.is_dir() or not p.suffix:
        return {f: p / REPORT_NAMES[f] for f in formats}
    return {f: p.with_suffix("." + f) for f in formats}


def write_report(result: MetricsResult, path_or_dir: str | os.PathLike,
                 formats: Sequence[str] = REPORT_FORMATS, metadata: dict | None = None) -> list[Path]:
    """Write `result` in each of `formats` ("json", "csv", "md"); returns the paths written.

    metadata: extra key -> value (e.g. pred/gt paths) for JSON and Markdown.
    See `report_paths` for where the files go. The files are written atomically, together: all or none.
    """
    formats = list(dict.fromkeys(formats))
    for f in formats:
        if f not in REPORT_FORMATS:
            raise InputError(f"report format: expected one of {', '.join(REPORT_FORMATS)}, got '{f}'")
    paths = report_paths(path_or_dir, formats)
    names = _names(result)
    texts = {}
    for f, path in paths.items():
        if f == "json":
            texts[path] = _json_text(result_to_dict(result, metadata))
        elif f == "csv":
            rows = [[t] + [float(result.per_frame[n][t]) for n in names] for t in range(result.n_frames)]
            texts[path] = _csv_text(["frame"] + names, rows)
        else:
            texts[path] = result_to_markdown(result, metadata)
    _atomic_write_texts(texts)
    return list(paths.values())
