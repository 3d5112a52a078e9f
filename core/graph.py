"""The garment graph of paper section 3.2.1: vertex features, edges, components, hop distances.

A garment mesh becomes a graph G = (X, E): X holds per-vertex rest positions,
normals and distances to every body joint in the body's rest pose (the
features the learned model reads), E the undirected mesh edges. Connected
components and breadth-first hop distances ("geodesic distance in the sense of
graph theory", section 3.3) serve the pooling hierarchy (`core.hierarchy`).
Everything here is O(V + E) memory; nothing builds a V x V dense matrix.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse import csgraph

from core.body import Body
from core.garment import Garment, mesh_edges
from core.geometry import vertex_normals

log = logging.getLogger(__name__)


@dataclass(frozen=True, eq=False)
class VertexFeatures:
    """Per-vertex features of a garment in the body's rest pose (paper X, section 3.2.1).

    positions: (V, 3) float32, metres, rest frame (Y-up).
    normals: (V, 3) float32, unit (zero for vertices without area).
    joint_distances: (V, J) float32, metres from each vertex to each rest joint of the body.
    """

    positions: np.ndarray
    normals: np.ndarray
    joint_distances: np.ndarray

    def as_array(self) -> np.ndarray:
        """(V, 6 + J) float32: positions, normals, joint distances side by side."""
        return np.concatenate([self.positions, self.normals, self.joint_distances], axis=1).astype(np.float32)


def vertex_features(garment: Garment, body: Body, betas: np.ndarray | None = None) -> VertexFeatures:
    """Rest positions, normals and vertex-to-joint distances of `garment` on `body` shaped by `betas`.

    garment: vertices (V, 3) metres in the body's rest frame; body: SMPL-format Body;
    betas: (S',) or None (zeros). Returns VertexFeatures (float32).
    """
    _, joints = body.shaped(betas)
    v = np.asarray(garment.vertices, dtype=np.float64)
    normals = vertex_normals(v, garment.faces)
    # (V, J) via |v|^2 - 2 v.j + |j|^2 would lose precision; V*J*3 floats is small enough to subtract.
    d = np.linalg.norm(v[:, None, :] - joints[None].astype(np.float64), axis=-1)
    return VertexFeatures(v.astype(np.float32), normals.astype(np.float32), d.astype(np.float32))


def undirected_edges(faces: np.ndarray) -> np.ndarray:
    """The mesh's unique undirected edges: faces (F, 3) int -> (E, 2) int64, edges[:, 0] < edges[:, 1]."""
    return mesh_edges(faces)


def adjacency(edges: np.ndarray, n_vertices: int, weights: np.ndarray | None = None) -> sp.csr_matrix:
    """Symmetric sparse adjacency (V, V) float64 of undirected edges (E, 2); entries 1 or `weights` (E,)."""
    edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    w = np.ones(len(edges)) if weights is None else np.asarray(weights, dtype=np.float64)
    a = sp.coo_matrix((np.r_[w, w], (np.r_[edges[:, 0], edges[:, 1]], np.r_[edges[:, 1], edges[:, 0]])),
                      shape=(n_vertices, n_vertices)).tocsr()
    a.sum_duplicates()
    a.sort_indices()
    return a


def connected_components(edges: np.ndarray, n_vertices: int) -> tuple[int, np.ndarray]:
    """Connected components of the edge graph: (count, labels (V,) int64).

    Labels are numbered by each component's smallest vertex index (component 0
    holds vertex 0); a vertex without edges is a component of its own.
    """
    n, labels = csgraph.connected_components(adjacency(edges, n_vertices), directed=False)
    # Relabel in order of first appearance so labels do not depend on scipy's internals.
    _, first = np.unique(labels, return_index=True)
    order = np.argsort(first)
    remap = np.empty(n, dtype=np.int64)
    remap[order] = np.arange(n)
    return int(n), remap[labels]


def hop_distances(adj: sp.csr_matrix, sources) -> np.ndarray:
    """Breadth-first hop distances from each source: (S, V) int64, -1 where unreachable.

    adj: (V, V) symmetric sparse adjacency; sources: (S,) int vertex indices.
    Memory S * V: meant for a few sources.
    """
    sources = np.atleast_1d(np.asarray(sources, dtype=np.int64))
    d = csgraph.shortest_path(adj, method="D", directed=True, unweighted=True, indices=sources)
    return np.where(np.isfinite(d), d, -1).astype(np.int64).reshape(len(sources), adj.shape[0])


def hop_distances_multi_source(adj: sp.csr_matrix, sources) -> np.ndarray:
    """Hop distance from each vertex to its nearest source: (V,) int64, -1 where no source is reachable.

    One breadth-first search from a virtual vertex joined to every source, so
    one seed per connected component costs one O(V + E) pass, not one per seed.
    """
    sources = np.atleast_1d(np.asarray(sources, dtype=np.int64))
    V = adj.shape[0]
    extra = sp.csr_matrix((np.ones(len(sources)), (np.full(len(sources), V), sources)), shape=(V + 1, V + 1))
    big = sp.bmat([[adj, None], [None, sp.csr_matrix((1, 1))]], format="csr") + extra
    d = csgraph.shortest_path(big, method="D", directed=True, unweighted=True, indices=[V])[0, :V]
    return np.where(np.isfinite(d), d - 1, -1).astype(np.int64)


def lexicographic_rank(points: np.ndarray) -> np.ndarray:
    """(V,) int64 rank of each point in lexicographic (x, y, z) order, ties by index.

    Used to break ties by geometry rather than by vertex numbering, so results do
    not depend on the order of vertices in the file.
    """
    p = np.asarray(points)
    order = np.lexsort((p[:, 2], p[:, 1], p[:, 0]))
    rank = np.empty(len(p), dtype=np.int64)
    rank[order] = np.arange(len(p))
    return rank


def peripheral_seeds(adj: sp.csr_matrix, labels: np.ndarray, points: np.ndarray) -> np.ndarray:
    """One high-eccentricity seed vertex per connected component: (C,) int64, seed of component c at [c].

    Exact eccentricity needs a BFS from every vertex (O(V E)); a double sweep
    finds a peripheral vertex in two BFS passes: start at the component's
    lexicographically smallest point (x, y, z), take the farthest vertex u
    (ties: smallest point). u's eccentricity is the component's diameter on
    trees and within a factor 2 of it in general. points: (V, 3) rest positions.
    """
    labels = np.asarray(labels, dtype=np.int64)
    rank = lexicographic_rank(points)
    n_comp = int(labels.max()) + 1 if len(labels) else 0
    # Per component, the vertex of smallest rank.
    start = np.full(n_comp, -1, dtype=np.int64)
    order = np.argsort(rank)
    lab_sorted = labels[order]
    _, first = np.unique(lab_sorted, return_index=True)
    start[lab_sorted[first]] = order[first]
    d = hop_distances_multi_source(adj, start)
    # Farthest vertex per component, ties broken by smallest rank.
    key = np.lexsort((rank, -d, labels))
    lab_key = labels[key]
    _, first = np.unique(lab_key, return_index=True)
    seeds = np.empty(n_comp, dtype=np.int64)
    seeds[lab_key[first]] = key[first]
    return seeds
