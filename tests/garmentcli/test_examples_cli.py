"""`garment examples` through click's CliRunner, with the generators replaced by a tiny garment and motion."""

import numpy as np
import pytest

import core.garmentgen
import core.motiongen
from core.garment import Garment
from core.motion import Motion
from tests.garmentcli.cli import invoke
from tests.meshes import grid


@pytest.fixture
def tiny_generators(monkeypatch):
    """The generators give one grid garment and one 2-frame motion; `calls` counts how often they ran."""
    calls = []

    def garments(body):
        calls.append("garments")
        v, f = grid(3, 3, size=0.2)
        return {"patch": Garment(np.asarray(v, np.float32), np.asarray(f, np.int64), name="patch")}

    def motions(fps=60.0):
        calls.append("motions")
        return {"still": Motion(poses=np.zeros((2, 24, 3), np.float32), trans=np.zeros((2, 3), np.float32), fps=fps,
                                betas=np.zeros(10, np.float32), name="still")}

    monkeypatch.setattr(core.garmentgen, "generate_example_garments", garments)
    monkeypatch.setattr(core.motiongen, "generate_example_motions", motions)
    return calls


def test_examples_refuses_an_existing_out_before_generating(tmp_path, tiny_generators):
    out = tmp_path / "ex"
    out.mkdir()
    r = invoke(["examples", "--out", out])
    assert r.exit_code != 0 and "exists: pass --overwrite" in r.output and "Traceback" not in r.output
    assert tiny_generators == []  # refused before the generators' seconds of work


def test_examples_overwrite_keeps_hand_made_files_and_folders(tmp_path, tiny_generators):
    out = tmp_path / "ex"
    r = invoke(["examples", "--out", out])
    assert r.exit_code == 0, r.output
    assert sorted(p.name for p in out.iterdir()) == ["patch.obj", "still.npz"]
    (out / "README.md").write_text("my notes\n")
    (out / "textures").mkdir()
    (out / "textures" / "patch.png").write_bytes(b"png")
    (out / "old_garment.obj").write_text("v 0 0 0\n")
    r = invoke(["examples", "--out", out, "--overwrite"])
    assert r.exit_code == 0, r.output
    assert (out / "README.md").read_text() == "my notes\n"
    assert (out / "textures" / "patch.png").read_bytes() == b"png"
    # a garment or capture of the user's beside them is kept, said (it was deleted without a word)
    assert (out / "old_garment.obj").read_text() == "v 0 0 0\n"
    assert f"{out}: kept old_garment.obj (not examples" in r.output
    assert sorted(p.name for p in out.iterdir()) == ["README.md", "old_garment.obj", "patch.obj", "still.npz",
                                                     "textures"]
    # a folder of the user's by an example's name was deleted with what it held: refused, kept
    (out / "still.npz").unlink()
    (out / "still.npz").mkdir()
    (out / "still.npz" / "mine.txt").write_text("mine")
    r = invoke(["examples", "--out", out, "--overwrite"])
    assert r.exit_code == 1 and "still.npz' is a folder where an example file goes" in r.output
    assert (out / "still.npz" / "mine.txt").read_text() == "mine"
