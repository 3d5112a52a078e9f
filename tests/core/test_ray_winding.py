"""Tests for core/ray_winding.py and the inside test built on it (`core.geometry.points_inside_mesh`): winding numbers
against a naive solid-angle sum, rays through edges and vertices, a mesh through itself, an open mesh, a mesh of
uneven faces."""

import numpy as np
import pytest

from core import geometry as G
from core import ray_winding as W
from core.geometry import TriangleMesh, outward_faces, points_inside_mesh
from tests.meshes import icosphere, points_around


def _naive_winding(points, verts, faces):
    """Generalised winding number: the solid angles of the faces seen from each point over 4 pi (Van Oosterom and
    Strackee), summed face by face in a loop."""
    out = np.zeros(len(points))
    for f in faces:
        a, b, c = (verts[f] - points[:, None]).transpose(1, 0, 2)
        la, lb, lc = (np.linalg.norm(x, axis=1) for x in (a, b, c))
        det = np.einsum("ij,ij->i", a, np.cross(b, c))
        den = la * lb * lc + np.einsum("ij,ij->i", a, b) * lc + np.einsum("ij,ij->i", b, c) * la \
            + np.einsum("ij,ij->i", c, a) * lb
        out += 2.0 * np.arctan2(det, den) / (4.0 * np.pi)
    return out


def _two_spheres():
    """One mesh of two closed spheres that overlap (a body whose arm passes into its torso)."""
    va, fa = icosphere(2, radius=1.0)
    vb, fb = icosphere(2, radius=0.6, center=(0.9, 0.1, 0.05))
    return np.concatenate([va, vb]), np.concatenate([fa, fb + len(va)])


def _cube(n=4, big_top=False):
    """A closed, outward unit cube [0, 1]^3 of n x n quads a side split in two, its vertices at multiples of 1/n;
    with `big_top`, its top (z = 1) two triangles across the whole side instead."""
    verts, faces = [], []
    for axis in range(3):
        for side in (0.0, 1.0):
            m = 1 if (big_top and axis == 2 and side == 1.0) else n
            s = np.linspace(0, 1, m + 1)
            a, b = np.meshgrid(s, s, indexing="ij")
            p = np.zeros((m + 1, m + 1, 3))
            others = [k for k in range(3) if k != axis]
            p[..., others[0]], p[..., others[1]], p[..., axis] = a, b, side
            idx = np.arange((m + 1) ** 2).reshape(m + 1, m + 1) + sum(len(x) for x in verts)
            q = np.stack([idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]], -1).reshape(-1, 4)
            faces.append(np.concatenate([q[:, [0, 1, 2]], q[:, [0, 2, 3]]]))
            verts.append(p.reshape(-1, 3))
    v, f = np.concatenate(verts), np.concatenate(faces)
    # Wind every face outward: its normal along the direction from the cube's centre to its centroid.
    n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    flip = np.einsum("ij,ij->i", n, v[f].mean(axis=1) - 0.5) < 0
    f[flip] = f[flip][:, ::-1]
    return v, f


@pytest.mark.parametrize("mesh", ["sphere", "two spheres"])
def test_ray_windings_equal_the_solid_angle_sum(mesh):
    v, f = icosphere(2, radius=1.0) if mesh == "sphere" else _two_spheres()
    pts = np.concatenate([points_around(400, 0.0, 1.6, seed=3),
                          points_around(200, 0.0, 0.7, seed=4) + [0.9, 0.1, 0.05]])
    want = _naive_winding(pts, v, f)
    clear = np.abs(want - np.round(want)) < 0.05  # not on the surface (the solid angle sum jumps there)
    plus, minus = W.ray_windings(pts, v, f)
    np.testing.assert_array_equal(plus[clear], np.round(want[clear]).astype(int))
    np.testing.assert_array_equal(minus, plus)
    if mesh == "two spheres":
        assert (plus == 2).sum() > 50  # the overlap is counted twice


def test_rays_through_edges_and_vertices_count_once():
    """Points whose rays run exactly through the cube's edges and vertices (two of their coordinates multiples of
    1/8, the cube's vertices at multiples of 1/4, along whichever axis the rays take): each inside point's winding
    is 1, each outside point's 0, both ways, whatever the order of the faces and of their corners."""
    v, f = _cube(4)
    s = np.arange(-1, 10) / 8.0
    pts = np.concatenate([np.roll(np.stack(np.meshgrid(s + 1 / 7, s, s, indexing="ij"), -1).reshape(-1, 3), a, axis=1)
                          for a in range(3)])
    pts = pts[~np.any((pts == 0) | (pts == 1), axis=1)]  # not on the surface
    inside = np.all((pts > 0) & (pts < 1), axis=1)
    assert 200 < inside.sum() < len(pts) - 200
    rng = np.random.default_rng(0)
    for faces in (f, np.roll(f[rng.permutation(len(f))], 1, axis=1)):
        plus, minus = W.ray_windings(pts, v, faces)
        np.testing.assert_array_equal(plus, inside.astype(int))
        np.testing.assert_array_equal(minus, inside.astype(int))


