"""Procedural example motions (walk, run, jump, arms raise, crouch, turn) in the AMASS convention.

Each clip is a `Motion` in the SMPL 24-joint layout, world Z-up: the root
orientation is `Rz(heading) @ Rx(+90 deg) @ R_pelvis`, where `Rx(+90 deg)`
(`core.motion.Y_UP_TO_Z_UP`) takes the Y-up body frame (facing +Z, left at +X)
to the world, so heading 0 faces world -Y. Joint curves are smooth (C1 or
better): periodic gaits are sums of sines and von Mises bumps of the gait phase,
one-shot clips are monotone cubic (PCHIP) keyframe curves. The pelvis height comes
from a planar (sagittal) leg model with the default body's rest offsets (`LegGeometry`) so
that the lowest foot point touches the ground plane z = 0, and feet that should be
planted stay in place. Angles are given in anatomical terms (flexion, abduction)
in degrees and mapped to SMPL's local joint axes in one place (`_Channels`).
New clips are new parameter sets of the same generators (speed, amplitude, ...).
"""

from __future__ import annotations

import functools
import logging
from dataclasses import dataclass, replace
from typing import Callable

import numpy as np
from scipy.interpolate import PchipInterpolator
from scipy.spatial.transform import Rotation

from core.body import SMPL_JOINT_NAMES
from core.motion import Y_UP_TO_Z_UP, Motion

log = logging.getLogger(__name__)

J = {name: i for i, name in enumerate(SMPL_JOINT_NAMES)}
GRAVITY_M_S2 = 9.81
_DEG = np.pi / 180.0


@dataclass(frozen=True)
class LegGeometry:
    """Rest-pose sagittal leg offsets, (up, forward) in metres in the Y-up body frame.

    Used to put the feet on the ground. hip: hip joint relative to the pelvis
    joint; thigh: knee relative to hip; shank: ankle relative to knee; toe / heel:
    the front / back of the sole relative to the ankle. Defaults are measured on
    the embedded default body (core.body.default_body(), betas 0).
    """

    hip: tuple[float, float] = (-0.016, -0.009)
    thigh: tuple[float, float] = (-0.373, 0.031)
    shank: tuple[float, float] = (-0.432, -0.032)
    toe: tuple[float, float] = (-0.077, 0.20)
    heel: tuple[float, float] = (-0.077, -0.055)

    @property
    def standing_height_m(self) -> float:
        """Pelvis joint height above the ground when standing in the rest pose."""
        return -(self.hip[0] + self.thigh[0] + self.shank[0] + self.toe[0])

    @classmethod
    def from_rest_joints(cls, joints: np.ndarray, sole_y: float, toe_z: float | None = None,
                         heel_z: float | None = None) -> "LegGeometry":
        """Offsets of a rest-pose SMPL skeleton (both sides averaged).

        joints: (24, 3) rest joint positions, metres, Y-up body frame. sole_y: height
        (Y) of the lowest rest vertex. toe_z / heel_z: forward (Z) extent of the sole
        (default: 6 cm ahead of the foot joint / 5.5 cm behind the ankle).
        """
        j = np.asarray(joints, dtype=np.float64)
        mid = lambda name: 0.5 * (j[J["left_" + name], 1:] + j[J["right_" + name], 1:])  # noqa: E731
        hip, knee, ankle, foot = mid("hip"), mid("knee"), mid("ankle"), mid("foot")
        toe_z = foot[1] + 0.06 if toe_z is None else toe_z
        heel_z = ankle[1] - 0.055 if heel_z is None else heel_z
        pair = lambda v: (float(v[0]), float(v[1]))  # noqa: E731
        return cls(hip=pair(hip - j[0, 1:]), thigh=pair(knee - hip), shank=pair(ankle - knee),
                   toe=(float(sole_y - ankle[0]), float(toe_z - ankle[1])),
                   heel=(float(sole_y - ankle[0]), float(heel_z - ankle[1])))


DEFAULT_LEGS = LegGeometry()


# --------------------------------------------------------------------------- joint channels


