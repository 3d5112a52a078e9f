"""Tests of core/metrics.py: each metric against a per-element loop, analytic cases, input checks."""

from __future__ import annotations

import math

import numpy as np
import pytest

from core.errors import InputError
from core.metrics import (MetricsResult, boundary_vertex_mask, compute_metrics, e_curv, e_edge, e_fnorm, e_verts,
                          e_vnorm, face_normals, frames_inside, gaussian_curvature, vertex_normals)
from tests.meshes import grid, icosphere

RNG = np.random.default_rng(0)


# ---------------------------------------------------------------------------
# Naive per-element references
# ---------------------------------------------------------------------------

def naive_face_normals(v, f):
    out = np.zeros((len(f), 3))
    for j, (a, b, c) in enumerate(f):
        n = np.cross(v[b] - v[a], v[c] - v[a])
        length = math.sqrt(float(n @ n))
        if length > 1e-12:
            out[j] = n / length
    return out


def naive_vertex_normals(v, f):
    out = np.zeros((len(v), 3))
    for a, b, c in f:
        n = np.cross(v[b] - v[a], v[c] - v[a])  # length 2*area: area weighting
        for i in (a, b, c):
            out[i] += n
    for i in range(len(v)):
        length = math.sqrt(float(out[i] @ out[i]))
        out[i] = out[i] / length if length > 1e-12 else 0.0
    return out


def naive_angle_deg(n, m):
    ln, lm = math.sqrt(float(n @ n)), math.sqrt(float(m @ m))
    if ln == 0 and lm == 0:
        return 0.0
    if ln == 0 or lm == 0:
        return 90.0
    return math.degrees(math.acos(max(-1.0, min(1.0, float(n @ m) / (ln * lm)))))


def naive_edges(f):
    edges = set()
    for tri in f:
        for k in range(3):
            a, b = int(tri[k]), int(tri[(k + 1) % 3])
            edges.add((min(a, b), max(a, b)))
    return sorted(edges)


def naive_curvature(v, f, area_normalised=True):
    count = {}
    for tri in f:
        for k in range(3):
            a, b = int(tri[k]), int(tri[(k + 1) % 3])
            count[(min(a, b), max(a, b))] = count.get((min(a, b), max(a, b)), 0) + 1
    boundary = {i for e, c in count.items() if c == 1 for i in e}
    angle = np.zeros(len(v))
    area = np.zeros(len(v))
    used = np.zeros(len(v), dtype=bool)
    for tri in f:
        p = [v[i] for i in tri]
        face_area = 0.5 * np.linalg.norm(np.cross(p[1] - p[0], p[2] - p[0]))
        for k in range(3):
            x, y = p[(k + 1) % 3] - p[k], p[(k + 2) % 3] - p[k]
            c = float(x @ y) / (np.linalg.norm(x) * np.linalg.norm(y))
            angle[tri[k]] += math.acos(max(-1.0, min(1.0, c)))
            area[tri[k]] += face_area / 3.0
            used[tri[k]] = True
    out = np.zeros(len(v))
    for i in range(len(v)):
        if not used[i]:
            continue
        deficit = (math.pi if i in boundary else 2 * math.pi) - angle[i]
        out[i] = deficit / area[i] if area_normalised else deficit
    return out


def naive_metrics(pred, gt, f):
    T, V = pred.shape[:2]
    out = {k: np.zeros(T) for k in ("e_verts", "e_vnorm", "e_fnorm", "e_edge", "e_curv")}
    edges = naive_edges(f)
    for t in range(T):
        p, g = pred[t], gt[t]
        out["e_verts"][t] = 1000 * sum(np.linalg.norm(p[i] - g[i]) for i in range(V)) / V
        pn, gn = naive_vertex_normals(p, f), naive_vertex_normals(g, f)
        out["e_vnorm"][t] = sum(naive_angle_deg(pn[i], gn[i]) for i in range(V)) / V
        pf, gf = naive_face_normals(p, f), naive_face_normals(g, f)
        out["e_fnorm"][t] = sum(naive_angle_deg(pf[j], gf[j]) for j in range(len(f))) / len(f)
        rel = [abs(np.linalg.norm(p[a] - p[b]) - np.linalg.norm(g[a] - g[b])) / np.linalg.norm(g[a] - g[b])
               for a, b in edges]
        out["e_edge"][t] = 100 * sum(rel) / len(rel)
        kp, kg = naive_curvature(p, f), naive_curvature(g, f)
        out["e_curv"][t] = sum(abs(kp[i] - kg[i]) for i in range(V)) / V
    return out


