"""Pose-space deformation fitted to simulations (core.psd, formats.psd)."""

import dataclasses

import numpy as np
import pytest
import torch

from core.body import skin_points
from core.deform import LBSDeformer, LBSOptions
from core.errors import InputError
from core.garment import Garment
from core.motion import Motion
from core.psd import PSDDeformer, fit_psd, pose_features, ridge_solve
from core.skinning import bind_garment, shaped_garment
from formats.psd import load_fit, save_fit
from tests.core.model_fixtures import tube
from tests.meshes import tiny_body


def _motion(seed: int, T: int = 24) -> Motion:
    rng = np.random.default_rng(seed)
    t = np.arange(T)[:, None] / 30.0
    poses = np.zeros((T, 24, 3), np.float32)
    poses[:, 1:] = 0.3 * np.sin(2 * np.pi * (0.5 + rng.uniform(size=(1, 23, 3))) * t[:, :, None]
                                + rng.uniform(0, 6, size=(1, 23, 3)))
    poses[:, 22:] = 0.0  # an SMPL body's hands: read at rest (core.motion.poses_for_body)
    trans = np.c_[0.4 * t[:, 0], np.zeros(T), 0.05 * np.sin(3 * t[:, 0])].astype(np.float32)
    return Motion(poses=poses, trans=trans, fps=30.0, betas=rng.uniform(-1, 1, 4).astype(np.float32),
                  name=f"m{seed}")


def _skinned(garment, body, motion, offsets):
    """Positions of `garment` skinned (the LBS method's binding) from its rest shape plus `offsets` (T, V, 3)."""
    binding = bind_garment(garment, body, 10, 0.5)
    rest = shaped_garment(garment.vertices, binding, body.fit_betas(motion.betas))
    A = body.skinning_transforms(motion.poses, motion.trans, motion.betas)
    return skin_points(torch.from_numpy((rest + offsets).astype(np.float32)), torch.from_numpy(binding.weights),
                       torch.from_numpy(A)).numpy()


def test_pose_features_at_rest_are_the_shape_and_one():
    X = pose_features(np.zeros((3, 24, 3)), np.zeros((3, 3)), np.array([1.0, -2.0]), 30.0)
    assert X.shape == (3, 24 * 9 * 2 + 6 + 2 + 1)
    np.testing.assert_allclose(X[:, -3:], [[0.3, -0.6, 1.0]] * 3)
    assert not X[:, :-3].any()


def test_pose_features_and_ridge():
    T, J, fps = 4, 3, 30.0
    poses = np.zeros((T, J, 3))
    poses[:, 0, 2] = np.pi / 2  # root turned 90 degrees about Z
    poses[:, 1, 0] = np.linspace(0.0, 0.3, T)  # joint 1 bends at 3 rad/s about X (0.1 rad a frame)
    trans = np.zeros((T, 3))
    trans[:, 0] = np.arange(T) / fps  # 1 m/s along world X
    betas = np.array([1.0, -2.0])
    X = pose_features(poses, trans, betas, fps)
    assert X.shape == (T, 9 * J * 2 + 6 + 2 + 1)
    pose, rate = X[:, :9 * J].reshape(T, J, 3, 3), X[:, 9 * J:18 * J].reshape(T, J, 3, 3)
    assert np.allclose(pose[:, 2], 0.0) and np.allclose(pose[0, 1], 0.0)
    c, s = np.cos(0.2), np.sin(0.2)  # frame 2: 0.2 rad about X
    assert np.allclose(pose[2, 1] + np.eye(3), [[1, 0, 0], [0, c, -s], [0, s, c]])
    # d/dt (R - I) at angle a about X is 3 rad/s times [[0,0,0],[0,-sin,-cos],[0,cos,-sin]]; x0.1 scale, central difference
    a = 0.1
    assert np.allclose(rate[1, 1] / 0.1, 3.0 * np.array([[0, 0, 0], [0, -np.sin(a), -np.cos(a)], [0, np.cos(a), -np.sin(a)]]),
                       atol=0.05)
    # world +X seen from a root turned +90 degrees about Z is its -Y; no acceleration
    assert np.allclose(X[:, 18 * J:18 * J + 3] / 0.3, [0.0, -1.0, 0.0], atol=1e-9)
    assert np.allclose(X[:, 18 * J + 3:18 * J + 6], 0.0, atol=1e-9)
    assert np.allclose(X[:, -3:-1] / 0.3, betas) and np.all(X[:, -1] == 1.0)
    rng = np.random.default_rng(0)
    A, Y = rng.normal(size=(20, 4)), rng.normal(size=(20, 3))
    lam = 0.5  # the closed form against least squares on the stacked system [A; sqrt(lam) I]
    stacked = np.linalg.lstsq(np.r_[A, np.sqrt(lam) * np.eye(4)], np.r_[Y, np.zeros((4, 3))], rcond=None)[0]
    np.testing.assert_allclose(ridge_solve(A, Y, lam), stacked, atol=1e-10)