class _Channels:
    """Per-frame joint angles in anatomical terms, mapped to SMPL local axes.

    Each joint's local rotation is Rx(x) @ Ry(y) @ Rz(z) (z applied first, in the
    parent frame), which with SMPL's T-pose (Y up, facing +Z, left at +X) means:
    hip flexion (knee forward) = -x, hip abduction = +z left / -z right;
    knee flexion (foot backward) = +x; ankle dorsiflexion (toes up) = -x;
    spine/neck flexion (bend forward) = +x, twist = y, side bend = z;
    shoulder: arm lowered from T-pose = -z left / +z right, then swung towards the
    front about the vertical ("across") = -y left / +y right, then arm forward = -x;
    elbow flexion (forearm forward) = -y left / +y right.
    """

    def __init__(self, n_frames: int):
        self.euler = np.zeros((n_frames, 24, 3))  # radians, (x, y, z) per joint
        self.n = n_frames

    def add(self, joint: str, axis: int, value_deg) -> None:
        self.euler[:, J[joint], axis] += np.asarray(value_deg, dtype=np.float64) * _DEG

    def leg(self, side: str, hip_flex=0.0, hip_abd=0.0, knee_flex=0.0, ankle_dorsi=0.0, hip_rot=0.0) -> None:
        s = 1.0 if side == "left" else -1.0
        self.add(f"{side}_hip", 0, -np.asarray(hip_flex))
        self.add(f"{side}_hip", 2, s * np.asarray(hip_abd))
        self.add(f"{side}_hip", 1, s * np.asarray(hip_rot))
        self.add(f"{side}_knee", 0, knee_flex)
        self.add(f"{side}_ankle", 0, -np.asarray(ankle_dorsi))

    def arm(self, side: str, lowered=75.0, forward=0.0, elbow_flex=0.0, collar_up=0.0, across=0.0) -> None:
        s = 1.0 if side == "left" else -1.0
        self.add(f"{side}_shoulder", 1, -s * np.asarray(across))
        self.add(f"{side}_shoulder", 2, -s * np.asarray(lowered))
        self.add(f"{side}_shoulder", 0, -np.asarray(forward))
        self.add(f"{side}_elbow", 1, -s * np.asarray(elbow_flex))
        self.add(f"{side}_collar", 2, s * np.asarray(collar_up))

    def spine(self, flex=0.0, twist=0.0, side_bend=0.0) -> None:
        """Spread over spine1/2/3 (40/30/30 %)."""
        for joint, share in (("spine1", 0.4), ("spine2", 0.3), ("spine3", 0.3)):
            self.add(joint, 0, share * np.asarray(flex))
            self.add(joint, 1, share * np.asarray(twist))
            self.add(joint, 2, share * np.asarray(side_bend))

    def head(self, flex=0.0, twist=0.0) -> None:
        for joint in ("neck", "head"):
            self.add(joint, 0, 0.5 * np.asarray(flex))
            self.add(joint, 1, 0.5 * np.asarray(twist))

    def local_axis_angle(self) -> np.ndarray:
        """(T, 24, 3) axis-angle of the local rotations (root still in the body frame)."""
        e = self.euler.reshape(-1, 3)
        rot = Rotation.from_euler("zyx", e[:, ::-1])  # extrinsic z, then y, then x: R = Rx Ry Rz
        return rot.as_rotvec().reshape(self.n, 24, 3)


def _assemble(ch: _Channels, heading_rad, trans: np.ndarray, fps: float, name: str) -> Motion:
    """Compose the world root orientation Rz(heading) @ Rx(90 deg) @ R_pelvis and build the Motion."""
    aa = ch.local_axis_angle()
    heading = np.broadcast_to(np.asarray(heading_rad, dtype=np.float64), (ch.n,)).copy()
    world = (Rotation.from_rotvec(np.stack([np.zeros(ch.n), np.zeros(ch.n), heading], -1))
             * Rotation.from_rotvec(np.tile(Y_UP_TO_Z_UP, (ch.n, 1)))
             * Rotation.from_rotvec(aa[:, 0]))
    aa[:, 0] = world.as_rotvec()
    return Motion(poses=aa.astype(np.float32), trans=np.asarray(trans, dtype=np.float32), fps=float(fps),
                  betas=None, gender="neutral", name=name)


def _forward_world(heading) -> np.ndarray:
    """(..., 2) world XY facing direction for a heading about Z (heading 0 faces -Y)."""
    h = np.asarray(heading, dtype=np.float64)
    return np.stack([np.sin(h), -np.cos(h)], -1)


# --------------------------------------------------------------------------- planar leg model


def _rot_x(y, z, angle):
    """Rotate sagittal points (y up, z forward) by `angle` radians about +X."""
    c, s = np.cos(angle), np.sin(angle)
    return c * y - s * z, s * y + c * z