def test_a_point_inside_where_the_mesh_passes_through_itself_is_inside():
    """A point inside the big sphere whose nearest surface is the small sphere's, itself inside the big one: the
    nearest face's normal calls it outside (what the penetration share read before), the winding number inside."""
    v, f = _two_spheres()
    p = np.array([[0.9 - 0.6 - 0.03, 0.1, 0.05]])  # 3 cm from the small sphere, outside it, inside the big one
    mesh = TriangleMesh(v, f)
    assert mesh.signed_distance(p)[0] > 0  # the normal of the nearest face says outside
    assert points_inside_mesh(p, v, f, depth=0.002)[0]
    assert not points_inside_mesh(p, v, f, depth=0.05)[0]  # its depth: the distance to the nearest surface


def test_points_inside_an_open_mesh_fall_back_to_the_nearest_faces_sign():
    """A sphere without the faces of its top cap: a ray through the hole meets one face, the other ray none, so
    the nearest face's normal decides; inside points under the hole stay inside, outside points outside."""
    v, f = icosphere(3, radius=1.0)
    open_f = f[v[f].mean(axis=1)[:, 2] < 0.95]
    pts = points_around(500, 0.0, 1.5, seed=6)
    r = np.linalg.norm(pts, axis=1)
    clear = np.abs(r - 1) > 0.05
    plus, minus = W.ray_windings(pts, v, open_f)
    assert ((plus > 0) != (minus > 0)).any()  # some rays went through the hole
    got = points_inside_mesh(pts, v, open_f, depth=0.002)
    np.testing.assert_array_equal(got[clear], (r < 1)[clear])


def _tube(radius=0.05, length=0.3, around=24, along=12):
    """A tube along +x from 0 to `length`, closed by a fan at x = 0 and open at x = `length` (a forearm cut at the
    wrist): (vertices, faces wound outward)."""
    t = np.linspace(0.0, 2 * np.pi, around, endpoint=False)
    rings = [np.stack([np.full(around, x), radius * np.cos(t), radius * np.sin(t)], axis=1)
             for x in np.linspace(0.0, length, along + 1)]
    v = np.concatenate(rings + [[[0.0, 0.0, 0.0]]])
    f = []
    for i in range(along):
        for j in range(around):
            a, b = i * around + j, i * around + (j + 1) % around
            f += [[a, a + around, b], [b, a + around, b + around]]
    centre = len(v) - 1
    f += [[centre, j, (j + 1) % around] for j in range(around)]
    return v, outward_faces(v, np.array(f))


def test_points_in_front_of_a_hole_are_outside_and_those_behind_it_inside():
    """Past the open end of a tube (a body cut at the wrist), in line with the opening, the nearest feature is the
    hole's rim, whose faces turn their backs to the point: it was called inside at any distance (a garment 5-25 cm
    past a forearm's cut 45 % inside). In front of the plane that would close the hole a point whose closest point
    is on the rim is outside; inside the tube, near the opening or not, inside."""
    v, f = _tube()
    beyond = np.array([[0.3 + d, y, 0.0] for d in (0.01, 0.05, 0.25) for y in (0.0, 0.02, -0.03)])
    within = np.array([[0.3 - d, y, 0.0] for d in (0.01, 0.1, 0.25) for y in (0.0, 0.02, -0.03)])
    beside = np.array([[0.15, 0.08, 0.0], [0.15, 0.0, -0.06], [-0.05, 0.0, 0.0]])
    got = points_inside_mesh(np.concatenate([beyond, within, beside]), v, f, depth=0.002)
    np.testing.assert_array_equal(got, [False] * 9 + [True] * 9 + [False] * 3)
    # The sphere without its top cap: under the hole inside, above it outside (the cap's plane at z = 0.95).
    v, f = icosphere(3, radius=1.0)
    open_f = f[v[f].mean(axis=1)[:, 2] < 0.95]
    pts = np.array([[0.0, 0.0, 0.9], [0.05, 0.0, 0.85], [0.0, 0.0, 1.05], [0.0, 0.1, 1.5]])
    np.testing.assert_array_equal(points_inside_mesh(pts, v, open_f, depth=0.002), [True, True, False, False])