def test_fit_recovers_blend_shapes_linear_in_the_features():
    """Simulations whose rest-frame offsets are a rank-4 linear function of the joints' rotations are reproduced
    by the fit to a micrometre on the six motions it was fitted to and within 0.1 mm on a seventh (LBS: over
    5 mm)."""
    body = tiny_body()
    v, f = tube(12, 6)
    garment = Garment(v, f)
    rng = np.random.default_rng(0)
    motions = [_motion(s, T=200) for s in range(7)]
    F = pose_features(motions[0].poses, motions[0].trans, body.fit_betas(motions[0].betas), 30.0).shape[1]
    W = 0.002 * rng.normal(size=(F, 4)) @ rng.normal(size=(4, garment.n_vertices * 3))
    W[24 * 9:] = 0.0  # the joints' R - I only

    def simulated(m):
        X = pose_features(m.poses, m.trans, body.fit_betas(m.betas), m.fps)
        return _skinned(garment, body, m, (X @ W).reshape(m.n_frames, -1, 3))

    fit = fit_psd(garment, body, [(m, simulated(m)) for m in motions[:6]], rank=8, ridge=1e-9)
    assert fit.meta["sequences"] == 6 and fit.meta["frames"] == 1200 and fit.meta["fit_residual_mm"] < 0.01
    psd = PSDDeformer(fit, contact_guard=False, strain_limit=None)  # the fit alone
    assert np.abs(psd.deform(garment, body, motions[1]) - simulated(motions[1])).max() < 1e-5
    truth = simulated(motions[6])
    error = {name: np.linalg.norm(d.deform(garment, body, motions[6]) - truth, axis=-1).mean()
             for name, d in (("psd", psd), ("lbs", LBSDeformer()))}
    assert error["lbs"] > 5e-3 and error["psd"] < 1e-4


