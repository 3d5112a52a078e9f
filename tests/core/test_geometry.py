import itertools

import numpy as np

from core.geometry import (
    TriangleMesh,
    closest_point_on_triangles,
    closest_points_on_mesh,
    face_normals,
    penetration_per_frame,
    points_inside_mesh,
    signed_distance,
    vertex_normals,
)
from tests.meshes import grid, icosphere, points_around


def naive_closest(points, verts, faces):
    """Reference: every point against every face, one at a time, via a dense parameter search."""
    out_d, out_f = [], []
    for p in points:
        best = (np.inf, -1)
        for fi, (a, b, c) in enumerate(verts[faces]):
            # Minimise over the triangle by projecting and clamping (brute-force on a fine grid + exact edges).
            cp, _ = closest_point_on_triangles(p, a, b, c)
            d = np.linalg.norm(cp - p)
            if d < best[0]:
                best = (d, fi)
        out_d.append(best[0])
        out_f.append(best[1])
    return np.array(out_d), np.array(out_f)


def test_closest_point_on_triangle_matches_dense_sampling():
    rng = np.random.default_rng(0)
    a, b, c = rng.normal(size=(3, 3))
    u, v = np.meshgrid(np.linspace(0, 1, 401), np.linspace(0, 1, 401))
    keep = u + v <= 1
    samples = a + u[keep, None] * (b - a) + v[keep, None] * (c - a)
    for p in rng.normal(size=(20, 3)) * 2:
        cp, bary = closest_point_on_triangles(p, a, b, c)
        d_dense = np.linalg.norm(samples - p, axis=1).min()
        assert np.linalg.norm(cp - p) <= d_dense + 1e-12
        assert np.linalg.norm(cp - p) >= d_dense - 5e-3
        assert bary.min() >= -1e-12 and abs(bary.sum() - 1) < 1e-9
        np.testing.assert_allclose(bary @ np.stack([a, b, c]), cp, atol=1e-12)


def test_closest_point_on_degenerate_triangles_is_on_an_edge():
    """Zero-area faces (collinear corners, repeated corners) occur in real meshes: the closest point is the
    nearest point of the three edges, found by dense sampling of the segments. Rounding used to leave points of
    such faces in the interior case, whose division by ~0 gave barycentric coordinates summing to 0.01."""
    rng = np.random.default_rng(2)
    t = np.linspace(0, 1, 2001)[:, None]
    for kind in ("collinear", "two corners equal", "one point"):
        for _ in range(30):
            a, b = rng.normal(size=(2, 3))
            c = {"collinear": 2 * b - a, "two corners equal": b.copy(), "one point": a.copy()}[kind]
            if kind == "one point":
                b = a.copy()
            samples = np.concatenate([u + t * (v - u) for u, v in ((a, b), (a, c), (b, c))])
            for p in rng.normal(size=(5, 3)) * 2:
                d_dense = np.linalg.norm(samples - p, axis=1).min()
                for order in itertools.permutations((a, b, c)):  # the degenerate corner in every position
                    cp, bary = closest_point_on_triangles(p, *order)
                    assert d_dense - 5e-3 <= np.linalg.norm(cp - p) <= d_dense + 1e-12, kind
                    assert bary.min() >= -1e-12 and abs(bary.sum() - 1) < 1e-9, (kind, bary)
                    np.testing.assert_allclose(bary @ np.stack(order), cp, atol=1e-12)


def test_closest_points_exact_against_brute_force():
    rng = np.random.default_rng(1)
    v, f = icosphere(2, radius=0.3)
    v = v * np.array([1.0, 2.0, 0.5])  # stretched: uneven triangles stress the candidate bound
    pts = rng.normal(size=(200, 3)) * 0.4
    res = closest_points_on_mesh(pts, v, f)
    d_ref, _ = naive_closest(pts, v, f)
    np.testing.assert_allclose(res.distance, d_ref, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(res.closest - pts, axis=1), res.distance, atol=1e-12)
    # barycentric coordinates reproduce the closest point on the reported face
    np.testing.assert_allclose(np.einsum("nk,nkc->nc", res.barycentric, v[f[res.face_index]]), res.closest, atol=1e-12)


