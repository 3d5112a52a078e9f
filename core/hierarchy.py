"""Structure-preserving pooling and weighted unpooling of paper section 3.3.

Pooling one level: in every connected component pick a seed by eccentricity
(`core.graph.peripheral_seeds`), measure hop distances from it, and remove the
vertices at odd distance. Retained vertices keep the edges they had and are
joined when a removed vertex linked them (i - r - j). Every retained vertex at
distance 2k reaches one at 2k - 2 through its removed BFS parent, so each
component stays connected and the number of components never changes; on
triangle meshes about half the vertices survive a level.

Unpooling: retained vertices copy their coarse value; a removed vertex r takes
the normalised weighted mean of its retained fine-level neighbours j, with
weights w_rj = 1 / |x_r - x_j| (rest positions). Every removed vertex has one
(its BFS parent). `Hierarchy.unpool[l]` is that operator as a sparse
(n_l, n_{l+1}) matrix whose rows sum to 1.

`build_hierarchy` repeats pooling L times. Everything is sparse and O(V + E).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from core.graph import adjacency, connected_components, hop_distances_multi_source, peripheral_seeds

DEFAULT_LEVELS = 2


@dataclass(frozen=True, eq=False)
class PoolResult:
    """One pooling step of a graph with n fine vertices.

    kept: (n_coarse,) int64 fine indices of retained vertices, increasing.
    coarse_edges: (E_c, 2) int64 coarse indices, [:, 0] < [:, 1], sorted, unique.
    unpool: (n, n_coarse) csr float64, rows sum to 1.
    seeds: (C,) int64 fine index of each component's seed; hops: (n,) int64 hop distance to the seed.
    """

    kept: np.ndarray
    coarse_edges: np.ndarray
    unpool: sp.csr_matrix
    seeds: np.ndarray
    hops: np.ndarray


@dataclass(frozen=True, eq=False)
class Hierarchy:
    """Levels 0 (the mesh) .. L of the pooling hierarchy.

    vertex_index[l]: (n_l,) int64 indices of level-l vertices into level 0 (vertex_index[0] = arange(V)).
    edges[l]: (E_l, 2) int64 level-l indices, [:, 0] < [:, 1].
    pool_index[l]: (n_{l+1},) int64 level-l indices of the vertices kept in level l+1 (l < L).
    unpool[l]: (n_l, n_{l+1}) csr float64, level l+1 values -> level l values (l < L).
    components[l]: number of connected components of level l (the same at every level).
    """

    vertex_index: list
    edges: list
    pool_index: list
    unpool: list
    components: list

    @property
    def n_levels(self) -> int:
        """L, the number of pooling steps (len(vertex_index) - 1)."""
        return len(self.vertex_index) - 1

    def sizes(self) -> list[int]:
        return [len(v) for v in self.vertex_index]

    def pool(self, values: np.ndarray, level: int) -> np.ndarray:
        """Level-`level` values (n_l, ...) -> level+1 values (n_{l+1}, ...) by selection."""
        return np.asarray(values)[self.pool_index[level]]

    def unpool_values(self, values: np.ndarray, level: int) -> np.ndarray:
        """Level-`level`+1 values (n_{l+1}, C) -> level-`level` values (n_l, C) by weighted filling."""
        return self.unpool[level] @ values


def _sorted_unique_edges(i: np.ndarray, j: np.ndarray) -> np.ndarray:
    e = np.stack([np.minimum(i, j), np.maximum(i, j)], axis=1)
    e = e[e[:, 0] != e[:, 1]]
    if len(e) == 0:
        return np.zeros((0, 2), dtype=np.int64)
    return np.unique(e, axis=0).astype(np.int64)


def pool_structure_preserving(edges: np.ndarray, points: np.ndarray) -> PoolResult:
    """One level of structure-preserving pooling (paper section 3.3), vectorised.

    edges: (E, 2) int undirected edges over n vertices; points: (n, 3) rest
    positions, metres (seed tie-breaking and unpooling weights).
    """
    points = np.asarray(points, dtype=np.float64)
    n = len(points)
    edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    adj = adjacency(edges, n)
    _, labels = connected_components(edges, n)
    seeds = peripheral_seeds(adj, labels, points)
    hops = hop_distances_multi_source(adj, seeds)
    keep_mask = hops % 2 == 0  # hops >= 0 everywhere: every vertex is in a component with a seed
    kept = np.flatnonzero(keep_mask)
    removed = np.flatnonzero(~keep_mask)
    new_id = np.full(n, -1, dtype=np.int64)
    new_id[kept] = np.arange(len(kept))

    # Edges between retained vertices, and pairs of retained neighbours of each removed vertex.
    both = keep_mask[edges[:, 0]] & keep_mask[edges[:, 1]]
    direct = edges[both]
    A_rk = adj[removed][:, kept]  # (removed, kept) pattern
    through = (A_rk.T @ A_rk).tocoo()  # kept x kept: linked through a removed vertex
    coarse_edges = _sorted_unique_edges(np.r_[new_id[direct[:, 0]], through.row],
                                        np.r_[new_id[direct[:, 1]], through.col])

    # Unpooling: identity on kept rows; inverse-distance weights over retained neighbours for removed rows.
    A_rk = A_rk.tocoo()
    r_fine = removed[A_rk.row]
    k_fine = kept[A_rk.col]
    w = 1.0 / np.maximum(np.linalg.norm(points[r_fine] - points[k_fine], axis=1), 1e-12)
    row_sum = np.bincount(A_rk.row, weights=w, minlength=len(removed))
    w = w / row_sum[A_rk.row]
    rows = np.r_[kept, r_fine]
    cols = np.r_[np.arange(len(kept)), A_rk.col]
    vals = np.r_[np.ones(len(kept)), w]
    unpool = sp.csr_matrix((vals, (rows, cols)), shape=(n, len(kept)))
    unpool.sort_indices()
    return PoolResult(kept=kept, coarse_edges=coarse_edges, unpool=unpool, seeds=seeds, hops=hops)


def build_hierarchy(edges: np.ndarray, points: np.ndarray, levels: int = DEFAULT_LEVELS) -> Hierarchy:
    """L levels of structure-preserving pooling of a mesh graph.

    edges: (E, 2) int level-0 edges; points: (V, 3) rest positions, metres; levels: L >= 0.
    """
    if levels < 0:
        raise ValueError(f"levels must be >= 0, got {levels}")
    points = np.asarray(points, dtype=np.float64)
    V = len(points)
    edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    n_comp, _ = connected_components(edges, V)
    vertex_index, edge_list, pool_index, unpool, comps = [np.arange(V, dtype=np.int64)], [edges], [], [], [n_comp]
    for _ in range(levels):
        res = pool_structure_preserving(edge_list[-1], points[vertex_index[-1]])
        pool_index.append(res.kept)
        unpool.append(res.unpool)
        vertex_index.append(vertex_index[-1][res.kept])
        edge_list.append(res.coarse_edges)
        comps.append(connected_components(res.coarse_edges, len(res.kept))[0])
    return Hierarchy(vertex_index=vertex_index, edges=edge_list, pool_index=pool_index, unpool=unpool,
                     components=comps)
