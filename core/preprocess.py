"""Preprocessing of a garment for the learned model (paper sections 3.2.1, 3.3, 4.2), cached.

`preprocess_garment` bundles everything the model reads about a garment's
rest mesh on a body: vertex features (`core.graph`), the edge graph and its
components, the Nystrom style descriptor (`core.descriptor`), the pooling
hierarchy (`core.hierarchy`) and the set of vertex pairs within 10 cm along
the rest surface (`core.geodesic`), whose complement is condition (a) of the
self-collision mask of Eq. 6. With `cache_dir` set the result is stored (via
`formats.cache`) under a key made of the garment's content hash, every
setting and the body's rest joints, so a changed mesh, setting or body is
never served a stale entry.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import logging
import os
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from core.body import Body
from core.descriptor import DEFAULT_EIGENVALUES, DEFAULT_LANDMARKS, DEFAULT_SIGMA_M, StyleDescriptor, style_descriptor
from core.errors import InputError
from core.garment import Garment
from core.geodesic import SELF_COLLISION_GEODESIC_M, geodesic_graph, geodesic_neighbourhood
from core.graph import VertexFeatures, connected_components, undirected_edges, vertex_features
from core.hierarchy import DEFAULT_LEVELS, Hierarchy, build_hierarchy

log = logging.getLogger(__name__)

MAX_LEVELS = 8
MAX_LANDMARKS = 1024
CACHE_KIND = "preprocess"
#: What the arrays are computed by, part of every cache entry's key: raised when the computation changes, so that
#: entries an earlier version wrote are computed again (2: the landmarks' ties within `LANDMARK_TIE_M`).
PREPROCESS_REVISION = 2


@dataclass(frozen=True)
class PreprocessSettings:
    """Settings that change the preprocessed arrays (all part of the cache key).

    levels: pooling levels L (0..8). n_landmarks: Nystrom landmarks N* (fixed for all garments).
    n_eigenvalues: descriptor length. sigma_m: affinity width, metres. seed: first-landmark direction.
    collision_radius_m: rest geodesic radius of the Eq. 6 near set (0 = not computed).
    """

    levels: int = DEFAULT_LEVELS
    n_landmarks: int = DEFAULT_LANDMARKS
    n_eigenvalues: int = DEFAULT_EIGENVALUES
    sigma_m: float = DEFAULT_SIGMA_M
    seed: int = 0
    collision_radius_m: float = SELF_COLLISION_GEODESIC_M

    def validate(self) -> None:
        if not (isinstance(self.levels, (int, np.integer)) and 0 <= self.levels <= MAX_LEVELS):
            raise InputError(f"preprocess levels: expected an integer from 0 to {MAX_LEVELS}, got {self.levels!r}")
        if not (isinstance(self.n_landmarks, (int, np.integer)) and 2 <= self.n_landmarks <= MAX_LANDMARKS):
            raise InputError(f"preprocess landmarks: expected an integer from 2 to {MAX_LANDMARKS}, "
                             f"got {self.n_landmarks!r}")
        if not (isinstance(self.n_eigenvalues, (int, np.integer)) and 1 <= self.n_eigenvalues):
            raise InputError(f"preprocess eigenvalues: expected a positive integer, got {self.n_eigenvalues!r}")
        if not (np.isfinite(self.sigma_m) and self.sigma_m > 0):
            raise InputError(f"preprocess sigma: expected a positive width in metres, got {self.sigma_m!r}")
        if not (np.isfinite(self.collision_radius_m) and self.collision_radius_m >= 0):
            raise InputError(f"preprocess collision radius: expected metres >= 0, got {self.collision_radius_m!r}")


@dataclass(frozen=True, eq=False)
class Preprocessed:
    """Everything the learned model needs about one garment on one body, in the rest pose.

    features: VertexFeatures (V rows). edges: (E, 2) int64 mesh edges. component: (V,) int64 labels.
    hierarchy: Hierarchy (levels 0..L). descriptor: StyleDescriptor (eigenvalues (n_eigenvalues,)).
    collision_near: (V, V) sparse bool pattern of pairs within `collision_radius_m` along the rest
    surface (Eq. 6: only pairs NOT in it may repel), or None when not computed.
    key: cache key (hex); garment_hash, body_key: the inputs' identities; cache_hit: served from cache.
    """

    settings: PreprocessSettings
    features: VertexFeatures
    edges: np.ndarray
    component: np.ndarray
    hierarchy: Hierarchy
    descriptor: StyleDescriptor
    collision_near: sp.csr_matrix | None
    key: str
    garment_hash: str
    body_key: str
    cache_hit: bool = False

    @property
    def n_components(self) -> int:
        return int(self.component.max()) + 1 if len(self.component) else 0


def body_key(body: Body, betas: np.ndarray | None = None) -> str:
    """Identity of the body as the features see it: SHA-256 of the shaped rest joints (J, 3) float32."""
    _, joints = body.shaped(betas)
    h = hashlib.sha256(np.ascontiguousarray(joints, dtype=np.float32).tobytes())
    h.update(str(joints.shape).encode())
    return h.hexdigest()


def cache_meta(garment_hash: str, body_id: str, settings: PreprocessSettings) -> dict:
    """The key fields stored with (and checked against) a cache entry."""
    return {"garment": garment_hash, "body": body_id, "settings": dataclasses.asdict(settings),
            "revision": PREPROCESS_REVISION}


def cache_key(meta: dict) -> str:
    return hashlib.sha256(json.dumps(meta, sort_keys=True).encode()).hexdigest()


def compute_preprocessed(garment: Garment, body: Body, settings: PreprocessSettings,
                         betas: np.ndarray | None = None) -> Preprocessed:
    """Compute (no cache) the preprocessed arrays of `garment` on `body` shaped by `betas`."""
    settings.validate()
    v = np.asarray(garment.vertices, dtype=np.float64)
    feats = vertex_features(garment, body, betas)
    edges = undirected_edges(garment.faces)
    _, labels = connected_components(edges, len(v))
    hier = build_hierarchy(edges, v, settings.levels)
    graph = geodesic_graph(v, garment.faces)
    desc = style_descriptor(v, garment.faces, graph, settings.n_landmarks, settings.n_eigenvalues,
                            settings.sigma_m, settings.seed)
    near = None
    if settings.collision_radius_m > 0:
        near = geodesic_neighbourhood(v, graph, settings.collision_radius_m, distances=False)
    g_hash, b_key = garment.content_hash(), body_key(body, betas)
    return Preprocessed(settings=settings, features=feats, edges=edges, component=labels, hierarchy=hier,
                        descriptor=desc, collision_near=near, key=cache_key(cache_meta(g_hash, b_key, settings)),
                        garment_hash=g_hash, body_key=b_key)


def to_arrays(p: Preprocessed) -> dict:
    """Flatten a Preprocessed into {name: ndarray} (for `formats.cache`)."""
    h = p.hierarchy
    out = {"positions": p.features.positions, "normals": p.features.normals,
           "joint_distances": p.features.joint_distances, "edges": p.edges, "component": p.component,
           "eigenvalues": p.descriptor.eigenvalues, "landmarks": p.descriptor.landmarks,
           "nystrom": p.descriptor.nystrom, "levels": np.array(h.n_levels),
           "level_components": np.asarray(h.components, dtype=np.int64)}
    for l in range(h.n_levels + 1):
        out[f"vertex_index_{l}"] = h.vertex_index[l]
        out[f"edges_{l}"] = h.edges[l]
    for l in range(h.n_levels):
        u = h.unpool[l]
        out[f"pool_index_{l}"] = h.pool_index[l]
        out[f"unpool_{l}_data"], out[f"unpool_{l}_indices"] = u.data, u.indices
        out[f"unpool_{l}_indptr"], out[f"unpool_{l}_shape"] = u.indptr, np.asarray(u.shape)
    if p.collision_near is not None:
        out["near_indices"], out["near_indptr"] = p.collision_near.indices, p.collision_near.indptr
    return out


def from_arrays(a: dict, settings: PreprocessSettings, key: str, garment_hash: str, body_id: str) -> Preprocessed:
    """Inverse of `to_arrays`."""
    L = int(a["levels"])
    unpool = [sp.csr_matrix((a[f"unpool_{l}_data"], a[f"unpool_{l}_indices"], a[f"unpool_{l}_indptr"]),
                            shape=tuple(a[f"unpool_{l}_shape"])) for l in range(L)]
    hier = Hierarchy(vertex_index=[a[f"vertex_index_{l}"] for l in range(L + 1)],
                     edges=[a[f"edges_{l}"] for l in range(L + 1)],
                     pool_index=[a[f"pool_index_{l}"] for l in range(L)], unpool=unpool,
                     components=[int(c) for c in a["level_components"]])
    V = len(a["positions"])
    near = None
    if "near_indices" in a:
        near = sp.csr_matrix((np.ones(len(a["near_indices"]), dtype=bool), a["near_indices"], a["near_indptr"]),
                             shape=(V, V))
    return Preprocessed(settings=settings,
                        features=VertexFeatures(a["positions"], a["normals"], a["joint_distances"]),
                        edges=a["edges"], component=a["component"], hierarchy=hier,
                        descriptor=StyleDescriptor(a["eigenvalues"], a["landmarks"], a["nystrom"]),
                        collision_near=near, key=key, garment_hash=garment_hash, body_key=body_id)


def preprocess_garment(garment: Garment, body: Body, levels: int = DEFAULT_LEVELS,
                       n_landmarks: int = DEFAULT_LANDMARKS, seed: int = 0, *,
                       n_eigenvalues: int = DEFAULT_EIGENVALUES, sigma_m: float = DEFAULT_SIGMA_M,
                       collision_radius_m: float = SELF_COLLISION_GEODESIC_M, betas: np.ndarray | None = None,
                       cache_dir: str | os.PathLike | None = None, cache_optional: bool = False) -> Preprocessed:
    """Preprocess `garment` (rest mesh on `body` shaped by `betas`) for the learned model.

    garment: Garment (vertices (V, 3) metres, rest frame). body: SMPL-format Body. levels: pooling
    levels L. n_landmarks: Nystrom N*. seed: first-landmark direction (see `core.descriptor`).
    cache_dir: None computes without a cache; a directory (e.g. `formats.cache.default_cache_dir()`)
    reuses an entry whose key (garment content hash, settings, body joints) matches, else computes
    and stores one. `Preprocessed.cache_hit` says which happened. cache_optional: an entry that cannot be
    stored (a full disk, a read-only folder) is warned about and the result returned (else InputError).
    Raises InputError for settings out of range.
    """
    settings = PreprocessSettings(levels=levels, n_landmarks=n_landmarks, n_eigenvalues=n_eigenvalues,
                                  sigma_m=float(sigma_m), seed=int(seed), collision_radius_m=float(collision_radius_m))
    settings.validate()
    if cache_dir is None:
        return compute_preprocessed(garment, body, settings, betas)
    from formats.cache import cache_path, read_cache, write_cache  # file I/O lives in formats/

    g_hash, b_key = garment.content_hash(), body_key(body, betas)
    meta = cache_meta(g_hash, b_key, settings)
    key = cache_key(meta)
    path = cache_path(cache_dir, CACHE_KIND, key)
    arrays = read_cache(path, meta)
    if arrays is not None:
        try:
            p = from_arrays(arrays, settings, key, g_hash, b_key)
            if len(p.features.positions) == garment.n_vertices:
                log.info("preprocess '%s': cache hit %s", garment.name, path)
                return dataclasses.replace(p, cache_hit=True)
        except (KeyError, ValueError, TypeError) as exc:
            log.warning("cache '%s' is incomplete (%s): recomputing", path, exc)
    p = compute_preprocessed(garment, body, settings, betas)
    try:
        write_cache(path, to_arrays(p), meta)
    except InputError as exc:
        if not cache_optional:
            raise
        log.warning("%s: the preprocessing is used without being cached", exc)
        return p
    log.info("preprocess '%s': cache miss, wrote %s", garment.name, path)
    return p
