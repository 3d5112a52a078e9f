"""core/body.py: lbs() against a per-vertex loop, beta fitting, and the embedded default body."""

from __future__ import annotations

import logging
import math
from importlib import resources

import numpy as np
import pytest
import torch

from core.body import SMPL_JOINT_NAMES, SMPL_PARENTS, body_from_arrays, default_body, lbs


def _rodrigues(aa):
    """Axis-angle (3,) -> rotation matrix, written out."""
    theta = math.sqrt(sum(a * a for a in aa))
    if theta < 1e-12:
        return np.eye(3)
    k = np.asarray(aa) / theta
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(theta) * K + (1 - math.cos(theta)) * K @ K


def naive_lbs(betas, pose, v_template, shapedirs, posedirs, J_regressor, parents, weights):
    """SMPL, one vertex and one joint at a time (float64). betas (S,), pose (J,3)."""
    V, J = v_template.shape[0], len(parents)
    v_shaped = np.array([[v_template[v, c] + sum(shapedirs[v, c, s] * betas[s] for s in range(len(betas)))
                          for c in range(3)] for v in range(V)])
    joints = np.array([[sum(J_regressor[j, v] * v_shaped[v, c] for v in range(V)) for c in range(3)]
                       for j in range(J)])
    R = [_rodrigues(pose[j]) for j in range(J)]
    feature = np.concatenate([(R[j] - np.eye(3)).reshape(-1) for j in range(1, J)])
    v_posed = v_shaped.copy()
    if posedirs is not None:
        for v in range(V):
            for c in range(3):
                v_posed[v, c] += sum(posedirs[v, c, p] * feature[p] for p in range(len(feature)))
    G = []
    for j in range(J):
        local = np.eye(4)
        local[:3, :3] = R[j]
        local[:3, 3] = joints[j] - (joints[parents[j]] if parents[j] >= 0 else 0)
        G.append(local if parents[j] < 0 else G[parents[j]] @ local)
    A = []
    for j in range(J):
        a = G[j].copy()
        a[:3, 3] -= G[j][:3, :3] @ joints[j]
        A.append(a)
    verts = np.zeros((V, 3))
    for v in range(V):
        T = sum(weights[v, j] * A[j] for j in range(J))
        verts[v] = T[:3, :3] @ v_posed[v] + T[:3, 3]
    return verts, np.array([g[:3, 3] for g in G])


def tiny_body(n_joints=24, V=12, S=4, seed=0, with_posedirs=True):
    rng = np.random.default_rng(seed)
    parents = list(SMPL_PARENTS) if n_joints == 24 else [-1] + [int(rng.integers(0, j)) for j in range(1, n_joints)]
    w = rng.random((V, n_joints)) ** 3
    Jr = rng.random((n_joints, V))
    return {
        "v_template": rng.normal(size=(V, 3)),
        "shapedirs": rng.normal(size=(V, 3, S)) * 0.1,
        "posedirs": rng.normal(size=(V, 3, 9 * (n_joints - 1))) * 0.05 if with_posedirs else None,
        "J_regressor": Jr / Jr.sum(1, keepdims=True),
        "weights": w / w.sum(1, keepdims=True),
        "parents": np.array(parents),
        "faces": np.array([[0, 1, 2], [2, 3, 4]]),
    }


@pytest.mark.parametrize("with_posedirs", [True, False])
def test_lbs_matches_naive_loop(with_posedirs):
    a = tiny_body(with_posedirs=with_posedirs)
    rng = np.random.default_rng(1)
    B = 3
    betas = rng.normal(size=(B, 4))
    pose = rng.normal(scale=0.7, size=(B, 24, 3))
    pose[0, 5] = 0.0  # a zero rotation among them
    t = lambda x: None if x is None else torch.as_tensor(x, dtype=torch.float64)  # noqa: E731
    verts, joints, A = lbs(t(betas), t(pose), t(a["v_template"]), t(a["shapedirs"]), t(a["posedirs"]),
                           t(a["J_regressor"]), torch.as_tensor(a["parents"]), t(a["weights"]),
                           return_transforms=True)
    for b in range(B):
        v_ref, j_ref = naive_lbs(betas[b], pose[b], a["v_template"], a["shapedirs"], a["posedirs"],
                                 a["J_regressor"], a["parents"], a["weights"])
        np.testing.assert_allclose(verts[b].numpy(), v_ref, atol=1e-10)
        np.testing.assert_allclose(joints[b].numpy(), j_ref, atol=1e-10)
    # A maps a rest point of the shaped body rigidly with its joint (no pose correctives).
    if not with_posedirs:
        v_shaped = a["v_template"] + np.einsum("vcs,s->vc", a["shapedirs"], betas[0])
        j_rest = a["J_regressor"] @ v_shaped
        mapped = np.einsum("jrc,jc->jr", A[0, :, :3, :3].numpy(), j_rest) + A[0, :, :3, 3].numpy()
        np.testing.assert_allclose(mapped, joints[0].numpy(), atol=1e-10)


