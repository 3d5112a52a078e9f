"""Path-integrated gradients of the model's deformation: quadrature, completeness, Riemann agreement, table."""

import numpy as np
import pytest
from core.attribution import (
    DeformationTarget,
    attribution_table,
    gauss_legendre_01,
    integrated_gradients,
    midpoint_01,
)
from core.errors import InputError
from core.garment import Garment
from core.model_data import prepare_garment
from core.motion import Motion, Y_UP_TO_Z_UP
from tests.core.model_fixtures import TINY_CONFIG, perturbed_model, tube
from tests.meshes import tiny_body


@pytest.fixture(scope="module")
def target(tmp_path_factory):
    body = tiny_body()
    v, f = tube(16, 8)
    garment = Garment(v, f, name="tube")
    model = perturbed_model(TINY_CONFIG, 0.2)  # away from the LBS-reproducing start, so f is not flat
    g = prepare_garment(garment, body, TINY_CONFIG, tmp_path_factory.mktemp("cache")).inputs
    T = 6
    poses = np.zeros((T, 24, 3), np.float32)
    poses[:, 0] = Y_UP_TO_Z_UP
    poses[:, 1, 0] = np.linspace(0, 0.8, T)
    poses[:, 16, 2] = np.linspace(0, -1.0, T)
    trans = np.stack([np.linspace(0, 0.2, T), np.zeros(T), np.zeros(T)], 1).astype(np.float32)
    motion = Motion(poses=poses, trans=trans, fps=30.0, betas=np.full(4, 0.5, np.float32), name="swing")
    return DeformationTarget(model, g, body, motion, frame=4)


def test_gauss_legendre_is_exact_for_polynomials_up_to_degree_2n_minus_1():
    x, w = gauss_legendre_01(5)
    assert np.isclose(w.sum(), 1.0) and np.all((x > 0) & (x < 1))
    for k in range(10):
        assert np.isclose((w * x**k).sum(), 1.0 / (k + 1)), k
    x, w = midpoint_01(4)
    np.testing.assert_allclose(x, [0.125, 0.375, 0.625, 0.875])


def test_completeness_and_gauss_legendre_matches_a_1000_step_riemann_sum(target):
    gl = integrated_gradients(target, target.input, target.baseline, steps=50)
    gap = gl.f_input - gl.f_baseline
    assert abs(gap) > 1e-3  # a non-trivial deformation to explain
    # Completeness: the attributions add up to f(x) - f(baseline) (stated tolerance: 0.5 % of the gap).
    assert gl.completeness_error <= 5e-3 * abs(gap), (gl.total, gap)
    riemann = integrated_gradients(target, target.input, target.baseline, steps=1000, rule="riemann")
    scale = max(float(b.abs().max()) for b in riemann.phi.as_tuple())
    for a, b in zip(gl.phi.as_tuple(), riemann.phi.as_tuple()):
        assert float((a - b).abs().max()) <= 1e-3 * scale  # every single attribution, against the largest
    assert abs(gl.total - riemann.total) <= 1e-3 * abs(gap)
    # Every input group takes part.
    assert all(float(p.abs().sum()) > 0 for p in gl.phi.as_tuple())


def test_region_and_table(target, tmp_path):
    top = np.flatnonzero(target.g.rest[:, 1].numpy() > 0.0)
    sub = DeformationTarget.__new__(DeformationTarget)
    sub.__dict__.update(target.__dict__, vertices=top)
    full = target.per_vertex(target.input).detach().numpy()
    assert np.isclose(float(sub(target.input)), full[top].mean())
    att = integrated_gradients(target, target.input, target.baseline, steps=8)
    rows = attribution_table(att, 24, TINY_CONFIG.window)
    names = [r[0] for r in rows]
    assert "rotation left_hip" in names and "body shape" in names and "garment features" in names
    assert len(names) == len(set(names)) == 23 + 2 + 24 + 1 + 2
    assert [abs(r[1]) for r in rows] == sorted((abs(r[1]) for r in rows), reverse=True)
    assert np.isclose(sum(r[1] for r in rows), att.total)


def test_bad_frame_and_vertices_are_refused(target):
    with pytest.raises(InputError, match="--frame"):
        DeformationTarget(target.model, target.g, tiny_body(), Motion(poses=np.zeros((2, 24, 3), np.float32),
                                                                       trans=np.zeros((2, 3), np.float32), fps=30.0),
                          frame=5)


def test_the_target_gives_the_network_the_shape_a_bake_gives_it(tmp_path):
    """Beyond the shapes a model was trained on a bake gives its network each coefficient within the trained range
    (`core.model_deform.within_trained`); the attribution explains that network: its body input and shape input
    are the clipped shape's, the garment's rest the body's own; within the range nothing changes."""
    import torch

    from core.model import body_distances, shaped_rest

    body = tiny_body()
    v, f = tube(16, 8)
    model = perturbed_model(TINY_CONFIG, 0.2)
    g = prepare_garment(Garment(v, f, name="tube"), body, TINY_CONFIG, tmp_path).inputs
    motion = Motion(poses=np.zeros((6, 24, 3), np.float32), trans=np.zeros((6, 3), np.float32), fps=30.0,
                    betas=np.float32([0.5, 0.5, 0.5, 0.5]), name="still")
    trained = (np.array([0.0, 0.0, 0.0, 0.0]), np.array([0.2, 0.5, 0.5, 0.5]))
    clipped = DeformationTarget(model, g, body, motion, 4, trained_betas=trained)
    seen = np.float32([0.21, 0.5, 0.5, 0.5])  # within TRAINED_BETAS_SLACK of the range
    torch.testing.assert_close(clipped.input.body, body_distances(body, seen).double())
    torch.testing.assert_close(clipped.shape_rest, shaped_rest(g, body, seen).double())
    torch.testing.assert_close(clipped.rest, shaped_rest(g, body, motion.betas).double())
    plain = DeformationTarget(model, g, body, motion, 4)
    assert plain.shape_rest is None and not torch.equal(plain.input.body, clipped.input.body)
    assert not torch.allclose(plain.verts(plain.input), clipped.verts(clipped.input))
    inside = DeformationTarget(model, g, body, motion, 4, trained_betas=(trained[0], trained[1] + 1))
    assert inside.shape_rest is None and torch.equal(inside.verts(inside.input), plain.verts(plain.input))