def test_depth_is_the_exact_distance_on_a_mesh_of_uneven_faces():
    """A cube whose top is two faces across it and whose sides are fine: points 1 mm under the top, a few cm from
    the fine sides, are 1 mm deep (the one-pass search over the 16 nearest centroids finds only the sides', 3-8 cm
    away, and counted them at 2 and 5 mm)."""
    v, f = _cube(40, big_top=True)
    pts = np.array([[0.5, 0.5, 0.999], [0.05, 0.5, 0.999], [0.5, 0.08, 0.999], [0.03, 0.03, 0.999],
                    [0.5, 0.5, 0.9]])
    assert np.array_equal(points_inside_mesh(pts, v, f, depth=0.0), [True] * 5)
    assert np.array_equal(points_inside_mesh(pts, v, f, depth=0.002), [False] * 4 + [True])
    assert np.array_equal(points_inside_mesh(pts, v, f, depth=0.05), [False] * 4 + [True])
    mesh = TriangleMesh(v, f)
    for radius, want in ((0.0009, [False] * 5), (0.0011, [True] * 4 + [False]), (0.11, [True] * 5)):
        np.testing.assert_array_equal(mesh.any_within(pts, radius), want)


@pytest.mark.parametrize("chunk", [False, True])
def test_any_within_is_whether_the_exact_distance_is_within_the_radius(chunk, monkeypatch):
    """Against the exact search, on a mesh of fine and large faces, at radii around each point's distance; split
    into chunks of a few points (memory flat however many points are inside: 200k took 3.8 GB at once), the same."""
    v, f = _cube(12, big_top=True)
    pts = np.random.default_rng(8).uniform(-0.2, 1.2, size=(400, 3))
    if chunk:
        monkeypatch.setattr(G, "WITHIN_CHUNK_PAIRS", 200)  # 5 points a chunk
    mesh = TriangleMesh(v, f)
    exact = mesh.closest(pts, exact=True).distance
    for scale in (0.999, 1.001):
        np.testing.assert_array_equal(mesh.any_within(pts, 0.0)[exact > 1e-9], False)
        got = np.array([mesh.any_within(p[None], d * scale)[0] for p, d in zip(pts[:60], exact[:60])])
        assert got.all() == (scale > 1) and got.any() == (scale > 1)
        np.testing.assert_array_equal(mesh.any_within(pts, 0.05), exact <= 0.05)


def test_an_open_tube_or_an_inverted_mesh_still_holds_its_inside():
    """A sleeve open at both ends along the rays' axis (both rays leave through the openings: 0 and 0, read as
    outside with no question asked) and a closed mesh wound inward (windings of -1: a body read as holding
    nothing): their insides are inside."""
    n, rings = 24, 21
    a = np.linspace(0, 2 * np.pi, n, endpoint=False)
    z = np.linspace(-0.5, 0.5, rings)
    v = np.stack([np.tile(0.05 * np.cos(a), rings), np.tile(0.05 * np.sin(a), rings), np.repeat(z, n)], axis=1)
    i, j = np.meshgrid(np.arange(rings - 1), np.arange(n), indexing="ij")
    q = np.stack([i * n + j, i * n + (j + 1) % n, (i + 1) * n + (j + 1) % n, (i + 1) * n + j], -1).reshape(-1, 4)
    f = np.concatenate([q[:, [0, 1, 2]], q[:, [0, 2, 3]]])
    inner = np.array([[0.0, 0.0, 0.0], [0.02, 0.0, 0.2], [0.0, -0.03, -0.3]])
    plus, minus = W.ray_windings(inner, v, f)
    assert W._ray_axis(v, f) == 2 and (plus == 0).all() and (minus == 0).all()
    assert points_inside_mesh(inner, v, f, depth=0.002).all()
    assert not points_inside_mesh(inner + [0.2, 0, 0], v, f).any()
    sphere_v, sphere_f = icosphere(3)
    pts = points_around(300, 0.0, 1.5, seed=9)
    r = np.linalg.norm(pts, axis=1)
    clear = np.abs(r - 1) > 0.05
    np.testing.assert_array_equal(points_inside_mesh(pts, sphere_v, sphere_f[:, ::-1], depth=0.002)[clear],
                                  (r < 1)[clear])


def test_a_grid_of_few_cells_is_made_coarser_for_large_faces(monkeypatch):
    """A mesh of a few faces across the whole grid keeps its entries bounded (the cells grow), and the windings
    stay right."""
    v, f = _cube(1)
    monkeypatch.setattr(W, "MAX_ENTRIES_PER_FACE", 2)
    monkeypatch.setattr(W, "CELLS_PER_FACE", 1000.0)
    *_, cell_face = W._grid(v[:, :2], f)
    assert len(cell_face) <= 2 * len(f) + 1024
    pts = np.array([[0.5, 0.5, 0.5], [1.5, 0.5, 0.5], [0.25, 0.75, 0.1]])
    np.testing.assert_array_equal(W.ray_windings(pts, v, f)[0], [1, 0, 1])
