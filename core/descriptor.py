"""The garment style descriptor of paper section 3.2.1: Nystrom eigenvalues of the geodesic affinity.

The affinity G_ij = exp(-d_ij^2 / (2 sigma^2)) of rest-surface geodesic
distances d (metres, `core.geodesic`) is approximated with N* landmarks
(Nystrom): G ~ C W^+ C^T with C = G[:, L] (V x N*) and W = G[L, L]. Its
non-zero eigenvalues are those of the N* x N* matrix
    G_nys = W^{+1/2} C^T A C W^{+1/2},
where A = diag(vertex area) / total area turns sums over vertices into
integrals over the surface: the eigenvalues then approximate those of the
integral operator (K f)(x) = (1 / area) * integral of k(x, y) f(y) dA(y), the same for
any mesh of the same surface (resolution-independent); they sum to about 1 (the
trace of G A). The geodesic Gaussian is not positive definite, so eigenvalues of
W below 1e-3 of its largest are dropped: smaller ones only add noise that
depends on the sampling.
The leading `n_eigenvalues` form the fixed-length descriptor.

Landmarks are chosen by geodesic farthest-point sampling from a vertex picked
by geometry (the extreme vertex along a direction fixed by `seed`), ties broken
by position, so the descriptor does not depend on vertex order and is
deterministic. Cost: N* Dijkstra searches, O(N* E log V) time, O(N* V) memory.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from core.geodesic import geodesic_distances_from
from core.geometry import vertex_areas
from core.graph import lexicographic_rank

log = logging.getLogger(__name__)

DEFAULT_LANDMARKS = 64
DEFAULT_EIGENVALUES = 16
DEFAULT_SIGMA_M = 0.3
#: Landmark scores (metres: along the start direction, then geodesic) within this of the best count as tied,
#: the tie going to the lexicographically smallest position: a garment's coordinates carry float32 rounding
#: (6e-8 m at a metre) and unit round trips (3e-8 m); with ties within 1e-9 relative, a 1e-7 m nudge of the
#: example dress (its hem flat) changed its first landmark and so all 64, and the network's output by 0.42 mm.
LANDMARK_TIE_M = 1e-5


@dataclass(frozen=True, eq=False)
class StyleDescriptor:
    """Nystrom style descriptor of one garment.

    eigenvalues: (n_eigenvalues,) float64, descending, >= 0, zero-padded when fewer landmarks exist.
    landmarks: (N,) int64 vertex indices in selection order (N = min(N*, V)).
    nystrom: (N, N) float64, the matrix G_nys whose eigenvalues these are.
    """

    eigenvalues: np.ndarray
    landmarks: np.ndarray
    nystrom: np.ndarray


def _start_direction(seed: int) -> np.ndarray:
    """Unit direction for the first landmark: -Y (the hem side) for seed 0, random from `seed` otherwise."""
    if seed == 0:
        return np.array([0.0, -1.0, 0.0])
    d = np.random.default_rng(seed).normal(size=3)
    return d / np.linalg.norm(d)


def farthest_point_landmarks(vertices: np.ndarray, graph: sp.csr_matrix, n: int, seed: int = 0,
                             tie: float = LANDMARK_TIE_M) -> tuple[np.ndarray, np.ndarray]:
    """Geodesic farthest-point sampling of `n` landmarks.

    vertices: (V, 3) metres; graph: `core.geodesic.geodesic_graph`. The first
    landmark is the vertex farthest along `_start_direction(seed)`; each next one
    maximises the geodesic distance to those chosen (unreachable counts as
    farthest, so every connected component gets landmarks). Near-ties (within
    `tie` metres) go to the lexicographically smallest position.
    Returns (landmarks (n,) int64, distances (n, V) float64 metres from each landmark).
    """
    v = np.asarray(vertices, dtype=np.float64)
    V = len(v)
    n = min(n, V)
    rank = lexicographic_rank(v)
    score = v @ _start_direction(seed)
    best = score.max()
    cand = np.flatnonzero(score >= best - tie)
    first = int(cand[np.argmin(rank[cand])])
    landmarks = [first]
    dists = np.empty((n, V))
    dists[0] = geodesic_distances_from(graph, [first])[0]
    nearest = dists[0].copy()
    big = 1e6 * (1.0 + float(np.ptp(v, axis=0).max()) if V else 1.0)
    for k in range(1, n):
        score = np.where(np.isfinite(nearest), nearest, big)
        score[landmarks] = -1.0
        best = score.max()
        cand = np.flatnonzero(score >= best - tie)
        nxt = int(cand[np.argmin(rank[cand])])
        landmarks.append(nxt)
        dists[k] = geodesic_distances_from(graph, [nxt])[0]
        nearest = np.minimum(nearest, dists[k])
    return np.asarray(landmarks, dtype=np.int64), dists


def nystrom_matrix(landmark_distances: np.ndarray, landmarks: np.ndarray, weights: np.ndarray,
                   sigma: float = DEFAULT_SIGMA_M, rcond: float = 1e-3) -> np.ndarray:
    """G_nys = W^{+1/2} C^T diag(weights) C W^{+1/2}: (N, N) float64, symmetric PSD.

    landmark_distances: (N, V) geodesic distances (metres, inf = unreachable);
    landmarks: (N,) vertex indices; weights: (V,) quadrature weights summing to 1;
    sigma: affinity width in metres. Eigenvalues of W below rcond * max are dropped (pseudo-inverse).
    """
    d = np.asarray(landmark_distances, dtype=np.float64)
    Ct = np.exp(-np.square(np.where(np.isfinite(d), d, np.inf)) / (2.0 * sigma ** 2))  # (N, V); inf -> 0
    W = Ct[:, landmarks]
    W = 0.5 * (W + W.T)
    lam, U = np.linalg.eigh(W)
    keep = lam > rcond * max(lam.max(), 1e-300)
    inv_sqrt = (U[:, keep] / np.sqrt(lam[keep])) @ U[:, keep].T
    M = inv_sqrt @ ((Ct * weights[None, :]) @ Ct.T) @ inv_sqrt
    return 0.5 * (M + M.T)


def style_descriptor(vertices: np.ndarray, faces: np.ndarray, graph: sp.csr_matrix,
                     n_landmarks: int = DEFAULT_LANDMARKS, n_eigenvalues: int = DEFAULT_EIGENVALUES,
                     sigma: float = DEFAULT_SIGMA_M, seed: int = 0) -> StyleDescriptor:
    """The Nystrom style descriptor (leading eigenvalues of G_nys) of a garment's rest mesh.

    vertices: (V, 3) metres; faces: (F, 3) int; graph: `core.geodesic.geodesic_graph(vertices, faces)`.
    n_landmarks: N*, the same for all garments; n_eigenvalues: descriptor length;
    sigma: affinity width, metres; seed: picks the first landmark's direction.
    """
    if n_landmarks < 1 or n_eigenvalues < 1:
        raise ValueError(f"n_landmarks and n_eigenvalues must be >= 1, got {n_landmarks}, {n_eigenvalues}")
    V = len(vertices)
    if V < n_landmarks:
        log.warning("garment has %d vertices, fewer than %d landmarks: using all of them", V, n_landmarks)
    landmarks, dists = farthest_point_landmarks(vertices, graph, n_landmarks, seed)
    a = vertex_areas(vertices, faces)
    total = a.sum()
    w = a / total if total > 0 else np.full(V, 1.0 / V)
    M = nystrom_matrix(dists, landmarks, w, sigma)
    lam = np.sort(np.clip(np.linalg.eigvalsh(M), 0.0, None))[::-1]
    out = np.zeros(n_eigenvalues)
    out[:min(n_eigenvalues, len(lam))] = lam[:n_eigenvalues]
    return StyleDescriptor(eigenvalues=out, landmarks=landmarks, nystrom=M)
