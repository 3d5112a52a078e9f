"""Nystrom style descriptor: invariance to vertex order, stability under remeshing, determinism, accuracy."""

import numpy as np
import pytest

from core.descriptor import farthest_point_landmarks, style_descriptor, vertex_areas
from core.geodesic import geodesic_distances_from, geodesic_graph
from tests.core.preprocess_meshes import EXAMPLES, NO_EXAMPLES, cylinder, example_garments, grid_with_hole, two_spheres


def descriptor(v, f, **kw):
    return style_descriptor(v, f, geodesic_graph(v, f), **kw)


def permuted(v, f, seed=1):
    p = np.random.default_rng(seed).permutation(len(v))
    inv = np.argsort(p)
    f2 = inv[f][np.random.default_rng(seed + 1).permutation(len(f))]
    return v[p], np.roll(f2, 1, axis=1)  # also rotate each face's corners


@pytest.mark.parametrize("mesh", [cylinder(), grid_with_hole(), two_spheres(2)])
def test_permuted_mesh_gives_the_same_descriptor(mesh):
    v, f = mesh
    a = descriptor(v, f, n_landmarks=32)
    b = descriptor(*permuted(v, f), n_landmarks=32)
    np.testing.assert_allclose(a.eigenvalues, b.eigenvalues, atol=1e-10)


def test_same_garment_at_two_resolutions_is_closer_than_different_garments():
    coarse = descriptor(*cylinder(24, 16), n_landmarks=32).eigenvalues
    fine = descriptor(*cylinder(40, 27, twist=0.5), n_landmarks=32).eigenvalues  # other sampling, same surface
    longer = descriptor(*cylinder(24, 24, height=0.75), n_landmarks=32).eigenvalues
    wider = descriptor(*cylinder(32, 16, radius=0.22), n_landmarks=32).eigenvalues
    same = np.linalg.norm(coarse - fine)
    assert same < 0.2 * np.linalg.norm(coarse - longer)
    assert same < 0.2 * np.linalg.norm(coarse - wider)


def test_deterministic_given_the_seed_and_close_across_seeds():
    v, f = grid_with_hole()
    a = descriptor(v, f, n_landmarks=32, seed=0)
    b = descriptor(v, f, n_landmarks=32, seed=0)
    c = descriptor(v, f, n_landmarks=32, seed=7)
    np.testing.assert_array_equal(a.eigenvalues, b.eigenvalues)
    np.testing.assert_array_equal(a.landmarks, b.landmarks)
    assert np.linalg.norm(a.eigenvalues - c.eigenvalues) < 0.02


def test_nystrom_eigenvalues_approximate_the_full_affinity_operator():
    v, f = cylinder(24, 16)
    g = geodesic_graph(v, f)
    d = style_descriptor(v, f, g, n_landmarks=48, n_eigenvalues=6, sigma=0.3)
    D = geodesic_distances_from(g, np.arange(len(v)))
    K = np.exp(-D ** 2 / (2 * 0.3 ** 2))
    K = 0.5 * (K + K.T)
    w = vertex_areas(v, f)
    w /= w.sum()
    exact = np.sort(np.linalg.eigvalsh(np.sqrt(w)[:, None] * K * np.sqrt(w)[None]))[::-1][:6]
    np.testing.assert_allclose(d.eigenvalues, exact, atol=0.01 * exact[0])
    assert np.all(np.diff(d.eigenvalues) <= 1e-12)


def test_fixed_length_with_fewer_vertices_than_landmarks():
    v = np.array([[0.0, 0, 0], [0.1, 0, 0], [0, 0.1, 0], [0.1, 0.1, 0]])
    f = np.array([[0, 1, 2], [1, 3, 2]])
    d = descriptor(v, f, n_landmarks=64, n_eigenvalues=16)
    assert d.eigenvalues.shape == (16,) and len(d.landmarks) == 4
    assert (d.eigenvalues[4:] == 0).all() and d.eigenvalues[0] > 0


def test_farthest_point_landmarks_are_spread_and_cover_components():
    v, f = two_spheres(2)
    L, dist = farthest_point_landmarks(v, geodesic_graph(v, f), 8)
    half = len(v) // 2
    assert (L < half).any() and (L >= half).any()  # both spheres get landmarks
    assert len(set(L.tolist())) == 8 and dist.shape == (8, len(v))


def test_areas_sum_to_the_surface_area():
    v, f = cylinder(64, 8, radius=0.1, height=0.2)
    assert abs(vertex_areas(v, f).sum() - 2 * np.pi * 0.1 * 0.2) < 0.01 * 2 * np.pi * 0.1 * 0.2


@pytest.mark.skipif(not EXAMPLES, reason=NO_EXAMPLES)
def test_example_garments_subdivided_stay_closer_than_other_garments():
    garments = example_garments()
    desc = {k: descriptor(g.vertices.astype(np.float64), g.faces).eigenvalues for k, g in garments.items()}
    for name, g in garments.items():
        v, f = g.vertices.astype(np.float64), g.faces
        # Midpoint subdivision: a different mesh (4x the triangles) of the same surface.
        e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
        uniq, inv = np.unique(e, axis=0, return_inverse=True)
        mid = len(v) + inv.reshape(3, -1).T  # (F, 3): midpoints of edges 01, 12, 20
        v2 = np.concatenate([v, v[uniq].mean(axis=1)])
        a, b, c, ab, bc, ca = f[:, 0], f[:, 1], f[:, 2], mid[:, 0], mid[:, 1], mid[:, 2]
        f2 = np.concatenate([np.stack(x, 1) for x in ([a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca])])
        same = np.linalg.norm(descriptor(v2, f2).eigenvalues - desc[name])
        others = [np.linalg.norm(desc[o] - desc[name]) for o in desc if o != name]
        assert not others or same < min(others), (name, same, others)
        np.testing.assert_allclose(descriptor(*permuted(v, f)).eigenvalues, desc[name], atol=1e-10)
