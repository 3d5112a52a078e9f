"""Scene analysis (core/scene.py): each skip against a naive reference, and the methods with and without it."""

import numpy as np
import pytest
import torch
from scipy.spatial import cKDTree

from core.deform import LBSDeformer
from core.garment import Garment
from core.geometry import closest_point_on_triangles
from core.motion import Motion
from core.scene import (
    SKIPS,
    SceneAnalysis,
    active_joints,
    distant_parts_meet,
    faces_in_reach,
    interpolation_slack_per_point,
    parse_no_skip,
    restrict_weights,
    suggested_levels,
    swing_reach,
)
from tests.core.model_fixtures import tube
from tests.meshes import grid, icosphere, tiny_body


def _motion(T=6, seed=0, scale=0.3):
    rng = np.random.default_rng(seed)
    poses = (rng.normal(size=(T, 24, 3)) * scale).astype(np.float32)
    poses[:, 0] = [np.pi / 2, 0, 0]
    return Motion(poses=poses, trans=np.zeros((T, 3), np.float32), fps=30.0, name="m")


def test_parse_no_skip():
    assert parse_no_skip(()) == frozenset(SKIPS)
    assert parse_no_skip(["joints"]) == frozenset(SKIPS) - {"joints"}
    assert parse_no_skip(["all"]) == frozenset()
    a = SceneAnalysis(parse_no_skip(["joints"]))
    a.record("joints", True, used=3)
    a.record("body-faces", True)
    assert a.report["joints"] == {"skipped_work": False, "overridden": True, "used": 3}
    assert a.report["body-faces"] == {"skipped_work": True, "overridden": False}


def test_active_joints_and_restricted_weights_sum_to_one():
    w = np.array([[0.7, 0.3, 0.0, 5e-5], [0.0, 0.5, 0.5, 0.0]], np.float32)
    act = active_joints(w, eps=1e-4)
    assert act.tolist() == [True, True, True, False]
    r = restrict_weights(w, act)
    assert r.shape == (2, 3) and np.allclose(r.sum(1), 1.0)
    assert np.allclose(r[1], [0.0, 0.5, 0.5])


def test_lbs_joint_skip_changes_nothing_measurable_and_is_reported():
    body = tiny_body(weight_falloff_m=0.01)  # negligible weights away from the tube's joints
    v, f = tube(16, 8)
    garment = Garment(v.astype(np.float32), f, name="tube")
    motion = _motion()
    d = LBSDeformer()
    skipped = d.deform(garment, body, motion)
    rep = d.scene["joints"]
    assert rep["skipped_work"] and rep["used"] < rep["joints"] == 24
    d.skips = parse_no_skip(["joints"])
    full = d.deform(garment, body, motion)
    assert d.scene["joints"]["overridden"] and not d.scene["joints"]["skipped_work"]
    # Dropped weight is below 1e-4 per joint: well under a millimetre on a metre-sized scene, even in wild poses.
    assert 0 < np.abs(skipped - full).max() < 5e-4


def test_interpolation_slack_naive():
    rng = np.random.default_rng(0)
    pts = np.cumsum(rng.normal(size=(9, 4, 3)) * 0.01, axis=0)
    frames = np.array([0, 3, 8])
    got = interpolation_slack_per_point(pts, frames)
    path = lambda a, b, n: sum(np.linalg.norm(pts[t + 1, n] - pts[t, n]) for t in range(a, b))  # noqa: E731
    for n in range(4):
        g = [path(0, 3, n), path(3, 8, n)]
        assert np.allclose(got[:, n], [0.5 * g[0], 0.5 * max(g), 0.5 * g[1]])


