"""Strain limit: no edge of the deformed garment longer than STRAIN_LIMIT times its rest length.

Skinning stretches cloth where neighbouring vertices follow different bones: a dress between the legs on a
stride (LBS's weights and the network's alike), trousers at the knee, a t-shirt's armpit when the arm is
raised. Real cloth hardly stretches (the simulator's edges keep within 1-2 % of their rest lengths on average);
the network's came out with edges stretched up to 7.5-19 times on the real captures of `--quality auto`'s
calibration, torn (an edge over twice its rest length and 2 cm longer) in 10-39 % of their frames by garment
(`benchmarks/results/strain_limit.md`).

The limit projects each edge over it back onto it (Provot's deformation constraint, Jacobi style): both
ends move towards each other by half the excess, a vertex taking the mean of the moves of its edges over the
limit, repeated (Chebyshev-accelerated) until none is over by more than STRAIN_TOLERANCE_M or for
STRAIN_ITERATIONS passes. A pass moves the excess one ring of edges further, so a wide tear needs many passes;
only frames with an edge over the limit take them, so a frame without one costs one check of its edges. It
shortens, never lengthens: compressed cloth (folds) is left as it is. It sees no body: applied after the
contact guard, it can pull a stretched vertex back into the body by up to the excess it removes (`bake
--push-out` runs after it). A pass's moves grow continuously from nothing as an edge crosses its limit (`_pass`),
so the limit passes its input's rounding on nearly as it comes: noise of 1e-6 m on the torn example garments
(dress, t-shirt, trousers; model and LBS on the kick, run and brisk walk) moved the limited cloth by 1.6 um on
average (the noise's own size) and by 0.5 mm at most (0.9 in another draw of the noise), where a frame's stop at
the tolerance falls the other way; an all-or-nothing pull at the tolerance, each edge over counting one in its
vertices' means, moved it by 10.7 um on average and 6.2 mm at most (`benchmarks/strain_rounding.py`).

On by default for the model and psd (`bake --strain-limit`), off for lbs, whose speed is its point (the limit
costs it 1.6-4.2 ms/frame on average on the real and synthetic sequences measured), where `--strain-limit 1.5`
turns it on.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import torch

from core.garment import Garment, frames_at_once, mesh_edges
from core.geodesic import edge_lengths
from core.graph import adjacency

#: The longest an edge may be, as a multiple of its rest length: beyond what cloth stretches, so only tears
#: are undone (on the real captures, 30 plain passes at 1.3 lowered E_verts by at most 0.1 mm more than at 1.5;
#: 1.75 halved the time on a kick's torn garments, E_verts 0.1-0.6 mm above 1.5's; 2.0 left them torn).
STRAIN_LIMIT = 1.5
#: Passes at most: after 60 the model left no frame torn on 78 simulated sequences and the examples (LBS 6 of
#: 3,988), and four torn sequences no edge longer than its limit by more than 4.4 mm (after 100: 2.9 mm, at up to
#: 30 % more time on average; `benchmarks/results/strain_limit.md`).
STRAIN_ITERATIONS = 60
#: An edge counts as over the limit when longer than it by more than this (metres).
STRAIN_TOLERANCE_M = 1e-3
#: Passes between checks of which frames still have an edge over the limit (a frame without one is left).
STRAIN_CHECK_PASSES = 10
#: Chebyshev acceleration of the passes (Wang 2015, "A Chebyshev semi-iterative approach for accelerating
#: projective and position-based dynamics"): the passes' estimated spectral radius, and how many plain passes
#: come first. Plain passes left LBS's example dress torn in 32 of the 151 frames of the example run after 100;
#: accelerated, none after 40. After 60 passes over four torn sequences the largest excess was 4.4 mm at 0.98,
#: 8.7 at 0.95, 8.5 at 0.9.
STRAIN_RHO = 0.98
STRAIN_PLAIN_PASSES = 10
#: Frames limited at once (their positions as one (3, V, frames) block): at most STRAIN_CHUNK_FRAMES, fewer for a
#: large garment (`strain_chunk_frames`: about STRAIN_CHUNK_VERTEX_FRAMES vertex-frames, STRAIN_MIN_CHUNK_FRAMES at
#: least). LBS's torn example dress subdivided 0-3 times, 64 frames of the run, one thread: 3,240 vertices 7.7
#: ms/frame at 32 (8.6 at 16); 12,816: 19.5 at 16 (27.0 at 32); 50,976: 99-109 at 8-16 (102 at 32, peak memory
#: 285 MB more than at 8); 203,328: 353 at 8 (569 at 32, peak +645 MB; 392 at 4, 500 at 2).
STRAIN_CHUNK_FRAMES = 32
STRAIN_CHUNK_VERTEX_FRAMES = 320_000
STRAIN_MIN_CHUNK_FRAMES = 8


def strain_chunk_frames(n_vertices: int) -> int:
    """Frames `limit_sequence` limits at once for a garment of `n_vertices` (`frames_at_once`)."""
    return frames_at_once(n_vertices, STRAIN_CHUNK_VERTEX_FRAMES, STRAIN_MIN_CHUNK_FRAMES, STRAIN_CHUNK_FRAMES)


@dataclass(frozen=True)
class StrainLimit:
    """A garment's edges (E, 2) int64, their rest lengths times the limit (E,) metres, and the vertex adjacency
    (V, V) that grows a region of edges by rings."""

    edges: np.ndarray
    longest: np.ndarray
    adjacency: sp.csr_matrix
    limit: float


def strain_limit(rest: np.ndarray, faces: np.ndarray, limit: float = STRAIN_LIMIT) -> StrainLimit:
    """The strain limit of a garment at rest (V, 3), faces (F, 3): no edge longer than `limit` times its rest
    length."""
    edges = mesh_edges(faces)
    return _strain_of(edges, adjacency(edges, len(rest)), rest, limit)


def _strain_of(edges: np.ndarray, adj: sp.csr_matrix, rest: np.ndarray, limit: float) -> StrainLimit:
    """The StrainLimit of a garment's edges (E, 2) and adjacency (V, V) against their lengths at `rest` (V, 3)."""
    return StrainLimit(edges, limit * edge_lengths(np.asarray(rest, dtype=np.float64), edges), adj, float(limit))


