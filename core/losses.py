"""Loss terms of the hybrid training (paper section 4), one function per term.

Every function takes garment vertices `verts (B, V, 3)` float32, metres, in the
Z-up world, and returns a scalar tensor already multiplied by its paper weight:
phase 1 (supervised): vertex L2 x100, edge L2 x15, normal cosine x50;
phase 2: penetration (Eq. 5, k_c 1.5), self-collision (Eq. 6, k_sc 2);
phase 3: gravity (Eq. 7, k_g 0.1), stretch (Eq. 8, k_s 5), shear (Eq. 9, k_h 2).
Sums over vertices/faces follow the paper's equations; frames are averaged.
Searches (closest body face, close vertex pairs) run without gradients in
numpy/scipy; the distances that enter the losses are recomputed in torch.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import torch
import torch.nn.functional as F
from scipy.spatial import cKDTree

from core.geodesic import far_by_neighbourhood
from core.geometry import TriangleMesh

#: Penetration threshold epsilon of Eq. 5: vertices closer than 2 mm to the body (HOOD's collision epsilon).
PENETRATION_EPS_M = 0.002
#: Eq. 6 mask (b): pairs closer than this in the deformed frame, metres.
SELF_COLLISION_EUCLIDEAN_M = 0.02
#: Eq. 6 reads lambda_a, lambda_b with distances in centimetres: in metres exp(-8 (d - 0.4)) would be
#: flat over the 2 cm mask (no repulsion profile); in cm it decays from e^3.2 at contact to ~0 at 2 cm.
SELF_COLLISION_UNIT_M = 0.01
#: Area density of the fabric (HOOD's default), kg/m^2, for the vertex masses of Eq. 7.
DENSITY_KG_M2 = 0.20022
GRAVITY_M_S2 = (0.0, 0.0, -9.8)


def vertex_loss(pred: torch.Tensor, target: torch.Tensor, weight: float = 100.0) -> torch.Tensor:
    """weight * mean over frames and vertices of |pred - target|^2 (m^2). pred, target: (B, V, 3)."""
    return weight * ((pred - target) ** 2).sum(-1).mean()


def edge_lengths(verts: torch.Tensor, edges: torch.Tensor) -> torch.Tensor:
    """(B, E) metres. verts: (B, V, 3); edges: (E, 2) int64."""
    return (verts[:, edges[:, 0]] - verts[:, edges[:, 1]]).norm(dim=-1)


def edge_loss(pred: torch.Tensor, target: torch.Tensor, edges: torch.Tensor, weight: float = 15.0) -> torch.Tensor:
    """weight * mean over frames and edges of (l - l_gt)^2 (m^2)."""
    return weight * ((edge_lengths(pred, edges) - edge_lengths(target, edges)) ** 2).mean()


def vertex_normals(verts: torch.Tensor, faces: torch.Tensor) -> torch.Tensor:
    """Area-weighted unit vertex normals (B, V, 3) of verts (B, V, 3), faces (F, 3) int64 (differentiable)."""
    tri = verts[:, faces]  # (B, F, 3, 3)
    fn = torch.linalg.cross(tri[:, :, 1] - tri[:, :, 0], tri[:, :, 2] - tri[:, :, 0], dim=-1)
    n = torch.zeros_like(verts)
    for k in range(3):
        n = n.index_add(1, faces[:, k], fn)
    return F.normalize(n, dim=-1, eps=1e-12)


def normal_loss(pred: torch.Tensor, target: torch.Tensor, faces: torch.Tensor, weight: float = 50.0) -> torch.Tensor:
    """weight * mean over frames and vertices of 1 - cos(n, n_gt) (cosine similarity of vertex normals)."""
    cos = (vertex_normals(pred, faces) * vertex_normals(target, faces)).sum(-1)
    return weight * (1.0 - cos).mean()


def closest_body_faces(verts: np.ndarray, body_verts: np.ndarray, body_faces: np.ndarray) -> np.ndarray:
    """Index of the closest body face of every garment vertex: (B, V) int64 (no gradient).

    verts: (B, V, 3); body_verts: (B, N_b, 3); body_faces: (F_b, 3).
    """
    out = np.empty(verts.shape[:2], dtype=np.int64)
    for b in range(verts.shape[0]):
        out[b] = TriangleMesh(body_verts[b], body_faces).closest(verts[b], exact=False).face_index
    return out


def penetration_loss(verts: torch.Tensor, body_verts: torch.Tensor, body_faces: torch.Tensor,
                     k_c: float = 1.5, eps: float = PENETRATION_EPS_M,
                     face_index: np.ndarray | None = None) -> torch.Tensor:
    """Eq. 5: k_c * sum_i min(l_i - eps, 0)^2, mean over frames.

    l_i is the signed distance (metres, negative inside) of vertex i to the plane of its closest body face,
    whose outward normal comes from the body's face winding. body_verts: (B, N_b, 3) posed body,
    body_faces: (F_b, 3) int64. face_index: (B, V) precomputed closest faces, else searched here.
    """
    if face_index is None:
        face_index = closest_body_faces(verts.detach().cpu().numpy(), body_verts.detach().cpu().numpy(),
                                        body_faces.cpu().numpy())
    fi = torch.as_tensor(face_index, dtype=torch.long, device=verts.device)
    tri = body_verts[:, body_faces.to(verts.device)]  # (B, F, 3, 3)
    n = F.normalize(torch.linalg.cross(tri[:, :, 1] - tri[:, :, 0], tri[:, :, 2] - tri[:, :, 0], dim=-1), dim=-1)
    b = torch.arange(verts.shape[0], device=verts.device)[:, None]
    d = ((verts - tri[b, fi, 0]) * n[b, fi]).sum(-1)  # (B, V)
    return k_c * (torch.clamp(d - eps, max=0.0) ** 2).sum(-1).mean()


def self_collision_pairs(verts: np.ndarray, near: sp.csr_matrix,
                         radius: float = SELF_COLLISION_EUCLIDEAN_M) -> np.ndarray:
    """The mask C of Eq. 6 for one frame as pairs (P, 2) int64, i < j.

    verts: (V, 3) metres. near: (V, V) sparse pattern of pairs within 10 cm along the rest surface
    (`Preprocessed.collision_near`). A pair is kept when closer than `radius` now and not in `near`.
    """
    pairs = cKDTree(np.asarray(verts, dtype=np.float64)).query_pairs(radius, output_type="ndarray").astype(np.int64)
    if len(pairs) == 0:
        return pairs.reshape(0, 2)
    pairs = pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]
    return pairs[far_by_neighbourhood(near, pairs)]


def self_collision_loss(verts: torch.Tensor, near: sp.csr_matrix, k_sc: float = 2.0, lambda_a: float = 8.0,
                        lambda_b: float = 0.4, radius: float = SELF_COLLISION_EUCLIDEAN_M,
                        unit_m: float = SELF_COLLISION_UNIT_M, pairs: list | None = None) -> torch.Tensor:
    """Eq. 6: k_sc / sum C * sum C_ij exp(-lambda_a (|v_i - v_j| - lambda_b)), mean over frames.

    Distances are divided by `unit_m` (centimetres by default, see SELF_COLLISION_UNIT_M). A frame with
    no masked pair contributes 0. pairs: per-frame (P, 2) masks, else found by `self_collision_pairs`.
    """
    total = verts.new_zeros(())
    for b in range(verts.shape[0]):
        p = pairs[b] if pairs is not None else self_collision_pairs(verts[b].detach().cpu().numpy(), near, radius)
        if len(p) == 0:
            continue
        p = torch.as_tensor(p, dtype=torch.long, device=verts.device)
        d = (verts[b, p[:, 0]] - verts[b, p[:, 1]]).norm(dim=-1) / unit_m
        total = total + k_sc * torch.exp(-lambda_a * (d - lambda_b)).mean()
    return total / verts.shape[0]


def vertex_masses(rest: np.ndarray, faces: np.ndarray, density_kg_m2: float = DENSITY_KG_M2) -> np.ndarray:
    """Lumped masses (V,) float32 kg: a third of each incident rest triangle's area times the density."""
    rest = np.asarray(rest, dtype=np.float64)
    tri = rest[faces]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    m = np.zeros(len(rest))
    for k in range(3):
        np.add.at(m, faces[:, k], area / 3.0)
    return (m * density_kg_m2).astype(np.float32)