def _leg_points(ch: _Channels, side: str, legs: LegGeometry):
    """Sagittal (y, z) of ankle, heel and toe relative to the pelvis joint, body frame, metres.

    Uses the x-components of pelvis, hip, knee and ankle (exact when those joints
    only flex; good enough with the small side rotations of these clips).
    Returns dict of name -> (y (T,), z (T,)).
    """
    e = ch.euler
    a_root = e[:, 0, 0]
    a_thigh = a_root + e[:, J[f"{side}_hip"], 0]
    a_shank = a_thigh + e[:, J[f"{side}_knee"], 0]
    a_foot = a_shank + e[:, J[f"{side}_ankle"], 0]
    hy, hz = _rot_x(*legs.hip, a_root)
    ty, tz = _rot_x(*legs.thigh, a_thigh)
    sy, sz = _rot_x(*legs.shank, a_shank)
    ay, az = hy + ty + sy, hz + tz + sz
    out = {"ankle": (ay, az)}
    for name in ("heel", "toe"):
        py, pz = _rot_x(*getattr(legs, name), a_foot)
        out[name] = (ay + py, az + pz)
    return out


def _sole_depth(ch: _Channels, side: str, legs: LegGeometry) -> np.ndarray:
    """(T,) how far the lowest sole point of a leg is below the pelvis joint, metres (smooth min)."""
    p = _leg_points(ch, side, legs)
    return _smooth_max(-p["heel"][0], -p["toe"][0], 0.004)


def _smooth_max(a, b, temperature_m: float):
    """C-infinity approximation of max(a, b), never below it (log-sum-exp)."""
    m = np.maximum(a, b)
    return m + temperature_m * np.log(np.exp((a - m) / temperature_m) + np.exp((b - m) / temperature_m))


def _vm_bump(phase, centre, kappa):
    """Periodic smooth bump in [0, 1], 1 at `centre` (von Mises shape, width ~ 1/sqrt(kappa))."""
    return np.exp(kappa * (np.cos(phase - centre) - 1.0))


def _times(fps: float, seconds: float) -> np.ndarray:
    n = int(round(seconds * fps)) + 1
    return np.arange(n, dtype=np.float64) / fps


def _keys(t: np.ndarray, key_times, key_values) -> np.ndarray:
    """Monotone cubic (PCHIP, C1, no overshoot) curve through keyframes, held outside them."""
    kt = np.asarray(key_times, dtype=np.float64)
    return PchipInterpolator(kt, np.asarray(key_values, dtype=np.float64))(np.clip(t, kt[0], kt[-1]))


# --------------------------------------------------------------------------- gaits


@dataclass(frozen=True)
class GaitParams:
    """A periodic gait. Angles in degrees; phase 0 = left hip passing neutral going forward.

    stride_hz: full gait cycles per second (two steps). speed_m_s: None -> the speed
    at which the stance foot does not slide (walks); runs set it.
    turn_deg_s: heading change rate (walking along a circle when non-zero).
    """

    stride_hz: float = 0.9
    speed_m_s: float | None = None
    hip_mean: float = 8.0
    hip_amp: float = 22.0
    knee_stance: float = 12.0
    knee_swing: float = 58.0
    knee_swing_centre: float = -0.15  # in cycles
    knee_swing_kappa: float = 3.0
    ankle_amp: float = 10.0
    trunk_lean: float = 3.0
    pelvis_twist: float = 4.0
    pelvis_roll: float = 3.0
    arm_swing: float = 16.0
    arms_lowered: float = 78.0
    elbow_mean: float = 15.0
    elbow_amp: float = 10.0
    bounce_m: float = 0.0  # extra flight lift for runs
    turn_deg_s: float = 0.0


WALK = GaitParams()
RUN = GaitParams(stride_hz=1.4, speed_m_s=3.2, hip_mean=15.0, hip_amp=33.0, knee_stance=35.0, knee_swing=95.0,
                 knee_swing_centre=-0.08, knee_swing_kappa=2.5, ankle_amp=12.0, trunk_lean=9.0, pelvis_twist=6.0,
                 pelvis_roll=4.0, arm_swing=30.0, arms_lowered=70.0, elbow_mean=80.0, elbow_amp=12.0,
                 bounce_m=0.05)
TURN = GaitParams(stride_hz=0.85, hip_amp=18.0, knee_swing=52.0, turn_deg_s=45.0)


