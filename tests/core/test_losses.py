"""Each loss term of core/losses.py on a case with a known answer."""

import numpy as np
import pytest
import scipy.sparse as sp
import torch

from core import losses as L
from tests.meshes import grid, icosphere


def _grid(n=4, size=0.4):
    v, f = grid(n, n, size)
    return torch.tensor(v, dtype=torch.float32)[None], torch.tensor(f)


def test_vertex_loss_constant_offset():
    v, _ = _grid()
    assert L.vertex_loss(v + torch.tensor([0.01, 0.0, 0.0]), v).item() == pytest.approx(100 * 1e-4, rel=1e-4)


def test_edge_loss_uniform_scale_matches_naive():
    v, f = _grid()
    from core.garment import mesh_edges

    e = torch.tensor(mesh_edges(f.numpy()))
    got = L.edge_loss(1.1 * v, v, e).item()
    ln = np.linalg.norm(v[0, e[:, 0]].numpy() - v[0, e[:, 1]].numpy(), axis=1)
    assert got == pytest.approx(15 * np.mean((0.1 * ln) ** 2), rel=1e-4)


def test_normal_loss_zero_same_and_flipped_max():
    v, f = _grid()
    assert L.normal_loss(v, v, f).item() == pytest.approx(0.0, abs=1e-6)
    assert L.normal_loss(v, v, f[:, [0, 2, 1]]).item() == pytest.approx(0.0, abs=1e-6)
    flipped = v * torch.tensor([1.0, 1.0, -1.0]) + torch.tensor([0, 0, 0.0])
    mirror = v.clone()
    mirror[..., 1] = -mirror[..., 1]  # mirroring reverses every normal: cos = -1, loss 50 * 2
    assert L.normal_loss(mirror, v, f).item() == pytest.approx(100.0, rel=1e-5)
    assert L.normal_loss(flipped, v, f).item() == pytest.approx(0.0, abs=1e-5)  # z-flat grid: z flip changes nothing


def test_vertex_normals_match_numpy():
    from core.geometry import vertex_normals

    v, f = icosphere(1)
    got = L.vertex_normals(torch.tensor(v, dtype=torch.float32)[None], torch.tensor(f))[0].numpy()
    assert np.allclose(got, vertex_normals(v, f), atol=1e-5)


def test_penetration_plane_known_depth():
    # Body: a big square (two triangles) in z = 0, normal +z. Garment points at z = -0.01, 0.001, 0.05.
    bv = torch.tensor([[[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]]], dtype=torch.float32)
    bf = torch.tensor([[0, 1, 2], [0, 2, 3]])
    x = torch.tensor([[[0.1, 0.2, -0.01], [0.3, -0.2, 0.001], [0.0, 0.0, 0.05]]], requires_grad=True)
    loss = L.penetration_loss(x, bv, bf)
    expect = 1.5 * ((-0.01 - 0.002) ** 2 + (0.001 - 0.002) ** 2)
    assert loss.item() == pytest.approx(expect, rel=1e-4)
    loss.backward()
    assert x.grad[0, 0, 2] < 0 and x.grad[0, 2].abs().max() == 0  # pushes the inside point out (+z)


def test_penetration_sphere_inside_outside():
    v, f = icosphere(3)
    bv = torch.tensor(v, dtype=torch.float32)[None]
    pts = torch.tensor([[[0.0, 0.0, 0.5], [0.0, 0.0, 1.5]]])
    # Inside point: ~0.5 m deep: 1.5 * (0.5 + 0.002)^2 within the tessellation error.
    assert L.penetration_loss(pts, bv, torch.tensor(f)).item() == pytest.approx(1.5 * 0.502 ** 2, rel=0.02)


def test_self_collision_mask_and_value():
    # Two parallel grids 1 cm apart (geodesically far: different components), plus a near pair in one sheet.
    v, f = grid(2, 2, 0.04)  # 3x3 vertices, 2 cm spacing
    top = v + np.array([0, 0, 0.01])
    verts = np.concatenate([v, top])
    near = sp.csr_matrix((18, 18), dtype=bool)
    near = sp.block_diag([sp.csr_matrix(np.ones((9, 9), bool) & ~np.eye(9, dtype=bool))] * 2).tocsr().astype(bool)
    pairs = L.self_collision_pairs(verts, near)
    # Only the 9 vertical pairs (1 cm) across sheets; in-sheet pairs are geodesically near,
    # diagonal cross pairs (sqrt(2^2+1) cm > 2 cm) are too far.
    assert sorted(map(tuple, pairs)) == [(i, i + 9) for i in range(9)]
    x = torch.tensor(verts, dtype=torch.float32)[None]
    got = L.self_collision_loss(x, near).item()
    assert got == pytest.approx(2.0 * np.exp(-8 * (1.0 - 0.4)), rel=1e-4)  # d = 1 cm for every pair