def test_faces_in_reach_contains_every_face_within_reach_naive():
    bv, bf = icosphere(2, radius=0.3)
    rng = np.random.default_rng(1)
    T = 3
    body = np.stack([bv + rng.normal(size=3) * 0.02 for _ in range(T)])
    garment = np.stack([bv[:40] * 1.2 + rng.normal(size=3) * 0.02 for _ in range(T)])
    reach = 0.05
    kept = set(faces_in_reach(body, bf, garment, reach).tolist())
    exact = set()
    for t in range(T):
        a, b, c = (body[t][bf[:, k]] for k in range(3))
        for p in garment[t]:
            closest = closest_point_on_triangles(np.broadcast_to(p, a.shape), a, b, c)[0]
            exact |= set(np.flatnonzero(np.linalg.norm(closest - p, axis=1) <= reach).tolist())
    assert exact <= kept  # conservative: nothing within reach is dropped
    assert 0 < len(kept) < len(bf)  # and the far side of the sphere is
    far = sorted(set(range(len(bf))) - kept)
    for t in range(T):  # every dropped face is further than reach from every garment point in every frame
        cen = body[t][bf[far]].mean(axis=1)
        assert np.linalg.norm(cen[:, None] - garment[t][None], axis=2).min() > reach


def test_faces_in_reach_widened_per_garment_point_naive():
    """A reach per garment point (the swing): a face is kept where it lies within the common reach plus that
    point's own of some garment point (naive: every face against every point); the grouping by similar reach only
    keeps more."""
    bv, bf = icosphere(2, radius=0.3)
    rng = np.random.default_rng(2)
    garment = (bv[:60] * 1.3 + rng.normal(size=(60, 3)) * 0.01)[None]
    more = rng.uniform(0.0, 0.2, 60)
    kept = set(faces_in_reach(bv[None], bf, garment, 0.02, more).tolist())
    a, b, c = (bv[bf[:, k]] for k in range(3))
    exact = set()
    for p, r in zip(garment[0], more):
        closest = closest_point_on_triangles(np.broadcast_to(p, a.shape), a, b, c)[0]
        exact |= set(np.flatnonzero(np.linalg.norm(closest - p, axis=1) <= 0.02 + r).tolist())
    assert exact <= kept and len(kept) < len(bf)
    plain = set(faces_in_reach(bv[None], bf, garment, 0.02).tolist())
    assert plain < kept  # the swing kept faces the common reach alone left out


def test_swing_reach_is_twice_the_distance_along_the_garment_from_where_it_rests_on_the_body():
    """A 1 m strip whose first 20 cm lie 1 cm off a body: those rest (ANCHOR_M), the rest can swing SWING_FACTOR
    times its distance along the strip from them; a strip resting nowhere can fall anywhere (inf)."""
    from core.scene import ANCHOR_M, SWING_FACTOR

    v, f = grid(20, 2, 1.0)  # vertices every 5 cm along x
    v[:, 1] *= 0.1
    strip = Garment(v.astype(np.float32), f)
    xs, ys = np.meshgrid(np.linspace(0.0, 0.2, 41), [0.0, 0.05, 0.1])
    body = np.stack([xs.ravel(), ys.ravel(), np.full(xs.size, -0.01)], axis=1)
    got = swing_reach(strip, v, body)
    resting = cKDTree(body).query(v)[0] <= ANCHOR_M
    assert np.all(v[resting, 0] <= 0.2 + 1e-9) and np.all(got[resting] == 0.0)
    np.testing.assert_allclose(got[~resting], SWING_FACTOR * (v[~resting, 0] - 0.2), atol=1e-9)
    assert np.all(np.isinf(swing_reach(strip, v + [0.0, 0.0, 0.5], body)))


def test_distant_parts_meet_on_a_folded_strip_only():
    v, f = grid(20, 2, 1.0)  # a 1 m x 0.1 m strip along x
    v[:, 1] *= 0.1
    strip = Garment(v.astype(np.float32), f)
    flat = v[None].astype(np.float32)
    assert not distant_parts_meet(strip, flat, 0.05)["meet"]
    # Folded in the middle: the two ends 3 cm apart, 1 m apart along the strip.
    folded = v.copy()
    right = folded[:, 0] > 0.5
    folded[right, 0] = 1.0 - folded[right, 0]
    folded[right, 2] = 0.03
    res = distant_parts_meet(strip, np.stack([v, folded]).astype(np.float32), 0.05)
    assert res["meet"] and res["frame"] == 1 and res["pairs"] > 0
    # Near the fold the halves are close but geodesically near too (within 10 cm): not enough alone.
    near_fold = np.abs(v[:, 0] - 0.5) < 0.04
    sub = Garment(v[near_fold].astype(np.float32), _faces_within(f, near_fold))
    assert not distant_parts_meet(sub, folded[near_fold][None].astype(np.float32), 0.05)["meet"]