def wavy_grid(n=5, amp=0.05, seed=1):
    """A 5x5 grid with random heights: interior and boundary vertices, curved."""
    v, f = grid(n, n, size=0.5)
    v = v.copy()
    v[:, 2] = np.random.default_rng(seed).normal(scale=amp, size=len(v))
    return v, f


def random_pair(v, f, T=3, noise=0.01, seed=2):
    rng = np.random.default_rng(seed)
    gt = v[None] + rng.normal(scale=noise, size=(T,) + v.shape)
    pred = gt + rng.normal(scale=noise, size=gt.shape)
    return pred, gt


# ---------------------------------------------------------------------------
# Normals and curvature against the loops
# ---------------------------------------------------------------------------

@pytest.mark.parametrize("mesh", ["wavy", "sphere"])
def test_normals_and_curvature_match_naive(mesh):
    v, f = wavy_grid() if mesh == "wavy" else icosphere(1, 0.3)
    v = v + RNG.normal(scale=0.005, size=v.shape)
    np.testing.assert_allclose(face_normals(v, f), naive_face_normals(v, f), atol=1e-12)
    np.testing.assert_allclose(vertex_normals(v, f), naive_vertex_normals(v, f), atol=1e-12)
    np.testing.assert_allclose(gaussian_curvature(v, f), naive_curvature(v, f), rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(gaussian_curvature(v, f, area_normalised=False),
                               naive_curvature(v, f, area_normalised=False), atol=1e-10)


def test_normals_batched_over_leading_axes_and_keep_float32():
    v, f = wavy_grid()
    batch = (v[None, None] + RNG.normal(scale=0.01, size=(2, 3) + v.shape)).astype(np.float32)
    fn, vn = face_normals(batch, f), vertex_normals(batch, f)
    assert fn.shape == (2, 3, len(f), 3) and vn.shape == (2, 3, len(v), 3)
    assert fn.dtype == np.float32 and vn.dtype == np.float32
    for i in range(2):
        for j in range(3):
            np.testing.assert_allclose(vn[i, j], naive_vertex_normals(batch[i, j].astype(np.float64), f), atol=1e-5)
            np.testing.assert_allclose(fn[i, j], naive_face_normals(batch[i, j].astype(np.float64), f), atol=1e-5)
    k = gaussian_curvature(batch, f)
    assert k.shape == (2, 3, len(v))
    np.testing.assert_allclose(k[1, 2], naive_curvature(batch[1, 2].astype(np.float64), f), rtol=1e-6, atol=1e-4)


def test_degenerate_faces_and_unused_vertices_give_zero_not_nan():
    v, f = wavy_grid()
    v = np.concatenate([v, [[9.0, 9.0, 9.0]]])  # an isolated vertex
    v[1] = v[0]  # collapses the faces that use edge 0-1
    fn = face_normals(v, f)
    assert np.isfinite(fn).all()
    degenerate = np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1) == 0
    assert degenerate.any() and np.all(fn[degenerate] == 0)
    vn = vertex_normals(v, f)
    assert np.all(vn[-1] == 0) and np.isfinite(vn).all()
    k = gaussian_curvature(v, f)
    assert np.isfinite(k).all() and k[-1] == 0


# ---------------------------------------------------------------------------
# Metrics against the loops
# ---------------------------------------------------------------------------

@pytest.mark.parametrize("mesh", ["wavy", "sphere"])
def test_metrics_match_naive(mesh):
    v, f = wavy_grid() if mesh == "wavy" else icosphere(1, 0.3)
    pred, gt = random_pair(v, f)
    ref = naive_metrics(pred, gt, f)
    for name, fn in (("e_verts", e_verts), ("e_vnorm", e_vnorm), ("e_fnorm", e_fnorm), ("e_edge", e_edge),
                     ("e_curv", e_curv)):
        got = fn(pred, gt, f)
        assert got.shape == (3,)
        np.testing.assert_allclose(got, ref[name], rtol=1e-7, atol=1e-7, err_msg=name)


