"""Tests of core/motiongen.py: every example clip is valid, smooth, anatomically signed and grounded."""

import numpy as np
import pytest

from core.body import SMPL_JOINT_NAMES, SMPL_PARENTS
from core.motion import Y_UP_TO_Z_UP
from core.motiongen import (
    DEFAULT_LEGS,
    EXAMPLE_MOTIONS,
    LegGeometry,
    generate_example_motions,
    make_crouch,
    make_jump,
    make_walk,
)
from core.rotations import axis_angle_to_matrix, matrix_to_axis_angle

J = {n: i for i, n in enumerate(SMPL_JOINT_NAMES)}
FPS = 30.0

# Approximate SMPL rest joints (Y up, facing +Z, left at +X, metres, pelvis at the origin);
# right side mirrored. Sagittal leg offsets agree with DEFAULT_LEGS.
_LEFT = {
    "pelvis": (0, 0, 0), "left_hip": (0.11, -0.016, -0.009), "spine1": (0, 0.08, -0.04),
    "left_knee": (0.14, -0.389, 0.022), "spine2": (0, 0.23, -0.03), "left_ankle": (0.19, -0.821, -0.01),
    "spine3": (0, 0.36, -0.04), "left_foot": (0.19, -0.871, 0.13), "neck": (0, 0.54, 0.0),
    "left_collar": (0.02, 0.46, 0.02), "head": (0, 0.64, 0.035), "left_shoulder": (0.175, 0.44, 0.01),
    "left_elbow": (0.43, 0.44, 0.01), "left_wrist": (0.66, 0.44, 0.01), "left_hand": (0.76, 0.44, 0.01),
}
REST = np.array([_LEFT[n] if n in _LEFT else np.array(_LEFT[n.replace("right", "left")]) * [-1, 1, 1]
                 for n in SMPL_JOINT_NAMES], dtype=np.float64)
SOLE_Y = -0.898


def _fk(poses, trans, rest=REST):
    """Naive per-joint forward kinematics: world joint positions (T, 24, 3) and rotations (T, 24, 3, 3)."""
    R = axis_angle_to_matrix(np.asarray(poses, np.float64))
    G = np.zeros_like(R)
    P = np.zeros(R.shape[:2] + (3,))
    for j, p in enumerate(SMPL_PARENTS):
        if p < 0:
            G[:, j], P[:, j] = R[:, j], rest[j] + trans
        else:
            G[:, j] = G[:, p] @ R[:, j]
            P[:, j] = P[:, p] + G[:, p] @ (rest[j] - rest[p])
    return P, G


@pytest.fixture(scope="module")
def motions():
    return generate_example_motions(fps=FPS)


def _angular_speed(poses, fps):
    """(T-1, J) rad/s from the relative rotation between consecutive frames (robust to aa wrap)."""
    R = axis_angle_to_matrix(np.asarray(poses, np.float64))
    rel = np.swapaxes(R[:-1], -1, -2) @ R[1:]
    return np.linalg.norm(matrix_to_axis_angle(rel), axis=-1) * fps


def test_registry(motions):
    assert set(EXAMPLE_MOTIONS) == {"walk", "run", "jump", "arms_raise", "crouch", "turn"}
    assert set(motions) == set(EXAMPLE_MOTIONS)
    for name, m in motions.items():
        assert m.name == name


def test_clips_are_valid(motions):
    for name, m in motions.items():
        assert m.layout == "smpl" and m.poses.dtype == np.float32 and m.trans.dtype == np.float32, name
        assert m.fps == FPS and 2.0 <= m.duration_s <= 4.0, name
        assert np.all(np.isfinite(m.poses)) and np.all(np.isfinite(m.trans)), name
        assert np.all(np.linalg.norm(m.poses, axis=-1) <= np.pi + 1e-5), name


def test_deterministic_and_fps_respected():
    a, b = make_walk(fps=60.0), make_walk(fps=60.0)
    np.testing.assert_array_equal(a.poses, b.poses)
    np.testing.assert_array_equal(a.trans, b.trans)
    c = make_walk(fps=30.0)
    assert c.n_frames == 91 and a.n_frames == 181
    np.testing.assert_allclose(c.poses[::3], a.poses[::6], atol=1e-6)  # same curve sampled differently


