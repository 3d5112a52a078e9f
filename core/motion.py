"""Motions: AMASS-style pose sequences, resampling, frame selection and settle blends.

A `Motion` is in the AMASS world frame (Z-up, metres, seconds); its root
orientation already contains the rotation from the Y-up body rest frame to the
Z-up world. Poses are kept in the joint layout of the file they came from
(SMPL 24, SMPL+H 52 or SMPL-X 55 joints); `poses_for_body` maps them onto a body.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, replace

import numpy as np

from core.body import LAYOUT_JOINTS, N_BODY_JOINTS, layout_for_joint_count
from core.errors import InputError
from core.geometry import Y_UP_TO_Z_UP_MATRIX
from core.rotations import axis_angle_to_quat, quat_slerp, quat_to_axis_angle

log = logging.getLogger(__name__)

# The SMPL-X layout puts jaw and eyes (3 joints) between the body and the hands.
_HAND_START = {"smplh": N_BODY_JOINTS, "smplx": N_BODY_JOINTS + 3}
_N_HAND_JOINTS = 30

#: Rotation taking the Y-up body rest frame to the Z-up world: +90 deg about X.
Y_UP_TO_Z_UP = np.array([np.pi / 2, 0.0, 0.0])

#: Source frame rates under this (Hz) are refused: no capture runs slower, and a BVH-style frame time (seconds per
#: frame, 0.0167 for 60 fps) stored as the rate would turn 10 frames into 16,201.
MIN_SOURCE_FPS = 1.0
#: The most a source's frame rate may be (motion capture records at up to 2 kHz): 1e300 was read as given, the
#: motion's whole length falling within one output frame (and its speed printed with 300 digits).
MAX_SOURCE_FPS = 10_000.0


def check_frame_rate(fps: float, where: str, advice: str = "") -> None:
    """Raise InputError naming `where` (the file and key, or the option) unless `fps` is a source frame rate:
    finite and at least MIN_SOURCE_FPS (under it, read as seconds per frame). `advice` ends the message."""
    if not (math.isfinite(fps) and fps > 0):
        raise InputError(f"{where}: expected a positive frame rate, got {fps}")
    if fps < MIN_SOURCE_FPS:
        raise InputError(f"{where}: expected a frame rate of at least {MIN_SOURCE_FPS:g} Hz, got {fps:.4g}: seconds "
                         f"per frame (a BVH Frame Time)? that is {1 / fps:.4g} fps{advice}")
    if fps > MAX_SOURCE_FPS:
        raise InputError(f"{where}: expected a frame rate of at most {MAX_SOURCE_FPS:,.0f} Hz, got {fps:.4g}{advice}")


#: Frame rates a rate read from seconds (a glTF's key times, a BVH's Frame Time) is snapped to within
#: COMMON_RATE_TOLERANCE: a file stores seconds to a few digits, not the rate.
#: Film and video's, and motion capture systems' (Vicon's, OptiTrack's, Xsens', Qualisys': 90 to 480): a BVH
#: of 240 fps written 'Frame Time: 0.0041666' was read and recorded as 240.004 fps.
COMMON_RATES = (12.0, 15.0, 24.0, 25.0, 30.0, 48.0, 50.0, 60.0, 72.0, 90.0, 96.0, 100.0, 120.0, 144.0, 180.0,
                200.0, 240.0, 250.0, 300.0, 360.0, 400.0, 480.0, 500.0, 600.0, 960.0, 1000.0, 23.976, 29.97, 59.94,
                119.88)
COMMON_RATE_TOLERANCE = 0.005


def common_rate(fps: float) -> float | None:
    """The rate of COMMON_RATES nearest to `fps` where within COMMON_RATE_TOLERANCE of it (relative), else None."""
    near = min(COMMON_RATES, key=lambda r: abs(r - fps))
    return near if abs(near - fps) <= COMMON_RATE_TOLERANCE * near else None


@dataclass(frozen=True, eq=False)
class Motion:
    """A pose sequence.

    poses: (T, J, 3) float32 axis-angle radians, J = 24 | 52 | 55 (layout).
    trans: (T, 3) float32 metres, Z-up world.
    fps: frames per second (> 0).
    betas: (S,) float32 or None. gender: str or None.
    n_settle: leading frames added by `settle` (blend from the rest pose).
    n_lead: leading frames deformed but not written (`preroll`: the motion before the frames asked for, so a
      simulated or learned garment arrives at the first written frame moving with the body, not at rest).
    n_tail: trailing frames deformed but not written (`preroll`'s context after the frames asked for: the psd
      blend shapes read each frame's rates from the frames around it).
    up: the world axis the file's body stood along as read, "z", or "y" / "-y" turned to Z-up (`y_up_to_z_up`).
    rest_up: the world axis the file's own rest skeleton stands along (a BVH's or FBX's: "z", "y", "-y"), or None
      where the file tells none; --motion-up left out or auto takes it (`garmentcli.common.resolved_up`).
    person: the id of the track read of a file of several tracked people (WHAM's, PHALP's), else None.
    take: the name of the animation stack read of an FBX of several, else None.
    """

    poses: np.ndarray
    trans: np.ndarray
    fps: float
    betas: np.ndarray | None = None
    gender: str | None = None
    name: str = "motion"
    n_settle: int = 0
    n_lead: int = 0
    n_tail: int = 0
    up: str = "z"
    rest_up: str | None = None
    person: str | None = None
    take: str | None = None

    def __post_init__(self):
        if self.poses.ndim != 3 or self.poses.shape[2] != 3 or layout_for_joint_count(self.poses.shape[1]) is None:
            raise InputError(f"motion '{self.name}': expected poses of shape (T, 24|52|55, 3), got {tuple(self.poses.shape)}")
        if self.trans.shape != (self.poses.shape[0], 3):
            raise InputError(f"motion '{self.name}': expected trans of shape ({self.poses.shape[0]}, 3), "
                             f"got {tuple(self.trans.shape)}")
        if self.poses.shape[0] < 1:
            raise InputError(f"motion '{self.name}': expected at least 1 frame, got 0")
        if not (np.isfinite(self.fps) and self.fps > 0):
            raise InputError(f"motion '{self.name}': expected a positive frame rate, got {self.fps}")

    @property
    def n_frames(self) -> int:
        return int(self.poses.shape[0])

    @property
    def n_written(self) -> int:
        """Frames between the lead (`n_lead`) and the tail (`n_tail`): those a bake writes."""
        return self.n_frames - self.n_lead - self.n_tail

    @property
    def layout(self) -> str:
        return layout_for_joint_count(self.poses.shape[1])

    @property
    def duration_s(self) -> float:
        return (self.n_frames - 1) / self.fps


def sequence_motion(seq, name: str = "motion", drop_settle: bool = False) -> Motion:
    """The Motion of a stored simulation (`formats.dataset.read_sequence`): its poses, translation, frame rate,
    body shape and settle frames; drop_settle: without the settle frames (the motion as the user gave it)."""
    k = seq.n_settle if drop_settle else 0
    return Motion(poses=seq.poses[k:], trans=seq.trans[k:], fps=seq.fps, betas=seq.betas,
                  n_settle=seq.n_settle - k, name=name)


def poses_for_body(motion: Motion, n_body_joints: int) -> np.ndarray:
    """The motion's poses in the joint layout of a body with `n_body_joints` joints.

    The first 22 (body) joints are shared by all layouts. Hands map between
    SMPL+H and SMPL-X; an SMPL body gets zero hand joints (22, 23), as AMASS
    recommends; joints a layout lacks are zero. Returns (T, n_body_joints, 3) float32.
    """
    target = layout_for_joint_count(n_body_joints)
    if target is None:
        raise InputError(f"body has {n_body_joints} joints; supported layouts are "
                         + ", ".join(f"{k} ({v})" for k, v in LAYOUT_JOINTS.items()))
    src = motion.layout
    T = motion.n_frames
    if src == target:
        return motion.poses.astype(np.float32, copy=True)
    out = np.zeros((T, n_body_joints, 3), dtype=np.float32)
    out[:, :N_BODY_JOINTS] = motion.poses[:, :N_BODY_JOINTS]
    if src in _HAND_START and target in _HAND_START:
        s, t = _HAND_START[src], _HAND_START[target]
        out[:, t:t + _N_HAND_JOINTS] = motion.poses[:, s:s + _N_HAND_JOINTS]
    return out


def resample(motion: Motion, fps: float) -> Motion:
    """Resample to `fps` for any ratio: slerp of joint rotations, linear translation.

    Output frame k lies at time k/fps, for every k with k/fps <= the clip's duration; with lead frames
    (`n_lead`), the grid is shifted so that an output frame lies on the first frame after them (the first
    written one), and the lead becomes the output frames before it; with tail frames (`n_tail`), the output frames
    after the last written source frame's time are the tail.
    """
    grid = _resample_grid(motion, fps)
    if grid is None:
        return replace(motion, fps=float(fps))
    n_lead, t0, n_out, n_tail = grid
    try:
        t_src = t0 * motion.fps + np.arange(n_out) * (motion.fps / fps)  # output times in source-frame units
        i0 = np.clip(np.floor(t_src).astype(np.int64), 0, motion.n_frames - 1)
        i1 = np.minimum(i0 + 1, motion.n_frames - 1)
        poses, trans = interpolate_frames(motion.poses, motion.trans, i0, i1, (t_src - i0).clip(0.0, 1.0))
    except MemoryError:  # callers check `resampled_frame_count` first; this is the net under them
        raise InputError(f"--fps {fps:g}: resampling motion '{motion.name}' ({motion.n_frames} frames at "
                         f"{motion.fps:g} fps) to {n_out} frames needs more memory than is free: lower --fps") from None
    # Settle frames keep their share of the clip's time.
    n_settle = min(n_out, int(np.ceil(motion.n_settle * fps / motion.fps - 1e-9)))
    return replace(motion, poses=poses, trans=trans, fps=float(fps), n_settle=n_settle, n_lead=n_lead,
                   n_tail=n_tail)


def interpolate_frames(poses: np.ndarray, trans: np.ndarray, i0: np.ndarray, i1: np.ndarray,
                       a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(K, J, 3) float32 poses and (K, 3) translations a share `a` (K,) of the way from frames `i0` to `i1` (K,):
    joint rotations slerped, the translation linear."""
    q = axis_angle_to_quat(poses)
    out = quat_to_axis_angle(quat_slerp(q[i0], q[i1], a[:, None])).astype(np.float32)
    return out, ((1 - a)[:, None] * trans[i0] + a[:, None] * trans[i1]).astype(np.float32)


def fill_untracked(poses: np.ndarray, trans: np.ndarray, frame_ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The (T, J, 3) poses and (T, 3) translations of a person tracked in the video frames `frame_ids` (T,
    increasing), on every frame from the first to the last: those between interpolated (`interpolate_frames`)."""
    ids = np.asarray(frame_ids, dtype=np.int64)
    every = np.arange(ids[0], ids[-1] + 1)
    i1 = np.searchsorted(ids, every)  # the first tracked frame at or after each
    i0 = np.where(ids[i1] == every, i1, i1 - 1)
    a = (every - ids[i0]) / np.maximum(ids[i1] - ids[i0], 1)
    return interpolate_frames(poses, trans, i0, i1, a)


def resampled_frame_count(motion: Motion, fps: float) -> int:
    """The number of frames `resample(motion, fps)` returns, known before anything is allocated (a caller
    checks it against the memory free)."""
    grid = _resample_grid(motion, fps)
    return motion.n_frames if grid is None else grid[2]


#: Output frames (a share of one) an output frame may lie past the clip's end and still be written, as its end.
RESAMPLE_SLACK_FRAMES = 1e-3


def _resample_grid(motion: Motion, fps: float) -> tuple[int, float, int, int] | None:
    """(lead frames, time of output frame 0 in s, output frames, tail frames) of `resample`; None where the frames
    stay."""
    if not (np.isfinite(fps) and fps > 0):
        raise InputError(f"--fps: expected a positive number, got {fps}")
    if abs(fps - motion.fps) < 1e-9 or motion.n_frames == 1:
        return None
    # An output frame within RESAMPLE_SLACK_FRAMES after the clip's end (or the first written frame) is its last
    # (first): a rate read from a file's seconds (30.0003 from 0.033333) lost the last frame to the rounding.
    t_first = motion.n_lead / motion.fps  # seconds: the first frame to write
    n_lead = int(np.floor(t_first * fps + RESAMPLE_SLACK_FRAMES))
    t0 = max(t_first - n_lead / fps, 0.0)
    n_out = int(np.floor((motion.duration_s - t0) * fps + RESAMPLE_SLACK_FRAMES)) + 1
    t_last = (motion.n_frames - 1 - motion.n_tail) / motion.fps  # seconds: the last frame to write
    n_tail = n_out - 1 - int(np.floor((t_last - t0) * fps + RESAMPLE_SLACK_FRAMES))
    return n_lead, t0, n_out, n_tail


def parse_frame_range(text: str) -> tuple[int | None, int | None]:
    """Parse 'START:STOP' (either side optional, Python slice semantics, STOP exclusive)."""
    parts = text.split(":")
    if len(parts) != 2:
        raise InputError(f"--frames: expected START:STOP (e.g. 0:120 or 30:), got '{text}'")
    try:
        start = int(parts[0]) if parts[0].strip() else None
        stop = int(parts[1]) if parts[1].strip() else None
    except ValueError:
        raise InputError(f"--frames: expected integers in START:STOP, got '{text}'") from None
    return start, stop


def select_frames(motion: Motion, start: int | None, stop: int | None) -> Motion:
    """Frames [start, stop) (Python slice semantics); an empty selection is an error."""
    sl = slice(start, stop)
    idx = range(motion.n_frames)[sl]
    if len(idx) == 0:
        raise InputError(f"--frames {'' if start is None else start}:{'' if stop is None else stop}: "
                         f"selects no frame of motion '{motion.name}' ({motion.n_frames} frames)")
    tail = motion.n_frames - motion.n_tail
    return replace(motion, poses=motion.poses[sl].copy(), trans=motion.trans[sl].copy(),
                   n_settle=sum(1 for i in idx if i < motion.n_settle), n_lead=sum(1 for i in idx if i < motion.n_lead),
                   n_tail=sum(1 for i in idx if i >= tail))


def written(motion: Motion) -> Motion:
    """The motion without its lead and tail frames (`Motion.n_lead`, `n_tail`): the frames a bake writes and is
    measured on."""
    if not (motion.n_lead or motion.n_tail):
        return motion
    return select_frames(motion, motion.n_lead, motion.n_frames - motion.n_tail)


#: A joint faster than this (m/s) between two frames is no human motion: a teleport of the root or a cut in the
#: capture (a hand in a throw reaches about 20 m/s).
CUT_SPEED_M_S = 25.0
#: A joint turning faster than this (rad/s) between two frames is a flip in the capture or its fit (a joint turned
#: 180 degrees in one frame at 30 fps: 94 rad/s; a dancer's fastest turns stay under 20, a pitcher's shoulder,
#: about the fastest of any, reaches 120 and is told too).
CUT_TURN_RAD_S = 60.0


def joint_speeds(body, poses: np.ndarray, trans: np.ndarray, betas, fps: float) -> np.ndarray:
    """(T - 1, J) metres a second: each joint's speed between consecutive frames of `body` posed by `poses`
    (T, J, 3), `trans` (T, 3) and `betas` (`Body.posed_joints`)."""
    return np.linalg.norm(np.diff(body.posed_joints(poses, trans, betas), axis=0), axis=-1) * fps


def motion_cuts(motion: Motion, body, chunk: int = 4096) -> list[tuple[int, str]]:
    """Where the body of `motion` (its frames after the settle blend) jumps between two frames: (the frame after
    the jump, what moved: a joint faster than CUT_SPEED_M_S or one turning faster than CUT_TURN_RAD_S), the
    fastest of each frame. body: the `core.body.Body` it is posed on; `chunk` frames posed at a time (a 50,000-frame
    motion's joints at once held 180 MB)."""
    poses = poses_for_body(motion, body.n_joints)
    first = motion.n_settle
    cuts = []
    for s in range(first, motion.n_frames - 1, chunk):
        at = slice(s, min(s + chunk + 1, motion.n_frames))  # one frame shared with the next chunk
        speed = joint_speeds(body, poses[at], motion.trans[at], motion.betas, motion.fps).max(axis=1)  # (t-1,)
        q = axis_angle_to_quat(poses[at].astype(np.float64))  # (t, J, 4)
        turn = 2.0 * np.arccos(np.clip(np.abs(np.sum(q[1:] * q[:-1], axis=-1)), 0.0, 1.0))  # (t-1, J) radians
        for k in np.flatnonzero((speed > CUT_SPEED_M_S) | (turn.max(axis=1) * motion.fps > CUT_TURN_RAD_S)):
            if speed[k] > CUT_SPEED_M_S:
                what = f"a joint moves {speed[k] / motion.fps:.2f} m in one frame ({speed[k]:.0f} m/s)"
            else:
                j = int(np.argmax(turn[k]))
                name = body.joint_names[j] if j < len(body.joint_names) else f"joint {j}"
                what = (f"the {name} turns {np.degrees(turn[k, j]):.0f} degrees in one frame "
                        f"({turn[k, j] * motion.fps:.0f} rad/s)")
            cuts.append((s + int(k) + 1, what))
    return cuts


def preroll(motion: Motion, start: int | None, stop: int | None, n_frames: int, context: tuple[int, int] = (0, 0)
            ) -> Motion:
    """Frames [start, stop) as `select_frames`, preceded by up to `n_frames` frames before `start` as lead
    frames (`Motion.n_lead`: deformed, not written); fewer where the motion begins sooner.

    context: (before, after): at least `before` lead frames and up to `after` frames after STOP as tail frames
    (`Motion.n_tail`), where the motion has them, without a word (a method's own need: psd's rates)."""
    if n_frames < 0:
        raise InputError(f"--preroll: expected a non-negative number of frames, got {n_frames}")
    first = select_frames(motion, start, stop)  # refuses an empty selection, naming it
    _warn_beyond(motion, start, stop)
    begin = range(motion.n_frames)[slice(start, stop)][0]
    lead = min(n_frames, begin)
    if lead < n_frames:
        log.warning("--preroll %d: motion '%s' has %s before --frames START (frame %d): %s", n_frames, motion.name,
                    f"only {begin} frame{'' if begin == 1 else 's'}" if begin else "no frame", begin,
                    f"deformed {lead} before it" if lead else "the cloth starts at rest there")
    lead = max(lead, min(context[0], begin))
    end = begin + first.n_frames
    tail = min(context[1], motion.n_frames - end)
    if lead == 0 and tail == 0:
        return first
    return replace(select_frames(motion, begin - lead, end + tail), n_lead=lead, n_tail=tail)


def _warn_beyond(motion: Motion, start: int | None, stop: int | None) -> None:
    """Warn where --frames START or STOP lies beyond `motion`'s frames (Python's slice clamps them silently)."""
    n = motion.n_frames
    text = f"{'' if start is None else start}:{'' if stop is None else stop}"
    if start is not None and start < -n:
        log.warning("--frames %s: START %d lies before the first of the %d frames of motion '%s': starts at frame 0",
                    text, start, n, motion.name)
    if stop is not None and stop > n:
        log.warning("--frames %s: STOP %d lies beyond the %d frames of motion '%s': stops after its last (frame %d)",
                    text, stop, n, motion.name, n - 1)


def blend_in(first_pose: np.ndarray, n_frames: int) -> np.ndarray:
    """The `n_frames` poses (n, J, 3) float32 that blend from the rest pose into `first_pose` (J, 3), the
    first of them the rest pose itself (the frame after them is `first_pose`).

    The root orientation is held; every other joint slerps from identity (T-pose) to its rotation in
    `first_pose`. The settle blend (`settle`), the simulator's internal lead-in and the model's
    (`core.model_deform.ModelDeformer`) are these frames, with the root translation held too.
    """
    q_first = axis_angle_to_quat(np.asarray(first_pose))
    q_rest = np.zeros_like(q_first)
    q_rest[:, 0] = 1.0
    q_rest[0] = q_first[0]
    t = np.arange(n_frames, dtype=np.float64) / n_frames  # 0 .. (K-1)/K, frame 0 itself follows
    return quat_to_axis_angle(quat_slerp(q_rest[None], q_first[None], t[:, None])).astype(np.float32)


def prepend_blend(poses: np.ndarray, trans: np.ndarray, n_frames: int) -> tuple[np.ndarray, np.ndarray]:
    """`poses` (T, J, 3) and `trans` (T, 3) after `n_frames` frames blending into their first frame
    (`blend_in`, the root translation held): the settle blend's frames (`settle`) and the model's lead-in."""
    if n_frames == 0:
        return poses, trans
    return (np.concatenate([blend_in(poses[0], n_frames), poses]),
            np.concatenate([np.repeat(trans[:1], n_frames, axis=0), trans]))


def settle(motion: Motion, n_frames: int) -> Motion:
    """Prepend `n_frames` frames that blend from the rest pose into the first frame (`blend_in`), so a
    garment authored on the rest body starts outside the posed body."""
    if n_frames < 0:
        raise InputError(f"--settle: expected a non-negative number of frames, got {n_frames}")
    if n_frames == 0:
        return motion
    if motion.n_lead:
        raise InputError(f"motion '{motion.name}': a settle blend goes before its first frame, which is a "
                         "pre-roll's (--settle and --preroll exclude each other)")
    poses, trans = prepend_blend(motion.poses, motion.trans, n_frames)
    return replace(motion, poses=poses, trans=trans, n_settle=motion.n_settle + n_frames)


#: The world axes a motion's body may stand along (`--motion-up`): AMASS's Z-up, the Y-up of most video pose
#: estimators' worlds (GVHMR, WHAM, TRAM), and the -Y up of camera coordinates (y down the image, z into it), in
#: which per-image estimators (SMPLer-X, 4D-Humans, ...) write the body; with the turn that takes each to Z-up.
UP_TURNS = {"y": Y_UP_TO_Z_UP_MATRIX, "-y": Y_UP_TO_Z_UP_MATRIX.T}
#: A body points its head along a world axis in a frame where the cosine between them is above UP_COSINE (37
#: degrees); a motion stands along the axis where it does so in UP_SHARE of its frames and along no other of
#: "z", "y", "-y" in any. The share is a majority, not all: a real AMASS clip bending over (human_body_prior's
#: sample) leans more than 37 degrees from +Z in 12 % of its frames.
UP_COSINE = 0.8
UP_SHARE = 0.5
_UP_VECTORS = {"z": (0.0, 0.0, 1.0), "y": (0.0, 1.0, 0.0), "-y": (0.0, -1.0, 0.0)}
UP_NAMES = {"z": "+Z", "y": "+Y", "-y": "-Y"}


def body_up_share(motion: Motion) -> dict:
    """How the body's own up axis (rest +Y, turned by the root orientation) lies in the world: per axis of
    `_UP_VECTORS` ("z", "y", "-y"), the share of frames with it within 37 degrees (UP_COSINE) of that axis."""
    from core.rotations import axis_angle_to_matrix

    up = axis_angle_to_matrix(motion.poses[:, 0].astype(np.float64))[:, :, 1]  # (T, 3): R @ (0, 1, 0)
    return {axis: float(np.mean(up @ np.array(v) > UP_COSINE)) for axis, v in _UP_VECTORS.items()}


def standing_axis(motion: Motion) -> tuple[str | None, dict]:
    """("z", "y" or "-y": the world axis the body stands along (UP_SHARE of its frames, along no other in any),
    else None; `body_up_share`)."""
    share = body_up_share(motion)
    for axis in _UP_VECTORS:
        if share[axis] >= UP_SHARE and not any(share[o] for o in _UP_VECTORS if o != axis):
            return axis, share
    return None, share


def y_up_to_z_up(motion: Motion, pelvis: np.ndarray, up: str = "y") -> Motion:
    """The motion of a Y-up world (most video pose estimators': GVHMR, WHAM, TRAM; `up` "-y": camera coordinates)
    in the Z-up world motions are read in: the whole posed body turned +90 degrees about X (`Y_UP_TO_Z_UP`; -90
    for "-y") about the world's origin, exactly.

    pelvis: (3,) the root joint of the body's rest pose at the motion's shape (the root turns about it, so the
    translation turns with it: trans' = Q (pelvis + trans) - pelvis)."""
    from core.rotations import axis_angle_to_matrix, matrix_to_axis_angle

    q = UP_TURNS[up]
    poses = np.array(motion.poses, dtype=np.float32)
    poses[:, 0] = matrix_to_axis_angle(q @ axis_angle_to_matrix(poses[:, 0].astype(np.float64)))
    pelvis = np.asarray(pelvis, dtype=np.float64)
    trans = (motion.trans.astype(np.float64) + pelvis) @ q.T - pelvis
    return replace(motion, poses=poses, trans=trans.astype(np.float32), up=up)


def _lies(axis: str, up: str) -> str:
    """How a body standing along world `axis` lies once turned as if it stood along `up`."""
    head = UP_TURNS[up] @ np.array(_UP_VECTORS[axis])
    return "stands on its head" if head[2] < -0.5 else "lies on its front" if head[1] < -0.5 else "lies on its back"


def warn_if_other_up(motion: Motion, source: str, up: str, given: bool = True) -> bool:
    """Log a warning, for a motion read as standing along `up` ("y" or "-y": `--motion-up` where `given`, else the
    axis its file's rest skeleton stands along), when its body stands along another axis (`standing_axis`): turned,
    it would lie down or stand on its head. Returns whether it warned."""
    axis, share = standing_axis(motion)
    if axis is None or axis == up:
        return False
    if given:
        how = f"given as {UP_NAMES[up]} up (--motion-up {up})"
        fix = f"leave out --motion-up {up}" if axis == "z" else f"pass --motion-up {axis}"
    else:  # a BVH written from a Z-up capture with a Y-up rest skeleton (smpl2bvh's)
        how = f"read as {UP_NAMES[up]} up (its rest skeleton stands along world {UP_NAMES[up]})"
        fix = f"pass --motion-up {axis}"
    looks = "it looks Z-up already" if axis == "z" else f"it looks {UP_NAMES[axis]} up"
    log.warning("motion '%s': %s, but the body stands along world %s in %.0f %% of its frames and along %s in none: "
                "%s, and turned it %s; %s", source, how, UP_NAMES[axis], share[axis] * 100, UP_NAMES[up], looks,
                _lies(axis, up), fix)
    return True


def warn_if_not_z_up(motion: Motion, source: str) -> bool:
    """Log a warning when the body stands along world +Y or -Y (`standing_axis`): read in AMASS's Z-up world, a Y-up
    motion lies on its back, and one in camera coordinates stands on its head, the simulator's gravity pulling along
    the body. Returns whether it warned."""
    axis, share = standing_axis(motion)
    if axis not in UP_TURNS:
        return False
    if axis == "y":
        log.warning("motion '%s': the body stands along world +Y in %.0f %% of its frames and along +Z in none: it "
                    "looks Y-up, but motions are read as AMASS's Z-up world, where it lies on its back and gravity "
                    "pulls along the body: pass --motion-up y (or turn its root orientation and translation +90 "
                    "degrees about X)", source, share["y"] * 100)
    else:
        log.warning("motion '%s': the body stands along world -Y in %.0f %% of its frames and along +Z or +Y in "
                    "none: it looks like camera coordinates (y down the image, z into it, as per-image pose "
                    "estimators such as SMPLer-X or 4D-Humans write the body), but motions are read as AMASS's Z-up "
                    "world, where it stands on its head: pass --motion-up -y (or turn its root orientation and "
                    "translation -90 degrees about X)", source, share["-y"] * 100)
    return True


#: Root translation beyond these (median over the frames) is not metres: the fastest sprinters reach 12 m/s,
#: and AMASS's capture volumes sit within a few metres of the origin (a centimetre pelvis stands 90-110 high).
TRANS_SPEED_LIMIT_M_S = 20.0
TRANS_DISTANCE_LIMIT_M = 50.0


def warn_if_not_metres(motion: Motion, source: str) -> bool:
    """Log a warning when `trans` looks like centimetres or millimetres (its median speed or median distance
    from the origin beyond TRANS_SPEED_LIMIT_M_S / TRANS_DISTANCE_LIMIT_M). Returns whether it warned."""
    trans = motion.trans.astype(np.float64)
    distance = float(np.median(np.linalg.norm(trans, axis=1)))
    speed = float(np.median(np.linalg.norm(np.diff(trans, axis=0), axis=1))) * motion.fps if len(trans) > 1 else 0.0
    if speed <= TRANS_SPEED_LIMIT_M_S and distance <= TRANS_DISTANCE_LIMIT_M:
        return False
    log.warning("motion '%s': trans moves the body at %.3g m/s and keeps it %.3g m from the origin (median): "
                "expected metres; is it in centimetres (scale it by 0.01) or millimetres (0.001)?",
                source, speed, distance)
    return True


#: Root translation further than this from the origin (metres) in any frame is refused: no capture volume spans
#: 10 km, and a glitch frame (1e30) would be baked into the outputs as it is (the unit checks above use medians).
TRANS_MAX_DISTANCE_M = 1e4


def validate_motion_values(motion: Motion, source: str) -> None:
    """Reject NaN/Inf in poses or translation, and a root translation beyond TRANS_MAX_DISTANCE_M, naming the
    first bad frame."""
    for key in ("poses", "trans"):
        arr = getattr(motion, key)
        bad = ~np.isfinite(arr.reshape(arr.shape[0], -1)).all(axis=1)
        if bad.any():
            raise InputError(f"motion '{source}': {key} contains NaN or Inf (first at frame {int(np.argmax(bad))})")
    distance = np.linalg.norm(motion.trans.astype(np.float64), axis=1)
    far = distance > TRANS_MAX_DISTANCE_M
    if far.any():
        i = int(np.argmax(far))
        raise InputError(f"motion '{source}': expected trans within {TRANS_MAX_DISTANCE_M:g} m (10 km) of the origin, "
                         f"got {distance[i]:.3g} m at frame {i} ({int(far.sum())} of {len(far)} frames that far): a "
                         f"glitch in the file, or millimetres (scale it by 0.001)?")