def test_compute_metrics_collects_all_and_means_over_frames():
    v, f = wavy_grid()
    pred, gt = random_pair(v, f, T=4)
    r = compute_metrics(pred.astype(np.float32), gt.astype(np.float32), f)
    assert isinstance(r, MetricsResult)
    assert set(r.per_frame) == {"e_verts", "e_vnorm", "e_fnorm", "e_edge", "e_curv"}
    assert (r.n_frames, r.n_vertices, r.n_faces) == (4, len(v), len(f))
    for name, values in r.per_frame.items():
        assert values.shape == (4,) and np.isfinite(values).all()
        assert r.overall[name] == pytest.approx(values.mean())
    np.testing.assert_allclose(r.per_frame["e_verts"], e_verts(pred, gt), rtol=1e-5)


# ---------------------------------------------------------------------------
# Analytic cases
# ---------------------------------------------------------------------------

def test_identical_inputs_give_exact_zeros():
    for v, f in (wavy_grid(), icosphere(2, 0.4)):
        seq = np.stack([v, v * 1.1, v + 0.2])
        r = compute_metrics(seq, seq.copy(), f)
        for name, values in r.per_frame.items():
            assert np.all(values == 0.0), name


def test_translation_gives_its_length_in_mm():
    v, f = icosphere(2, 0.4)
    shift = np.array([0.003, -0.004, 0.012])  # 13 mm
    gt = np.stack([v, v * 0.9])
    r = compute_metrics(gt + shift, gt, f)
    np.testing.assert_allclose(r.per_frame["e_verts"], 13.0, rtol=1e-9)
    for name in ("e_vnorm", "e_fnorm", "e_edge", "e_curv"):
        assert np.all(np.abs(r.per_frame[name]) < 1e-5), name


@pytest.mark.parametrize("deg", [10.0, 35.0, 90.0, 150.0])
def test_rotated_flat_grid_normals_turn_by_the_rotation_angle(deg):
    v, f = grid(6, 6, size=1.0)
    a = math.radians(deg)
    rot_x = np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])
    gt = v[None]
    pred = (v @ rot_x.T)[None]
    np.testing.assert_allclose(e_fnorm(pred, gt, f), deg, atol=1e-6)
    np.testing.assert_allclose(e_vnorm(pred, gt, f), deg, atol=1e-6)
    assert abs(e_edge(pred, gt, f)[0]) < 1e-9  # rotations keep lengths
    assert abs(e_curv(pred, gt, f)[0]) < 1e-6


@pytest.mark.parametrize("scale", [1.05, 1.5, 0.8])
def test_uniform_scale_gives_relative_edge_error(scale):
    v, f = icosphere(2, 0.4)
    r = compute_metrics((scale * v)[None], v[None], f)
    assert r.per_frame["e_edge"][0] == pytest.approx(100 * abs(scale - 1), rel=1e-9)
    assert r.per_frame["e_fnorm"][0] < 1e-6 and r.per_frame["e_vnorm"][0] < 1e-6


def test_icosphere_curvature_is_one_over_r_squared_and_obeys_gauss_bonnet():
    r = 0.3
    v, f = icosphere(4, r)
    k = gaussian_curvature(v, f)
    assert np.median(k) == pytest.approx(1 / r ** 2, rel=0.02)
    assert np.all(np.abs(k * r ** 2 - 1) < 0.2)  # the 12 valence-5 vertices are the worst, ~15%
    deficit = gaussian_curvature(v, f, area_normalised=False)
    assert deficit.sum() == pytest.approx(4 * math.pi, abs=1e-9)  # Gauss-Bonnet, chi = 2
    # Scaling the sphere by 2 divides the curvature density by 4; the deficit is unchanged.
    np.testing.assert_allclose(gaussian_curvature(2 * v, f), k / 4, rtol=1e-9)
    np.testing.assert_allclose(gaussian_curvature(2 * v, f, area_normalised=False), deficit, atol=1e-12)


def test_flat_grid_has_zero_curvature_except_the_rim_corners():
    v, f = grid(6, 6, size=1.0)
    boundary = boundary_vertex_mask(f, len(v))
    assert boundary.sum() == 24 and not boundary[3 * 7 + 3]
    deficit = gaussian_curvature(v, f, area_normalised=False)
    corners = [0, 6, 42, 48]
    np.testing.assert_allclose(deficit[~boundary], 0.0, atol=1e-12)
    straight_rim = boundary.copy()
    straight_rim[corners] = False
    np.testing.assert_allclose(deficit[straight_rim], 0.0, atol=1e-12)
    np.testing.assert_allclose(deficit[corners], math.pi / 2, atol=1e-12)  # the rim's turning angle
    np.testing.assert_allclose(gaussian_curvature(v, f)[~boundary], 0.0, atol=1e-9)


