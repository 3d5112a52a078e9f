"""Reading a long motion in every format `garment` reads: seconds and peak memory of `load_motion`.

    python benchmarks/motion_readers.py [--frames 9000] [--repeats 3] [--machine "..."]

One random SMPL motion of --frames frames (9,000: five minutes at 30 fps) is written in each format as its
producer writes it (AMASS's npz; AIST++'s pickle; WHAM's joblib result with its per-frame vertices, where joblib
is installed; Motion-X's .npy; SMPLCodec's .smpl; a BVH of the SMPL skeleton; a BVH of a Mixamo rig of 27 joints
(fingers, CMU's hip joints) resting in an A-pose, 15 % larger, retargeted, its binary FBX (pre-rotated
joints, curves per axis, half of them zlib-compressed), that FBX as ASCII and as FBX 6.1 (Takes of letter-coded
keys), the rig as a .glb and as a UsdSkel
crate (.usdc, Blender's layout: a Skeleton, its SkelAnimation sampled per frame) and as COLLADA (a matrix per joint
and frame, Blender's); an Xsens MVNX (23 segments' quaternions and positions
per frame, XML); a BVH of a LAFAN1-like rig (every
bone along its joint's X: its zero pose folds the body, so each bone is turned from the frame it stands best in,
here the first, SMPL's T-pose); PHALP's per-frame pickle with a
4,096-value appearance feature per detection; TRAM's np.save of torch tensors; GVHMR's torch.save), then read by
`formats.motion.load_motion` --repeats times: the median seconds, the peak of Python's traced allocations
(tracemalloc: numpy's arrays included) over one read, the file's size, and whether the joint rotations read are
the motion's (as rotation matrices, within 1e-4). Writes benchmarks/results/motion_readers.md (or --out).
Nothing here is asserted by tests.
"""

from __future__ import annotations

import argparse
import datetime
import pickle
import platform
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from core.rotations import axis_angle_to_matrix  # noqa: E402
from formats.fbx import forget_parsed  # noqa: E402
from formats.motion import load_motion  # noqa: E402
from formats.report import markdown_table, write_markdown  # noqa: E402
from tests.formats.test_bvh import LAFAN1, MIXAMO, rig_bvh, write_bvh  # noqa: E402
from tests.formats.test_collada import rig_dae  # noqa: E402
from tests.formats.test_fbx import rig_fbx  # noqa: E402
from tests.formats.test_gltf import rig_gltf  # noqa: E402
from tests.formats.test_mvnx import write_mvnx  # noqa: E402
from tests.formats.test_usdskel import rig_usd  # noqa: E402


