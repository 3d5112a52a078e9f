"""Structure-preserving pooling (paper 3.3): a naive loop reference, and the properties the paper relies on."""

from collections import deque

import numpy as np
import pytest

from core.garment import mesh_edges
from core.graph import connected_components
from core.hierarchy import build_hierarchy, pool_structure_preserving
from tests.core.preprocess_meshes import EXAMPLES, NO_EXAMPLES, example_garments, synthetic_meshes


# ---------------------------------------------------------------- naive reference (loops, dicts, sets)

def naive_pool(edges, points):
    n = len(points)
    nbrs = [set() for _ in range(n)]
    for a, b in edges:
        nbrs[a].add(int(b))
        nbrs[b].add(int(a))

    def bfs(src):
        dist = {src: 0}
        q = deque([src])
        while q:
            u = q.popleft()
            for w in nbrs[u]:
                if w not in dist:
                    dist[w] = dist[u] + 1
                    q.append(w)
        return dist

    key = lambda i: (points[i][0], points[i][1], points[i][2], i)  # noqa: E731  lexicographic, ties by index
    hops = [-1] * n
    seen = set()
    seeds = []
    for start in sorted(range(n), key=key):
        if start in seen:
            continue
        d = bfs(start)  # start = smallest point of its component
        seen |= set(d)
        far = max(d.values())
        seed = min((i for i in d if d[i] == far), key=key)
        seeds.append(seed)
        for i, h in bfs(seed).items():
            hops[i] = h
    kept = [i for i in range(n) if hops[i] % 2 == 0]
    new = {i: k for k, i in enumerate(kept)}
    coarse = set()
    for a, b in edges:
        if a in new and b in new:
            coarse.add((min(new[a], new[b]), max(new[a], new[b])))
    for r in range(n):
        if r in new:
            continue
        ks = sorted(new[j] for j in nbrs[r] if j in new)
        for x in ks:
            for y in ks:
                if x < y:
                    coarse.add((x, y))
    U = np.zeros((n, len(kept)))
    for i in range(n):
        if i in new:
            U[i, new[i]] = 1.0
        else:
            ws = {new[j]: 1.0 / np.linalg.norm(points[i] - points[j]) for j in nbrs[i] if j in new}
            total = sum(ws.values())
            for c, w in ws.items():
                U[i, c] = w / total
    return np.array(kept), np.array(sorted(coarse)).reshape(-1, 2), U, sorted(seeds)


MESHES = synthetic_meshes()


@pytest.mark.parametrize("name", sorted(MESHES))
def test_vectorised_pooling_matches_naive_reference(name):
    v, f, _ = MESHES[name]
    e = mesh_edges(f)
    res = pool_structure_preserving(e, v)
    kept, coarse, U, seeds = naive_pool(e, v)
    np.testing.assert_array_equal(res.kept, kept)
    np.testing.assert_array_equal(res.coarse_edges, coarse)
    np.testing.assert_allclose(res.unpool.toarray(), U, atol=1e-12)
    assert sorted(res.seeds.tolist()) == seeds


def test_second_level_matches_naive_reference_on_the_coarse_graph():
    v, f, _ = MESHES["grid_with_hole"]
    h = build_hierarchy(mesh_edges(f), v, levels=2)
    kept, coarse, U, _ = naive_pool(h.edges[1], v[h.vertex_index[1]])
    np.testing.assert_array_equal(h.pool_index[1], kept)
    np.testing.assert_array_equal(h.edges[2], coarse)
    np.testing.assert_allclose(h.unpool[1].toarray(), U, atol=1e-12)


def test_path_graph_seed_is_an_end_and_every_other_vertex_survives():
    v = np.stack([np.linspace(0, 1, 9), np.zeros(9), np.zeros(9)], 1)
    e = np.stack([np.arange(8), np.arange(1, 9)], 1)
    res = pool_structure_preserving(e, v[::-1].copy())  # the smallest point is vertex 8: the seed is vertex 0
    assert res.seeds.tolist() == [0]
    np.testing.assert_array_equal(res.kept, [0, 2, 4, 6, 8])
    np.testing.assert_array_equal(res.coarse_edges, [[0, 1], [1, 2], [2, 3], [3, 4]])


# ---------------------------------------------------------------- properties, synthetic meshes and examples