def test_collapsed_prediction_is_finite_and_scores_90_degrees():
    v, f = icosphere(1, 0.3)
    pred = np.zeros((1,) + v.shape)  # every face degenerate: zero normals
    r = compute_metrics(pred, v[None], f)
    assert all(np.isfinite(x).all() for x in r.per_frame.values())
    assert r.per_frame["e_fnorm"][0] == pytest.approx(90.0)
    assert r.per_frame["e_vnorm"][0] == pytest.approx(90.0)
    assert r.per_frame["e_edge"][0] == pytest.approx(100.0)


def test_zero_length_gt_edges_are_left_out_of_e_edge():
    v, f = wavy_grid()
    gt = v.copy()
    gt[1] = gt[0]  # the edge 0-1 has zero length
    pred = gt * 1.1
    got = e_edge(pred[None], gt[None], f)
    assert np.isfinite(got).all() and got[0] == pytest.approx(10.0)


# ---------------------------------------------------------------------------
# Penetration hook
# ---------------------------------------------------------------------------

def below_plane(points, body_points, body_faces):
    """Stand-in inside test: inside = below the body's lowest point + 0.1 m (per frame)."""
    return points[..., 2] < body_points[..., 2].min(axis=-1, keepdims=True) + 0.1


def test_penetration_uses_inside_fn_for_pred_and_gt():
    v, f = grid(3, 3, size=1.0)  # 16 vertices on z=0
    gt = np.stack([v, v])
    pred = gt.copy()
    pred[0, :4, 2] = -1.0  # 4 of 16 vertices sink in frame 0
    body = np.zeros((2, 3, 3))
    body_faces = np.array([[0, 1, 2]])
    body[:, :, 2] = -0.5  # inside = z < -0.4
    r = compute_metrics(pred, gt, f, body_points=body, body_faces=body_faces, inside_fn=below_plane)
    np.testing.assert_allclose(r.per_frame["penetration_pct"], [25.0, 0.0])
    np.testing.assert_allclose(r.per_frame["gt_penetration_pct"], [0.0, 0.0])
    assert r.overall["penetration_pct"] == pytest.approx(12.5)
    # Without an inside test (or body), no penetration entry.
    assert "penetration_pct" not in compute_metrics(pred, gt, f, body_points=body, body_faces=body_faces).per_frame


def test_frames_inside_lifts_a_one_frame_test():
    calls = []

    def inside_sphere(points, verts, faces):
        calls.append(points.shape)
        centre = verts.mean(axis=0)
        return np.linalg.norm(points - centre, axis=1) < 0.5

    points = np.array([[[0.0, 0, 0], [1.0, 0, 0]], [[0.0, 0, 0], [0.2, 0, 0]]])
    body = np.stack([np.zeros((3, 3)), np.full((3, 3), 5.0)])
    inside = frames_inside(inside_sphere)(points, body, np.array([[0, 1, 2]]))
    assert inside.tolist() == [[True, False], [False, False]]
    assert calls == [(2, 3), (2, 3)]