def y_up(poses: np.ndarray, trans: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The Z-up motion turned to a Y-up world (the one `write_mvnx` turns back to MVN's Z-up)."""
    from core.motion import Y_UP_TO_Z_UP_MATRIX
    from core.rotations import matrix_to_axis_angle

    turned = poses.astype(np.float64)
    turned[:, 0] = matrix_to_axis_angle(Y_UP_TO_Z_UP_MATRIX.T @ axis_angle_to_matrix(turned[:, 0]))
    return turned.astype(np.float32), trans @ Y_UP_TO_Z_UP_MATRIX


def writers(poses: np.ndarray, trans: np.ndarray, fps: float) -> dict:
    """name -> (file name, write(path)) of every format (`poses` (T, 24, 3), `trans` (T, 3) metres)."""
    import torch

    T = len(poses)
    flat = poses.reshape(T, 72)
    matrices = axis_angle_to_matrix(poses).astype(np.float32)
    betas = np.zeros((T, 10), np.float32)

    def amass(p):
        np.savez(p, poses=flat, trans=trans, betas=np.zeros(16), mocap_framerate=fps)

    def aist(p):
        p.write_bytes(pickle.dumps({"smpl_loss": 1.0, "smpl_poses": flat, "smpl_trans": trans * 95.0,
                                    "smpl_scaling": np.float32([95.0])}))

    def wham(p):
        import joblib

        joblib.dump({0: {"pose": flat, "trans": trans, "pose_world": flat, "trans_world": trans, "betas": betas,
                         "verts": np.zeros((T, 6890, 3), np.float32), "frame_ids": np.arange(T)}}, p)

    def motion_x(p):
        rows = np.zeros((T, 322), np.float32)
        rows[:, :66], rows[:, 309:312] = flat[:, :66], trans
        np.save(p, rows)

    def codec(p):
        with open(p, "wb") as fh:
            np.savez(fh, smplVersion=np.int32(0), bodyPose=poses, bodyTranslation=trans, frameRate=np.float32(fps),
                     shapeParameters=np.zeros(10, np.float32))

    def phalp(p):
        def appearance():  # one feature per detection, as PHALP writes: not one object shared by the pickle
            return [np.zeros(4096, np.float32)]

        frames = {f"img/{t:06d}.jpg": {"time": t, "tid": [1], "camera": [trans[t]], "appe": appearance(),
                                       "smpl": [{"global_orient": matrices[t, :1], "body_pose": matrices[t, 1:],
                                                 "betas": betas[t]}]} for t in range(T)}
        p.write_bytes(pickle.dumps(frames))

    def tram(p):
        np.save(p, {"pred_rotmat": torch.tensor(matrices), "pred_trans": torch.tensor(trans[:, None]),
                    "pred_shape": torch.tensor(betas), "frame": torch.arange(T)}, allow_pickle=True)

    def gvhmr(p):
        params = {"global_orient": torch.tensor(flat[:, :3]), "body_pose": torch.tensor(flat[:, 3:66]),
                  "transl": torch.tensor(trans), "betas": torch.tensor(betas)}
        torch.save({"smpl_params_global": params, "smpl_params_incam": params}, p)

    return {"AMASS npz": ("amass.npz", amass), "AIST++ pickle": ("aist.pkl", aist),
            "WHAM joblib (vertices)": ("wham_output.pkl", wham), "Motion-X npy": ("motionx.npy", motion_x),
            "SMPLCodec .smpl": ("codec.smpl", codec),
            "BVH (SMPL skeleton)": ("smpl.bvh", lambda p: write_bvh(p, poses, trans, fps)),
            "BVH (Mixamo rig, retargeted)": ("mixamo.bvh", lambda p: rig_bvh(p, poses, trans, MIXAMO, scale=1.15,
                                                                            a_pose=40.0)),
            "FBX (Mixamo rig, retargeted)": ("mixamo.fbx", lambda p: rig_fbx(p, poses, trans)),
            "FBX ASCII (Mixamo rig, retargeted)": ("mixamo_ascii.fbx", lambda p: rig_fbx(p, poses, trans, ascii=True)),
            "FBX 6.1 (Mixamo rig, retargeted)": ("mixamo6.fbx", lambda p: rig_fbx(p, poses, trans, version=6100)),
            "glTF .glb (Mixamo rig, retargeted)": ("mixamo.glb", lambda p: rig_gltf(p, {"take": (poses, trans)})),
            "USD .usdc UsdSkel (Mixamo rig, retargeted)": (
                "mixamo.usdc", lambda p: rig_usd(p, {"take": (poses, trans)}, armature=False)),
            "COLLADA .dae (Mixamo rig, retargeted)": ("mixamo.dae", lambda p: rig_dae(p, poses, trans, fps=fps)),
            "Xsens MVNX (23 segments, retargeted)": ("xsens.mvnx", lambda p: write_mvnx(p, *y_up(poses, trans))),
            "BVH (LAFAN1-like rig, bones from their best frames)": (
                "lafan.bvh", lambda p: rig_bvh(p, poses, trans, LAFAN1, along_x=True, order="ZYX")),
            "PHALP pickle": ("phalp.pkl", phalp), "TRAM npy": ("hps_track_0.npy", tram),
            "GVHMR pt": ("hmr4d_results.pt", gvhmr)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=9000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--machine", default=platform.processor() or platform.machine())
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "motion_readers.md")
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    poses = rng.normal(scale=0.3, size=(args.frames, 24, 3)).astype(np.float32)
    poses[:, 0] = [np.pi / 2, 0, 0]  # standing in a Z-up world
    poses[0, 1:] = 0  # the first frame SMPL's rest, the others' knees bent at least 29 degrees: the first is the
    poses[1:, 4:6, 0] = np.abs(poses[1:, 4:6, 0]) + 0.5  # straightest, the rest a LAFAN1-like rig is turned from
    trans = np.stack([np.linspace(0, 5, args.frames), np.zeros(args.frames), np.full(args.frames, 0.9)],
                     1).astype(np.float32)
    want = axis_angle_to_matrix(poses[:, :22])
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name, (file, write) in writers(poses, trans, 30.0).items():
            path = Path(tmp) / file
            try:
                write(path)
            except ImportError as exc:  # joblib: not a dependency
                rows.append([name, "-", "-", "-", f"not written ({exc.name} missing)"])
                continue
            seconds = []
            for _ in range(args.repeats):
                forget_parsed()  # every read parses the file: none takes the last one's parse
                t0 = time.perf_counter()
                motion = load_motion(path, fps=30.0, world_checks=False)
                seconds.append(time.perf_counter() - t0)
            forget_parsed()
            tracemalloc.start()
            load_motion(path, fps=30.0, world_checks=False)
            peak = tracemalloc.get_traced_memory()[1]
            tracemalloc.stop()
            same = motion.n_frames == args.frames and np.allclose(
                axis_angle_to_matrix(motion.poses[:, :22]), want, atol=1e-4)
            rows.append([name, f"{path.stat().st_size / 1e6:,.1f}", f"{np.median(seconds):.3f}", f"{peak / 1e6:,.1f}",
                         "yes" if same else "NO"])
            path.unlink()
    header = ["format", "file MB", "seconds (median)", "peak MB (traced)", "the motion's rotations"]
    today = datetime.date.today().isoformat()
    write_markdown(args.out, [
        f"# Reading a {args.frames:,}-frame motion in every format", "",
        f"Made by `python benchmarks/motion_readers.py --frames {args.frames} --repeats {args.repeats}` on {today}, "
        f"{args.machine}, Python {platform.python_version()}, numpy {np.__version__}. `formats.motion.load_motion` "
        f"of one random SMPL motion written as each producer writes it (see the script's docstring).", "",
        markdown_table(header, rows)])
    print(args.out.read_text())


if __name__ == "__main__":
    main()