def _edges_of(x: torch.Tensor, a: torch.Tensor, b: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """The edges (a, b) (E,) of positions x (3, V, T), coordinate-first: their vectors (3, E, T) and lengths (E, T)
    (coordinate planes: the squares summed by hand run 3x faster than `vector_norm` over a last axis of 3)."""
    d = torch.index_select(x, 1, b) - torch.index_select(x, 1, a)
    return d, torch.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])


def _pass(x: torch.Tensor, a: torch.Tensor, b: torch.Tensor, longest: torch.Tensor) -> torch.Tensor:
    """One Jacobi pass of the limit over edges (a, b) (E,) of positions x (3, V, T): each edge longer than
    `longest` (E, 1) has both ends moved towards each other by half its excess, a vertex by the mean of its
    edges' moves, an edge counting in that mean as its excess over STRAIN_TOLERANCE_M (at most 1: a vertex with
    one edge over takes its whole move). Every move grows from nothing as an edge crosses its limit, so a pass is
    continuous in x (an all-or-nothing pull at the tolerance, each edge counting 1, turned rounding into moves
    of up to 6 mm). Returns the moved positions."""
    d, length = _edges_of(x, a, b)
    e, t = torch.nonzero(length > longest, as_tuple=True)  # the few edges over, per frame
    if len(e) == 0:
        return x.clone()
    _, V, T = x.shape
    ll = length[e, t]
    excess = ll - longest[e, 0]
    pull = (0.5 * excess / ll) * d[:, e, t]  # (3, n)
    share = (excess / STRAIN_TOLERANCE_M).clamp(max=1.0)
    ends = torch.cat([a[e] * T + t, b[e] * T + t])  # (vertex, frame) of x viewed as (3, V * T)
    move = torch.zeros(3, V * T, device=x.device).index_add_(1, ends, torch.cat([pull, -pull], dim=1))
    count = torch.zeros(V * T, device=x.device).index_add_(0, ends, torch.cat([share, share]))
    return x + (move / count.clamp(min=1.0)).view(x.shape)


def _edge_tensors(strain: StrainLimit, device) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """The edges' ends a, b (E,) and their longest lengths (E, 1) float32 of `strain`, on `device`."""
    a, b = (torch.as_tensor(strain.edges[:, i], device=device) for i in (0, 1))
    return a, b, torch.as_tensor(strain.longest, dtype=torch.float32, device=device)[:, None]