def make_gait(params: GaitParams, fps: float, seconds: float, name: str, legs: LegGeometry = DEFAULT_LEGS,
              heading_rad: float = 0.0) -> Motion:
    """A periodic gait (walk, run, curved walk) starting at the world origin, heading `heading_rad`."""
    t = _times(fps, seconds)
    ch = _gait_channels(params, t)
    phase = 2 * np.pi * params.stride_hz * t
    z = _gait_pelvis_height(params, legs, phase)
    speed = params.speed_m_s if params.speed_m_s is not None else _no_slip_speed(params, legs)
    omega = params.turn_deg_s * _DEG
    heading = heading_rad + omega * t
    if abs(omega) < 1e-9:
        xy = speed * t[:, None] * _forward_world(heading_rad)[None]
    else:  # integral of speed * (sin h, -cos h) over h = heading_rad + omega s
        xy = (speed / omega) * np.stack([np.cos(heading_rad) - np.cos(heading),
                                         np.sin(heading_rad) - np.sin(heading)], -1)
    trans = np.concatenate([xy, z[:, None]], axis=1)
    return _assemble(ch, heading, trans, fps, name)


def _gait_channels(p: GaitParams, t: np.ndarray) -> _Channels:
    ch = _Channels(len(t))
    phase = 2 * np.pi * p.stride_hz * t
    for side, ph in (("left", phase), ("right", phase + np.pi)):
        hip = p.hip_mean + p.hip_amp * np.sin(ph)
        knee_stance = 3.0 + p.knee_stance * _vm_bump(ph, 0.65 * np.pi, 8.0)
        knee_swing = p.knee_swing * _vm_bump(ph, 2 * np.pi * p.knee_swing_centre, p.knee_swing_kappa)
        knee = knee_stance + knee_swing
        # Foot level in mid-stance (flat on the ground), toes up at heel strike, toes down at
        # push-off; in swing the ankle follows 70 % of the knee so the toes clear the ground.
        level = knee_stance + 0.7 * knee_swing - hip + p.trunk_lean
        ankle = (level + 0.8 * p.ankle_amp * _vm_bump(ph, 0.5 * np.pi, 6.0)
                 - 1.8 * p.ankle_amp * _vm_bump(ph, -0.62 * np.pi, 6.0)
                 + 0.5 * p.ankle_amp * _vm_bump(ph, -0.25 * np.pi, 4.0))
        ch.leg(side, hip_flex=hip, knee_flex=knee, ankle_dorsi=ankle, hip_abd=1.5)
        # Arms swing against the same-side leg.
        ch.arm(side, lowered=p.arms_lowered, forward=-p.arm_swing * np.sin(ph),
               elbow_flex=p.elbow_mean + p.elbow_amp * (0.5 - 0.5 * np.sin(ph)))
    # Pelvis: forward lean, twist towards the swinging leg, drop on the swing side.
    ch.add("pelvis", 0, p.trunk_lean)
    ch.add("pelvis", 1, p.pelvis_twist * np.sin(phase))
    ch.add("pelvis", 2, p.pelvis_roll * np.sin(2 * phase))
    ch.spine(flex=0.5 * p.trunk_lean, twist=-1.5 * p.pelvis_twist * np.sin(phase),
             side_bend=-0.8 * p.pelvis_roll * np.sin(2 * phase))
    ch.head(flex=-0.5 * p.trunk_lean, twist=-0.3 * p.pelvis_twist * np.sin(phase))
    if p.turn_deg_s:
        ch.spine(side_bend=-0.08 * p.turn_deg_s)  # lean into the curve
    return ch


@functools.lru_cache(maxsize=32)
def _gait_height_series(params: GaitParams, legs: LegGeometry, n_harmonics: int = 4):
    """Fourier coefficients of the pelvis height over one gait cycle.

    The exact height (lowest sole on the ground) has kinks where the supporting
    foot changes; keeping `n_harmonics` harmonics makes it smooth (vertical
    accelerations of a few m/s^2, as measured on walking people), and the constant
    term is raised so that no foot goes below the ground.
    """
    n = 720
    t = np.arange(n) / (n * params.stride_hz)
    ch = _gait_channels(params, t)
    phase = 2 * np.pi * params.stride_hz * t
    exact = np.maximum(_sole_depth(ch, "left", legs), _sole_depth(ch, "right", legs))
    # Runs: lift the body between stances (0 at mid stance of either leg, max in flight).
    exact = exact + params.bounce_m * 0.5 * (1 - np.cos(2 * (phase - 0.5 * np.pi - 0.35)))
    coeffs = np.fft.rfft(exact) / n
    coeffs[n_harmonics + 1:] = 0.0
    smooth = np.fft.irfft(coeffs * n, n)
    coeffs[0] += np.max(exact - smooth)
    return coeffs[: n_harmonics + 1]