def test_self_collision_zero_without_pairs():
    x = torch.zeros(1, 2, 3)
    x[0, 1, 0] = 0.5
    near = sp.csr_matrix((2, 2), dtype=bool)
    assert L.self_collision_loss(x, near).item() == 0.0


def test_gravity_known_energy():
    x = torch.tensor([[[0.0, 0.0, 1.0], [5.0, 3.0, 2.0]]])
    m = torch.tensor([1.0, 0.5])
    assert L.gravity_loss(x, m).item() == pytest.approx(0.1 * 9.8 * (1.0 + 1.0), rel=1e-6)


def test_vertex_masses_sum_to_area_density():
    v, f = grid(3, 3, 0.3)
    assert L.vertex_masses(v, f).sum() == pytest.approx(0.09 * L.DENSITY_KG_M2, rel=1e-5)


def _sheet():
    v, f = grid(3, 3, 0.3)
    dm, area = L.rest_uv_frame(v, f)
    return v, torch.tensor(f), torch.tensor(dm), torch.tensor(area)


def test_stretch_zero_at_rest_and_rigid_motion_and_known_scale():
    v, f, dm, a = _sheet()
    x = torch.tensor(v, dtype=torch.float32)[None]
    assert L.stretch_loss(x, f, dm, a).item() == pytest.approx(0.0, abs=1e-9)
    from scipy.spatial.transform import Rotation

    R = torch.tensor(Rotation.from_rotvec([0.3, -0.5, 1.0]).as_matrix(), dtype=torch.float32)
    assert L.stretch_loss(x @ R.T + 1.0, f, dm, a).item() == pytest.approx(0.0, abs=1e-8)
    # Uniform 10 % stretch: |w^u| = |w^v| = 1.1, Huber_0.05(0.1) = 0.05 * (0.1 - 0.025).
    expect = 5 * 0.09 * 2 * 0.05 * (0.1 - 0.025)
    assert L.stretch_loss(1.1 * x, f, dm, a).item() == pytest.approx(expect, rel=1e-3)


def test_shear_known_value_and_stretch_free():
    v, f, dm, a = _sheet()
    x = torch.tensor(v, dtype=torch.float32)[None]
    assert L.shear_loss(x, f, dm, a).item() == pytest.approx(0.0, abs=1e-10)
    uv = v[:, :2]
    dm2, a2 = L.rest_uv_frame(v, f.numpy(), uv, f.numpy())
    # Scaling along the UV axes does not shear.
    assert L.shear_loss(x * torch.tensor([1.2, 0.9, 1.0]), f, torch.tensor(dm2), a).item() == pytest.approx(0.0, abs=1e-8)
    # Simple shear x += g y with UVs aligned to x, y: w^u = (1,0,0), w^v = (g,1,0) -> dot = g.
    g = 0.2
    xs = x.clone()
    xs[..., 0] += g * x[..., 1]
    got = L.shear_loss(xs, f, torch.tensor(dm2), torch.tensor(a2)).item()
    assert got == pytest.approx(2 * 0.09 * g ** 2, rel=1e-4)


def test_deformation_gradient_matches_naive():
    v, f, dm, a = _sheet()
    rng = np.random.default_rng(0)
    x = v + rng.normal(scale=0.01, size=v.shape)
    wu, wv = L.deformation_gradients(torch.tensor(x, dtype=torch.float32)[None], f, dm)
    for i in range(0, len(f), 5):
        i0, i1, i2 = f[i].tolist()
        D = np.stack([x[i1] - x[i0], x[i2] - x[i0]], 1)
        W = D @ dm[i].numpy()
        assert np.allclose(W[:, 0], wu[0, i].numpy(), atol=1e-5) and np.allclose(W[:, 1], wv[0, i].numpy(), atol=1e-5)