def test_body_pose_float32_matches_naive_with_translation():
    a = tiny_body(n_joints=7, V=9, S=3, seed=3)
    body = body_from_arrays(a, name="tiny")
    rng = np.random.default_rng(4)
    pose = rng.normal(scale=0.5, size=(5, 7, 3))
    trans = rng.normal(size=(5, 3))
    betas = np.array([0.5, -1.0, 2.0])
    verts, joints = body.pose(pose, trans=trans, betas=betas, batch_size=2)
    assert verts.shape == (5, 9, 3) and verts.dtype == np.float32
    for f in range(5):
        v_ref, j_ref = naive_lbs(betas, pose[f], *(a[k] for k in ("v_template", "shapedirs", "posedirs",
                                                                  "J_regressor", "parents", "weights")))
        np.testing.assert_allclose(verts[f], v_ref + trans[f], atol=2e-5)
        np.testing.assert_allclose(joints[f], j_ref + trans[f], atol=2e-5)


@pytest.mark.parametrize("with_posedirs", [True, False])
def test_body_posed_at_some_vertices_is_the_naive_body_there(with_posedirs):
    """`Body.pose_at`: the posed body at the ids given only (arrays in, arrays out; tensors in, tensors out), as
    the whole body posed there; another set of ids after it is not served the first's rows."""
    a = tiny_body(n_joints=7, V=9, S=3, seed=5, with_posedirs=with_posedirs)
    body = body_from_arrays(a, name="tiny")
    rng = np.random.default_rng(6)
    pose = rng.normal(scale=0.5, size=(4, 7, 3))
    trans = rng.normal(size=(4, 3))
    betas = np.array([1.0, -0.5, 0.3])
    for ids in (np.array([1, 4, 5, 8]), np.array([0, 2])):
        got = body.pose_at(ids, pose, trans, betas)
        assert isinstance(got, np.ndarray) and got.shape == (4, len(ids), 3) and got.dtype == np.float32
        for f in range(4):
            v_ref, _ = naive_lbs(betas, pose[f], *(a[k] for k in ("v_template", "shapedirs", "posedirs",
                                                                  "J_regressor", "parents", "weights")))
            np.testing.assert_allclose(got[f], v_ref[ids] + trans[f], atol=2e-5)
        tensor = body.pose_at(ids, torch.from_numpy(pose.astype(np.float32)),
                              torch.from_numpy(trans.astype(np.float32)), betas)
        assert isinstance(tensor, torch.Tensor)
        np.testing.assert_allclose(tensor.numpy(), got, atol=1e-6)


def test_fit_betas_pads_and_truncates_with_warning(caplog):
    body = body_from_arrays(tiny_body(), name="tiny")  # 4 betas
    with caplog.at_level(logging.WARNING, logger="core.body"):
        padded = body.fit_betas(np.array([1.0, 2.0]))
    np.testing.assert_array_equal(padded, [1, 2, 0, 0])
    assert any("padded" in r.getMessage() for r in caplog.records)
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="core.body"):
        cut = body.fit_betas(np.arange(1.0, 17.0))
    np.testing.assert_array_equal(cut, [1, 2, 3, 4])
    assert any("ignored" in r.getMessage() for r in caplog.records)
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="core.body"):
        body.fit_betas(np.array([1.0, 2.0, 3.0, 4.0, 0.0, 0.0]))  # trailing zeros change nothing
        body.fit_betas(None)
    assert not caplog.records


def test_fit_betas_warning_names_its_source_and_note_on_one_line(caplog):
    """The warning leads with where the betas come from and ends with the caller's note; fitted betas warn no
    more (a caller that fits a motion's betas once warns once)."""
    body = body_from_arrays(tiny_body(), name="tiny")  # 4 betas
    with caplog.at_level(logging.WARNING, logger="core.body"):
        fitted = body.fit_betas(np.arange(1.0, 17.0), source="motion 'smplh.npz'", note="fitted to SMPL+H")
        body.fit_betas(fitted)
    assert [r.getMessage() for r in caplog.records] == [
        "motion 'smplh.npz': 16 betas given, body 'tiny' has 4 shape coefficients: extra ones ignored "
        "(fitted to SMPL+H)"]