def _excess(x: torch.Tensor, a: torch.Tensor, b: torch.Tensor, longest: torch.Tensor) -> torch.Tensor:
    """(E, T): how much longer than its limit each edge (a, b) of positions x (3, V, T) is (negative: shorter)."""
    return _edges_of(x, a, b)[1] - longest


def _reach(seed: np.ndarray, strain: StrainLimit, rings: int) -> np.ndarray:
    """Ids of the edges with an end within `rings` rings of the vertices marked in `seed` (V,) bool."""
    near = seed.copy()
    for _ in range(rings):
        near |= strain.adjacency @ near > 0
    return np.flatnonzero(near[strain.edges[:, 0]] | near[strain.edges[:, 1]])


def limit_strain(points, strain: StrainLimit, iterations: int = STRAIN_ITERATIONS):
    """Shorten every edge of `points` (T, V, 3) longer than its limit.

    Returns (points (T, V, 3) float32, over (T,) int64: how many edges each frame had longer than the limit by
    more than STRAIN_TOLERANCE_M before, passes made). `points` an array: an array back; a tensor: a tensor on
    its device (a GPU bake's frames limited where the network made them). The frames that have such an
    edge take Jacobi passes (`_pass`), Chebyshev-accelerated after STRAIN_PLAIN_PASSES, until none has one
    (checked every STRAIN_CHECK_PASSES; a frame without one is left as it is) or `iterations` passes are made.
    Between checks the passes work on a region only: the edges within as many rings as passes of an edge longer
    than its limit by any amount (every edge a pass pulls) or of a vertex still moving (the acceleration carries
    a move on) and their ends, renumbered; no other vertex can move. A frame's result does not depend on the
    others given with it.
    """
    tensor = isinstance(points, torch.Tensor)
    x = points.float() if tensor else torch.from_numpy(np.asarray(points, dtype=np.float32))
    x = x.permute(2, 1, 0).contiguous()  # (3, V, T): coordinate planes
    device = x.device
    a, b, longest = _edge_tensors(strain, device)
    excess = _excess(x, a, b, longest)
    counts = (excess > STRAIN_TOLERANCE_M).sum(dim=0)
    frames = torch.nonzero(counts).ravel()
    sub, excess, prev, omega, done = x[:, :, frames], excess[:, frames], None, 1.0, 0
    while len(frames) and done < iterations:
        n = min(STRAIN_CHECK_PASSES, iterations - done)
        seed = np.zeros(x.shape[1], dtype=bool)
        seed[strain.edges[(excess > 0).any(dim=1).cpu().numpy()].ravel()] = True  # every edge a pass would pull
        if prev is not None:
            seed |= (sub != prev).any(dim=0).any(dim=1).cpu().numpy()
        region = _reach(seed, strain, n + 1)
        verts, local = np.unique(strain.edges[region], return_inverse=True)
        local = torch.from_numpy(local.reshape(-1, 2)).to(device)
        verts = torch.from_numpy(verts).to(device)
        ra, rb, rl = local[:, 0], local[:, 1], longest[torch.from_numpy(region).to(device)]
        s_here = sub[:, verts]
        p_here = None if prev is None else prev[:, verts]
        for _ in range(n):
            moved = _pass(s_here, ra, rb, rl)
            done += 1
            if done > STRAIN_PLAIN_PASSES:  # y <- omega (y - y_prev) + y_prev, omega growing to its limit
                omega = 2.0 / (2.0 - STRAIN_RHO ** 2) if omega == 1.0 else 4.0 / (4.0 - STRAIN_RHO ** 2 * omega)
                moved = omega * (moved - p_here) + p_here
            p_here, s_here = s_here, moved
        prev = sub.clone()  # a vertex outside the region stands still: its previous position is its position
        prev[:, verts], sub[:, verts] = p_here, s_here
        x[:, :, frames] = sub
        excess = _excess(sub, a, b, longest)
        left = (excess > STRAIN_TOLERANCE_M).any(dim=0)
        frames, sub, prev, excess = frames[left], sub[:, :, left], prev[:, :, left], excess[:, left]
    x = x.permute(2, 1, 0)
    return (x.contiguous() if tensor else x.numpy()), counts.cpu().numpy(), done