def test_signed_distance_sphere_and_inside():
    v, f = icosphere(3, radius=1.0)
    pts = points_around(300, 0.2, 1.8, seed=2)
    radii = np.linalg.norm(pts, axis=1)
    sd = signed_distance(pts, v, f)
    # The icosphere is inscribed in the unit sphere: within its sagitta of the analytic value.
    np.testing.assert_allclose(sd, radii - 1.0, atol=0.02)
    far = np.abs(radii - 1) > 0.03
    assert np.all((sd < 0)[far] == (radii < 1)[far])
    inside = points_inside_mesh(pts, v, f)
    assert np.array_equal(inside[far], (radii < 1)[far])
    # Points exactly at vertices and on edges are on the surface, not inside.
    assert np.all(np.abs(signed_distance(v, v, f)) < 1e-12)


def test_signed_distance_vertex_and_edge_regions_use_pseudo_normals():
    # Points straight out from a vertex or an edge midpoint of a cube-like coarse sphere are outside.
    v, f = icosphere(0, radius=1.0)
    sd_out = signed_distance(v * 1.1, v, f)
    assert np.all(sd_out > 0)
    mids = (v[f[:, 0]] + v[f[:, 1]]) / 2
    assert np.all(signed_distance(mids * 1.05, v, f) > 0)
    assert np.all(signed_distance(mids * 0.95, v, f) < 0)


def test_normals_of_flat_grid_and_sphere():
    v, f = grid(4, 3)
    np.testing.assert_allclose(face_normals(v, f), np.tile([0, 0, 1.0], (len(f), 1)), atol=1e-12)
    np.testing.assert_allclose(vertex_normals(v, f), np.tile([0, 0, 1.0], (len(v), 1)), atol=1e-12)
    vs, fs = icosphere(2)
    n = vertex_normals(vs, fs)
    assert np.all(np.einsum("ij,ij->i", n, vs) > 0.99)
    # batched input gives the same as per-frame input
    batch = np.stack([vs, vs * 2 + 1])
    np.testing.assert_allclose(vertex_normals(batch, fs)[1], vertex_normals(vs * 2 + 1, fs), atol=1e-12)


def test_penetration_per_frame():
    v, f = icosphere(2, radius=1.0)
    pts = np.array([[[0, 0, 0], [0, 0, 2.0]], [[0, 0, 2.0], [3, 0, 0]]])
    body = np.stack([v, v])
    np.testing.assert_allclose(penetration_per_frame(pts, body, f), [0.5, 0.0])
    # depth: a point about 5 mm inside counts at depth 0 and 2 mm, not at 1 cm
    p = np.array([[[0, 0, 0.995]]])
    assert -0.007 < signed_distance(p[0], v, f)[0] < -0.004
    assert penetration_per_frame(p, v[None], f, depth=0.002)[0] == 1.0
    assert penetration_per_frame(p, v[None], f, depth=0.01)[0] == 0.0


def test_triangle_mesh_reuse_gives_same_answer():
    v, f = icosphere(1)
    mesh = TriangleMesh(v, f)
    pts = np.random.default_rng(3).normal(size=(50, 3))
    np.testing.assert_array_equal(mesh.signed_distance(pts), signed_distance(pts, v, f))


def test_approximate_inside_test_agrees_with_exact_on_a_body():
    from core.body import default_body
    from core.geometry import vertex_normals

    b = default_body()
    rng = np.random.default_rng(4)
    idx = rng.choice(b.n_vertices, 3000, replace=False)
    offsets = rng.uniform(-0.03, 0.05, size=(len(idx), 1))
    pts = b.v_template[idx] + offsets * vertex_normals(b.v_template, b.faces)[idx]
    mesh = TriangleMesh(b.v_template, b.faces)
    exact = mesh.signed_distance(pts, exact=True)
    approx = mesh.signed_distance(pts, exact=False)
    assert np.all(np.abs(approx) >= np.abs(exact) - 1e-12)
    assert np.mean(np.sign(approx) == np.sign(exact)) > 0.999


def test_outward_faces_flips_an_inward_mesh_only():
    from core.geometry import outward_faces

    v, f = icosphere(1)
    np.testing.assert_array_equal(outward_faces(v, f), f)
    np.testing.assert_array_equal(outward_faces(v, f[:, ::-1]), f)