def test_the_ground_is_the_motions_lowest_body_point_lowered_under_the_lead_in(monkeypatch):
    """analyse_collisions' ground: the lowest body point over the motion's frames (motion_from on); in a lead-in
    frame whose body reaches lower, that frame's lowest point; kept where the garment's LBS preview, lowered by
    its swing, comes within FLOOR_REACH_M of it, skipped above, and left out with floor=False. A garment that
    rests nowhere on the body keeps the ground and every body face (its cloth can fall anywhere)."""
    import core.scene
    from core.scene import FLOOR_REACH_M, analyse_collisions

    body = tiny_body()
    v, f = icosphere(2)
    body_faces = body.faces
    rest = body.v_template.astype(np.float64)
    # The lead-in (31 frames) rises from 30 cm below the motion's lowest frame; 1 cm steps, so that the slack
    # between frames (half a step) stays small.
    lead_in = 31
    lift = np.concatenate([np.linspace(-0.3, 0.0, lead_in), [0.0, 0.01, 0.02, 0.01]])
    body_points = np.stack([rest + [0.0, 0.0, dz] for dz in lift]).astype(np.float32)
    transforms = np.tile(np.eye(4, dtype=np.float32), (len(lift), body.n_joints, 1, 1))
    for t, dz in enumerate(lift):
        transforms[t, :, 2, 3] = dz
    weights = np.full((len(v), body.n_joints), 1.0 / body.n_joints, np.float32)
    lowest_body = rest[:, 2].min() + lift
    # A small ball floating inside the body: nothing of it rests on the body (5 cm from it at least)
    ball = (v * 0.05 + [0.0, 0.0, lowest_body[lead_in:].min() + 0.05 + 0.05]).astype(np.float32)
    loose = SceneAnalysis()
    got = analyse_collisions(loose, Garment(ball, f), body_points, body_faces, ball, weights, transforms, False,
                             motion_from=lead_in)
    assert got.floor_z is not None and got.body_faces is None and not loose.report["body-faces"]["skipped_work"]
    assert "rests within 3 cm" in loose.report["body-faces"]["reason"]
    for swing in (0.0, FLOOR_REACH_M):  # a swing of 10 cm lowers the ball's reach by it
        monkeypatch.setattr(core.scene, "swing_reach", lambda g, p, b: np.full(g.n_vertices, swing))
        _ground_at_each_gap(FLOOR_REACH_M, swing, v, f, lowest_body, lead_in, body_points, body_faces, weights,
                            transforms)
    off = SceneAnalysis()
    assert analyse_collisions(off, Garment(ball, f), body_points, body_faces, ball, weights, transforms, False,
                              floor=False, motion_from=lead_in).floor_z is None
    assert off.report["floor"] == {"skipped_work": False, "overridden": False, "reason": "floor none"}


