"""Binding a garment to a body: skinning weights and shape offsets transferred from the body surface.

Each garment vertex takes the barycentric blend of the skinning weights (and
shape blend shapes) of the nearest point on the body's rest surface; weights
can then be smoothed over the garment's edge graph so loose parts (a skirt
between the legs) do not tear between neighbouring joints.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from core.body import Body
from core.errors import InputError
from core.garment import Garment, mesh_edges
from core.geometry import TriangleMesh

#: A garment whose median distance to the rest body exceeds this is not authored on it.
MAX_MEDIAN_BODY_DISTANCE_M = 0.25


@dataclass(frozen=True, eq=False)
class GarmentBinding:
    """How a garment follows a body.

    weights: (V, J) float32, rows sum to 1.
    shapedirs: (V, 3, S) float32, metres per unit beta (garment moves with the body's shape).
    body_distance: (V,) float32, metres from each vertex to the rest body surface.
    """

    weights: np.ndarray
    shapedirs: np.ndarray
    body_distance: np.ndarray


def bind_garment(garment: Garment, body: Body, smooth_iterations: int = 0, smooth_strength: float = 0.5,
                 source: str | None = None) -> GarmentBinding:
    """Transfer skinning weights and shape blend shapes from the nearest body face.

    smooth_iterations: passes of neighbour averaging of the weights over the
    garment graph (x <- (1-s) x + s mean(neighbours)); 0 keeps the raw transfer.
    Raises InputError when the garment is not near the body's rest surface.
    """
    mesh = TriangleMesh(body.v_template, body.faces)
    hit = mesh.closest(garment.vertices)
    median = float(np.median(hit.distance))
    if median > MAX_MEDIAN_BODY_DISTANCE_M:
        name = source or garment.name
        raise InputError(
            f"garment mesh '{name}': expected a garment authored on the body's rest pose (Y-up, T-pose, within "
            f"{MAX_MEDIAN_BODY_DISTANCE_M * 100:.0f} cm of its surface), got a median distance of {median:.2f} m")
    corners = body.faces[hit.face_index]  # (V, 3)
    b = hit.barycentric.astype(np.float32)[..., None]  # (V, 3, 1)
    weights = np.einsum("vk,vkj->vj", hit.barycentric, body.weights[corners]).astype(np.float32)
    shapedirs = np.einsum("vk,vkcs->vcs", b[..., 0], body.shapedirs[corners]).astype(np.float32)
    if smooth_iterations > 0:
        weights = smooth_over_graph(weights, garment.faces, smooth_iterations, smooth_strength)
    weights /= np.maximum(weights.sum(axis=1, keepdims=True), 1e-12)
    return GarmentBinding(weights=weights, shapedirs=shapedirs, body_distance=hit.distance.astype(np.float32))


def shaped_garment(vertices: np.ndarray, binding: GarmentBinding, betas: np.ndarray) -> np.ndarray:
    """The garment's rest vertices (V, 3) moved with the body's shape: betas (S,) as `Body.fit_betas` gives them."""
    return vertices + np.einsum("vcs,s->vc", binding.shapedirs, betas)


def smooth_over_graph(values: np.ndarray, faces: np.ndarray, iterations: int, strength: float = 0.5) -> np.ndarray:
    """Uniform-Laplacian smoothing of per-vertex values over the mesh edge graph.

    values: (V, C); faces: (F, 3). Each pass: x <- (1 - strength) x + strength * mean of neighbours.
    Isolated vertices keep their values. Returns (V, C) of the input dtype.
    """
    V = values.shape[0]
    e = mesh_edges(faces)
    adj = sp.coo_matrix((np.ones(2 * len(e)), (np.r_[e[:, 0], e[:, 1]], np.r_[e[:, 1], e[:, 0]])), shape=(V, V)).tocsr()
    deg = np.asarray(adj.sum(axis=1)).ravel()
    has = deg > 0
    mean_op = sp.diags(np.where(has, 1.0 / np.maximum(deg, 1), 0.0)) @ adj
    x = values.astype(np.float64)
    for _ in range(iterations):
        x = np.where(has[:, None], (1 - strength) * x + strength * (mean_op @ x), x)
    return x.astype(values.dtype)