def gravity_loss(verts: torch.Tensor, masses: torch.Tensor, k_g: float = 0.1,
                 g: tuple = GRAVITY_M_S2) -> torch.Tensor:
    """Eq. 7: -k_g sum_i m_i v_i . g (potential energy, J), mean over frames. masses: (V,) kg."""
    gv = torch.as_tensor(g, dtype=verts.dtype, device=verts.device)
    return -k_g * ((verts @ gv) * masses[None]).sum(-1).mean()


def rest_uv_frame(rest: np.ndarray, faces: np.ndarray, uvs: np.ndarray | None = None,
                  face_uvs: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The fixed (u, v) plane of Eq. 10 per rest triangle: Dm^-1 (F, 2, 2) float32 and area (F,) float32 m^2.

    Each rest triangle is laid flat in its own orthonormal 2D frame (metric: rest edges keep their
    lengths, so b = 1 is the rest state). With UVs, that frame is rotated so u follows the direction in
    which the texture u grows (warp/weft directions); triangles with degenerate UVs keep their own frame.
    """
    x = np.asarray(rest, dtype=np.float64)[faces]
    e1, e2 = x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]
    l1 = np.maximum(np.linalg.norm(e1, axis=1), 1e-12)
    t = e1 / l1[:, None]
    n = np.cross(e1, e2)
    area = 0.5 * np.linalg.norm(n, axis=1)
    n /= np.maximum(2 * area, 1e-20)[:, None]
    bvec = np.cross(n, t)
    P = np.stack([np.stack([l1, np.zeros_like(l1)], 1), np.stack([(e2 * t).sum(1), (e2 * bvec).sum(1)], 1)], 2)
    # P: (F, 2, 2), columns are the rest edges in the 2D frame.
    if uvs is not None and face_uvs is not None:
        uv = np.asarray(uvs, dtype=np.float64)[face_uvs]
        E = np.stack([uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]], 2)  # (F, 2, 2) uv edges as columns
        det = np.linalg.det(E)
        ok = np.abs(det) > 1e-12
        Fm = np.zeros_like(P)
        Fm[ok] = P[ok] @ np.linalg.inv(E[ok])  # maps uv -> rest 2D
        du = Fm[:, :, 0]
        ang = np.arctan2(du[:, 1], du[:, 0])
        c, s = np.cos(-ang), np.sin(-ang)
        R = np.stack([np.stack([c, -s], 1), np.stack([s, c], 1)], 1)
        P = np.where(ok[:, None, None] & (np.linalg.norm(du, axis=1) > 1e-12)[:, None, None], R @ P, P)
    det = np.linalg.det(P)
    Pinv = np.zeros_like(P)
    good = np.abs(det) > 1e-20
    Pinv[good] = np.linalg.inv(P[good])
    return Pinv.astype(np.float32), area.astype(np.float32)


def deformation_gradients(verts: torch.Tensor, faces: torch.Tensor, dm_inv: torch.Tensor):
    """Eq. 10: (w^u, w^v) = (dx1 dx2) Dm^-1, each (B, F, 3). dm_inv: (F, 2, 2) from `rest_uv_frame`."""
    x = verts[:, faces]
    D = torch.stack([x[:, :, 1] - x[:, :, 0], x[:, :, 2] - x[:, :, 0]], dim=-1)  # (B, F, 3, 2)
    W = D @ dm_inv[None]
    return W[..., 0], W[..., 1]


def stretch_loss(verts: torch.Tensor, faces: torch.Tensor, dm_inv: torch.Tensor, area: torch.Tensor,
                 k_s: float = 5.0, delta: float = 0.05, b_u: float = 1.0, b_v: float = 1.0) -> torch.Tensor:
    """Eq. 8: k_s sum_i a_i (L_delta(|w^u| - b^u) + L_delta(|w^v| - b^v)), Huber delta 0.05, mean over frames."""
    wu, wv = deformation_gradients(verts, faces, dm_inv)
    hu = F.huber_loss(wu.norm(dim=-1) - b_u, torch.zeros_like(wu[..., 0]), reduction="none", delta=delta)
    hv = F.huber_loss(wv.norm(dim=-1) - b_v, torch.zeros_like(wv[..., 0]), reduction="none", delta=delta)
    return k_s * ((hu + hv) * area[None]).sum(-1).mean()


def shear_loss(verts: torch.Tensor, faces: torch.Tensor, dm_inv: torch.Tensor, area: torch.Tensor,
               k_h: float = 2.0) -> torch.Tensor:
    """Eq. 9 as an energy: k_h sum_i a_i (w^u . w^v)^2, mean over frames.

    The paper writes the condition a w^u.w^v; squared (Baraff-Witkin) it is bounded below and zero at rest.
    """
    wu, wv = deformation_gradients(verts, faces, dm_inv)
    return k_h * (((wu * wv).sum(-1) ** 2) * area[None]).sum(-1).mean()