def test_metrics_taken_a_few_frames_at_a_time_equal_all_at_once(monkeypatch, caplog):
    """`compute_metrics` works through METRIC_VERTEX_FRAMES vertex-frames at a time (its float64 temporaries took
    10 GB on 91 frames of a 213k-vertex garment): float32 input in parts of 1 or 2 frames gives every metric and
    the penetration of all frames at once (to the rounding of float64 sums), and calls the inside test once per frame
    for PRED and GT together where they share the body (twice where GT has another)."""
    import core.metrics as M

    v, f = wavy_grid()
    rng = np.random.default_rng(3)
    pred = (v + rng.normal(0, 0.01, (5, *v.shape))).astype(np.float32)
    gt = (v + rng.normal(0, 0.01, (5, *v.shape))).astype(np.float32)
    body = np.repeat(v[None, :3] + 0.2, 5, axis=0)
    calls = []

    def inside(points, verts, faces):
        calls.append(points.dtype)
        return points[:, 2] > verts[:, 2].mean() - 0.2

    whole = compute_metrics(pred, gt, f, body, np.array([[0, 1, 2]]), frames_inside(inside))
    assert calls == [np.float64] * 5
    calls.clear()  # GT's own body, the same points: still one test a frame
    same = compute_metrics(pred, gt, f, body, np.array([[0, 1, 2]]), frames_inside(inside),
                           gt_body_points=body.copy(), gt_body_faces=np.array([[0, 1, 2]]))
    assert calls == [np.float64] * 5 and same.per_frame.keys() == whole.per_frame.keys()
    calls.clear()  # another body for GT: each garment against its own
    other = compute_metrics(pred, gt, f, body, np.array([[0, 1, 2]]), frames_inside(inside),
                            gt_body_points=body + 0.01, gt_body_faces=np.array([[0, 1, 2]]))
    assert calls == [np.float64] * 10
    for b, garment, name in ((body, pred, "penetration_pct"), (body + 0.01, gt, "gt_penetration_pct")):
        alone = np.array([100 * inside(garment[t].astype(np.float64), b[t], None).mean() for t in range(5)])
        np.testing.assert_allclose(other.per_frame[name], alone, err_msg=name)
        np.testing.assert_allclose(same.per_frame[name], whole.per_frame[name], err_msg=name)
    np.testing.assert_allclose(whole.per_frame["penetration_pct"],
                               [100 * inside(pred[t].astype(np.float64), body[t], None).mean() for t in range(5)])
    for frames in (1, 2):
        monkeypatch.setattr(M, "METRIC_VERTEX_FRAMES", frames * v.shape[0])
        parts = compute_metrics(pred, gt, f, body, np.array([[0, 1, 2]]), frames_inside(inside))
        assert parts.per_frame.keys() == whole.per_frame.keys()
        for name, values in whole.per_frame.items():
            assert values.shape == (5,), name  # equal up to the order of float64 sums
            np.testing.assert_allclose(parts.per_frame[name], values, rtol=1e-12, atol=1e-12, err_msg=name)
    assert 0 < whole.overall["penetration_pct"] < 100
    gt[1:3, 1] = gt[1:3, 0]  # an edge of zero length in two frames: one warning for both parts
    with caplog.at_level("WARNING", logger="core.metrics"):
        compute_metrics(pred, gt, f)
    assert [r.getMessage() for r in caplog.records] == ["2 ground-truth edges of zero length left out of E_edge"]
    caplog.clear()
    pred[4] = pred[4, :1]  # the last frame collapsed to a point (in the parts of 2 frames): one warning for all
    with caplog.at_level("WARNING", logger="core.metrics"):
        compute_metrics(pred, gt, f)
    assert [r.getMessage() for r in caplog.records][1:] == [
        f"{len(v)} vertex-frames of the prediction have under 1 % of the ground truth's area around them (collapsed "
        "faces): their curvature density dominates E_curv"]


# ---------------------------------------------------------------------------
# Bad input
# ---------------------------------------------------------------------------

def test_bad_inputs_raise_one_line_input_errors():
    v, f = wavy_grid()
    seq = np.stack([v, v, v])
    with pytest.raises(InputError, match=r"'p.npz' has 3 frames, 'g.npz' has 2") as e:
        compute_metrics(seq, seq[:2], f, pred_name="p.npz", gt_name="g.npz")
    assert "\n" not in str(e.value)
    with pytest.raises(InputError, match=r"'p.npz' has 36 vertices, 'g.npz' has 35: expected the same garment "
                                         r"mesh \(same vertices and faces\)$"):
        compute_metrics(seq, seq[:, :-1], f, pred_name="p.npz", gt_name="g.npz")
    # a side split at its seams (one vertex per UV corner, as some exporters write it): its doubles named
    split = np.concatenate([seq, seq[:, [3, 4, 5]]], axis=1)
    with pytest.raises(InputError, match=r"'p.npz' has 36 vertices, 'g.npz' has 39: expected the same garment mesh "
                                         r"\(same vertices and faces\): 3 of 'g.npz''s vertices lie where others do "
                                         r"\(the mesh split at its UV or panel seams"):
        compute_metrics(seq, split, f, pred_name="p.npz", gt_name="g.npz")
    bad = seq.copy()
    bad[1, 7, 0] = np.nan
    with pytest.raises(InputError, match=r"'g.npz'.*got NaN at frame 1, vertex 7"):
        compute_metrics(seq, bad, f, pred_name="p.npz", gt_name="g.npz")
    bad[1, 7, 0] = -np.inf
    with pytest.raises(InputError, match=r"'g.npz'.*got Inf at frame 1, vertex 7"):
        compute_metrics(seq, bad, f, pred_name="p.npz", gt_name="g.npz")
    with pytest.raises(InputError, match=r"expected points of shape \(T, V, 3\)"):
        compute_metrics(v, v, f)
    with pytest.raises(InputError, match=r"face indices in \[0, 35\]"):
        compute_metrics(seq, seq, f + 1)
    with pytest.raises(InputError, match=r"body'.*2 frames.*garment has 3"):
        compute_metrics(seq, seq, f, body_points=np.zeros((2, 3, 3)), body_faces=np.array([[0, 1, 2]]),
                        inside_fn=below_plane)