def _ground_at_each_gap(reach, swing, v, f, lowest_body, lead_in, body_points, body_faces, weights, transforms):
    from core.scene import analyse_collisions

    for gap, kept in ((swing + 0.5 * reach, True), (swing + 2.0 * reach, False)):
        # A small ball whose lowest point is `gap` above the ground in the motion's lowest frame.
        ball = (v * 0.05 + [0.0, 0.0, lowest_body[lead_in:].min() + 0.05 + gap]).astype(np.float32)
        garment = Garment(ball, f)
        analysis = SceneAnalysis()
        got = analyse_collisions(analysis, garment, body_points, body_faces, ball, weights, transforms, False,
                                 motion_from=lead_in)
        ground = float(lowest_body[lead_in:].min())
        rec = analysis.report["floor"]
        assert rec["ground_z_m"] == pytest.approx(ground, abs=1e-6)
        assert rec["lowered_in_lead_in_m"] == pytest.approx(0.3, abs=1e-6)
        assert rec["skipped_work"] is (not kept)
        if kept:
            np.testing.assert_allclose(got.floor_z, np.minimum(lowest_body, ground), atol=1e-6)
        else:
            assert got.floor_z is None
        # The ball rides with the body, `gap` above the ground in every frame (the lead-in's lowered one too),
        # less the slack of half a 1 cm step.
        assert rec["garment_lowest_above_ground_m"] == pytest.approx(gap - swing - 0.005, abs=1e-4)


def _faces_within(f, keep):
    idx = -np.ones(len(keep), np.int64)
    idx[keep] = np.arange(keep.sum())
    g = idx[f]
    return g[(g >= 0).all(1)]


@pytest.mark.parametrize("n,loose,levels", [(50, 0.05, 0), (299, 0.05, 0), (300, 0.05, 1), (1499, 0.05, 1),
                                            (1500, 0.05, 2), (50000, 0.05, 2), (4000, 0.005, 1)])
def test_suggested_levels(n, loose, levels):
    assert suggested_levels(n, loose) == levels


def test_model_joint_skip_is_exact():
    from core.model import GarmentModel, body_distances, motion_features, shaped_rest, window_index
    from core.model_data import prepare_garment
    from tests.core.model_fixtures import TINY_CONFIG

    torch.manual_seed(0)
    body = tiny_body(min_weight=1e-2)  # sparse weights, as real bodies have (a few joints a vertex)
    v, f = tube(12, 6)
    g = prepare_garment(Garment(v, f), body, TINY_CONFIG).inputs
    model = GarmentModel(TINY_CONFIG).eval()
    mf = motion_features(body, _motion(T=6).poses, np.zeros((6, 3), np.float32), None, 30.0)
    fr = torch.arange(2, 6)
    win = window_index(fr, model.config.window)
    with torch.no_grad():
        fused = model.encode(g, body_distances(body, None))
        args = (fused, g, shaped_rest(g, body, None), mf.pose[win], mf.velocity[win], mf.transforms[fr])
        a = model.forward_frames(*args, skip_joints=True).verts
        b = model.forward_frames(*args, skip_joints=False).verts
    assert int((g.prior_weights > 0).any(0).sum()) < 24  # something is skipped
    assert torch.allclose(a, b, atol=1e-6)


def test_self_contact_first_frame_is_counted_in_the_motions_frames():
    """Where distant parts first meet is recorded as the motion's frame (it counted the simulator's lead-in frames
    before it: 11 meant the motion's frame 0), negative within the lead-in."""
    from core.scene import analyse_collisions

    v, f = grid(20, 2, 1.0)  # a 1 m x 0.1 m strip along x
    v[:, 1] *= 0.1
    strip = Garment(v.astype(np.float32), f)
    weights = np.zeros((len(v), 24), np.float32)
    right = v[:, 0] > 0.5
    weights[~right, 0], weights[right, 1] = 1.0, 1.0
    body = tiny_body()
    for lead_in, fold_at in ((3, 5), (3, 1)):
        T = 8
        transforms = np.tile(np.eye(4, dtype=np.float32), (T, 24, 1, 1))
        transforms[fold_at:, 1, :3, 3] = [-0.5, 0.0, 0.03]  # the right half over the left, 3 cm above it
        body_points = np.repeat((body.v_template + [0.0, 0.0, -5.0])[None], T, axis=0).astype(np.float32)
        analysis = SceneAnalysis()
        analyse_collisions(analysis, strip, body_points, body.faces, v, weights, transforms, True, motion_from=lead_in)
        assert analysis.report["self-contact"]["first_frame"] == fold_at - lead_in
