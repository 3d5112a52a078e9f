"""The learned garment model of paper section 3.2: dynamic skinning weights and multi-scale blend shapes.

One network serves every garment and body shape (no per-garment parameters):
everything garment-specific enters as inputs built by `garment_inputs` from the
cached preprocessing (`core.preprocess`) and the LBS binding (`core.skinning`).

Per (garment, body shape), once ("rest-pose module", frozen in training phase 2):
  vertex features X (position, normal, joint distances) -> GAT encoder -> X^gg;
  Nystrom eigenvalues -> style MLP -> C^gs, added to X^gg and refined by an
  induced self-attention block (Set-Transformer ISAB: V x M attention through
  M learned inducing points instead of V x V, so 6k-vertex garments stay cheap)
  -> X^gg_hat; body joint-vertex distances D (N_b, S) -> shared MLP per body
  vertex, mean/max pooled (any body vertex count) -> C^bs;
  X^fuse = X^gg_hat * C^bs (element-wise).
Per frame, from a window of m frames:
  poses (axis-angle of the non-root joints, the up axis and the translation
  velocity in the root's frame: heading-invariant) -> LSTM E^t1 -> a (hidden, S)
  matrix M; skinning weights (Eq. 3) W = softmax_S(X^fuse M + log W_prior),
  where W_prior are the weights transferred from the body surface, so an
  untrained model starts as LBS;
  body-vertex velocities (pooled per joint by the body's skinning weights,
  root frame) -> LSTM E^t2 -> per-joint codes spread to garment vertices by W,
  plus a global code, combined with X^fuse -> multi-scale GAT U-Net over the
  pooling hierarchy -> blend shapes B (Eq. 4, rest frame, metres; output layer
  zero-initialised); two inputs beyond the paper (ModelConfig.shape_input,
  pose_codes; off in the models up to model_v5): per-joint codes from E^t1
  too, and each vertex's displacement by the body's shape, because a per-garment
  linear regression on pose and shape beat the network without them
  (benchmarks/results/error_ceiling.md);
  garment = LBS of T + B with W and the body's skinning transforms (Eq. 1-2).

Graph attention is PyG's GATv2Conv: `GATv2Weights` holds its parameters under
its names and initialisation (checkpoints load either way), so that the model
loads without importing torch_geometric (whose import pulls in torch._dynamo,
about a third of the command's start-up); `GATv2` evaluates it on a padded
(V, K) neighbour table with gather + masked softmax, which FACTS.md measured
about 2x faster on CPU and which batches frames; tests check it against
`GATv2Conv.forward` and its initialisation against GATv2Conv's.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import torch
import torch.nn.functional as F
from torch import nn

from core.body import Body
from core.errors import InputError

#: Floor of the prior weights before the log (joints with no transferred weight stay reachable).
PRIOR_FLOOR = 1e-4
#: ModelConfig.pooling values: ours, then the learned baselines of PyTorch Geometric.
POOLINGS = ("structure", "topk", "sag", "asap")
#: Blend shapes (Eq. 4) are squashed to at most m per vertex: m tanh(raw / m), the identity for small
#: offsets, so no input can fling a vertex far from the skinned garment. m is this many metres or this
#: fraction of the garment's largest extent, whichever is smaller.
MAX_BLEND_M = 0.25
MAX_BLEND_FRACTION = 0.2
#: Root and body-vertex speeds fed to the temporal encoders are clipped to this (m/s; a sprinter's
#: foot peaks near 20): a teleport or a broken frame reads as very fast motion, not as an input the
#: network never saw by orders of magnitude.
MAX_SPEED_M_S = 20.0
#: The shape displacement input (ModelConfig.shape_input) in centimetres (a body's shape moves the garment's
#: rest by 2-10 cm): its layer starts at zero and Adam moves each weight by about the learning rate per step,
#: so in decimetres the input took hundreds of steps to reach the features (weights 0.06 after 300 steps).
SHAPE_INPUT_SCALE = 100.0
#: ModelConfig inputs that a fine-tune may add to a trained network (`train --init` with them in --config),
#: each with the module of zero-initialised weights it brings: the network starts as the one it came from.
ADDABLE_INPUTS = {"shape_input": "shape_code", "pose_codes": "pose_codes"}


def keep_levels(state: dict, levels: int) -> dict:
    """A network's weights without those of its pooling levels from `levels` down (`GraphUNet`'s
    `unet.down/merge/up.<l>`): the start of the same network with fewer levels, its bottom layers then
    working one level finer (`garment train --init` with a smaller `"levels"` in --config)."""
    def level(key: str) -> int:
        parts = key.split(".")
        return int(parts[2]) if parts[0] == "unet" and parts[1] in ("down", "merge", "up") else -1
    return {k: v for k, v in state.items() if level(k) < levels}


@dataclass(frozen=True)
class ModelConfig:
    """Sizes of the network (stored in every checkpoint).

    n_joints: S, the body skeleton's joints (24 for SMPL). hidden: graph feature width.
    heads: GATv2 attention heads (hidden must divide by heads). encoder_layers: GAT blocks of E^gg.
    level_layers: GAT blocks per U-Net level on the way down and up; bottom_layers: at the coarsest.
    levels: pooling levels L of the U-Net (the preprocessing must have at least L).
    window: m, frames seen by the temporal encoders. lstm_hidden: their width.
    inducing_points: M of the self-attention block; attention_heads: its heads.
    n_eigenvalues: style descriptor length; n_landmarks: Nystrom N* (preprocessing settings).
    pooling: "structure" (the paper's structure-preserving hierarchy, precomputed per garment) or a
      learned baseline pooling of PyTorch Geometric, for the comparison of paper section 5: "topk"
      (TopKPooling), "sag" (SAGPooling), "asap" (ASAPooling), each keeping half the nodes per level.
    shape_input: 1 feeds each vertex's displacement by the body's shape (shaped rest - authored rest,
      rest frame) into the per-frame features through a zero-initialised layer, so the blend shapes see
      the body under each vertex directly and not only through the global code C^bs; 0 (the models up
      to model_v5) leaves it out. A network can gain it when fine-tuned (`train --init`): it starts as
      the network it came from.
    pose_codes: 1 adds per-joint codes from the pose encoder E^t1 to those of E^t2 (zero-initialised), so
      the blend shapes see each joint's pose and not only the body's velocities (the pose reached them only
      through the skinning weights); 0 (up to model_v5) leaves them out. Added by fine-tuning as shape_input.
    """

    n_joints: int = 24
    hidden: int = 32
    heads: int = 1
    encoder_layers: int = 2
    level_layers: int = 1
    bottom_layers: int = 2
    levels: int = 2
    window: int = 5
    lstm_hidden: int = 64
    inducing_points: int = 16
    attention_heads: int = 2
    n_eigenvalues: int = 16
    n_landmarks: int = 64
    pooling: str = "structure"
    shape_input: int = 0
    pose_codes: int = 0

    def validate(self, source: str = "model config") -> None:
        for name in ("n_joints", "hidden", "heads", "window", "lstm_hidden", "inducing_points",
                     "attention_heads", "n_eigenvalues", "n_landmarks"):
            if int(getattr(self, name)) < 1:
                raise InputError(f"{source}: expected {name} >= 1, got {getattr(self, name)!r}")
        for name in ("encoder_layers", "level_layers", "bottom_layers", "levels"):
            if int(getattr(self, name)) < 0:
                raise InputError(f"{source}: expected {name} >= 0, got {getattr(self, name)!r}")
        from core.preprocess import MAX_LEVELS

        if self.levels > MAX_LEVELS:  # (the garment's preprocessing refused it later, naming no config)
            raise InputError(f"{source}: expected levels from 0 to {MAX_LEVELS}, got {self.levels!r}")
        for name in ("shape_input", "pose_codes"):
            if getattr(self, name) not in (0, 1):
                raise InputError(f"{source}: expected {name} 0 or 1, got {getattr(self, name)!r}")
        if self.pooling not in POOLINGS:
            raise InputError(f"{source}: expected pooling among {', '.join(POOLINGS)}, got {self.pooling!r}")
        if self.hidden % self.heads or self.hidden % self.attention_heads:
            raise InputError(f"{source}: expected hidden ({self.hidden}) divisible by heads ({self.heads}) and "
                             f"attention_heads ({self.attention_heads})")

    @property
    def vertex_features(self) -> int:
        """Width of the input vertex features: position 3 + normal 3 + joint distances S."""
        return 6 + self.n_joints

    @property
    def pose_features(self) -> int:
        """Per-frame input of E^t1: (S-1) axis-angles, up axis, translation velocity."""
        return 3 * (self.n_joints - 1) + 6

    @property
    def velocity_features(self) -> int:
        """Per-frame input of E^t2: S joint-pooled body velocities and the up axis."""
        return 3 * self.n_joints + 3


def check_config_values(values: dict, source: str = "model config") -> dict:
    """Raise InputError naming `source` and the key for an unknown key or a value of the wrong type (a string for a
    string field, else an integer, not a bool) in a partial ModelConfig dict; returns the fields by name."""
    known = {f.name: f for f in dataclasses.fields(ModelConfig)}
    for key, val in values.items():
        if key not in known:
            raise InputError(f"{source}: unknown key '{key}' (expected one of {', '.join(known)})")
        want_str = known[key].type in (str, "str")
        if not (isinstance(val, str) if want_str else isinstance(val, (int, np.integer)) and not isinstance(val, bool)):
            raise InputError(f"{source}: model '{key}': expected {'a string' if want_str else 'an integer'}, "
                             f"got {val!r}")
    return known


def config_from_dict(values: dict, source: str = "model config") -> ModelConfig:
    """A ModelConfig from a dict (a --config's 'model' section, a checkpoint's config), checked by
    `check_config_values`."""
    known = check_config_values(values, source)
    cfg = ModelConfig(**{k: (str(v) if known[k].type in (str, "str") else int(v)) for k, v in values.items()})
    cfg.validate(source)
    return cfg


# ----------------------------------------------------------------------------------------------- graph inputs

def neighbour_table(edges: np.ndarray, n: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Padded incoming-neighbour table of an undirected graph, self loop first (GATv2Conv's default).

    edges: (E, 2) int, undirected, no self loops. Returns nbr (n, K) int64 (padding repeats the
    vertex itself) and mask (n, K) bool; K = 1 + max degree. Neighbours are in increasing order.
    """
    edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    edges = edges[edges[:, 0] != edges[:, 1]]
    src = np.r_[edges[:, 0], edges[:, 1]]
    dst = np.r_[edges[:, 1], edges[:, 0]]
    order = np.lexsort((src, dst))
    src, dst = src[order], dst[order]
    deg = np.bincount(dst, minlength=n)
    K = 1 + int(deg.max(initial=0))
    nbr = np.repeat(np.arange(n, dtype=np.int64)[:, None], K, axis=1)
    mask = np.zeros((n, K), dtype=bool)
    mask[:, 0] = True
    start = np.r_[0, np.cumsum(deg)[:-1]]
    col = 1 + np.arange(len(dst)) - np.repeat(start, deg)
    nbr[dst, col] = src
    mask[dst, col] = True
    return torch.from_numpy(nbr), torch.from_numpy(mask)


def padded_rows(m: sp.csr_matrix) -> tuple[torch.Tensor, torch.Tensor]:
    """A sparse (n, k) matrix as padded gather: index (n, K) int64, weight (n, K) float32 (0 where padded)."""
    m = sp.csr_matrix(m)
    m.sort_indices()
    n = m.shape[0]
    counts = np.diff(m.indptr)
    K = max(1, int(counts.max(initial=0)))
    idx = np.zeros((n, K), dtype=np.int64)
    w = np.zeros((n, K), dtype=np.float32)
    rows = np.repeat(np.arange(n), counts)
    col = np.arange(m.nnz) - np.repeat(m.indptr[:-1], counts)
    idx[rows, col] = m.indices
    w[rows, col] = m.data
    return torch.from_numpy(idx), torch.from_numpy(w)


@dataclass(frozen=True, eq=False)
class GarmentInputs:
    """What the network reads about one garment (rest frame, built by `garment_inputs`).

    features: (V, 6+S) float32. eigenvalues: (n_eig,) float32. prior_weights: (V, S) float32, rows sum to 1.
    rest: (V, 3) float32 metres. shapedirs: (V, 3, n_betas) float32 (garment follows the body's shape).
    nbr[l], mask[l]: (n_l, K_l) neighbour tables of level l. pool_index[l]: (n_{l+1},) int64 level-l rows.
    unpool_index[l], unpool_weight[l]: (n_l, K) padded rows of the level l+1 -> l unpooling matrix.
    faces: (F, 3) int64. edges: (E, 2) int64.
    """

    features: torch.Tensor
    eigenvalues: torch.Tensor
    prior_weights: torch.Tensor
    rest: torch.Tensor
    shapedirs: torch.Tensor
    nbr: list
    mask: list
    pool_index: list
    unpool_index: list
    unpool_weight: list
    faces: torch.Tensor
    edges: torch.Tensor

    @property
    def n_vertices(self) -> int:
        return int(self.rest.shape[0])


def garment_inputs(prep, binding, faces: np.ndarray, levels: int) -> GarmentInputs:
    """Tensors of `GarmentInputs` from a `core.preprocess.Preprocessed` and a `core.skinning.GarmentBinding`.

    levels: U-Net levels used (<= the hierarchy's). Raises InputError when the hierarchy is shallower.
    """
    h = prep.hierarchy
    if h.n_levels < levels:
        raise InputError(f"preprocessed garment: expected at least {levels} pooling levels, got {h.n_levels}")
    nbr, mask, pool, up_i, up_w = [], [], [], [], []
    for l in range(levels + 1):
        t, m = neighbour_table(h.edges[l], len(h.vertex_index[l]))
        nbr.append(t)
        mask.append(m)
    for l in range(levels):
        pool.append(torch.as_tensor(h.pool_index[l], dtype=torch.long))
        i, w = padded_rows(h.unpool[l])
        up_i.append(i)
        up_w.append(w)
    w = np.maximum(binding.weights, 0).astype(np.float32)
    w /= np.maximum(w.sum(1, keepdims=True), 1e-12)
    return GarmentInputs(
        features=torch.from_numpy(prep.features.as_array()),
        eigenvalues=torch.as_tensor(prep.descriptor.eigenvalues, dtype=torch.float32),
        prior_weights=torch.from_numpy(w), rest=torch.as_tensor(prep.features.positions, dtype=torch.float32),
        shapedirs=torch.as_tensor(binding.shapedirs, dtype=torch.float32), nbr=nbr, mask=mask, pool_index=pool,
        unpool_index=up_i, unpool_weight=up_w, faces=torch.as_tensor(faces, dtype=torch.long),
        edges=torch.as_tensor(prep.edges, dtype=torch.long))


# ------------------------------------------------------------------------------------------- body and motion

def body_distances(body: Body, betas: np.ndarray | None) -> torch.Tensor:
    """D of section 3.2.1: (N_b, S) float32 metres from each rest body vertex to each joint (shaped by betas)."""
    v, j = body.shaped(betas)
    return torch.from_numpy(np.linalg.norm(v[:, None, :] - j[None], axis=-1).astype(np.float32))


@dataclass(frozen=True, eq=False)
class MotionFeatures:
    """Per-frame inputs of one sequence on one body (all float32).

    pose: (T, 3(S-1)+6) E^t1 inputs. velocity: (T, 3S+3) E^t2 inputs.
    transforms: (T, S, 4, 4) skinning transforms (rest body of these betas -> world, Z-up, metres).
    """

    pose: torch.Tensor
    velocity: torch.Tensor
    transforms: torch.Tensor

    @property
    def n_frames(self) -> int:
        return int(self.pose.shape[0])


def _pooled_vertex_moments(body: Body, betas: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """P (S, S, 4) = sum_v w_vj w_vk [x_v, 1] over the rest body shaped by betas, and W (S,) = sum_v w_vj."""
    verts, _ = body.shaped(betas)
    w = np.asarray(body.weights, dtype=np.float64)
    xh = np.concatenate([verts.astype(np.float64), np.ones((len(verts), 1))], axis=1)
    P = np.stack([(w * xh[:, c:c + 1]).T @ w for c in range(4)], axis=-1)  # einsum "vj,vk,vc->jkc": 60x slower
    return P.astype(np.float32), np.maximum(w.sum(0), 1e-8).astype(np.float32)


def _clip_speed(v: np.ndarray) -> np.ndarray:
    """Scale each (..., 3) velocity down to at most MAX_SPEED_M_S, keeping its direction."""
    speed = np.linalg.norm(v, axis=-1, keepdims=True)
    return v * np.minimum(1.0, MAX_SPEED_M_S / np.maximum(speed, 1e-12))


def motion_features(body: Body, poses: np.ndarray, trans: np.ndarray, betas: np.ndarray | None,
                    fps: float) -> MotionFeatures:
    """Temporal-encoder inputs of a pose sequence.

    poses: (T, S, 3) axis-angle radians (body joint layout); trans: (T, 3) metres, Z-up world;
    betas: (n,) or None; fps: frames per second. Velocities are finite differences times fps (m/s),
    zero at frame 0, expressed in the root joint's frame (heading-invariant); body-vertex velocities are
    pooled per joint with the body's skinning weights (any body vertex count gives (S, 3); computed from
    the skinning transforms, pose correctives left out); speeds are clipped to MAX_SPEED_M_S.
    """
    poses = np.asarray(poses, dtype=np.float32)
    trans = np.asarray(trans, dtype=np.float32)
    T = poses.shape[0]
    A = body.skinning_transforms(poses, trans, betas)  # (T, S, 4, 4)
    # Skinning-weighted mean of the posed body vertices per joint, m_j(t) = sum_v w_vj x_v(t) / sum_v w_vj,
    # is linear in the transforms: x_v(t) = sum_k w_vk A_k(t) [x_v, 1], so m_j(t) = sum_k A_k(t) P_jk / W_j with
    # P_jk = sum_v w_vj w_vk [x_v, 1] computed once. No (T, Vb, 3) array is ever posed.
    P, W = _pooled_vertex_moments(body, betas)
    # optimize: a matrix product (about 45x faster than einsum's own loop for a 24-joint body)
    means = np.einsum("tkrc,jkc->tjr", A[:, :, :3, :], P, optimize=True) / W[None, :, None]  # (T, S, 3)
    vel = np.zeros_like(means)
    vel[1:] = (means[1:] - means[:-1]) * fps
    vel = _clip_speed(vel)
    R = A[:, 0, :3, :3]  # root's world rotation (T, 3, 3)
    Rt = np.transpose(R, (0, 2, 1))
    up = np.einsum("tij,j->ti", Rt, np.array([0.0, 0.0, 1.0], dtype=np.float32))
    dtrans = np.zeros_like(trans)
    dtrans[1:] = (trans[1:] - trans[:-1]) * fps
    dtrans = _clip_speed(np.einsum("tij,tj->ti", Rt, dtrans))
    pose = np.concatenate([poses[:, 1:].reshape(T, -1), up, dtrans], axis=1)
    pooled = np.einsum("tij,tsj->tsi", Rt, vel)
    velocity = np.concatenate([pooled.reshape(T, -1), up], axis=1)
    return MotionFeatures(torch.from_numpy(pose.astype(np.float32)), torch.from_numpy(velocity.astype(np.float32)),
                          torch.from_numpy(A.astype(np.float32)))


def window_index(frames: torch.Tensor | np.ndarray, m: int) -> torch.Tensor:
    """Frame indices of the windows ending at `frames` (B,): (B, m), oldest first, clamped at frame 0; on the
    device of a tensor `frames`."""
    f = frames.long() if isinstance(frames, torch.Tensor) else torch.as_tensor(np.asarray(frames), dtype=torch.long)
    return (f[:, None] + torch.arange(-m + 1, 1, device=f.device)[None]).clamp(min=0)


# ------------------------------------------------------------------------------------------------- layers

def gather_rows(x: torch.Tensor, index: torch.Tensor) -> torch.Tensor:
    """x[:, index] for x (B, n, ...) and index (m, K): (B, m, K, ...), by index_select (advanced indexing was
    about 2x slower on a CPU)."""
    return x.index_select(1, index.reshape(-1)).view(x.shape[0], *index.shape, *x.shape[2:])


def _glorot_(t: torch.Tensor) -> None:
    """PyG's `glorot`: uniform in +-sqrt(6 / (size(-2) + size(-1)))."""
    bound = math.sqrt(6.0 / (t.size(-2) + t.size(-1)))
    with torch.no_grad():
        t.uniform_(-bound, bound)


class GATv2Weights(nn.Module):
    """The parameters of PyG's `GATv2Conv(in_features, channels, heads=heads)` (concatenated heads, bias, no
    edge features, no residual, no shared weights): the same names (lin_l, lin_r, att, bias), shapes and
    initialisation, random numbers drawn in the same order (the same values after the same seed)."""

    negative_slope = 0.2

    def __init__(self, in_features: int, channels: int, heads: int):
        super().__init__()
        self.lin_l = nn.Linear(in_features, heads * channels)
        self.lin_r = nn.Linear(in_features, heads * channels)
        self.att = nn.Parameter(torch.empty(1, heads, channels))
        self.bias = nn.Parameter(torch.empty(heads * channels))
        self.reset_parameters()

    def reset_parameters(self) -> None:
        for lin in (self.lin_l, self.lin_r):  # PyG's Linear(weight_initializer="glorot"): bias +-1/sqrt(fan-in)
            _glorot_(lin.weight)
            with torch.no_grad():
                lin.bias.uniform_(-1.0 / math.sqrt(lin.in_features), 1.0 / math.sqrt(lin.in_features))
        _glorot_(self.att)
        nn.init.zeros_(self.bias)

    def pyg(self):
        """A torch_geometric GATv2Conv holding these parameters (the reference of the tests)."""
        from torch_geometric.nn import GATv2Conv

        conv = GATv2Conv(self.lin_l.in_features, self.att.shape[2], heads=self.att.shape[1], concat=True)
        conv.load_state_dict(self.state_dict())
        return conv.to(self.att.device)


class GATv2(nn.Module):
    """PyG's GATv2Conv (concatenated heads, self loops) evaluated on a padded neighbour table, batched.

    forward(x (B, n, F_in), nbr (n, K), mask (n, K)) -> (B, n, F_out).
    `reference(x (n, F_in), edge_index (2, E))` runs GATv2Conv.forward itself (for tests).
    """

    def __init__(self, in_features: int, out_features: int, heads: int = 1):
        super().__init__()
        self.heads, self.channels = heads, out_features // heads
        self.conv = GATv2Weights(in_features, self.channels, heads)

    def forward(self, x: torch.Tensor, nbr: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        B, n, _ = x.shape
        H, C = self.heads, self.channels
        K = nbr.shape[1]
        # In place when no gradient is taken (inference): two (B, n, K, H, C) temporaries fewer.
        inplace = not torch.is_grad_enabled()
        xl = self.conv.lin_l(x).view(B, n, H, C)
        xr = self.conv.lin_r(x).view(B, n, H, C)
        xj = gather_rows(xl, nbr)  # (B, n, K, H, C)
        e = F.leaky_relu(xj + xr[:, :, None], self.conv.negative_slope, inplace=inplace)
        if H == 1:  # a matrix product instead of broadcast-and-sum: no permuted copies
            score = (e.view(B, n, K, C) @ self.conv.att.view(C, 1)).view(B, n, K, 1)
        else:
            score = (e * self.conv.att.view(1, 1, 1, H, C)).sum(-1)  # (B, n, K, H)
        score = score.masked_fill(~mask[None, :, :, None], float("-inf"))
        alpha = torch.softmax(score, dim=2)[..., None]  # (B, n, K, H, 1)
        weighted = torch.mul(alpha, xj, out=e) if inplace else alpha * xj
        return weighted.sum(2).reshape(B, n, H * C) + self.conv.bias

    def reference(self, x: torch.Tensor, edge_index: torch.Tensor) -> torch.Tensor:
        return self.conv.pyg()(x, edge_index)


class GATBlock(nn.Module):
    """x + SiLU(GATv2(x)): a residual graph-attention block of constant width."""

    def __init__(self, width: int, heads: int):
        super().__init__()
        self.gat = GATv2(width, width, heads)

    def forward(self, x, nbr, mask):
        return x + F.silu(self.gat(x, nbr, mask))


def _last_state(lstm: nn.LSTM, x: torch.Tensor) -> torch.Tensor:
    """The last layer's final hidden state of `lstm` over the (B, window, features) sequence `x`, in the weights'
    precision even under bfloat16 autocast: oneDNN has no bfloat16 LSTM on CPUs without native bfloat16 (it raised "could not
    create a primitive descriptor" on an AMD EPYC with AVX2 only), and the two LSTMs are a sliver of the cost."""
    with torch.autocast(device_type=x.device.type, enabled=False):
        _, (h, _) = lstm(x.to(lstm.weight_ih_l0.dtype))
    return h[-1]


def zero_linear(a: int, b: int) -> nn.Linear:
    """nn.Linear(a, b) with zero weights and bias: a head or added input that starts by changing nothing."""
    layer = nn.Linear(a, b)
    nn.init.zeros_(layer.weight)
    nn.init.zeros_(layer.bias)
    return layer


def mlp(sizes: list[int]) -> nn.Sequential:
    layers = []
    for a, b in zip(sizes[:-1], sizes[1:]):
        layers += [nn.Linear(a, b), nn.SiLU()]
    return nn.Sequential(*layers[:-1])


class InducedSelfAttention(nn.Module):
    """Set-Transformer ISAB over vertices: H = MHA(I, X, X); X + MHA(X, H, H), layer-normalised. (n, C)."""

    def __init__(self, width: int, inducing: int, heads: int):
        super().__init__()
        self.inducing = nn.Parameter(torch.randn(1, inducing, width) / math.sqrt(width))
        self.gather = nn.MultiheadAttention(width, heads, batch_first=True)
        self.scatter = nn.MultiheadAttention(width, heads, batch_first=True)
        self.norm = nn.LayerNorm(width)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        x = x[None]
        h, _ = self.gather(self.inducing, x, x, need_weights=False)
        y, _ = self.scatter(x, h, h, need_weights=False)
        return self.norm(x + y)[0]


class RestPoseModule(nn.Module):
    """Garment encoder, style encoder + self-attention, body-shape encoder: -> X^fuse (V, hidden)."""

    def __init__(self, cfg: ModelConfig):
        super().__init__()
        h = cfg.hidden
        self.inp = nn.Linear(cfg.vertex_features, h)
        self.encoder = nn.ModuleList(GATBlock(h, cfg.heads) for _ in range(cfg.encoder_layers))
        self.style = mlp([cfg.n_eigenvalues, h, h])
        self.attention = InducedSelfAttention(h, cfg.inducing_points, cfg.attention_heads)
        self.body_point = mlp([cfg.n_joints, h, h])
        self.body_shape = mlp([2 * h, h, h])
        # C^bs starts near 1 so the product does not wipe the garment features at initialisation.
        nn.init.normal_(self.body_shape[-1].weight, std=0.01)
        nn.init.ones_(self.body_shape[-1].bias)

    def forward(self, g: GarmentInputs, body_dist: torch.Tensor) -> torch.Tensor:
        x = self.inp(g.features)[None]
        for blk in self.encoder:
            x = blk(x, g.nbr[0], g.mask[0])
        eig = torch.log(g.eigenvalues.clamp(min=0) + 1e-4) / 5.0
        x = self.attention(x[0] + self.style(eig)[None])
        p = self.body_point(body_dist)  # (N_b, h)
        c_bs = self.body_shape(torch.cat([p.mean(0), p.max(0).values]))
        return x * c_bs[None]


class GraphUNet(nn.Module):
    """Multi-scale GAT U-Net over the pooling hierarchy (section 3.3): (B, V, h) -> (B, V, 3)."""

    def __init__(self, cfg: ModelConfig):
        super().__init__()
        h, L = cfg.hidden, cfg.levels
        self.levels = L
        self.down = nn.ModuleList(nn.ModuleList(GATBlock(h, cfg.heads) for _ in range(cfg.level_layers))
                                  for _ in range(L))
        self.bottom = nn.ModuleList(GATBlock(h, cfg.heads) for _ in range(cfg.bottom_layers))
        self.merge = nn.ModuleList(nn.Linear(2 * h, h) for _ in range(L))
        self.up = nn.ModuleList(nn.ModuleList(GATBlock(h, cfg.heads) for _ in range(cfg.level_layers))
                                for _ in range(L))
        self.out = zero_linear(h, 3)

    def forward(self, x: torch.Tensor, g: GarmentInputs) -> torch.Tensor:
        skips = []
        for l in range(self.levels):
            for blk in self.down[l]:
                x = blk(x, g.nbr[l], g.mask[l])
            skips.append(x)
            x = x.index_select(1, g.pool_index[l])
        for blk in self.bottom:
            x = blk(x, g.nbr[self.levels], g.mask[self.levels])
        for l in reversed(range(self.levels)):
            x = (gather_rows(x, g.unpool_index[l]) * g.unpool_weight[l][None, :, :, None].to(x.dtype)).sum(2)
            x = F.silu(self.merge[l](torch.cat([x, skips[l]], dim=-1)))
            for blk in self.up[l]:
                x = blk(x, g.nbr[l], g.mask[l])
        return self.out(x)


class LearnedPoolUNet(nn.Module):
    """The U-Net of `GraphUNet` with a learned PyTorch Geometric pooling in place of ours (the baselines).

    Level 0 is the garment graph; each pooling keeps half the nodes of the level above, chosen from
    the features of each frame (TopK, SAG: scored nodes and the edges among them; ASAP: clusters),
    so coarse graphs differ between frames and are processed frame by frame with GATv2Conv on edge
    lists. Unpooling scatters the pooled features back to the kept nodes (zeros elsewhere), as in
    Graph U-Nets, then merges with the skip connection. (B, V, h) -> (B, V, 3).
    """

    def __init__(self, cfg: ModelConfig):
        super().__init__()
        from torch_geometric.nn import ASAPooling, GATv2Conv, SAGPooling, TopKPooling

        h, L = cfg.hidden, cfg.levels
        self.levels = L
        make = {"topk": lambda: TopKPooling(h, ratio=0.5), "sag": lambda: SAGPooling(h, ratio=0.5),
                "asap": lambda: ASAPooling(h, ratio=0.5)}[cfg.pooling]
        self.kind = cfg.pooling
        self.pools = nn.ModuleList(make() for _ in range(L))
        # Level 0 (the garment's own graph) uses GAT blocks on its neighbour table; levels 1..L-1 GATv2Conv on
        # each frame's pooled edges; the bottom (level L) likewise.
        def fine():
            return nn.ModuleList(GATBlock(h, cfg.heads) for _ in range(cfg.level_layers if L else 0))

        def coarse():
            return nn.ModuleList(nn.ModuleList(GATv2Conv(h, h // cfg.heads, heads=cfg.heads)
                                               for _ in range(cfg.level_layers)) for _ in range(max(L - 1, 0)))

        self.down, self.up = fine(), fine()
        self.coarse, self.coarse_up = coarse(), coarse()
        self.bottom = nn.ModuleList(GATv2Conv(h, h // cfg.heads, heads=cfg.heads) for _ in range(cfg.bottom_layers))
        self.merge = nn.ModuleList(nn.Linear(2 * h, h) for _ in range(L))
        self.out = zero_linear(h, 3)

    def _pool(self, l: int, x: torch.Tensor, edge_index: torch.Tensor):
        if self.kind == "asap":
            x, edge_index, _, _, perm = self.pools[l](x, edge_index)
        else:
            x, edge_index, _, _, perm, _ = self.pools[l](x, edge_index)
        return x, edge_index, perm

    def _descend(self, xb: torch.Tensor, g: GarmentInputs):
        """The way down for one frame: (coarsest features, its edge_index, skips, perms, edge_index per level)."""
        skips, perms, edges = [], [], []
        y, edge_index = xb, _both_directions(g.edges)
        for l in range(self.levels):
            y = self._level_blocks(y, l, edge_index, g, self.down, self.coarse[l - 1] if l else None)
            skips.append(y)
            edges.append(edge_index)
            y, edge_index, perm = self._pool(l, y, edge_index)
            perms.append(perm)
        return y, edge_index, skips, perms, edges

    def pooled_graphs(self, x: torch.Tensor, g: GarmentInputs) -> list[tuple[np.ndarray, torch.Tensor]]:
        """Levels for one frame's features x (V, h), as the forward pass pools them (for diagnostics).

        Returns per level (kept: level-0 vertex indices of its nodes, edge_index (2, E) among them).
        """
        _, last_edges, _, perms, edges = self._descend(x, g)
        kept = [np.arange(x.shape[0])]
        for perm in perms:
            kept.append(kept[-1][perm.cpu().numpy()])
        return list(zip(kept, [*edges, last_edges]))

    def forward(self, x: torch.Tensor, g: GarmentInputs) -> torch.Tensor:
        frames = []
        for xb in x:
            y, edge_index, skips, perms, edges = self._descend(xb, g)
            for conv in self.bottom:
                y = y + F.silu(conv(y, edge_index))
            for l in reversed(range(self.levels)):
                up = skips[l].new_zeros(skips[l].shape).index_copy(0, perms[l], y)
                y = F.silu(self.merge[l](torch.cat([up, skips[l]], dim=-1)))
                y = self._level_blocks(y, l, edges[l], g, self.up, self.coarse_up[l - 1] if l else None)
            frames.append(y)
        return self.out(torch.stack(frames))

    @staticmethod
    def _level_blocks(y, l, edge_index, g, fine_blocks, coarse_convs):
        """Level 0: the garment's GAT blocks on its neighbour table; coarser: GATv2Conv on this frame's edges."""
        if l == 0:
            for blk in fine_blocks:
                y = blk(y[None], g.nbr[0], g.mask[0])[0]
            return y
        for conv in coarse_convs:
            y = y + F.silu(conv(y, edge_index))
        return y


def _both_directions(edges: torch.Tensor) -> torch.Tensor:
    """(E, 2) undirected edges -> (2, 2E) edge_index with both directions."""
    e = edges.t()
    return torch.cat([e, e.flip(0)], dim=1)


@dataclass
class ModelOutput:
    """verts: (B, V, 3) world, metres. weights: (B, V, S) skinning weights. blend: (B, V, 3) rest-frame offsets."""

    verts: torch.Tensor
    weights: torch.Tensor
    blend: torch.Tensor


class GarmentModel(nn.Module):
    """The whole network. `encode` once per (garment, body shape); `forward_frames` per batch of frames."""

    def __init__(self, cfg: ModelConfig = ModelConfig()):
        super().__init__()
        cfg.validate()
        self.config = cfg
        h, S = cfg.hidden, cfg.n_joints
        self.rest_pose = RestPoseModule(cfg)
        self.temporal_pose = nn.LSTM(cfg.pose_features, cfg.lstm_hidden, batch_first=True)
        self.skinning = zero_linear(cfg.lstm_hidden, h * S)
        self.temporal_velocity = nn.LSTM(cfg.velocity_features, cfg.lstm_hidden, batch_first=True)
        self.joint_codes = nn.Linear(cfg.lstm_hidden, h * S)
        self.global_code = nn.Linear(cfg.lstm_hidden, h)
        self.combine = nn.Linear(2 * h, h)
        if cfg.shape_input:
            self.shape_code = zero_linear(3, h)
        if cfg.pose_codes:
            self.pose_codes = zero_linear(cfg.lstm_hidden, h * S)
        self.unet = GraphUNet(cfg) if cfg.pooling == "structure" else LearnedPoolUNet(cfg)

    def check_inputs(self, g: GarmentInputs) -> None:
        cfg = self.config
        if g.features.shape[1] != cfg.vertex_features or g.prior_weights.shape[1] != cfg.n_joints:
            raise InputError(f"garment inputs: the model expects a {cfg.n_joints}-joint body, got features for "
                             f"{g.prior_weights.shape[1]} joints")
        if g.eigenvalues.shape[0] != cfg.n_eigenvalues:
            raise InputError(f"garment inputs: expected {cfg.n_eigenvalues} style eigenvalues, got {g.eigenvalues.shape[0]}")
        if len(g.pool_index) < cfg.levels:
            raise InputError(f"garment inputs: expected {cfg.levels} pooling levels, got {len(g.pool_index)}")

    def encode(self, g: GarmentInputs, body_dist: torch.Tensor) -> torch.Tensor:
        """X^fuse: (V, hidden). body_dist: (N_b, S) from `body_distances`."""
        self.check_inputs(g)
        return self.rest_pose(g, body_dist)

    def forward_frames(self, fused: torch.Tensor, g: GarmentInputs, rest: torch.Tensor, pose_win: torch.Tensor,
                       vel_win: torch.Tensor, transforms: torch.Tensor, skip_joints: bool = True,
                       shape_rest: torch.Tensor | None = None) -> ModelOutput:
        """Garment vertices for B frames.

        skip_joints: leave joints without prior weight on any vertex out of the per-vertex sums (their
        weights are exactly 0, so the result is the same; `bake --no-skip joints` turns it off).

        fused: (V, h) from `encode`. rest: (V, 3) rest garment on the shaped body (metres); shape_rest: the rest
        garment on the shape the network is given (shape_input; None: `rest`'s).
        pose_win: (B, m, 3(S-1)+6); vel_win: (B, m, 3S+3) windows ending at each frame.
        transforms: (B, S, 4, 4) skinning transforms of each frame.
        """
        B = pose_win.shape[0]
        S, h = self.config.n_joints, self.config.hidden
        h1 = _last_state(self.temporal_pose, pose_win)
        M = self.skinning(h1).view(B, h, S)
        logits = torch.einsum("vc,bcs->bvs", fused, M) / math.sqrt(h)
        # Only joints with transferred (prior) weight at a vertex may move it: joints that do not influence a
        # region are never computed into it, and no learned weights can carry a vertex to a distant bone.
        logits = logits.masked_fill((g.prior_weights <= 0)[None], float("-inf"))
        # In float32 also under bfloat16 autocast: rounded weights would move vertices by millimetres.
        weights = torch.softmax(logits.float() + torch.log(g.prior_weights + PRIOR_FLOOR)[None], dim=-1)  # Eq. 3
        h2 = _last_state(self.temporal_velocity, vel_win)
        codes = self.joint_codes(h2).view(B, S, h)
        if self.config.pose_codes:
            codes = codes + self.pose_codes(h1).view(B, S, h)
        used = (g.prior_weights > 0).any(0) if skip_joints else None
        w_used = weights if used is None else weights[..., used]
        if used is not None:
            codes, transforms = codes[:, used], transforms[:, used]
        per_vertex = torch.einsum("bvs,bsc->bvc", w_used, codes)
        pre = (self.combine(torch.cat([fused[None].expand(B, -1, -1), per_vertex], dim=-1))
               + self.global_code(h2)[:, None])
        if self.config.shape_input:
            seen = rest if shape_rest is None else shape_rest
            pre = pre + self.shape_code(SHAPE_INPUT_SCALE * (seen - g.rest).to(pre.dtype))[None]
        x = F.silu(pre)
        cap = torch.clamp(MAX_BLEND_FRACTION * (rest.amax(0) - rest.amin(0)).max(), max=MAX_BLEND_M).detach()
        blend = cap * torch.tanh(self.unet(x, g).float() / cap)  # Eq. 4, bounded
        with torch.autocast(device_type=blend.device.type, enabled=False):  # world coordinates in float32
            shaped = rest[None] + blend  # Eq. 2
            Mx = torch.einsum("bvs,bsrc->bvrc", w_used, transforms[:, :, :3, :])
            # Eq. 1; multiply-and-sum: as einsum it was a batched product of B * V 3x3 matrices (slow on a CPU)
            verts = (Mx[..., :3] * shaped[:, :, None, :]).sum(-1) + Mx[..., 3]
        return ModelOutput(verts=verts, weights=weights, blend=blend)


def tensors_to(obj, device):
    """A copy of the frozen dataclass `obj` with every tensor field (also in lists and nested dataclasses) on
    `device`; other fields (arrays, sparse matrices, strings) shared. The same object when nothing moves."""
    def move(v):
        if isinstance(v, torch.Tensor):
            return v.to(device)
        if isinstance(v, list):
            return [move(u) for u in v]
        if dataclasses.is_dataclass(v) and not isinstance(v, type):
            return tensors_to(v, device)
        return v

    values = {f.name: getattr(obj, f.name) for f in dataclasses.fields(obj) if f.init}
    moved = {k: move(v) for k, v in values.items()}
    if all(moved[k] is v or (isinstance(v, list) and all(a is b for a, b in zip(moved[k], v)))
           for k, v in values.items()):
        return obj
    return dataclasses.replace(obj, **moved)


def shaped_rest(g: GarmentInputs, body: Body, betas: np.ndarray | None) -> torch.Tensor:
    """The garment's rest vertices on the body shaped by betas: (V, 3) float32, metres."""
    b = torch.from_numpy(body.fit_betas(betas)).to(g.shapedirs.device)
    n = min(g.shapedirs.shape[2], b.shape[0])
    return g.rest + torch.einsum("vcs,s->vc", g.shapedirs[..., :n], b[:n])


def count_parameters(model: nn.Module) -> int:
    return sum(p.numel() for p in model.parameters())