def check_hierarchy_properties(v, f, expected_components=None, levels=3):
    v = np.asarray(v, dtype=np.float64)
    e0 = mesh_edges(f)
    n0, lab0 = connected_components(e0, len(v))
    if expected_components is not None:
        assert n0 == expected_components
    h = build_hierarchy(e0, v, levels=levels)
    assert h.n_levels == levels and h.components == [n0] * (levels + 1)
    for l in range(levels):
        fine_idx, coarse_idx = h.vertex_index[l], h.vertex_index[l + 1]
        np.testing.assert_array_equal(coarse_idx, fine_idx[h.pool_index[l]])
        # Components: same count, and each coarse component is exactly one original component.
        nc, labc = connected_components(h.edges[l + 1], len(coarse_idx))
        assert nc == n0
        orig = lab0[coarse_idx]
        for c in range(nc):
            assert len(np.unique(orig[labc == c])) == 1
        # Roughly half the vertices survive (each component keeps at least its seed).
        ratio = len(coarse_idx) / len(fine_idx)
        if len(fine_idx) > 50 * n0:
            assert 0.3 <= ratio <= 0.7, ratio
        # Unpooling: rows sum to 1, kept vertices copied, linear fields reproduced with small error.
        U = h.unpool[l]
        np.testing.assert_allclose(np.asarray(U.sum(axis=1)).ravel(), 1.0, atol=1e-12)
        assert (U.data > 0).all()
        pf, pc = v[fine_idx], v[coarse_idx]
        A = np.array([[0.3, -1.2, 0.7], [2.0, 0.1, -0.4]])
        field = pf @ A.T + [0.5, -1.0]
        rec = U @ (pc @ A.T + [0.5, -1.0])
        err = np.linalg.norm(rec - field, axis=1) / np.linalg.norm(A, 2)  # metres of position error
        el = np.linalg.norm(pf[h.edges[l][:, 0]] - pf[h.edges[l][:, 1]], axis=1)
        np.testing.assert_allclose(err[h.pool_index[l]], 0.0, atol=1e-9)
        assert err.mean() < 0.25 * el.mean(), (l, err.mean(), el.mean())
        assert err.max() <= el.max() + 1e-9
    return h


@pytest.mark.parametrize("name", sorted(MESHES))
def test_hierarchy_properties_on_synthetic_meshes(name):
    v, f, n_comp = MESHES[name]
    check_hierarchy_properties(v, f, n_comp)


def test_isolated_vertices_and_tiny_components_survive():
    v, f, _ = MESHES["two_spheres"]
    v = np.concatenate([v, [[2.0, 0, 0], [2.1, 0, 0], [2.05, 0.1, 0]]])
    f = np.concatenate([f, [[len(v) - 3, len(v) - 2, len(v) - 1]]])
    h = build_hierarchy(mesh_edges(f), v, levels=4)
    assert h.components == [3] * 5


def test_pooling_does_not_depend_on_vertex_order():
    v, f, _ = MESHES["cylinder"]
    p = np.random.default_rng(3).permutation(len(v))
    inv = np.argsort(p)
    h1 = build_hierarchy(mesh_edges(f), v, 2)
    h2 = build_hierarchy(mesh_edges(inv[f]), v[p], 2)
    for l in range(3):
        a = {tuple(x) for x in v[h1.vertex_index[l]].round(9)}
        b = {tuple(x) for x in v[p][h2.vertex_index[l]].round(9)}
        assert a == b


def test_unpool_values_and_pool_helpers():
    v, f, _ = MESHES["grid_with_hole"]
    h = build_hierarchy(mesh_edges(f), v, 1)
    coarse = h.pool(v, 0)
    assert coarse.shape == (h.sizes()[1], 3)
    assert h.unpool_values(coarse, 0).shape == v.shape


def test_negative_levels_rejected():
    v, f, _ = MESHES["cylinder"]
    with pytest.raises(ValueError, match="levels"):
        build_hierarchy(mesh_edges(f), v, -1)


@pytest.mark.skipif(not EXAMPLES, reason=NO_EXAMPLES)
def test_hierarchy_properties_on_example_garments():
    for name, g in example_garments().items():
        check_hierarchy_properties(g.vertices, g.faces, levels=2)
