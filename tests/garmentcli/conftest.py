"""Small input files for CLI tests: a tiny body, a garment around it and short motions."""

import numpy as np
import pytest

from tests.meshes import tiny_body


def write_tiny_body(path):
    body = tiny_body()
    kintree = np.stack([body.parents, np.arange(body.n_joints)])
    kintree[0, 0] = 2**32 - 1  # as official SMPL files store the root's parent
    np.savez(path, v_template=body.v_template, shapedirs=body.shapedirs, J_regressor=body.J_regressor,
             weights=body.weights, kintree_table=kintree.astype(np.int64), f=body.faces.astype(np.uint32))
    return body


def write_shell_obj(path, body, offset=0.02, scale=1.0):
    from core.geometry import vertex_normals

    v = (body.v_template + offset * vertex_normals(body.v_template, body.faces)) * scale
    lines = [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in v] + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in body.faces]
    path.write_text("\n".join(lines) + "\n")


def write_motion(path, n_frames=12, fps=60.0, n_values=72, seed=0, **overrides):
    rng = np.random.default_rng(seed)
    poses = (rng.normal(size=(n_frames, n_values)) * 0.2).astype(np.float32)
    poses[:, :3] = [np.pi / 2, 0, 0]
    data = {"poses": poses, "trans": np.zeros((n_frames, 3), np.float32), "betas": np.zeros(16, np.float32),
            "mocap_framerate": np.array(fps), "gender": np.array("neutral")}
    data.update(overrides)
    np.savez(path, **data)


@pytest.fixture
def scene(tmp_path):
    """Paths of a tiny body, a garment on it and two motions, plus an output directory."""
    body = write_tiny_body(tmp_path / "tiny_body.npz")
    write_shell_obj(tmp_path / "shell.obj", body)
    write_motion(tmp_path / "walk.npz")
    write_motion(tmp_path / "jump.npz", n_frames=7, fps=120.0, n_values=156, seed=1)
    return {"body": str(tmp_path / "tiny_body.npz"), "garment": str(tmp_path / "shell.obj"),
            "motion": str(tmp_path / "walk.npz"), "motion2": str(tmp_path / "jump.npz"),
            "out": tmp_path / "out", "dir": tmp_path, "tiny": body}