def _gait_pelvis_height(params: GaitParams, legs: LegGeometry, phase: np.ndarray) -> np.ndarray:
    """(T,) pelvis height in metres at gait phases `phase` (radians, left leg)."""
    c = _gait_height_series(params, legs)
    k = np.arange(len(c))
    terms = c[None, 1:] * np.exp(1j * phase[:, None] * k[None, 1:])
    return c[0].real + 2.0 * terms.real.sum(axis=1)


@functools.lru_cache(maxsize=32)
def _no_slip_speed(params: GaitParams, legs: LegGeometry) -> float:
    """Mean backward speed of the lower (stance) ankle over one cycle, m/s."""
    t = np.linspace(0.0, 1.0 / params.stride_hz, 721)
    ch = _gait_channels(params, t)
    depth = {s: _sole_depth(ch, s, legs) for s in ("left", "right")}
    az = {s: _leg_points(ch, s, legs)["ankle"][1] for s in ("left", "right")}
    stance = np.where(depth["left"] > depth["right"], az["left"], az["right"])
    v = -np.gradient(stance, t)
    return float(np.mean(np.clip(v, 0.0, None)))


def make_walk(fps: float = 60.0, seconds: float = 3.0, legs: LegGeometry = DEFAULT_LEGS, **overrides) -> Motion:
    """Straight walk at ~1.2 m/s (0.9 strides/s). `overrides`: any GaitParams field."""
    return make_gait(_with(WALK, overrides), fps, seconds, "walk", legs)


def make_run(fps: float = 60.0, seconds: float = 2.5, legs: LegGeometry = DEFAULT_LEGS, **overrides) -> Motion:
    """Straight run at 3.2 m/s (1.4 strides/s) with a short flight phase."""
    return make_gait(_with(RUN, overrides), fps, seconds, "run", legs)


def make_turn(fps: float = 60.0, seconds: float = 4.0, legs: LegGeometry = DEFAULT_LEGS, **overrides) -> Motion:
    """Slow walk along a left-hand circle, turning 45 deg/s (180 deg over 4 s)."""
    return make_gait(_with(TURN, overrides), fps, seconds, "turn", legs)


def _with(params: GaitParams, overrides: dict) -> GaitParams:
    return replace(params, **overrides) if overrides else params


# --------------------------------------------------------------------------- keyframed clips


def _standing(ch: _Channels, t: np.ndarray, arms: bool = True) -> None:
    """Relaxed stance: arms down by the sides, elbows slightly bent, tiny breathing sway."""
    if arms:
        for side in ("left", "right"):
            ch.arm(side, lowered=78.0, elbow_flex=12.0)
    ch.spine(flex=1.0 * np.sin(2 * np.pi * 0.25 * t))
    for side in ("left", "right"):
        ch.leg(side, hip_abd=2.0)


def _planted_trans(ch: _Channels, legs: LegGeometry, heading_rad: float = 0.0, lift=None) -> np.ndarray:
    """(T, 3) trans that keeps both feet planted where they were at frame 0 (plus `lift` metres up)."""
    depth = _smooth_max(_sole_depth(ch, "left", legs), _sole_depth(ch, "right", legs), 0.004)
    ankle_z = 0.5 * (_leg_points(ch, "left", legs)["ankle"][1] + _leg_points(ch, "right", legs)["ankle"][1])
    back = -(ankle_z - ankle_z[0])  # move the pelvis so the ankles stay put (body +Z = forward)
    xy = back[:, None] * _forward_world(heading_rad)[None]
    z = depth + (0.0 if lift is None else lift)
    return np.concatenate([xy, z[:, None]], axis=1)