def test_smooth_joint_speeds_and_accelerations(motions):
    for name, m in generate_example_motions(fps=120.0).items():
        w = _angular_speed(m.poses, m.fps)
        assert w.max() < 20.0, (name, SMPL_JOINT_NAMES[np.unravel_index(w.argmax(), w.shape)[1]], w.max())
        # C1: no jumps in angular velocity (a kink would show as a huge per-frame change).
        R = axis_angle_to_matrix(m.poses.astype(np.float64))
        omega = matrix_to_axis_angle(np.swapaxes(R[:-1], -1, -2) @ R[1:]) * m.fps  # body-local angular velocity
        acc = np.linalg.norm(np.diff(omega, axis=0), axis=-1) * m.fps
        assert acc.max() < 600.0, (name, acc.max())
        v = np.diff(m.trans, axis=0) * m.fps
        assert np.linalg.norm(v, axis=1).max() < 6.0, name
        # Below ~8 g (jump landings reach 5-6 g); a velocity jump of 1 m/s would read 120 m/s^2 here.
        assert np.linalg.norm(np.diff(v, axis=0), axis=1).max() * m.fps < 80.0, name


def _max_trans_acceleration(m):
    v = np.diff(m.trans.astype(np.float64), axis=0) * m.fps
    return np.linalg.norm(np.diff(v, axis=0), axis=1).max() * m.fps


@pytest.mark.parametrize("name", sorted(EXAMPLE_MOTIONS))
def test_c1_acceleration_does_not_grow_with_fps(name):
    """A velocity discontinuity makes finite-difference accelerations grow with fps; C1 curves don't."""
    coarse = _max_trans_acceleration(EXAMPLE_MOTIONS[name](fps=120.0))
    fine = _max_trans_acceleration(EXAMPLE_MOTIONS[name](fps=960.0))
    assert fine < 1.5 * coarse + 1.0, (coarse, fine)


def test_root_is_z_up_and_head_above_pelvis(motions):
    for name, m in motions.items():
        P, G = _fk(m.poses, m.trans)
        up = G[:, 0] @ np.array([0.0, 1.0, 0.0])  # body up in the world
        assert np.all(up[:, 2] > 0.75), name  # upright within ~40 degrees
        assert np.all(P[:, J["head"], 2] > P[:, 0, 2] + 0.4), name
        assert np.all(P[:, 0, 2] > 0.5) and np.all(P[:, 0, 2] < 1.3), name


def test_first_frame_root_contains_y_up_to_z_up():
    m = make_crouch(fps=FPS)
    R0 = axis_angle_to_matrix(m.poses[0, 0].astype(np.float64))
    np.testing.assert_allclose(R0, axis_angle_to_matrix(Y_UP_TO_Z_UP), atol=0.05)  # standing, heading 0


def test_feet_on_or_above_ground_with_synthetic_skeleton(motions):
    for name, m in motions.items():
        P, _ = _fk(m.poses, m.trans)
        feet = P[:, [J["left_ankle"], J["right_ankle"], J["left_foot"], J["right_foot"]], 2]
        assert feet.min() > -0.02, (name, feet.min())
        lowest = P[:, [J["left_ankle"], J["right_ankle"]], 2].min(1)
        assert np.median(lowest) < 0.2, name  # not floating


def test_walks_move_forward_along_their_heading(motions):
    for name, speed in (("walk", (0.9, 1.6)), ("run", (2.5, 4.0))):
        m = motions[name]
        _, G = _fk(m.poses, m.trans)
        forward = (G[:, 0] @ np.array([0.0, 0.0, 1.0]))[:, :2]
        v = np.diff(m.trans[:, :2], axis=0) * m.fps
        assert np.all(np.sum(v * forward[1:], axis=1) > 0), name
        mean_speed = np.linalg.norm(m.trans[-1, :2] - m.trans[0, :2]) / m.duration_s
        assert speed[0] < mean_speed < speed[1], (name, mean_speed)


def test_turn_changes_heading(motions):
    m = motions["turn"]
    _, G = _fk(m.poses, m.trans)
    f = (G[:, 0] @ np.array([0.0, 0.0, 1.0]))[:, :2]
    a0, a1 = np.arctan2(f[0, 1], f[0, 0]), np.arctan2(f[-1, 1], f[-1, 0])
    turned = np.degrees((a1 - a0 + np.pi) % (2 * np.pi) - np.pi)
    assert abs(abs(turned) - 180.0) < 25.0 or abs(turned) > 150.0


