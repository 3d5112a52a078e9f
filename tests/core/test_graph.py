"""Garment graph: vertex features, edges, components, hop distances (against loop references)."""

from collections import deque

import numpy as np

from core.garment import Garment, mesh_edges
from core.geometry import vertex_normals
from core.graph import (adjacency, connected_components, hop_distances, hop_distances_multi_source,
                        lexicographic_rank, peripheral_seeds, undirected_edges, vertex_features)
from tests.core.preprocess_meshes import synthetic_meshes
from tests.meshes import tiny_body

MESHES = synthetic_meshes()


def naive_bfs(edges, n, src):
    nbrs = [[] for _ in range(n)]
    for a, b in edges:
        nbrs[a].append(b)
        nbrs[b].append(a)
    d = [-1] * n
    d[src] = 0
    q = deque([src])
    while q:
        u = q.popleft()
        for w in nbrs[u]:
            if d[w] < 0:
                d[w] = d[u] + 1
                q.append(w)
    return np.array(d)


def test_vertex_features_match_a_loop():
    body = tiny_body()
    v = body.v_template * 1.05
    g = Garment(vertices=v.astype(np.float32), faces=body.faces)
    betas = np.array([0.5, -0.3, 0.0, 0.2])
    feats = vertex_features(g, body, betas)
    _, joints = body.shaped(betas)
    V, J = len(v), body.n_joints
    assert feats.joint_distances.shape == (V, J) and feats.joint_distances.dtype == np.float32
    for i in [0, 17, V - 1]:
        for j in range(J):
            assert abs(feats.joint_distances[i, j] - np.linalg.norm(v[i] - joints[j])) < 1e-5
    np.testing.assert_allclose(feats.normals, vertex_normals(v, body.faces), atol=1e-6)
    np.testing.assert_allclose(np.linalg.norm(feats.normals, axis=1), 1.0, atol=1e-5)
    assert feats.as_array().shape == (V, 6 + J)


def test_edges_and_adjacency_are_undirected():
    v, f, _ = MESHES["cylinder"]
    e = undirected_edges(f)
    assert (e[:, 0] < e[:, 1]).all() and len(np.unique(e, axis=0)) == len(e)
    # A closed-around tube: V + F - E = 0 (Euler characteristic of an annulus).
    assert len(v) + len(f) - len(e) == 0
    a = adjacency(e, len(v))
    assert (a != a.T).nnz == 0 and a.sum() == 2 * len(e)


def test_connected_components_count_and_labels():
    for name, (v, f, n_comp) in MESHES.items():
        n, lab = connected_components(mesh_edges(f), len(v))
        assert n == n_comp, name
        assert lab[0] == 0 and set(lab.tolist()) == set(range(n))
        e = mesh_edges(f)
        assert (lab[e[:, 0]] == lab[e[:, 1]]).all()
    n, lab = connected_components(np.zeros((0, 2), np.int64), 3)  # vertices without edges
    assert n == 3 and lab.tolist() == [0, 1, 2]


def test_hop_distances_match_naive_bfs():
    v, f, _ = MESHES["two_spheres"]
    e = mesh_edges(f)
    a = adjacency(e, len(v))
    d = hop_distances(a, [0, 5])
    np.testing.assert_array_equal(d[0], naive_bfs(e, len(v), 0))
    np.testing.assert_array_equal(d[1], naive_bfs(e, len(v), 5))
    assert (d[0] == -1).sum() == len(v) // 2  # the other sphere is unreachable


def test_multi_source_hops_are_the_minimum_over_sources():
    v, f, _ = MESHES["grid_with_hole"]
    e = mesh_edges(f)
    a = adjacency(e, len(v))
    src = [0, 40, len(v) - 1]
    expected = np.min([naive_bfs(e, len(v), s) for s in src], axis=0)
    np.testing.assert_array_equal(hop_distances_multi_source(a, src), expected)


def test_lexicographic_rank_and_peripheral_seeds_use_geometry():
    p = np.array([[1.0, 0, 0], [0.0, 1, 0], [0.0, 0, 1], [0.0, 0, 1]])
    assert lexicographic_rank(p).tolist() == [3, 2, 0, 1]
    # A path 0-1-2-3-4 laid out along x from 4 to 0: the start is vertex 4, the farthest vertex 0.
    pts = np.stack([np.arange(5)[::-1].astype(float), np.zeros(5), np.zeros(5)], 1)
    e = np.stack([np.arange(4), np.arange(1, 5)], 1)
    seeds = peripheral_seeds(adjacency(e, 5), np.zeros(5, np.int64), pts)
    assert seeds.tolist() == [0]
    # One seed per component, inside its component.
    v, f, _ = MESHES["two_spheres"]
    n, lab = connected_components(mesh_edges(f), len(v))
    s = peripheral_seeds(adjacency(mesh_edges(f), len(v)), lab, v)
    assert lab[s].tolist() == list(range(n))