# --- the embedded default body ------------------------------------------------------------


@pytest.fixture(scope="module")
def body():
    return default_body()


def test_default_body_layout(body):
    assert body.n_joints == 24 and body.layout == "smpl"
    assert body.parents.tolist() == list(SMPL_PARENTS)
    assert body.joint_names == SMPL_JOINT_NAMES
    assert body.n_betas >= 10
    assert body.posedirs is None
    assert body.v_template.dtype == np.float32 and body.faces.min() >= 0
    np.testing.assert_allclose(body.weights.sum(1), 1.0, atol=1e-5)
    assert body.weights.min() >= 0
    np.testing.assert_allclose(body.J_regressor.sum(1), 1.0, atol=1e-4)


def test_default_body_is_a_y_up_t_pose(body):
    v = body.v_template
    j = body.J_regressor @ v
    idx = {n: i for i, n in enumerate(SMPL_JOINT_NAMES)}
    height = v[:, 1].max() - v[:, 1].min()
    assert 1.5 < height < 1.9
    assert np.linalg.norm(j[idx["pelvis"]]) < 0.05  # pelvis at the origin
    # Arms along +-X at shoulder height; the body's left at +X.
    for side, sign in (("left", 1), ("right", -1)):
        s, e, w, h = (j[idx[f"{side}_{n}"]] for n in ("shoulder", "elbow", "wrist", "hand"))
        for p in (e, w, h):
            assert abs(p[1] - s[1]) < 0.03 and abs(p[2] - s[2]) < 0.03
        assert sign * s[0] < sign * e[0] < sign * w[0] < sign * h[0]
        assert sign * h[0] > 0.6
        # Legs hang down, feet at the bottom, toes forward (+Z).
        hip, knee, ankle, foot = (j[idx[f"{side}_{n}"]] for n in ("hip", "knee", "ankle", "foot"))
        assert hip[1] > knee[1] > ankle[1]
        assert sign * hip[0] > 0
        assert foot[2] > ankle[2] + 0.05
        assert ankle[1] - v[:, 1].min() < 0.12
    assert j[idx["head"]][1] > j[idx["neck"]][1] > j[idx["spine3"]][1] > j[idx["pelvis"]][1]
    assert v[:, 1].max() - j[idx["head"]][1] < 0.3
    # The widest extent is the arm span, along X.
    extent = v.max(0) - v.min(0)
    assert extent[0] > extent[1] * 0.9 and extent[0] > 5 * extent[2]


def test_default_body_betas_change_shape_smoothly(body):
    v0, j0 = body.shaped(None)
    v1, j1 = body.shaped(np.eye(body.n_betas)[0] * 2.0)
    d = np.linalg.norm(v1 - v0, axis=1)
    assert 0.01 < d.max() < 0.4  # two standard deviations: centimetres, not metres
    assert np.isfinite(v1).all()


def test_default_body_bends_sanely(body):
    idx = {n: i for i, n in enumerate(SMPL_JOINT_NAMES)}
    pose = np.zeros((2, 24, 3), dtype=np.float32)
    pose[0, idx["left_elbow"]] = [0, -np.pi / 2, 0]  # forearm forward
    pose[1, idx["left_shoulder"]] = [0, 0, 1.2]  # arm raised
    verts, joints = body.pose(pose)
    assert np.isfinite(verts).all()
    # The wrist follows its bone: 90 degrees at the elbow puts it in front of the elbow.
    e, w = joints[0, idx["left_elbow"]], joints[0, idx["left_wrist"]]
    rest = body.J_regressor @ body.v_template
    forearm = np.linalg.norm(rest[idx["left_wrist"]] - rest[idx["left_elbow"]])
    np.testing.assert_allclose(w - e, [0, 0, forearm], atol=1e-4)
    assert joints[1, idx["left_hand"], 1] > rest[idx["left_hand"], 1] + 0.2
    # The skin moves with the skeleton: vertices stay close to where their joints went.
    for f in range(2):
        bone = body.weights.argmax(1)
        shift = np.linalg.norm((verts[f] - joints[f][bone]) - (body.v_template - rest[bone]), axis=1)
        assert np.median(shift) < 0.02 and shift.max() < 0.35