def test_a_fit_round_trips_and_belongs_to_its_garment_and_body(tmp_path):
    body = tiny_body()
    v, f = tube(12, 6)
    garment = Garment(v, f)
    m = _motion(1)
    fit = fit_psd(garment, body, [(m, _skinned(garment, body, m, np.zeros((m.n_frames, len(v), 3))))], rank=4)
    back = load_fit(save_fit(tmp_path / "g.psd.npz", fit))
    for k in ("mean", "basis", "weights"):
        np.testing.assert_array_equal(getattr(back, k), getattr(fit, k))
    assert (back.garment_sha256, back.n_joints, back.meta) == (fit.garment_sha256, fit.n_joints, fit.meta)
    np.testing.assert_allclose(PSDDeformer(back, contact_guard=False).deform(garment, body, m),
                               # the offsets are zero: LBS as psd binds it (10 passes, not the legs' spread)
                               LBSDeformer(LBSOptions(leg_spread_m=None)).deform(garment, body, m), atol=1e-5)
    other = Garment(*tube(10, 5))
    with pytest.raises(InputError, match="fitted to another garment"):
        PSDDeformer(back).prepare(other, body, source="other.obj")
    # The same garment through a unit round trip (float rounding) and with its faces starting at another corner
    # (an export's): its fit; moved by 0.1 mm, or with a face turned over, another garment.
    rng = np.random.default_rng(0)
    nudged = (v + rng.uniform(-1e-7, 1e-7, v.shape)).astype(np.float32)
    turned = np.roll(f, 1, axis=1)
    assert back.garment_vertices is not None and Garment(nudged, turned).content_hash() != fit.garment_sha256
    PSDDeformer(back).prepare(Garment(nudged, turned), body)
    flipped = f.copy()
    flipped[0] = flipped[0, ::-1]
    for changed in (Garment(v + np.float32(1e-4), f), Garment(v, flipped)):
        with pytest.raises(InputError, match="fitted to another garment"):
            PSDDeformer(back).prepare(changed, body)
    with pytest.raises(InputError, match="fitted to another garment"):  # a fit written before: the bytes alone
        PSDDeformer(dataclasses.replace(back, garment_vertices=None)).prepare(Garment(nudged, turned), body)
    # another body of the same joints and betas (its shape basis reversed), refused as the README says; the same
    # body read again (another object, the same arrays) is the body it was fitted on
    assert back.body_sha256 == body.content_hash() == tiny_body().content_hash()
    PSDDeformer(back).prepare(garment, tiny_body())
    reshaped = dataclasses.replace(body, shapedirs=body.shapedirs[..., ::-1].copy())
    with pytest.raises(InputError, match="fitted on body 'tiny' .*, got another body 'tiny' .* of its joints and "
                                         "betas: fit it on this body's simulations"):
        PSDDeformer(back).prepare(garment, reshaped)
    PSDDeformer(dataclasses.replace(back, body_sha256=None)).prepare(garment, reshaped)  # a fit from before: as then
    (tmp_path / "junk.npz").write_bytes(b"junk")
    with pytest.raises(InputError, match="junk.npz': cannot be read"):
        load_fit(tmp_path / "junk.npz")
    torch.save({"model": {}}, tmp_path / "model.pt")
    with pytest.raises(InputError, match="got a torch checkpoint \\(a model\\? bake it with --method model --model"):
        load_fit(tmp_path / "model.pt")
    np.savez(tmp_path / "motion.npz", poses=np.zeros((2, 72)))
    with pytest.raises(InputError, match="expected a fit written by `garment fit`"):
        load_fit(tmp_path / "motion.npz")


def test_the_contact_guard_lifts_what_the_offsets_carry_into_the_body():
    """Offsets that carry every vertex of a tube 1 cm into the body it hangs around (past its closest face) put
    it inside; the contact guard (on by default, as the model's) lifts those vertices back out and leaves the
    fit's result elsewhere untouched."""
    import dataclasses

    from core.geometry import TriangleMesh, points_inside_mesh

    body = tiny_body()
    v, f = tube(12, 6)
    garment = Garment(v, f)
    still = Motion(poses=np.zeros((4, 24, 3), np.float32), trans=np.zeros((4, 3), np.float32), fps=30.0)
    fit = fit_psd(garment, body, [(still, _skinned(garment, body, still, np.zeros((4, len(v), 3))))], rank=2)
    closest = TriangleMesh(body.v_template, body.faces).closest(v.astype(np.float64)).closest
    gap = closest - v
    sink = gap * (1.0 + 0.01 / np.linalg.norm(gap, axis=1, keepdims=True))
    sink[v[:, 1] > 0.0] = 0.0  # the tube's top ring stays where it is
    fit = dataclasses.replace(fit, mean=sink.reshape(-1).astype(np.float32))
    raw = PSDDeformer(fit, contact_guard=False).deform(garment, body, still)
    psd = PSDDeformer(fit)
    guarded = psd.deform(garment, body, still)
    inside = [points_inside_mesh(p[0], body.v_template, body.faces).mean() for p in (raw, guarded)]
    assert inside[0] > 0.5 and inside[1] < 0.05, inside
    top = v[:, 1] > 0.0
    np.testing.assert_allclose(guarded[:, top], raw[:, top], atol=1e-6)
    assert psd.report["contact_guard"]["vertices_moved_per_frame_mean"] > 0.5 * (~top).sum()
