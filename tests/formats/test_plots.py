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


def _boxes(points, placed, n_chars, char_w=4.5, height=7.0):
    return [(p[0] + dx, p[1] + dy, p[0] + dx + n * char_w, p[1] + dy + height)
            for p, ((dx, dy), _), n in zip(points, placed, n_chars)]


def test_pareto_labels_of_clustered_points_do_not_overlap(tmp_path):
    rng = np.random.default_rng(0)
    # a cluster of 9 points within a few points of each other (the model rows), and two lone ones
    pts = np.r_[rng.normal(100.0, 2.0, (9, 2)), [[10.0, 10.0], [300.0, 200.0]]]
    n_chars = [len(str(i + 1)) for i in range(len(pts))]
    placed = plots.label_offsets(pts, n_chars)
    boxes = _boxes(pts, placed, n_chars)
    for i in range(len(boxes)):
        for j in range(i):
            a, b = boxes[i], boxes[j]
            assert a[2] <= b[0] or b[2] <= a[0] or a[3] <= b[1] or b[3] <= a[1], (i, j)
    assert placed[9] == ((3, 3), False) and placed[10] == ((3, 3), False)  # lone points keep the default place
    assert any(far for _, far in placed[:9])  # the crowd needs leaders
    # labels to the left of a point end where it starts: a two-digit label is shifted by its width
    left = [((dx, dy), n) for ((dx, dy), _), n in zip(placed, n_chars) if dx < 0]
    assert all(dx == -4 - 4.5 * n for (dx, _), n in left)
    path = plots.plot_pareto([f"c{i}" for i in range(len(pts))], list(np.geomspace(1e-3, 1.0, len(pts))),
                             list(pts[:, 1] / 10), [i % 2 == 0 for i in range(len(pts))], tmp_path / "p.png")
    assert read_png(path).shape[0] > 100