def test_check_comparable_rejects_different_faces():
    from core.metrics import check_comparable

    v, f = wavy_grid()
    seq = v[None]
    f2 = f.copy()
    f2[5] = [0, f.max(), f.max() // 2]  # a face across the sheet: another surface
    with pytest.raises(InputError, match=r"different faces \(first difference at face 5\)"):
        check_comparable(seq, f, seq, f2, "a", "b")
    with pytest.raises(InputError, match=r"different faces \(50 vs 49 faces\)") as e:
        check_comparable(seq, f, seq, f[:-1], "a", "b")
    assert "another order" not in str(e.value)
    # The same mesh with its vertices renumbered (an exporter that reorders them): the message says what to do.
    order = np.random.default_rng(0).permutation(len(v))
    with pytest.raises(InputError, match="its vertices in another order"):
        check_comparable(seq, f, seq[:, order], np.argsort(order)[f], "a", "b")


def test_check_comparable_accepts_the_same_quads_split_by_other_diagonals():
    """A quad grid triangulated by two tools: each quad split along either diagonal, faces in another order and
    one winding reversed. One surface: compared, with the prediction's faces for both."""
    from core.metrics import check_comparable, compute_metrics, same_surface

    n = 6
    idx = np.arange(n * n).reshape(n, n)
    quads = np.stack([idx[:-1, :-1], idx[:-1, 1:], idx[1:, 1:], idx[1:, :-1]], -1).reshape(-1, 4)
    xy = np.stack(np.meshgrid(np.arange(n), np.arange(n), indexing="ij"), -1).reshape(-1, 2) * 0.1
    v = np.c_[xy, np.sin(xy[:, 0] * 3) * 0.05]
    a = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])  # every quad along a-c
    flip = np.random.default_rng(0).random(len(quads)) < 0.5
    b = np.concatenate([np.where(flip[:, None], quads[:, [0, 1, 3]], quads[:, [0, 1, 2]]),
                        np.where(flip[:, None], quads[:, [1, 2, 3]], quads[:, [0, 2, 3]])])
    b = b[np.random.default_rng(1).permutation(len(b))]
    b[0] = b[0, ::-1]
    assert flip.any() and not np.array_equal(a, b)
    assert same_surface(a, b, len(v)) and same_surface(b, a, len(v))
    check_comparable(v[None], a, v[None] + 0.01, b, "pred", "gt")
    assert compute_metrics(v[None], v[None] + 0.01, a).overall["e_verts"] == pytest.approx(np.sqrt(3) * 10)
    c = a.copy()
    c[0] = [0, 7, 35]  # one triangle across the grid instead: another surface
    assert not same_surface(a, c, len(v))
    with pytest.raises(InputError, match="different faces"):
        check_comparable(v[None], a, v[None], c, "pred", "gt")


def test_self_intersection_pct_counts_faces_per_frame():
    from core.metrics import self_intersection_pct
    from tests.meshes import grid

    v, f = grid(6, 6, 0.3)
    folded = v.copy()
    far = folded[:, 0] > 0.15
    folded[far, 2] = 0.05 * np.sin(12 * folded[far, 1])
    folded[far, 0] = 0.3 - folded[far, 0]
    pct = self_intersection_pct(np.stack([v, folded]), f)
    assert pct.shape == (2,) and pct[0] == 0.0 and 0.0 < pct[1] < 100.0


def test_topology_cache_keeps_meshes_apart():
    """The edges and rim `e_edge` and `e_curv` cache per face array are those of the faces given, whichever came
    before: a grid, then the same grid with one face dropped (a new rim), then the grid again."""
    from core.garment import mesh_edges
    from core.metrics import _topology

    v, f = grid(3, 3, size=1.0)
    for faces in (f, f[1:], f):
        edges, rim = _topology(faces, len(v))
        np.testing.assert_array_equal(edges, mesh_edges(faces))
        np.testing.assert_array_equal(rim, boundary_vertex_mask(faces, len(v)))
        np.testing.assert_allclose(gaussian_curvature(v, faces), gaussian_curvature(v.copy(), faces.copy()))