def _naive_self_intersections(v, f):
    """Every edge against every face sharing none of its vertices, one pair at a time."""
    from core.garment import mesh_edges
    from core.geometry import segment_triangle_hits

    marked = np.zeros(len(f), dtype=bool)
    for e in mesh_edges(f):
        for k, face in enumerate(f):
            if e[0] in face or e[1] in face:
                continue
            a, b, c = (v[face[i]][None] for i in range(3))
            if segment_triangle_hits(v[e[0]][None], v[e[1]][None], a, b, c)[0]:
                marked[k] = True
                marked |= np.array([e[0] in g and e[1] in g for g in f])
    return marked


def test_self_intersecting_faces_matches_the_naive_loop_and_known_cases():
    from core.geometry import self_intersecting_faces

    v, f = grid(6, 6, 0.3)
    assert not self_intersecting_faces(v, f).any()  # a flat sheet
    s, sf = icosphere(2)
    assert not self_intersecting_faces(s, sf).any()  # a closed smooth surface
    # A sheet whose far half is lifted and pushed back through the near half.
    folded = v.copy()
    far = folded[:, 0] > 0.15
    folded[far, 2] = 0.05 * np.sin(12 * folded[far, 1])
    folded[far, 0] = 0.3 - folded[far, 0]
    marked = self_intersecting_faces(folded, f)
    assert marked.any()
    np.testing.assert_array_equal(marked, _naive_self_intersections(folded, f))
    rng = np.random.default_rng(3)
    crumpled = v + rng.normal(scale=0.03, size=v.shape)
    np.testing.assert_array_equal(self_intersecting_faces(crumpled, f), _naive_self_intersections(crumpled, f))


def test_bincount_rows_matches_add_at():
    from core.geometry import _bincount_rows

    rng = np.random.default_rng(0)
    index = rng.integers(0, 7, 50)
    values = rng.normal(size=(50, 3))
    want = np.zeros((9, 3))
    np.add.at(want, index, values)  # the naive scatter-add it replaces
    np.testing.assert_allclose(_bincount_rows(index, values, 9), want, atol=1e-12)


def _naive_point_triangle(p, a, b, c):
    """Distance from p to triangle abc by the plane projection when it falls inside, else the nearest of the three
    clamped edge projections (no Voronoi regions: independent of Ericson's formulas). Plain floats, one at a time."""
    n = np.cross(b - a, c - a)
    nn = float(n @ n)
    if nn > 1e-30:
        q = p - (float((p - a) @ n) / nn) * n
        # inside when q is on the inner side of all three edges
        if all(float(np.cross(v - u, q - u) @ n) >= 0 for u, v in ((a, b), (b, c), (c, a))):
            return float(np.linalg.norm(p - q))
    best = np.inf
    for u, v in ((a, b), (b, c), (c, a)):
        e = v - u
        ee = float(e @ e)
        t = 0.0 if ee == 0 else min(1.0, max(0.0, float((p - u) @ e) / ee))
        best = min(best, float(np.linalg.norm(p - (u + t * e))))
    return best


def _naive_best_of_nearest(points, verts, faces, k):
    """The one-pass closest face (`TriangleMesh.closest(exact=False)`) written as loops: per point, the faces of
    its k nearest centroids (every centroid's distance, sorted), each measured by `_naive_point_triangle`, the
    nearest kept. Returns (distance (N,), face (N,), gap (N,): how much farther the second-best candidate is)."""
    centroids = verts[faces].mean(axis=1)
    out_d, out_f, gap = [], [], []
    for p in points:
        cand = np.argsort(np.linalg.norm(centroids - p, axis=1), kind="stable")[:k]
        d = np.array([_naive_point_triangle(p, *verts[faces[f]]) for f in cand])
        order = np.argsort(d, kind="stable")
        out_d.append(d[order[0]])
        out_f.append(cand[order[0]])
        gap.append(d[order[1]] - d[order[0]] if len(d) > 1 else np.inf)
    return np.array(out_d), np.array(out_f), np.array(gap)


def _lumpy_body():
    """A closed stretched icosphere with uneven triangles, plus three zero-area faces glued onto it (a collinear
    sliver, a face with a repeated corner, a point face): the flat-face path of the closest-point formulas."""
    v, f = icosphere(2, radius=0.3)
    v = v * np.array([1.0, 1.6, 0.7])
    v = v + 0.02 * np.sin(7 * v[:, [1, 2, 0]])
    extra = np.array([[0.0, 0.0, 0.5], [0.05, 0.0, 0.5], [0.1, 0.0, 0.5]])
    n = len(v)
    return np.concatenate([v, extra]), np.concatenate([f, [[n, n + 1, n + 2], [n, n, n + 1], [n + 2, n + 2, n + 2]]])