def test_default_body_file_is_small():
    ref = resources.files("core.assets").joinpath("default_body.npz")
    with resources.as_file(ref) as path:
        assert path.stat().st_size < 6e6


@pytest.mark.parametrize("layout", ["smplh", "smplx"])
def test_an_smplh_or_smplx_body_seen_on_smpls_joints_poses_as_itself_with_the_hands_at_rest(layout):
    """`Body.smpl_view` (a model of SMPL's 24 joints on an SMPL+H or SMPL-X body): SMPL's skeleton, the fingers'
    weights back on the hand joints (and SMPL-X's jaw and eyes on the head), and posed by the 22 body joints
    with the hands at rest it puts every vertex where the whole body does (its pose correctives included)."""
    from tests.meshes import tiny_body, with_fingers

    small = tiny_body()
    body = body_from_arrays(with_fingers(small, layout), layout)
    assert body.layout == layout and body.posedirs is not None
    view = body.smpl_view()
    assert view is body.smpl_view() and small.smpl_view() is None and view.layout == "smpl"
    np.testing.assert_array_equal(view.parents, SMPL_PARENTS)
    assert view.joint_names == SMPL_JOINT_NAMES and view.name == layout
    np.testing.assert_allclose(view.weights, small.weights, atol=1e-6)  # the fingers' split summed back
    roots = [j for j in range(22, body.n_joints) if body.parents[j] == 20]
    assert len(roots) == 5
    np.testing.assert_allclose(view.J_regressor[22], body.J_regressor[roots].mean(0), atol=1e-7)
    rng = np.random.default_rng(1)
    poses = np.zeros((3, body.n_joints, 3), np.float32)
    poses[:, :22] = 0.4 * rng.standard_normal((3, 22, 3))
    trans = rng.standard_normal((3, 3)).astype(np.float32)
    betas = rng.standard_normal(small.n_betas).astype(np.float32)
    whole, _ = body.pose(poses, trans, betas)
    seen, _ = view.pose(np.concatenate([poses[:, :22], np.zeros((3, 2, 3), np.float32)], 1), trans, betas)
    np.testing.assert_allclose(seen, whole, atol=1e-5)
    # the body's correctives are the view's: without them its vertices move
    bare = body_from_arrays(with_fingers(small, layout, seed=None), layout)
    assert np.abs(bare.pose(poses, trans, betas)[0] - whole).max() > 1e-3


@pytest.mark.parametrize("layout", ["smplh", "smplx"])
def test_a_body_file_names_its_joints_by_its_layout_or_by_its_own_names(layout, tmp_path):
    """SMPL+H's and SMPL-X's files name no joints: their first 22 are SMPL's (so that what looks joints up by name,
    LBS's legs' spread, finds the legs; they were 'joint1'...), then SMPL-X's jaw and eyes and the fingers; a file
    that names its joints keeps its names, and one whose names are not one string per joint is refused."""
    from core.body import default_joint_names
    from core.errors import InputError
    from formats.body import load_body
    from tests.meshes import tiny_body, with_fingers

    arrays = with_fingers(tiny_body(), layout)
    np.savez(tmp_path / "plain.npz", **arrays)
    body = load_body(tmp_path / "plain.npz")
    assert body.joint_names == default_joint_names(body.n_joints) and len(set(body.joint_names)) == body.n_joints
    assert body.joint_names[:22] == SMPL_JOINT_NAMES[:22]
    assert body.joint_names[22] == ("jaw" if layout == "smplx" else "left_index1")
    assert body.joint_names[-1] == "right_thumb3" and body.parents[body.joint_names.index("left_index1")] == 20
    own = [f"j{k}" for k in range(body.n_joints)]
    np.savez(tmp_path / "named.npz", joint_names=np.array(own), **arrays)
    assert load_body(tmp_path / "named.npz").joint_names == tuple(own)
    np.savez(tmp_path / "objects.npz", joint_names=np.array(own, dtype=object), **arrays)
    assert load_body(tmp_path / "objects.npz").joint_names == body.joint_names  # unreadable names: the layout's
    np.savez(tmp_path / "short.npz", joint_names=np.array(own[:5]), **arrays)
    with pytest.raises(InputError, match=r"short.npz': expected joint_names to be \d+ strings \(one per joint\), "
                                         r"got <U\d+ of shape \(5,\)"):
        load_body(tmp_path / "short.npz")
    assert default_joint_names(24) == SMPL_JOINT_NAMES and default_joint_names(3) == ("joint0", "joint1", "joint2")