def make_jump(fps: float = 60.0, seconds: float = 3.0, legs: LegGeometry = DEFAULT_LEGS,
              height_scale: float = 1.0) -> Motion:
    """Counter-movement vertical jump in place: crouch with arms back, take off, 0.4 s flight, land, stand.

    height_scale scales the crouch depth and flight time (1.0: ~0.2 m rise).
    """
    t = _times(fps, seconds)
    s = seconds / 3.0
    k = lambda *times: [s * x for x in times]  # noqa: E731
    c = height_scale
    flight = 0.40 * np.sqrt(c)
    t_off, t_land = 1.15 * s, 1.15 * s + flight
    times = k(0.0, 0.40, 0.85, 1.15) + [t_land - 0.2 * flight, t_land, t_land + 0.25 * s, t_land + 0.85 * s, 3.0 * s]
    hip = [0, 0, 75 * c, 2, 18 * c, 12, 55 * c, 0, 0]
    knee = [2, 2, 95 * c, 4, 25 * c, 10, 70 * c, 2, 2]
    trunk = [0, 0, 30 * c, 0, 8, 5, 25 * c, 0, 0]  # pelvis forward tilt
    # Feet flat on the ground except the push-off / landing plantarflexion (toes down) on top.
    plantar = [0, 0, 0, 35, 30, 20, 0, 0, 0]
    arm_fwd = [0, 0, -35, 120, 60, 20, 40, 0, 0]
    arm_low = [78, 78, 65, 10, 40, 60, 70, 78, 78]
    ch = _Channels(len(t))
    _standing(ch, t, arms=False)
    for side in ("left", "right"):
        h, kn, tr = _keys(t, times, hip), _keys(t, times, knee), _keys(t, times, trunk)
        ch.leg(side, hip_flex=h, knee_flex=kn, ankle_dorsi=kn - h + tr - _keys(t, times, plantar))
        ch.arm(side, lowered=_keys(t, times, arm_low), forward=_keys(t, times, arm_fwd), elbow_flex=15.0)
    ch.add("pelvis", 0, _keys(t, times, trunk))
    ch.head(flex=-0.5 * _keys(t, times, trunk))
    # Flight: a C1 lift (zero slope at take-off and landing) with the ballistic apex g T^2 / 8.
    u = np.clip((t - t_off) / flight, 0.0, 1.0)
    lift = GRAVITY_M_S2 * flight**2 / 8.0 * np.sin(np.pi * u) ** 2
    return _assemble(ch, 0.0, _planted_trans(ch, legs, lift=lift), fps, "jump")


def make_crouch(fps: float = 60.0, seconds: float = 3.0, legs: LegGeometry = DEFAULT_LEGS,
                depth: float = 1.0) -> Motion:
    """Stand, squat down with flat feet and arms forward for balance, hold, stand up. depth in (0, 1]."""
    t = _times(fps, seconds)
    s = seconds / 3.0
    times = [0.0, 0.4 * s, 1.35 * s, 1.85 * s, 2.7 * s, 3.0 * s]
    amount = _keys(t, times, [0, 0, 1, 1, 0, 0]) * depth
    ch = _Channels(len(t))
    _standing(ch, t, arms=False)
    lean, hip, knee = 20 * amount, 90 * amount, 110 * amount
    ch.add("pelvis", 0, lean)
    for side in ("left", "right"):
        # Flat feet: thigh, shank and foot angles about X sum to zero -> ankle dorsiflexion.
        dorsi = knee - hip + lean
        ch.leg(side, hip_flex=hip, knee_flex=knee, ankle_dorsi=dorsi, hip_abd=10 * amount)
        ch.arm(side, lowered=78 - 70 * amount, forward=80 * amount, elbow_flex=12 + 10 * amount)
    ch.spine(flex=10 * amount)
    ch.head(flex=-25 * amount)
    return _assemble(ch, 0.0, _planted_trans(ch, legs), fps, "crouch")


def make_arms_raise(fps: float = 60.0, seconds: float = 3.0, legs: LegGeometry = DEFAULT_LEGS,
                    top_deg: float = 165.0) -> Motion:
    """Standing; both arms rise sideways from the sides to overhead (`top_deg` from down) and back."""
    t = _times(fps, seconds)
    s = seconds / 3.0
    amount = _keys(t, [0.0, 0.3 * s, 1.3 * s, 1.7 * s, 2.7 * s, 3.0 * s], [0, 0, 1, 1, 0, 0])
    ch = _Channels(len(t))
    _standing(ch, t, arms=False)
    for side in ("left", "right"):
        ch.arm(side, lowered=78.0 - top_deg * amount, elbow_flex=12.0 - 7.0 * amount,
               collar_up=12.0 * amount, across=20.0)
    ch.spine(flex=-5.0 * amount)
    ch.head(flex=-8.0 * amount)
    return _assemble(ch, 0.0, _planted_trans(ch, legs), fps, "arms_raise")


EXAMPLE_MOTIONS: dict[str, Callable[..., Motion]] = {
    "walk": make_walk,
    "run": make_run,
    "jump": make_jump,
    "arms_raise": make_arms_raise,
    "crouch": make_crouch,
    "turn": make_turn,
}


def generate_example_motions(fps: float = 60.0, legs: LegGeometry = DEFAULT_LEGS) -> dict[str, Motion]:
    """Every registered example clip at `fps`, keyed by name (deterministic)."""
    return {name: make(fps=fps, legs=legs) for name, make in EXAMPLE_MOTIONS.items()}


# --------------------------------------------------------------------------- training library


