"""Surface geodesics: accuracy against analytic distances, truncated searches against dense references."""

import numpy as np
import pytest
from scipy.sparse import csgraph

from core.garment import mesh_edges
from core.geodesic import (edge_lengths, far_by_neighbourhood, geodesic_distances_from, geodesic_graph,
                           geodesic_neighbourhood, geodesically_far, unfolded_diagonals)
from tests.core.preprocess_meshes import cylinder, synthetic_meshes, two_spheres
from tests.meshes import grid, icosphere

MESHES = synthetic_meshes()


def dense_geodesics(v, f):
    return csgraph.dijkstra(geodesic_graph(v, f), directed=True)


def test_flat_grid_geodesics_are_close_to_euclidean_and_never_below():
    v, f = grid(12, 12, 0.6)
    src = 0
    d = geodesic_distances_from(geodesic_graph(v, f), [src])[0]
    eu = np.linalg.norm(v - v[src], axis=1)
    assert (d >= eu - 1e-12).all()
    rel = (d[1:] - eu[1:]) / eu[1:]
    assert rel.max() < 0.03  # plain edge paths are up to 8 % longer here
    d_edges = geodesic_distances_from(geodesic_graph(v, f, diagonals=False), [src])[0]
    assert ((d_edges[1:] - eu[1:]) / eu[1:]).max() > 0.05


def test_sphere_geodesics_match_great_circles():
    v, f = icosphere(3, radius=0.2)
    d = geodesic_distances_from(geodesic_graph(v, f), [0, 7])
    for row, s in zip(d, [0, 7]):
        arc = 0.2 * np.arccos(np.clip(v @ v[s] / 0.04, -1, 1))
        far = arc > 0.05
        assert np.abs(row[far] - arc[far]).max() / 0.2 < 0.05
        assert (row >= arc * (1 - 1e-9) - 1e-12).all() or np.abs(row - arc).max() < 0.01


def test_unfolded_diagonal_of_a_flat_square():
    v = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    f = np.array([[0, 1, 2], [0, 2, 3]])
    pairs, lengths = unfolded_diagonals(v, f)
    assert pairs.tolist() == [[1, 3]]
    np.testing.assert_allclose(lengths, [np.sqrt(2)])
    # Folded 90 degrees along the shared edge: the unfolded length is still sqrt(2) (the surface path).
    v2 = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 0, 1.0]])
    v2[3] = [0, 0, 1]  # triangle 0-2-3 stands up from the x=y diagonal
    _, lengths2 = unfolded_diagonals(v2, f)
    assert lengths2[0] >= np.linalg.norm(v2[1] - v2[3]) - 1e-12


def test_edge_lengths():
    v, f = grid(2, 2, 1.0)
    e = mesh_edges(f)
    L = edge_lengths(v, e)
    assert np.isclose(L.min(), 0.5) and np.isclose(L.max(), np.sqrt(0.5))


@pytest.mark.parametrize("name", sorted(MESHES))
def test_neighbourhood_matches_dense_dijkstra(name):
    v, f, _ = MESHES[name]
    D = dense_geodesics(v, f)
    r = 0.1
    near = geodesic_neighbourhood(v, geodesic_graph(v, f), r)
    expected = (D <= r)
    np.fill_diagonal(expected, False)
    got = near.toarray() > 0
    np.testing.assert_array_equal(got, expected)
    i, j = near.nonzero()
    np.testing.assert_allclose(near.toarray()[i, j], np.maximum(D[i, j], 1e-12), rtol=1e-6)  # stored as float32


@pytest.mark.parametrize("name", sorted(MESHES))
def test_geodesically_far_matches_dense_reference(name):
    v, f, _ = MESHES[name]
    D = dense_geodesics(v, f)
    rng = np.random.default_rng(0)
    # Candidate pairs: Euclidean-close ones (as the self-collision loss proposes) plus random ones.
    close = np.argwhere(np.linalg.norm(v[:, None] - v[None], axis=-1) < 0.12)
    pairs = np.concatenate([close[rng.choice(len(close), 400)], rng.integers(0, len(v), (200, 2))])
    g = geodesic_graph(v, f)
    far = geodesically_far(v, g, pairs, 0.1)
    np.testing.assert_array_equal(far, D[pairs[:, 0], pairs[:, 1]] > 0.1)
    np.testing.assert_array_equal(far_by_neighbourhood(geodesic_neighbourhood(v, g, 0.1), pairs), far)
    assert far.any() and (~far).any()


def test_separate_components_are_far_and_same_vertex_is_near():
    v, f = two_spheres(2, radius=0.15)
    v = v.copy()
    v[len(v) // 2:] -= [0.49, 0.1, 0.0]  # the second sphere now overlaps the first in space
    g = geodesic_graph(v, f)
    pairs = np.array([[0, len(v) // 2], [3, 3]])
    assert geodesically_far(v, g, pairs).tolist() == [True, False]
    assert geodesically_far(v, g, np.zeros((0, 2), np.int64)).shape == (0,)


def test_cylinder_seam_is_handled():
    v, f = cylinder(32, 10, radius=0.1, height=0.3)
    d = geodesic_distances_from(geodesic_graph(v, f), [0])[0]
    # Around the bottom ring the geodesic is the shorter arc, never through the open end.
    ring = np.arange(32)
    arc = 0.1 * np.minimum(ring, 32 - ring) * 2 * np.pi / 32
    chord_bound = 0.1 * 2 * np.sin(np.minimum(ring, 32 - ring) * np.pi / 32)
    assert (d[ring] <= arc + 1e-9).all() and (d[ring] >= chord_bound - 1e-9).all()
