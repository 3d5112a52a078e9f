"""Penetration push-out: vertices inside or within the margin of the body end `margin` outside; others stay."""

import numpy as np

from core.geometry import TriangleMesh
from core.pushout import PushOutDeformer, push_out
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