def make_arm_swing(fps: float = 60.0, seconds: float = 3.0, legs: LegGeometry = DEFAULT_LEGS,
                   amplitude_deg: float = 50.0, hz: float = 0.8, name: str = "arm_swing") -> Motion:
    """Standing; both arms swing forward and back in opposite phase (pendulum), ramping in and out over 0.5 s."""
    t = _times(fps, seconds)
    ramp = _keys(t, [0.0, 0.5, seconds - 0.5, seconds], [0, 1, 1, 0])
    ch = _Channels(len(t))
    _standing(ch, t, arms=False)
    for side, ph in (("left", 0.0), ("right", np.pi)):
        ch.arm(side, lowered=78.0, forward=ramp * amplitude_deg * np.sin(2 * np.pi * hz * t + ph),
               elbow_flex=15.0 + 10.0 * ramp)
    ch.spine(twist=-4.0 * ramp * np.sin(2 * np.pi * hz * t))
    return _assemble(ch, 0.0, _planted_trans(ch, legs), fps, name)


def make_bend(fps: float = 60.0, seconds: float = 3.0, legs: LegGeometry = DEFAULT_LEGS, flex_deg: float = 60.0,
              side_deg: float = 0.0, twist_deg: float = 0.0, name: str = "bend") -> Motion:
    """Standing; bend forward (hips and spine, `flex_deg` in total), sideways or twist, hold, come back up."""
    t = _times(fps, seconds)
    s = seconds / 3.0
    amount = _keys(t, [0.0, 0.3 * s, 1.3 * s, 1.7 * s, 2.7 * s, 3.0 * s], [0, 0, 1, 1, 0, 0])
    ch = _Channels(len(t))
    _standing(ch, t, arms=False)
    hip = 0.55 * flex_deg * amount
    ch.add("pelvis", 0, hip)
    for sd in ("left", "right"):
        ch.leg(sd, hip_flex=hip)  # thighs stay vertical: hip flexion cancels the pelvis tilt, feet flat
        ch.arm(sd, lowered=78.0 - 0.3 * flex_deg * amount, forward=0.6 * flex_deg * amount, elbow_flex=12.0)
    ch.spine(flex=0.45 * flex_deg * amount, side_bend=side_deg * amount, twist=twist_deg * amount)
    ch.head(flex=-0.2 * flex_deg * amount)
    return _assemble(ch, 0.0, _planted_trans(ch, legs), fps, name)


def _stance_trans(ch: _Channels, legs: LegGeometry, side: str) -> np.ndarray:
    """(T, 3) trans keeping the `side` foot planted where it was at frame 0."""
    depth = _sole_depth(ch, side, legs)
    ankle_z = _leg_points(ch, side, legs)["ankle"][1]
    xy = -(ankle_z - ankle_z[0])[:, None] * _forward_world(0.0)[None]
    return np.concatenate([xy, depth[:, None]], axis=1)


def make_kick(fps: float = 60.0, seconds: float = 2.5, legs: LegGeometry = DEFAULT_LEGS, side: str = "right",
              height_deg: float = 70.0, name: str = "kick") -> Motion:
    """Standing on one leg, a front kick: chamber (knee up), extend, recoil, put the foot down."""
    t = _times(fps, seconds)
    s = seconds / 2.5
    times = [0.0, 0.4 * s, 0.8 * s, 1.05 * s, 1.35 * s, 1.8 * s, 2.5 * s]
    hip = _keys(t, times, [0, 0, 0.8, 1.0, 0.8, 0, 0]) * height_deg
    knee = _keys(t, times, [0, 0, 90, 5, 80, 0, 0]) * min(1.0, height_deg / 70.0)
    other = "left" if side == "right" else "right"
    ch = _Channels(len(t))
    _standing(ch, t, arms=False)
    ch.leg(side, hip_flex=hip, knee_flex=knee + 2.0, ankle_dorsi=-20 * hip / max(height_deg, 1e-6))
    ch.leg(other, knee_flex=8.0 * hip / max(height_deg, 1e-6) + 2.0, ankle_dorsi=8.0 * hip / max(height_deg, 1e-6))
    ch.add("pelvis", 0, -0.15 * hip)  # lean back a little
    for sd in ("left", "right"):
        ch.arm(sd, lowered=60.0, forward=20.0 * hip / max(height_deg, 1e-6), elbow_flex=70.0)
    return _assemble(ch, 0.0, _stance_trans(ch, legs, other), fps, name)


