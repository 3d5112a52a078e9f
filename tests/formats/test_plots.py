"""Tests of formats/plots.py: per-frame curves, error histograms and the Markdown/HTML report."""

from __future__ import annotations

import numpy as np

from core.metrics import compute_metrics
from formats import plots
from formats.render import read_png
from tests.meshes import grid


def sequences():
    v, f = grid(4, 4, size=0.4)
    gt = np.stack([v + [0, 0, 0.01 * t] for t in range(5)])
    pred = gt.copy()
    pred[:, :, 2] += 0.003 * np.sin(9 * gt[:, :, 0])
    return pred, gt, f


def test_per_element_errors_match_loops():
    pred, gt, f = sequences()
    err = plots.per_element_errors(pred, gt, f)
    d = err["vertex distance (mm)"]
    assert d.shape == (5 * 25,)
    ref = [1000 * np.sqrt(((pred[t, v] - gt[t, v]) ** 2).sum()) for t in range(5) for v in range(25)]
    np.testing.assert_allclose(d, ref, rtol=1e-9)
    assert (err["vertex normal angle (deg)"] >= 0).all() and err["vertex normal angle (deg)"].max() < 30
    edges = {tuple(sorted((a, b))) for tri in f for a, b in ((tri[0], tri[1]), (tri[1], tri[2]), (tri[2], tri[0]))}
    assert err["edge length error (%)"].shape == (5 * len(edges),)


def test_write_plot_report_shows_tables_and_pictures(tmp_path):
    pred, gt, f = sequences()
    result = compute_metrics(pred, gt, f)
    extra = tmp_path / "heat.png"
    from formats.render import write_png

    write_png(extra, np.zeros((8, 8, 3), np.uint8))
    paths = plots.write_plot_report(result, tmp_path, pred, gt, f, images=[("Heatmap", extra)])
    names = {p.name for p in paths}
    assert {plots.PER_FRAME_PNG, plots.HISTOGRAMS_PNG, plots.REPORT_MD, plots.REPORT_HTML, "heat.png"} <= names
    img = read_png(tmp_path / plots.PER_FRAME_PNG)
    assert img.shape[0] > 200 and img.shape[1] > 400 and img.std() > 10  # a real picture, not blank
    assert read_png(tmp_path / plots.HISTOGRAMS_PNG).std() > 10
    md = (tmp_path / plots.REPORT_MD).read_text()
    assert "E_verts (mm)" in md and "![Heatmap](heat.png)" in md and f"]({plots.PER_FRAME_PNG})" in md
    assert f"{result.overall['e_verts']:.4g}"[:4] in md
    html = (tmp_path / plots.REPORT_HTML).read_text()
    assert html.count("<img") == 3 and "<table>" in html and "E_verts (mm)" in html


def test_report_without_sequences_has_curves_only(tmp_path):
    pred, gt, f = sequences()
    paths = plots.write_plot_report(compute_metrics(pred, gt, f), tmp_path)
    assert not (tmp_path / plots.HISTOGRAMS_PNG).exists()
    assert (tmp_path / plots.PER_FRAME_PNG) in paths
