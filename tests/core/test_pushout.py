"""Penetration post-processes: the push-out (vertices inside or within the margin of the body end `margin`
outside; others stay) and the model's contact guard (against a vertex-by-vertex reference)."""

import numpy as np
import torch

from core.geometry import TriangleMesh, closest_point_on_triangles, face_cross, normalise, outward_faces, outward_offsets
from core.pushout import (GUARD_DEPTH_FADE_M, GUARD_DEPTH_M, GUARD_MARGIN_M, GUARD_MOVED_M, PushOutDeformer,
                          contact_anchors, guard_contact, push_out)
from tests.meshes import icosphere, points_around, tiny_body


def test_push_out_moves_inside_and_near_vertices_to_the_margin_only():
    v, f = icosphere(3, radius=0.5)
    pts = points_around(300, 0.1, 0.8).astype(np.float32)
    mesh = TriangleMesh(v, f)
    before = mesh.signed_distance(pts)
    margin = 0.003
    out, moved = push_out(pts[None], v[None], f, margin)
    after = mesh.signed_distance(out[0])
    touched = before < margin
    assert moved.tolist() == [int(touched.sum())] and 50 < touched.sum() < 290
    np.testing.assert_allclose(after[touched], margin, atol=2e-5)
    np.testing.assert_array_equal(out[0][~touched], pts[~touched])
    # Pushed along the shortest way out: each moved vertex travels its distance to the surface plus the margin.
    np.testing.assert_allclose(np.linalg.norm(out[0] - pts, axis=1)[touched], margin - before[touched], atol=2e-5)


