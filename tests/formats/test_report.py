"""Tests of formats/report.py: JSON round trip, CSV shape, Markdown content, the generic table."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from core.errors import InputError
from core.metrics import MetricsResult, compute_metrics
from formats.report import (markdown_table, overall_markdown, read_json_report, result_to_markdown,
                            write_report)
from tests.meshes import icosphere


def make_result(T=4, penetration=False):
    v, f = icosphere(1, 0.3)
    rng = np.random.default_rng(0)
    gt = v[None] + rng.normal(scale=0.01, size=(T,) + v.shape)
    pred = gt + rng.normal(scale=0.005, size=gt.shape)
    kw = {}
    if penetration:
        kw = dict(body_points=np.zeros((T, 3, 3)), body_faces=np.array([[0, 1, 2]]),
                  inside_fn=lambda p, b, bf: p[..., 2] < 0)
    return compute_metrics(pred, gt, f, **kw)


def test_json_round_trip_keeps_every_number(tmp_path):
    r = make_result(penetration=True)
    meta = {"pred": "runs/pred.usd", "gt": "sim/gt.npz"}
    (path,) = write_report(r, tmp_path, formats=("json",), metadata=meta)
    assert path == tmp_path / "metrics.json"
    doc = json.loads(path.read_text())
    assert doc["metadata"] == meta
    assert doc["units"]["e_verts"] == "mm" and doc["units"]["e_curv"] == "1/m^2"
    assert doc["units"]["penetration_pct"] == "%"
    back = read_json_report(path)
    assert (back.n_frames, back.n_vertices, back.n_faces) == (r.n_frames, r.n_vertices, r.n_faces)
    assert back.overall == r.overall  # floats survive JSON exactly (repr round trip)
    assert set(back.per_frame) == set(r.per_frame)
    for name in r.per_frame:
        np.testing.assert_array_equal(back.per_frame[name], r.per_frame[name])
    assert back.metadata == meta


def test_csv_has_a_header_and_one_row_per_frame(tmp_path):
    r = make_result(T=5)
    (path,) = write_report(r, tmp_path, formats=("csv",))
    rows = list(csv.reader(path.open()))
    assert rows[0] == ["frame", "e_verts", "e_vnorm", "e_fnorm", "e_edge", "e_curv"]
    assert len(rows) == 1 + 5
    assert [int(row[0]) for row in rows[1:]] == list(range(5))
    values = np.array([[float(x) for x in row[1:]] for row in rows[1:]])
    np.testing.assert_array_equal(values[:, 0], r.per_frame["e_verts"])
    np.testing.assert_array_equal(values[:, 4], r.per_frame["e_curv"])


def test_markdown_has_units_and_per_frame_rows_for_short_sequences(tmp_path):
    r = make_result(T=3, penetration=True)
    paths = write_report(r, tmp_path, metadata={"pred": "a.npz", "gt": "b.npz"})
    assert sorted(p.name for p in paths) == ["metrics.csv", "metrics.json", "metrics.md"]
    md = (tmp_path / "metrics.md").read_text()
    for title in ("E_verts (mm)", "E_vnorm (deg)", "E_fnorm (deg)", "E_edge (%)", "E_curv (1/m^2)",
                  "penetration (%)"):
        assert title in md
    assert "`a.npz`" in md and "## Per frame" in md
    assert f"{r.overall['e_verts']:.4f}" in md
    assert not list(tmp_path.glob("*.partial"))


def test_markdown_summarises_long_sequences():
    r = make_result(T=40)
    md = result_to_markdown(r, max_frames_table=30)
    assert "## Per frame" not in md
    lines = [line for line in md.splitlines() if line.startswith("| min") or line.startswith("| max")]
    assert len(lines) == 2
    assert f"{r.per_frame['e_verts'].max():.4f}" in md


def test_overall_markdown_is_one_row():
    r = MetricsResult(per_frame={"e_verts": np.array([1.0, 3.0])}, overall={"e_verts": 2.0},
                      n_frames=2, n_vertices=10)
    assert overall_markdown(r).splitlines() == ["| E_verts (mm) |", "| -----------: |", "|       2.0000 |"]


def test_markdown_table_aligns_and_escapes():
    text = markdown_table(["name", "value"], [["a|b", 1.5], ["c", 20]])
    assert text.splitlines() == [
        "| name |  value |",
        "| ---- | -----: |",
        "| a\\|b | 1.5000 |",
        "| c    |     20 |",
    ]
    assert text.endswith("\n")
    with pytest.raises(ValueError, match="row 0 has 1 cells, expected 2"):
        markdown_table(["a", "b"], [[1]])


def test_stem_path_and_bad_format(tmp_path):
    r = make_result(T=2)
    paths = write_report(r, tmp_path / "run1.json", formats=("json", "md"))
    assert [p.name for p in paths] == ["run1.json", "run1.md"]
    with pytest.raises(InputError, match="report format: expected one of json, csv, md, got 'xml'"):
        write_report(r, tmp_path, formats=("xml",))
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    with pytest.raises(InputError, match="metrics report '.*bad.json'"):
        read_json_report(bad)


def test_write_markdown_makes_the_folder_and_says_where(tmp_path, capsys):
    from formats.report import write_markdown

    path = write_markdown(tmp_path / "new" / "table.md", ["# Title", "", "| a |"], show=True)
    assert path.read_text() == "# Title\n\n| a |\n"
    out = capsys.readouterr().out
    assert out.startswith("# Title\n") and out.rstrip().endswith(f"wrote {path}")
    write_markdown(path, ["again"])
    assert path.read_text() == "again\n" and capsys.readouterr().out == f"wrote {path}\n"