def test_one_pass_closest_matches_the_naive_loop_in_chunks_and_threads(monkeypatch):
    """The penetration metric's kernel (`TriangleMesh.closest(exact=False)`, best of the 16 nearest centroids'
    faces) against `_naive_best_of_nearest`; with all faces as candidates, against brute force over every face.
    Taken in chunks of a few points on two threads (and in Z-order), it gives the same bits as in one piece."""
    import core.geometry as G

    v, f = _lumpy_body()
    rng = np.random.default_rng(5)
    pts = np.concatenate([rng.normal(size=(150, 3)) * 0.3, v[:20] * 1.03, v[20:40] * 0.97,
                          [[0.05, 0.0, 0.52], [0.05, 0.01, 0.5]]])  # the last two: nearest the flat faces
    mesh = TriangleMesh(v, f)
    for k in (16, len(f)):
        res = mesh.closest(pts, k=k, exact=False)
        d_ref, f_ref, gap = _naive_best_of_nearest(pts, v, f, k)
        np.testing.assert_allclose(res.distance, d_ref, rtol=0, atol=1e-12)
        clear = gap > 1e-9  # a near tie (a shared edge or vertex) may go to either face
        np.testing.assert_array_equal(res.face_index[clear], f_ref[clear])
        np.testing.assert_allclose(np.linalg.norm(res.closest - pts, axis=1), res.distance, atol=1e-12)
        np.testing.assert_allclose(np.einsum("nk,nkc->nc", res.barycentric, v[f[res.face_index]]), res.closest,
                                   atol=1e-12)
    d_all = np.array([min(_naive_point_triangle(p, *v[tri]) for tri in f) for p in pts])
    np.testing.assert_allclose(mesh.closest(pts, k=len(f), exact=False).distance, d_all, rtol=0, atol=1e-12)
    whole = mesh.closest(pts, exact=False)
    exact = mesh.closest(pts, exact=True)
    inside = points_inside_mesh(pts, v, f, depth=0.002)
    monkeypatch.setattr(G, "CLOSEST_CHUNK_PAIRS", 48)  # 3 points a chunk: ~60 chunks, Z-ordered
    monkeypatch.setattr(G, "CLOSEST_THREADS", 2)
    for exact_mode, want in ((False, whole), (True, exact)):
        got = TriangleMesh(v, f).closest(pts, exact=exact_mode)
        for name in ("distance", "face_index", "barycentric", "closest"):
            np.testing.assert_array_equal(getattr(got, name), getattr(want, name), err_msg=name)
    np.testing.assert_array_equal(points_inside_mesh(pts, v, f, depth=0.002), inside)


def test_closest_formulas_give_the_same_bits_with_per_face_flat_tolerance():
    """`_closest_on_triangles_soa` with the per-face flat tolerance `TriangleMesh` gathers equals it computed per
    pair, on random and degenerate triangles (repeated corners, collinear, points at corners and on edges)."""
    from core.geometry import _closest_on_triangles_soa, _dot3_soa

    rng = np.random.default_rng(6)
    p = rng.normal(size=(3, 400, 1))
    a, b, c = rng.normal(size=(3, 3, 400, 8))
    b[:, :50], c[:, 50:100] = a[:, :50], 0.5 * (a[:, 50:100] + b[:, 50:100])
    a[:, 100:120] = b[:, 100:120] = c[:, 100:120]
    p[:, 120:140] = a[:, 120:140, :1]
    p[:, 140:160] = 0.5 * (a[:, 140:160, :1] + c[:, 140:160, :1])
    ab, ac = b - a, c - a
    plain = _closest_on_triangles_soa(p, a, b, c)
    tol = _closest_on_triangles_soa(p, a, b, c, flat_tol=1e-9 * _dot3_soa(ab, ab) * _dot3_soa(ac, ac))
    for x, y in zip(plain, tol):
        np.testing.assert_array_equal(x, y)
    for i in (0, 50, 100, 120, 140, 399):  # and each pair against the one-triangle form
        cp, bary = closest_point_on_triangles(p[:, i, 0], a[:, i, 3], b[:, i, 3], c[:, i, 3])
        np.testing.assert_array_equal(cp, plain[0][:, i, 3])
        np.testing.assert_array_equal(bary, plain[1][:, i, 3])