def still_over(points, strain: StrainLimit) -> tuple[np.ndarray, np.ndarray]:
    """After the limit: per frame of `points` (T, V, 3; an array or a tensor), how many edges are still longer than
    their limit by more than STRAIN_TOLERANCE_M (T,) and the largest excess (T,) metres (0 where none is over)."""
    x = points.float() if isinstance(points, torch.Tensor) else torch.from_numpy(np.asarray(points, np.float32))
    x = x.permute(2, 1, 0)
    excess = _excess(x, *_edge_tensors(strain, x.device))
    return ((excess > STRAIN_TOLERANCE_M).sum(dim=0).cpu().numpy(),
            excess.max(dim=0).values.clamp(min=0.0).cpu().numpy() if len(excess) else np.zeros(x.shape[2]))


def strain_report(strain: StrainLimit, iterations: int, over: list[np.ndarray], passes: int, seconds: float,
                  n_frames: int, left: list[tuple[np.ndarray, np.ndarray]] = ()) -> dict:
    """The report's "strain_limit" entry of a sequence of `n_frames` limited in parts: their edges over the limit
    per frame before it (`limit_strain`'s `over`), those still over after it (`still_over` of each part: where its
    passes ran out before the widest tears were undone), the most passes a part took and the seconds all took."""
    over = np.concatenate(over) if over else np.zeros(1, dtype=np.int64)
    after = np.concatenate([n for n, _ in left]) if left else np.zeros(1, dtype=np.int64)
    excess = np.concatenate([e for _, e in left]) if left else np.zeros(1)
    return {"limit": strain.limit, "iterations": iterations, "passes_max": passes,
            "frames_limited": int((over > 0).sum()), "edges_over_per_frame_max": int(over.max(initial=0)),
            "frames_still_over": int((after > 0).sum()), "edges_still_over_per_frame_max": int(after.max(initial=0)),
            "excess_left_max_mm": round(float(excess.max(initial=0.0)) * 1e3, 3),
            "seconds_per_frame": seconds / max(n_frames, 1)}


def limit_sequence(points: np.ndarray, strain: StrainLimit, iterations: int = STRAIN_ITERATIONS,
                   on_frames=None) -> tuple[np.ndarray, dict]:
    """`limit_strain` over a sequence (T, V, 3), `strain_chunk_frames` frames at a time, written in place
    (`on_frames(n)` after each chunk of n frames, for a progress bar). Returns (points, the report's
    "strain_limit" entry)."""
    t0 = time.perf_counter()
    over, left, passes = [], [], 0
    chunk = strain_chunk_frames(points.shape[1])
    for s in range(0, len(points), chunk):
        fr = slice(s, s + chunk)
        points[fr], n, done = limit_strain(points[fr], strain, iterations)
        over.append(n)
        left.append(still_over(points[fr], strain))
        passes = max(passes, done)
        if on_frames is not None:
            on_frames(len(points[fr]))
    return points, strain_report(strain, iterations, over, passes, time.perf_counter() - t0, len(points), left)


def garment_strain(garment: Garment, rest: np.ndarray, limit: float, cache: dict) -> StrainLimit:
    """The StrainLimit of `garment` against its edges' lengths at `rest` (V, 3): the garment at rest as a deformer
    shaped it for the motion's body (as authored on the mean shape; a body of betas +5 lengthens a third of the
    example dress's edges by more than half at rest, which a limit against the authored lengths would pull back
    into the body). The garment's edges and adjacency are made once in `cache` (the deformer's), the rest lengths
    every call."""
    key = garment.content_hash()
    if key not in cache:
        cache.clear()
        edges = mesh_edges(garment.faces)
        cache[key] = edges, adjacency(edges, garment.n_vertices)
    return _strain_of(*cache[key], rest, limit)


def limit_garment(points: np.ndarray, garment: Garment, rest: np.ndarray, limit: float, cache: dict,
                  on_frames=None) -> tuple[np.ndarray, dict]:
    """`limit_sequence` of a deformer's output (T, V, 3) of `garment` against its lengths at `rest`
    (`garment_strain`; `on_frames` its progress). Returns (points, the report's entries: {"strain_limit": ...})."""
    strain = garment_strain(garment, rest, limit, cache)
    points, report = limit_sequence(np.ascontiguousarray(points, dtype=np.float32), strain, on_frames=on_frames)
    return points, {"strain_limit": report}