def make_sit(fps: float = 60.0, seconds: float = 4.0, legs: LegGeometry = DEFAULT_LEGS, name: str = "sit_down") -> Motion:
    """Stand, sit down (thighs level, as on a chair; the seat itself is not modelled), hold, stand up."""
    t = _times(fps, seconds)
    s = seconds / 4.0
    times = [0.0, 0.4 * s, 1.2 * s, 1.6 * s, 2.6 * s, 3.4 * s, 4.0 * s]
    amount = _keys(t, times, [0, 0, 1, 1, 1, 0, 0])
    lean = _keys(t, times, [0, 0, 35, 10, 10, 0, 0])  # lean forward while lowering / rising
    ch = _Channels(len(t))
    _standing(ch, t, arms=False)
    hip, knee = 90 * amount, 90 * amount
    ch.add("pelvis", 0, lean)
    for sd in ("left", "right"):
        ch.leg(sd, hip_flex=hip, knee_flex=knee, ankle_dorsi=knee - hip + lean, hip_abd=5 * amount)  # flat feet
        ch.arm(sd, lowered=78 - 20 * amount, forward=30 * amount, elbow_flex=15 + 30 * amount)
    ch.spine(flex=-0.3 * lean)
    return _assemble(ch, 0.0, _planted_trans(ch, legs), fps, name)


def _named(make: Callable[..., Motion], name: str, **kwargs) -> Callable[..., Motion]:
    def build(fps: float = 60.0, legs: LegGeometry = DEFAULT_LEGS) -> Motion:
        return replace(make(fps=fps, legs=legs, **kwargs), name=name)

    return build


#: The training motion library: the six examples plus variations (speed, amplitude, direction) and new actions.
MOTION_LIBRARY: dict[str, Callable[..., Motion]] = {
    **{name: _named(make, name) for name, make in EXAMPLE_MOTIONS.items()},
    "walk_slow": _named(make_walk, "walk_slow", stride_hz=0.7, hip_amp=18.0, arm_swing=10.0),
    "walk_fast": _named(make_walk, "walk_fast", stride_hz=1.05, hip_amp=26.0, arm_swing=22.0),
    "walk_brisk": _named(make_walk, "walk_brisk", stride_hz=1.15, hip_amp=28.0, knee_swing=62.0, arm_swing=28.0,
                         elbow_mean=35.0),
    "run_jog": _named(make_run, "run_jog", stride_hz=1.25, speed_m_s=2.3, hip_amp=28.0, knee_swing=85.0),
    "run_fast": _named(make_run, "run_fast", stride_hz=1.6, speed_m_s=4.3, hip_amp=38.0, knee_swing=105.0,
                       arm_swing=38.0),
    "turn_left_sharp": _named(make_turn, "turn_left_sharp", turn_deg_s=75.0),
    "turn_right": _named(make_turn, "turn_right", turn_deg_s=-45.0),
    "turn_right_wide": _named(make_turn, "turn_right_wide", turn_deg_s=-25.0, stride_hz=0.95, hip_amp=22.0),
    "jump_small": _named(make_jump, "jump_small", height_scale=0.5),
    "jump_high": _named(make_jump, "jump_high", height_scale=1.4),
    "crouch_half": _named(make_crouch, "crouch_half", depth=0.5),
    "arms_raise_half": _named(make_arms_raise, "arms_raise_half", top_deg=90.0),
    "arm_swing": _named(make_arm_swing, "arm_swing"),
    "arm_swing_fast": _named(make_arm_swing, "arm_swing_fast", amplitude_deg=70.0, hz=1.3),
    "bend_forward": _named(make_bend, "bend_forward", flex_deg=60.0),
    "bend_forward_deep": _named(make_bend, "bend_forward_deep", flex_deg=95.0),
    "bend_side_left": _named(make_bend, "bend_side_left", flex_deg=5.0, side_deg=30.0),
    "bend_side_right": _named(make_bend, "bend_side_right", flex_deg=5.0, side_deg=-30.0),
    "twist": _named(make_bend, "twist", flex_deg=5.0, twist_deg=45.0),
    "kick_right": _named(make_kick, "kick_right", side="right"),
    "kick_left": _named(make_kick, "kick_left", side="left"),
    "kick_high": _named(make_kick, "kick_high", side="right", height_deg=95.0),
    "sit_down": _named(make_sit, "sit_down"),
    "sit_down_slow": _named(make_sit, "sit_down_slow", seconds=6.0),
}


def generate_motion_library(fps: float = 60.0, legs: LegGeometry = DEFAULT_LEGS) -> dict[str, Motion]:
    """Every clip of MOTION_LIBRARY at `fps`, keyed by name (deterministic); the examples are included unchanged."""
    return {name: make(fps=fps, legs=legs) for name, make in MOTION_LIBRARY.items()}