def test_push_out_moves_points_inside_a_body_that_passes_through_itself_to_its_outer_surface():
    """Two overlapping spheres, as an arm pressed into the torso: a point inside the large one just outside the
    small one has the small one's face nearest (inside the large one), whose side called it outside, and it was
    left where it was (a t-shirt baked with --push-out kept 0.9-3.2 % of its vertices inside by winding, none
    after). Now every point inside either sphere ends outside both, at the nearest point of the outer surface
    (checked against a dense sampling of it, analytic), and points outside stay."""
    from core.geometry import points_inside_mesh

    va, fa = icosphere(4, radius=0.3)
    vb, fb = icosphere(4, radius=0.5, center=(0.6, 0.0, 0.0))
    v, f = np.concatenate([va, vb]), np.concatenate([fa, fb + len(va)])
    rng = np.random.default_rng(1)
    pts = rng.uniform([-0.35, -0.5, -0.5], [1.15, 0.5, 0.5], (4000, 3))
    pts = np.concatenate([pts, [[0.32, 0.0, 0.0], [0.31, 0.05, 0.0]]])  # outside the small one, inside the large
    pts = pts.astype(np.float32).astype(np.float64)
    inside = points_inside_mesh(pts, v, f)
    margin = 0.002
    report = {}
    out, moved = push_out(pts[None], v[None], f, margin, report=report)
    out = out[0].astype(np.float64)
    assert inside.sum() > 1000 and report["vertices_to_outer_surface"] > 10 and report["vertices_left_inside"] == 0
    assert not points_inside_mesh(out, v, f).any()
    np.testing.assert_array_equal(out[~inside & (TriangleMesh(v, f).closest(pts).distance > margin)],
                                  pts[~inside & (TriangleMesh(v, f).closest(pts).distance > margin)])
    # The outer surface, analytic and dense: each sphere's points outside the other.
    d = rng.normal(size=(400_000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    sa, sb = 0.3 * d, 0.5 * d + [0.6, 0.0, 0.0]
    surface = np.concatenate([sa[np.linalg.norm(sa - [0.6, 0, 0], axis=1) > 0.5], sb[np.linalg.norm(sb, axis=1) > 0.3]])
    from scipy.spatial import cKDTree

    nearest, _ = cKDTree(surface).query(pts[inside])
    travelled = np.linalg.norm(out[inside] - pts[inside], axis=1)
    # The mesh's chords lie up to 1.1 mm inside the spheres; faces along the crease are passed over (their corners
    # inside the other sphere), about one edge (2-4 cm) along the surface at most.
    assert (travelled >= nearest - 0.003).all()
    assert (travelled <= nearest + 0.045).all() and np.median(travelled - nearest) < 0.004
    crease = np.flatnonzero(inside)[-2:]  # the two points beside the small sphere: to the crease, 0.29 m away
    np.testing.assert_allclose(np.linalg.norm(out[crease] - pts[crease], axis=1), nearest[-2:], atol=0.045)


def test_push_out_takes_back_moves_to_the_outer_surface_that_tear_the_cloth():
    """A strip of cloth across the lens where two spheres overlap (an armpit): every vertex's closest point pushes
    it into the other sphere, and the nearest point of the outer surface lies on the crease above the axis for
    those above it, below for those below, so the two rows beside the axis went 0.3-0.5 m apart (the example
    t-shirt's armpits tore in every frame of a walk, edges 10x long). With the garment's edges, the moves that
    make an edge longer than PUSH_OUT_TEAR_RATIO times its length before plus the slack are taken back to the
    closest point's target (which itself stretches the strip by its projection onto the faceted sphere, 1.4-1.7x) (`margin` out of the nearest face, inside the other sphere), round after round until
    none is: the strip goes back whole, a patch beside it that goes out whole stays on the outer surface, and the
    report counts both."""
    from core.garment import mesh_edges
    from core.geometry import points_inside_mesh
    from core.pushout import PUSH_OUT_TEAR_RATIO, PUSH_OUT_TEAR_SLACK_M

    va, fa = icosphere(4, radius=0.3)
    vb, fb = icosphere(4, radius=0.5, center=(0.6, 0.0, 0.0))
    v, f = np.concatenate([va, vb]), np.concatenate([fa, fb + len(va)])
    def strip(ys):  # a grid in the plane z = 2 mm, x from 0.22 to 0.25 m: the small sphere's face nearest
        # (off the plane z = 0 of the spheres' symmetry, where a vertex's nearest outer point ties between the
        # crease's upper and lower halves and which one a search returns is a matter of rounding: the packages
        # installed on 2026-12-07 sent one of the patch's 16 vertices down, and the patch was taken back whole)
        xs = np.linspace(0.22, 0.25, 4)
        gx, gy = np.meshgrid(xs, ys, indexing="ij")
        i = (np.arange(len(xs) - 1)[:, None] * len(ys) + np.arange(len(ys) - 1)[None, :]).ravel()
        return (np.stack([gx.ravel(), gy.ravel(), np.full(gx.size, 0.002)], axis=1),
                np.concatenate([np.stack([i, i + len(ys), i + 1], 1), np.stack([i + 1, i + len(ys), i + len(ys) + 1], 1)]))

    across, across_faces = strip(np.linspace(-0.105, 0.105, 22))  # no row on the axis itself
    aside, aside_faces = strip(np.linspace(0.12, 0.15, 4))  # all above the axis: to the crease above, whole
    pts, faces = np.concatenate([across, aside]), np.concatenate([across_faces, aside_faces + len(across)])
    edges = mesh_edges(faces)
    before = np.linalg.norm(pts[edges[:, 0]] - pts[edges[:, 1]], axis=1)
    longest = PUSH_OUT_TEAR_RATIO * before + PUSH_OUT_TEAR_SLACK_M
    assert points_inside_mesh(pts, va, fa).all() and points_inside_mesh(pts, vb, fb).all()
    margin = 0.001
    torn, _ = push_out(pts[None], v[None], f, margin)
    lengths = lambda p: np.linalg.norm(p[edges[:, 0]] - p[edges[:, 1]], axis=1)  # noqa: E731
    assert (lengths(torn[0].astype(np.float64)) > longest).sum() > 5  # without the edges: torn
    report = {}
    out, moved = push_out(pts[None], v[None], f, margin, report=report, edges=edges)
    out = out[0].astype(np.float64)
    assert moved[0] == len(pts)
    taken_back = points_inside_mesh(out, v, f)
    assert (lengths(out) <= longest + 1e-6)[~taken_back[edges].all(axis=1)].all()  # no edge to the outer surface torn
    assert taken_back[:len(across)].all() and not taken_back[len(across):].any()  # the torn strip back whole
    assert report["vertices_kept_off_outer_surface"] == len(across) and report["vertices_left_inside"] == 0
    assert report["vertices_to_outer_surface"] == len(aside)
    # those taken back are at their closest point's target: `margin` out of the small sphere's face nearest them
    np.testing.assert_allclose(TriangleMesh(va, fa).signed_distance(out[taken_back]), margin, atol=2e-5)
    np.testing.assert_array_equal(out[~taken_back], torn[0][~taken_back])


def test_push_out_lifts_vertices_under_the_ground_straight_up():
    """With a ground, vertices under it (a hem through the floor) end `margin` above it, moved along Z only, away
    from the body; every vertex ends outside the body (which wins under its lowest point)."""
    v, f = icosphere(3, radius=0.5)
    rng = np.random.default_rng(3)
    pts = np.concatenate([points_around(100, 0.1, 0.8), rng.uniform(-1, 1, (50, 3)) * [1.5, 1.5, 0.1]
                          + [0, 0, -0.55]]).astype(np.float32)  # a sheet around the sphere's bottom (z -0.5)
    margin, ground = 0.003, -0.5
    plain, _ = push_out(pts[None], v[None], f, margin)
    out, moved = push_out(pts[None], v[None], f, margin, ground_z=ground)
    aside = np.linalg.norm(pts[:, :2], axis=1) > 0.3  # beyond the sphere's bottom: the ground alone
    low = (pts[:, 2] < ground + margin) & aside
    assert low.sum() > 10 and moved[0] >= low.sum()
    np.testing.assert_allclose(out[0, low, 2], ground + margin, atol=1e-6)
    np.testing.assert_array_equal(out[0, low, :2], pts[low, :2])
    untouched = pts[:, 2] >= ground + margin
    np.testing.assert_array_equal(out[0, untouched], plain[0, untouched])
    assert (TriangleMesh(v, f).signed_distance(out[0]) > margin - 1e-4).all()


def test_push_out_deformer_wraps_any_method_and_reports():
    from core.deform import LBSDeformer
    from core.garment import Garment
    from core.motion import Motion

    body = tiny_body()
    shrunk = body.v_template * 0.9 + body.v_template.mean(0) * 0.1  # a garment inside the body
    garment = Garment(shrunk.astype(np.float32), body.faces.astype(np.int64))
    poses = np.zeros((3, body.n_joints, 3), np.float32)
    motion = Motion(poses=poses, trans=np.zeros((3, 3), np.float32), fps=30.0)
    inner = LBSDeformer()
    inner.prepare(garment, body)
    wrapped = PushOutDeformer(LBSDeformer())
    wrapped.prepare(garment, body)
    plain = inner.deform(garment, body, motion)
    pushed = wrapped.deform(garment, body, motion)
    bp, _ = body.pose(poses, motion.trans, None)
    inside = [TriangleMesh(bp[t], body.faces).signed_distance(plain[t]) < 0 for t in range(3)]
    assert all(i.mean() > 0.9 for i in inside)
    assert all((TriangleMesh(bp[t], body.faces).signed_distance(pushed[t]) > 0).all() for t in range(3))
    assert wrapped.name == "lbs" and wrapped.report["push_out"]["vertices_moved_per_frame_max"] > 0
    assert wrapped.report["push_out"]["ground_z_m"] == float(bp[..., 2].min())


def _naive_weight(x, bound, fade):
    """1 up to the bound, then a straight line down to 0 at bound + fade (a cut-off at the bound when fade is 0)."""
    if x <= bound:
        return 1.0
    return 0.0 if x >= bound + fade else 1.0 - (x - bound) / fade


def _naive_lift(behind, depth, fade):
    """All of `behind` up to the depth, then a straight line from the depth down to 0 at depth + fade (a cut-off at
    the depth when fade is 0)."""
    if behind <= depth:
        return behind
    return 0.0 if behind >= depth + fade else depth * (depth + fade - behind) / fade


def _naive_guard(points, body_points, body_faces, rest, rest_body, margin, reach, depth, reach_fade, depth_fade):
    """Vertex by vertex: every rest body face's closest point (exhaustive), those within the blend's margin of
    the nearest weighted down to 0 at it, their points and area-weighted vertex normals blended; in each posed
    frame the same blend of the posed body's; beyond GUARD_NEAR_FROM_M along that plane blended with the plane of
    the nearest vertices of the faces touching the blends' vertices (their normals over those faces, blended), as
    far as the nearest is at most half as far as the anchor's point."""
    from core.pushout import GUARD_NEAR_FROM_M, GUARD_NEAR_TO_M, GUARD_NEAR_VERTICES
    from core.skinning import BLEND_MAX_M, BLEND_MIN_M, BLEND_SHARE

    out = np.array(points, dtype=np.float64)
    tris = rest_body[body_faces]

    around = [[k for k, f in enumerate(body_faces) if b in f] for b in range(len(rest_body))]

    def plane(verts, blend):  # the blend's point and unit normal on the body `verts`
        c0, c1, c2 = (verts[body_faces[:, k]] for k in range(3))
        cross = np.cross(c1 - c0, c2 - c0)
        q = sum(w * verts[b] for b, w in blend.items())
        n = sum(w * cross[around[b]].sum(axis=0) for b, w in blend.items())  # area-weighted vertex normals
        return q, n / np.linalg.norm(n)

    blends = []
    for p in np.asarray(rest, dtype=np.float64):
        cps, barys = closest_point_on_triangles(p[None], tris[:, 0], tris[:, 1], tris[:, 2])  # every face
        d = np.linalg.norm(cps - p, axis=1)
        width = min(max(BLEND_SHARE * d.min(), BLEND_MIN_M), BLEND_MAX_M)
        blend = {}
        for k in np.flatnonzero(d <= d.min() + width):
            for corner in range(3):
                b = int(body_faces[k][corner])
                blend[b] = blend.get(b, 0.0) + (1.0 - (d[k] - d.min()) / width) * barys[k][corner]
        total = sum(blend.values())
        blends.append({b: w / total for b, w in blend.items()})
    used = {b for blend in blends for b in blend}
    ring = [k for k, f in enumerate(body_faces) if used & set(int(b) for b in f)]
    ring_vertices = sorted({int(b) for k in ring for b in body_faces[k]})

    def nearest_plane(verts, x):  # the nearest ring vertices' points and normals over the ring's faces, blended
        order = sorted(ring_vertices, key=lambda v: np.linalg.norm(verts[v] - x))[:GUARD_NEAR_VERTICES + 1]
        d = [np.linalg.norm(verts[v] - x) for v in order]
        weights = [max(1.0 - di / d[-1], 0.0) for di in d[:-1]]
        c0, c1, c2 = (verts[body_faces[ring][:, k]] for k in range(3))
        cross = np.cross(c1 - c0, c2 - c0)
        q, n = np.zeros(3), np.zeros(3)
        for b, w in zip(order, weights):
            nb = cross[[j for j, k in enumerate(ring) if b in body_faces[k]]].sum(axis=0)
            q, n = q + w * verts[b], n + w * nb / np.linalg.norm(nb)
        return q / sum(weights), n / np.linalg.norm(n), d[0]

    for i, p in enumerate(np.asarray(rest, dtype=np.float64)):
        q0, n0 = plane(rest_body, blends[i])
        floor = min(margin, float(np.dot(p - q0, n0)))
        for t in range(len(out)):
            verts = body_points[t].astype(np.float64)
            x = out[t, i].copy()
            q, n = plane(verts, blends[i])
            along = np.dot(x - q, n)
            lateral = np.linalg.norm(x - q - along * n)
            within = _naive_weight(lateral, reach, reach_fade)
            behind = max(floor - along, 0.0)
            lift = _naive_lift(behind, depth, depth_fade) * within * n
            w = min(max((lateral - GUARD_NEAR_FROM_M) / (GUARD_NEAR_TO_M - GUARD_NEAR_FROM_M), 0.0), 1.0) * within
            if w > 0:
                qn, nn, nearest = nearest_plane(verts, x)
                w *= min(max(2.0 - 2.0 * nearest / np.linalg.norm(x - q), 0.0), 1.0)  # its vertices nearer
                behind_n = max(floor - np.dot(x - qn, nn), 0.0)
                lift = (1.0 - w) * lift + w * _naive_lift(behind_n, depth, depth_fade) * nn
            out[t, i] += lift
    return out


def test_contact_guard_matches_a_vertex_by_vertex_reference_and_only_lifts():
    body = tiny_body()
    rest_body = body.v_template.astype(np.float64)
    faces = outward_faces(rest_body, body.faces)
    rng = np.random.default_rng(0)
    # A garment around the body at 0-3 cm (some authored closer than the margin), then frames of a posed body
    # with the garment pushed in and out along random directions.
    # Off the body's faces' centres: a blend over the faces about as near as the nearest.
    centres = rest_body[faces[::2]].mean(axis=1)
    _, cp, out_dir = outward_offsets(centres, rest_body, faces)
    rest = cp + out_dir * rng.uniform(0.0, 0.03, len(cp))[:, None]
    poses = rng.normal(0, 0.3, (3, body.n_joints, 3)).astype(np.float32)
    body_points, _ = body.pose(poses, np.zeros((3, 3), np.float32), None)
    skinned = body_points[:, faces[::2]].mean(axis=2) + rng.normal(0, 0.01, (3, len(rest), 3))
    anchors = contact_anchors(rest, rest_body, faces, margin=0.002)
    # Bounds and fades at the scale of the offsets, so that every band holds vertices; fades of 0 cut off.
    outputs = []
    for bounds in ({"reach": 0.05, "depth": 0.01, "reach_fade": 0.02, "depth_fade": 0.005},
                   {"reach": 0.05, "depth": 0.01, "reach_fade": 0.0, "depth_fade": 0.0}):
        got, moved = guard_contact(skinned.astype(np.float32), body_points, anchors, **bounds)
        want = _naive_guard(skinned, body_points, faces, rest, rest_body, 0.002, **bounds)
        np.testing.assert_allclose(got, want, atol=1e-5)
        lifted = np.linalg.norm(got - skinned, axis=-1) > 1e-7
        counted = np.linalg.norm(want - skinned, axis=-1) > GUARD_MOVED_M
        assert moved.tolist() == counted.sum(axis=1).tolist() and 0 < lifted.mean() < 1
        outputs.append(got)
    # The fades reach vertices the cut-off leaves alone.
    assert (np.abs(outputs[0] - outputs[1]).max(axis=-1) > 1e-4).sum() >= 10
    # Only along each anchor face's outward normal: a lifted vertex ends farther from the body's centre.
    centre = body_points.mean(axis=1, keepdims=True)
    grew = np.linalg.norm(got - centre, axis=-1) > np.linalg.norm(skinned - centre, axis=-1)
    assert grew[lifted].mean() > 0.9


def test_contact_guard_leaves_the_rest_pose_and_far_vertices_alone():
    body = tiny_body()
    rest_body = body.v_template.astype(np.float64)
    faces = outward_faces(rest_body, body.faces)
    _, cp, out_dir = outward_offsets(rest_body[::2], rest_body, faces)
    rest = cp + 0.02 * out_dir
    anchors = contact_anchors(rest, rest_body, faces)
    same, moved = guard_contact(rest[None].astype(np.float32), rest_body[None], anchors)
    assert moved.tolist() == [0]
    np.testing.assert_array_equal(same[0], rest.astype(np.float32))
    # Deep inside but far along the plane from the anchor (beyond the reach): left alone.
    far = (rest - 0.05 * out_dir + 0.3 * np.cross(out_dir, [0.0, 0.0, 1.0]))[None].astype(np.float32)
    kept, _ = guard_contact(far, rest_body[None], anchors, reach=0.1, reach_fade=0.05)
    lateral = np.linalg.norm(0.3 * np.cross(out_dir, [0.0, 0.0, 1.0]), axis=1)
    np.testing.assert_array_equal(kept[0][lateral > 0.15], far[0][lateral > 0.15])


def test_contact_guard_lift_is_continuous_across_its_bounds():
    """A vertex swept ever deeper behind its face, and ever farther along the plane: the lift never jumps (a
    cut-off at the bounds moved cloth by the whole depth in one step), it is never more than the depth bound,
    and what is left behind the plane grows with the depth (the guard keeps vertices in order)."""
    body = tiny_body()
    rest_body = body.v_template.astype(np.float64)
    faces = outward_faces(rest_body, body.faces)
    _, cp, out_dir = outward_offsets(rest_body[:1], rest_body, faces)
    anchors = contact_anchors(cp + 0.01 * out_dir, rest_body, faces)
    n = normalise(anchors.normal[0] @ face_cross(rest_body, anchors.ring))[0]
    side = np.cross(n, [0.0, 0.0, 1.0])
    side /= np.linalg.norm(side)
    anchor = (anchors.point[0] @ rest_body)[0]
    bounds = {"reach": 0.1, "depth": 0.05, "reach_fade": 0.05, "depth_fade": 0.03}
    step = 1e-4
    behind = np.arange(0.0, 0.1, step)
    lateral = np.arange(0.0, 0.2, step)
    sweeps = {"depth": anchor + (anchors.floor[0] - behind)[:, None] * n,
              "lateral": anchor - 0.02 * n + lateral[:, None] * side}
    lifts = {}
    for name, pts in sweeps.items():
        got, _ = guard_contact(pts[:, None], np.repeat(rest_body[None], len(pts), 0), anchors, **bounds)
        lifts[name] = np.linalg.norm(got[:, 0] - pts, axis=1)
        # Slope at most depth / depth_fade (depth sweep) or 2 cm / reach_fade (lateral): no jump.
        assert np.abs(np.diff(lifts[name])).max() < step * 0.05 / 0.03 + 1e-5, name
        assert lifts[name].max() <= 0.05 + 1e-5 and lifts[name][-1] < 1e-6, name  # none beyond the fade
    np.testing.assert_allclose(lifts["depth"][behind < 0.05], behind[behind < 0.05], atol=1e-5)
    from core.pushout import GUARD_NEAR_FROM_M  # beyond, the body's nearest vertices' planes blend in

    np.testing.assert_allclose(lifts["lateral"][lateral < GUARD_NEAR_FROM_M], 0.02 + anchors.floor[0], atol=1e-5)
    assert np.all(np.diff(behind - lifts["depth"]) > -1e-5)



def _grid(n: int, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """An n x n grid of vertices in the plane z = 0 (spacing in metres) and its triangles (two a cell)."""
    ii, jj = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    verts = np.stack([ii.ravel() * spacing, jj.ravel() * spacing, np.zeros(n * n)], axis=1)
    k = (ii[:-1, :-1] * n + jj[:-1, :-1]).ravel()
    faces = np.concatenate([np.stack([k, k + n, k + 1], 1), np.stack([k + 1, k + n, k + n + 1], 1)])
    return verts, faces


def _neighbours(faces: np.ndarray, n_vertices: int) -> list[set]:
    """Each vertex's neighbours along the faces' edges."""
    out = [set() for _ in range(n_vertices)]
    for a, b, c in faces:
        for u, v in ((a, b), (b, c), (c, a)):
            out[u].add(v)
            out[v].add(u)
    return out


def _longest_edge(points: np.ndarray, neighbours: list[set]) -> float:
    return max(float(np.linalg.norm(points[u] - points[v])) for u in range(len(points)) for v in neighbours[u])


def _cloth_over_ground(n: int):
    """An n x n grid of 1 cm cells 1 cm above a flat body (the ground, normal +z), tied to it: (faces, the ground's
    vertices, the grid's rest vertices, its contact anchors)."""
    verts, faces = _grid(n, 0.01)
    ground = np.array([[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [-1.0, 1.0, 0.0], [1.0, 1.0, 0.0]])
    ground_faces = np.array([[0, 1, 3], [0, 3, 2]])  # normal +z
    rest = verts + [0.0, 0.0, 0.01]
    return faces, ground, rest, contact_anchors(rest, ground, ground_faces, garment_faces=faces)


def test_contact_guard_spreads_its_lifts_as_a_vertex_by_vertex_reference_does(monkeypatch):
    """A garment 1 cm above a flat body with a vertex pushed 3 cm through it: the lift, shared with the
    neighbours as four passes of (1 - 0.5) x + 0.5 * mean of the neighbours' do it vertex by vertex, and lifted
    further in a second round; a garment pushed through whole is lifted whole (the spread changes nothing). The
    top-up round after the spread ones is the guard once more, unspread (GUARD_TOP_UP_SPREAD 0): it leaves no vertex
    behind its plane; by default its lifts are spread over a quarter of the passes."""
    from core import pushout

    monkeypatch.setattr(pushout, "GUARD_TOP_UP", False)
    n = 9
    faces, ground, rest, anchors = _cloth_over_ground(n)
    dent = rest.astype(np.float32)
    centre = (n // 2) * n + n // 2
    dent[centre, 2] = -0.03
    alone, _ = guard_contact(dent[None], ground[None], anchors, passes=0)
    spread, moved = guard_contact(dent[None], ground[None], anchors, passes=4, rounds=1)
    np.testing.assert_allclose(alone[0, centre], [*dent[centre, :2], GUARD_MARGIN_M], atol=1e-7)
    neighbours = _neighbours(faces, n * n)
    shift = (alone[0] - dent).astype(np.float64)  # exactly 0 where the guard left a vertex
    for _ in range(4):
        shift = np.array([0.5 * shift[v] + 0.5 * np.mean([shift[u] for u in neighbours[v]], axis=0)
                          for v in range(n * n)])
    np.testing.assert_allclose(spread[0], dent + shift, atol=1e-6)
    assert moved.tolist() == [int((np.linalg.norm(shift, axis=1) > GUARD_MOVED_M).sum())] and 10 < moved[0] < 40
    assert (np.abs(shift).max(axis=1) > 0).sum() > moved[0]  # the spread's tails are not counted
    # A second round lifts what the first left behind the plane, as the guard run again on its output does.
    again, _ = guard_contact(spread, ground[None], anchors, passes=4, rounds=1)
    twice, _ = guard_contact(dent[None], ground[None], anchors, passes=4, rounds=2)
    np.testing.assert_allclose(twice, again, atol=1e-6)
    assert twice[0, centre, 2] > spread[0, centre, 2] + 0.003
    through = (rest - [0.0, 0.0, 0.03]).astype(np.float32)
    whole, _ = guard_contact(through[None], ground[None], anchors)
    np.testing.assert_allclose(whole[0], through + [0.0, 0.0, 0.02 + GUARD_MARGIN_M], atol=1e-6)
    monkeypatch.setattr(pushout, "GUARD_TOP_UP", True)
    monkeypatch.setattr(pushout, "GUARD_TOP_UP_SPREAD", 0.0)
    topped, _ = guard_contact(dent[None], ground[None], anchors, passes=4, rounds=2)
    np.testing.assert_allclose(topped, guard_contact(twice, ground[None], anchors, passes=0)[0], atol=1e-6)
    assert twice[0, centre, 2] < GUARD_MARGIN_M - 1e-3 and topped[0, :, 2].min() >= GUARD_MARGIN_M - 1e-6
    # Spread over a share of the passes (one of four here): the same lifts, shared as one pass shares them.
    monkeypatch.setattr(pushout, "GUARD_TOP_UP_SPREAD", 0.25)
    spread_top, _ = guard_contact(dent[None], ground[None], anchors, passes=4, rounds=2)
    lift = (topped - twice)[0].astype(np.float64)
    once = np.array([0.5 * lift[v] + 0.5 * np.mean([lift[u] for u in neighbours[v]], axis=0) for v in range(n * n)])
    np.testing.assert_allclose(spread_top[0], twice[0] + once, atol=1e-6)


def test_the_guard_lifts_by_the_depth_share_decided_on_the_networks_output(monkeypatch):
    """A vertex the network left too deep behind its plane to lift (11 cm: beyond the depth and its fade) among
    neighbours 3 cm deep: the first round's spread drags it up into the fade band, where a round deciding the share
    anew lifted it by its plane (the dress's hem at the knee jumped 28 mm in a frame on the example crouch); the
    later rounds, and a later guard of the same frames given the first's state, lift it by the share decided
    first (none): only the spread moves it."""
    from core import pushout

    monkeypatch.setattr(pushout, "GUARD_TOP_UP", False)
    n = 9
    faces, ground, rest, anchors = _cloth_over_ground(n)
    centre = (n // 2) * n + n // 2
    patch = [centre + di * n + dj for di in (-1, 0, 1) for dj in (-1, 0, 1)]
    dent = rest.astype(np.float32)
    dent[patch, 2] = -0.03
    dent[centre, 2] = -0.106  # behind its plane (the floor at the 4 mm margin): 11 cm
    first, _ = guard_contact(dent[None], ground[None], anchors, passes=1, rounds=1)
    assert GUARD_DEPTH_M < GUARD_MARGIN_M - first[0, centre, 2] < GUARD_DEPTH_M + GUARD_DEPTH_FADE_M  # in the band
    decided, _ = guard_contact(dent[None], ground[None], anchors, passes=1, rounds=2)
    anew, _ = guard_contact(first, ground[None], anchors, passes=1, rounds=1)  # its share decided on `first`
    assert decided[0, centre, 2] < anew[0, centre, 2] - 0.003
    alone, _ = guard_contact(first, ground[None], anchors, passes=0)
    assert alone[0, centre, 2] > first[0, centre, 2] + 0.003  # what a round deciding anew lifts it by its plane
    state = {}
    once, _ = guard_contact(dent[None], ground[None], anchors, passes=1, rounds=1, state=state)
    again, _ = guard_contact(once, ground[None], anchors, passes=1, rounds=1, state=state)
    np.testing.assert_allclose(again, decided, atol=1e-6)


def test_contact_guard_spread_keeps_cloth_pushed_into_a_corner_whole():
    """Cloth across a body's inner corner (an armpit: a wall and a floor at right angles), its vertices on either
    side of the corner's diagonal nearer either face, pushed 4 cm into the corner: tied each to its nearest face
    alone, neighbours across the diagonal parted by 1.6 cm (edges of 5-7 mm torn, twice their length); tied to
    a blend of the faces about as near, the normals turn across the diagonal and the cloth stays whole even
    unspread; spread too, and it still leaves the body."""
    n, spacing = 9, 0.005
    grid, faces = _grid(n, spacing)
    across = np.array([1.0, 0.0, -1.0]) / np.sqrt(2.0)  # the cloth spans the corner's cross-section and its length
    c = (n - 1) / 2 * spacing
    rest = [0.03, 0.0, 0.03] + (grid[:, :1] - c) * across + (grid[:, 1:2] - c) * [0.0, 1.0, 0.0]
    corner = np.array([[0.0, -1.0, 0.0], [0.0, 1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0],
                       [0.0, -1.0, 1.0], [0.0, 1.0, 1.0]])
    corner_faces = np.array([[0, 2, 3], [0, 3, 1], [0, 1, 5], [0, 5, 4]])  # the floor (+z), the wall (+x)
    anchors = contact_anchors(rest, corner, corner_faces, garment_faces=faces)
    pushed = (rest - [0.04, 0.0, 0.04]).astype(np.float32)
    neighbours = _neighbours(faces, n * n)
    alone, _ = guard_contact(pushed[None], corner[None], anchors, passes=0)
    spread, _ = guard_contact(pushed[None], corner[None], anchors)
    for lifted in (alone, spread):
        assert _longest_edge(lifted[0], neighbours) < 1.1 * spacing * np.sqrt(2.0)  # the longest rest edge
        # Every vertex lifted off its face at least half way (4 cm in at the centre, more at the sides).
        assert (np.maximum(lifted[0, :, 0], lifted[0, :, 2]) > -0.01).all()


def test_the_spread_covers_the_same_distance_on_fine_and_coarse_garments():
    """Passes grow with the square of the fineness (a pass spreads over about an edge); a garment coarser than
    the spread, or degenerate, is not spread; the finest are capped."""
    from core.pushout import GUARD_MAX_SPREAD_PASSES, GUARD_SPREAD_M, spread_passes

    assert spread_passes(GUARD_SPREAD_M / 2) == 8 and spread_passes(GUARD_SPREAD_M / 4) == 32
    assert spread_passes(GUARD_SPREAD_M) == 2 and spread_passes(2 * GUARD_SPREAD_M) == 0
    assert spread_passes(0.0) == 0 and spread_passes(float("nan")) == 0
    assert spread_passes(GUARD_SPREAD_M / 100) == GUARD_MAX_SPREAD_PASSES


def test_guard_sequence_poses_the_body_at_its_anchor_faces_only():
    """`guard_sequence` poses only the body vertices the anchor faces use (`anchored_body`, `Body.pose_at`): the
    frames of the guard against the whole posed body, to float32 rounding of the body's points."""
    from pathlib import Path

    from core.body import default_body
    from core.deform import LBSDeformer
    from core.motion import poses_for_body
    from core.pushout import anchored_body, body_anchors, guard_sequence
    from formats.motion import load_motion
    from formats.obj import read_garment

    root = Path(__file__).resolve().parents[2]
    garment, body = read_garment(root / "examples" / "trousers.obj"), default_body()
    run = load_motion(root / "examples" / "run.npz", fps=30.0)
    frames = slice(40, 60)
    poses, trans = poses_for_body(run, body.n_joints)[frames], run.trans[frames]
    points = LBSDeformer().deform(garment, body, run)[frames]
    anchors = body_anchors(garment.vertices, garment.faces, body, run.betas)
    ids, local = anchored_body(anchors)
    assert len(ids) < body.n_vertices / 2 and np.array_equal(ids[local.ring], anchors.ring)
    got, report = guard_sequence(points.copy(), garment.vertices, garment.faces, body, poses, trans, run.betas,
                                 anchors)
    whole, _ = body.pose(poses, trans, run.betas)
    want, moved = guard_contact(points, whole, anchors)
    assert report["contact_guard"]["vertices_moved_per_frame_max"] == moved.max() > 0
    assert np.abs(got - want).max() < 1e-5 and np.abs(got - points).max() > 1e-3


def test_a_spread_of_many_passes_is_their_polynomial_within_its_tolerance():
    """`spread_over` of a fine garment's many passes (`spread_polynomial`: a Chebyshev polynomial of the pass, of
    fewer products) spreads lifts as the passes one by one do, within SPREAD_TOLERANCE of the largest lift, in
    float64 on the CPU (scipy) and in float32 as a GPU would (torch); a few passes stay plain passes."""
    import torch

    from core.garment import Garment
    from core.pushout import SPREAD_TOLERANCE, _torch_operator, spread_over, spread_polynomial
    from core.skinning import graph_smoothing
    from tests.meshes import grid

    assert spread_polynomial(5) is None and spread_polynomial(15) is None  # the example garments' spreads
    assert [len(spread_polynomial(n)) - 1 for n in (40, 80, 200)] == [20, 28, 45]
    verts, faces = grid(40, 40, 0.4)
    garment = Garment(verts.astype(np.float32), faces)
    op = graph_smoothing(garment.faces, garment.n_vertices)
    rng = np.random.default_rng(0)
    shift = np.zeros((2, garment.n_vertices, 3))
    lifted = rng.choice(garment.n_vertices, 30, replace=False)
    shift[:, lifted] = rng.uniform(0.0, 0.05, (2, 30, 3))
    for passes in (40, 200):
        want = shift.transpose(1, 0, 2).reshape(garment.n_vertices, 6)
        for _ in range(passes):
            want = op @ want
        want = want.reshape(garment.n_vertices, 2, 3).transpose(1, 0, 2)
        got = spread_over(torch.from_numpy(shift), op, passes).numpy()
        assert np.abs(got - want).max() < SPREAD_TOLERANCE * 0.05 and np.abs(want).max() > 1e-4
        got32 = spread_over(torch.from_numpy(shift).float(), _torch_operator(op, torch.float32, "cpu"), passes)
        assert np.abs(got32.numpy() - want).max() < 1e-6


def test_the_spread_operator_is_made_for_a_device_once_per_anchors():
    """`_torch_operator` (the spread as a torch CSR tensor, for a GPU's guard) is made once per scipy operator,
    dtype and device and reused on the next batch; its entry goes with the operator."""
    import gc

    import torch

    from core.pushout import _TORCH_OPERATORS, _torch_operator
    from core.skinning import graph_smoothing
    from tests.meshes import grid

    verts, faces = grid(6, 6, 0.1)
    op = graph_smoothing(faces, len(verts))
    first = _torch_operator(op, torch.float32, "cpu")
    assert _torch_operator(op, torch.float32, torch.device("cpu")) is first
    other = _torch_operator(op, torch.float64, "cpu")
    assert other is not first and other.dtype == torch.float64
    np.testing.assert_allclose(first.to_dense().numpy(), op.toarray(), atol=1e-7)
    assert any(key[0] == id(op) for key in _TORCH_OPERATORS)
    del op
    gc.collect()
    assert not any(held[1] is first for held in _TORCH_OPERATORS.values())


def test_a_large_garment_is_guarded_in_fewer_frames_at_once():
    """`guard_chunk_frames`: 16 frames at once for a garment of 2k-4k vertices, powers of two down to 4 beyond (the
    time and peak memory measured on 3k-203k vertices: core/pushout.py), up to 128 below (a chunk's fixed work)."""
    from core.garment import frames_at_once
    from core.pushout import guard_chunk_frames

    got = [guard_chunk_frames(v) for v in (1, 384, 1000, 2016, 3240, 4001, 6698, 8001, 12816, 203328)]
    assert got == [128, 128, 64, 16, 16, 8, 8, 4, 4, 4]
    assert frames_at_once(1000, 64_000, 4, 16) == 16 and frames_at_once(3000, 64_000, 1, 64) == 16


def test_a_vertex_slid_far_along_its_anchor_is_kept_out_of_the_body_vertices_nearest_it(monkeypatch):
    """Cloth lagging centimetres behind the body along it: its anchor's plane (the flat ground it rested over)
    calls it outside where it sank into a step the body rises to there (the t-shirt's front into the belly on the
    run: holes in every render); beyond GUARD_NEAR_TO_M the nearest body vertices' plane lifts it, and within
    GUARD_NEAR_FROM_M nothing changes."""
    import core.pushout as pushout
    from core.pushout import GUARD_NEAR_FROM_M, GUARD_NEAR_TO_M

    body, body_faces = _grid(25, 0.01)
    body[:, :2] -= [0.05, 0.12]
    body[body[:, 0] >= 0.05 - 1e-9, 2] = 0.03  # a step 3 cm up from x = 5 cm
    xs, ys = np.meshgrid(np.arange(0.0, 0.125, 0.01), np.arange(-0.02, 0.025, 0.01), indexing="ij")
    rest = np.stack([xs.ravel(), ys.ravel(), np.where(xs.ravel() >= 0.05 - 1e-9, 0.04, 0.01)], axis=1)
    n, m = xs.shape
    k = (np.arange(n - 1)[:, None] * m + np.arange(m - 1)[None]).ravel()
    faces = np.concatenate([np.stack([k, k + m, k + 1], 1), np.stack([k + 1, k + m, k + m + 1], 1)])
    anchors = contact_anchors(rest, body, body_faces, garment_faces=faces)
    posed = (rest + [0.04, 0.0, 0.0]).astype(np.float32)
    alone, _ = guard_contact(posed[None], body[None], anchors, passes=0)
    sank = np.flatnonzero((rest[:, 0] >= 0.02 - 1e-9) & (rest[:, 0] <= 0.04 + 1e-9))  # now over the step
    assert 0.04 >= GUARD_NEAR_TO_M and alone[0, sank, 2].min() > 0.028  # out of it, within a millimetre at its edge
    # 3 cm from its edge (the vertices around it on its top): to the margin above it, straight up
    flat = np.flatnonzero(np.abs(rest[:, 0] - 0.03) < 1e-9)
    np.testing.assert_allclose(alone[0, flat], posed[flat] + [0.0, 0.0, 0.02 + GUARD_MARGIN_M], atol=1e-6)
    edge = np.flatnonzero((rest[:, 0] >= 0.01 - 1e-9) & (rest[:, 0] <= 0.04 + 1e-9))  # and the one onto its edge
    others = np.setdiff1d(np.arange(len(rest)), edge)
    np.testing.assert_allclose(alone[0, others], posed[others], atol=1e-7)  # above their planes: left
    spread, _ = guard_contact(posed[None], body[None], anchors)  # lifts spread over the cloth: half way
    assert spread[0, sank, 2].min() > 0.02
    # Within GUARD_NEAR_FROM_M of its anchor, the anchor's plane alone, as before.
    near = (rest + [0.9 * GUARD_NEAR_FROM_M, 0.0, 0.0]).astype(np.float32)
    got, _ = guard_contact(near[None], body[None], anchors, passes=0)
    within = pushout.anchor_offsets(near[None], body[None], anchors)[1][0] < GUARD_NEAR_FROM_M
    assert within.mean() > 0.9 and np.abs(got - near)[0, within].max() > 1e-3  # some slid onto the ramp: lifted
    monkeypatch.setattr(pushout, "GUARD_NEAR_FROM_M", 1e3)
    monkeypatch.setattr(pushout, "GUARD_NEAR_TO_M", 1e3 + 0.02)
    np.testing.assert_array_equal(got[0, within], guard_contact(near[None], body[None], anchors, passes=0)[0][0, within])


def test_the_nearest_body_vertices_of_a_gpu_are_the_k_d_trees():
    """The search on a GPU (all distances, `_nearest_by_distances`) finds what the CPU's k-d trees (a frame per
    thread; points in any order of frames, a frame with none) do."""
    from core.pushout import _nearest_body_vertices, _nearest_by_distances

    rng = np.random.default_rng(4)
    bp = torch.from_numpy(rng.normal(size=(4, 300, 3)))
    frames = rng.choice([0, 2, 3], size=(50, 1))
    p = torch.from_numpy(np.concatenate([frames, rng.normal(size=(50, 3))], axis=1))
    index, distance = _nearest_body_vertices(p, bp, 5)
    for s in range(len(p)):
        want_d, want_i = _nearest_by_distances(p[s:s + 1, 1:], bp[int(p[s, 0])], 5)
        assert index[s].tolist() == want_i[0].tolist()
        np.testing.assert_allclose(distance[s].numpy(), want_d[0].numpy(), atol=1e-12)