def test_jump_leaves_the_ground():
    m = make_jump(fps=60.0)
    P, _ = _fk(m.poses, m.trans)
    feet = P[:, [J["left_foot"], J["right_foot"]], 2].min(1)
    assert feet.max() > feet[0] + 0.1
    assert abs(feet[-1] - feet[0]) < 0.01


def test_anatomical_signs(motions):
    """Knees bend backward only, elbows one way, hips flex forward in walks."""
    for name, m in motions.items():
        p = m.poses.astype(np.float64)
        for side, s in (("left", 1.0), ("right", -1.0)):
            knee = p[:, J[f"{side}_knee"]]
            assert np.all(knee[:, 0] > -0.02), (name, side)  # flexion is +x
            assert np.all(np.abs(knee[:, 1:]) < 0.05), (name, side)  # a hinge
            elbow = p[:, J[f"{side}_elbow"]]
            assert np.all(s * elbow[:, 1] <= 1e-3), (name, side)  # left flexes about -y, right about +y
    # Flexing the hip moves the knee forward (+Z of the pelvis frame) in a walk.
    m = motions["walk"]
    P, G = _fk(m.poses, m.trans)
    hip_flex = -m.poses[:, J["left_hip"], 0]
    i = int(np.argmax(hip_flex))
    knee_local = np.swapaxes(G[i, 0], 0, 1) @ (P[i, J["left_knee"]] - P[i, J["left_hip"]])
    assert hip_flex[i] > 0.3 and knee_local[2] > 0.1
    # Crouch: knees ahead of ankles, pelvis well down.
    c = motions["crouch"]
    P, G = _fk(c.poses, c.trans)
    k = int(np.argmin(c.trans[:, 2]))
    ahead = np.swapaxes(G[k, 0], 0, 1) @ (P[k, J["left_knee"]] - P[k, J["left_ankle"]])
    assert ahead[2] > 0.1 and c.trans[k, 2] < c.trans[0, 2] - 0.2


def test_leg_geometry_from_rest_joints_matches_default():
    legs = LegGeometry.from_rest_joints(REST, SOLE_Y)
    assert legs.standing_height_m == pytest.approx(0.898, abs=1e-6)
    np.testing.assert_allclose(legs.thigh, DEFAULT_LEGS.thigh, atol=0.01)
    np.testing.assert_allclose(legs.shank, DEFAULT_LEGS.shank, atol=0.01)
    # A taller skeleton gets a higher pelvis.
    tall = LegGeometry.from_rest_joints(REST * 1.2, SOLE_Y * 1.2)
    assert make_walk(fps=FPS, legs=tall).trans[:, 2].mean() > make_walk(fps=FPS).trans[:, 2].mean() + 0.1


def test_parameters_scale_clips():
    slow, fast = make_walk(fps=FPS, stride_hz=0.8), make_walk(fps=FPS, stride_hz=1.0)
    assert np.linalg.norm(fast.trans[-1] - fast.trans[0]) > np.linalg.norm(slow.trans[-1] - slow.trans[0])
    shallow, deep = make_crouch(fps=FPS, depth=0.5), make_crouch(fps=FPS)
    assert shallow.trans[:, 2].min() > deep.trans[:, 2].min() + 0.1
    assert make_walk(fps=FPS, seconds=2.0).n_frames == 61


def test_save_load_round_trip(tmp_path, motions):
    from formats.motion import load_motion, save_motion
    for name, m in motions.items():
        save_motion(tmp_path / f"{name}.npz", m)
        back = load_motion(tmp_path / f"{name}.npz")
        np.testing.assert_array_equal(back.poses, m.poses)
        np.testing.assert_array_equal(back.trans, m.trans)
        assert back.fps == m.fps


def _default_body_or_skip():
    try:
        from core.body import default_body
        return default_body()
    except (FileNotFoundError, OSError, ModuleNotFoundError):
        pytest.skip("embedded default body not available")


def test_default_body_feet_touch_but_do_not_sink(motions):
    body = _default_body_or_skip()
    for name, m in motions.items():
        verts, _ = body.pose(m.poses[::2], m.trans[::2])
        lowest = verts[..., 2].min(axis=1)
        assert lowest.min() > -0.015, (name, lowest.min())
        if name in ("walk", "turn", "crouch", "arms_raise"):  # always in contact
            assert lowest.max() < 0.05, (name, lowest.max())
        else:  # run and jump have flight phases, but land
            assert np.median(lowest) < 0.05, (name, np.median(lowest))
