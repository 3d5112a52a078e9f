"""`garment info`: what bake reads in each file (a garment and its rest on the body, a motion and the parts it
holds), as text or JSON; files that cannot be read or garments that would be refused told, the exit code 1."""

import json
import logging
import pickle
from pathlib import Path

import numpy as np
import pytest

from tests.formats.test_bvh import _motion
from tests.formats.test_fbx import rig_fbx
from tests.formats.test_usdskel import rig_usd, write_usd_mesh
from tests.garmentcli.cli import invoke
from tests.garmentcli.test_bake_motion_input_cli import _wham_file

ROOT = Path(__file__).resolve().parents[2]
DRESS, WALK = ROOT / "examples" / "dress.obj", ROOT / "examples" / "walk.npz"


def _json(*args):
    r = invoke(["info", *args, "--format", "json"])
    return r, json.loads(r.output)


def test_info_tells_a_garments_rest_on_the_body_and_a_motions_frames(scene):
    """The example dress (its mesh, its median distance to the embedded body, none inside: it bakes) and walk (its
    frames, rate, joints, betas, Z-up, the root's path), as text and as JSON; exit 0; the dress 1.5 m up is far
    from the body: refused, told, exit 1."""
    r = invoke(["info", DRESS, WALK])
    assert r.exit_code == 0, r.output
    assert "dress.obj: garment, 3,240 vertices, 6,336 triangles, 0.54 x 0.80 x 0.45 m; on the embedded default " \
           "body: 32 mm from it (median), 0.0 % inside: bakes as it is" in r.output
    assert "walk.npz: motion, 181 frames at 60 fps (3.0 s), 24 joints, read z-up, 16 betas; the root travels " \
           "3.9 m, up to 1.4 m/s" in r.output
    r, (dress, walk) = _json(DRESS, WALK)
    assert dress["vertices"] == 3240 and dress["refused"] is None and dress["inside_percent"] == 0.0
    with np.load(WALK) as m:
        assert walk["frames"] == len(m["poses"]) and walk["fps"] == float(m["mocap_framerate"])
    assert walk["up"] == "z" and walk["people"] == {} and walk["takes"] == {} and walk["person"] is None
    assert walk["jumps"] == []
    # a teleport in the capture: the source frame after it, as --frames takes it
    with np.load(WALK) as m:
        trans = m["trans"].copy()
        trans[100:, 0] += 10.0
        np.savez(scene["dir"] / "glitch.npz", **{**dict(m), "trans": trans})
    r = invoke(["info", scene["dir"] / "glitch.npz"])
    assert "; the body jumps at frame 100: a joint moves 10.01 m in one frame (600 m/s)" in r.output, r.output  # and walks
    lifted = scene["dir"] / "lifted.obj"
    from formats.obj import read_obj, write_obj

    dress = read_obj(DRESS)
    write_obj(lifted, dress.vertices + [0.0, 1.5, 0.0], dress.faces)
    r, (far,) = _json(lifted)
    assert r.exit_code == 1 and far["refused"].startswith(f"garment mesh '{lifted}': expected a garment authored on")


def test_info_lists_the_tracked_people_and_takes_a_file_holds_and_the_part_read(scene):
    """A WHAM result of two people: both with their frames, the longest read ('--person 3' the other); an FBX of
    two takes: both with their frames, the first read ('--take Run' the other), with what retargeting its rig
    said; a motion that cannot be read is told beside them, exit 1; --person all is bake's only."""
    path, fps = _wham_file(scene)
    r, (wham,) = _json(path, "--source-fps", fps)
    assert r.exit_code == 0, r.output
    n = wham["frames"]
    assert wham["people"] == {"0": n, "3": n - 2} and wham["person"] == "0"
    assert any("holds 2 tracked people" in note for note in wham["notes"])
    r = invoke(["info", path, "--person", "3", "--source-fps", fps])
    assert f"; person '3' of 2 ('0' {n} frames, '3' {n - 2} frames: --person)" in r.output, r.output

    (walk, walk_trans), (run, run_trans) = _motion(5, seed=3), _motion(3, seed=4)
    moves = rig_fbx(scene["dir"] / "moves.fbx", None, None, takes={"Walk": (walk, walk_trans), "Run": (run, run_trans)})
    broken = scene["dir"] / "broken.npz"
    broken.write_bytes(b"PK\x03\x04 not a zip")
    r, (fbx, bad) = _json(moves, broken, "--take", "Run")
    assert r.exit_code == 1
    assert fbx["takes"] == {"Walk": 5, "Run": 3} and fbx["take"] == "Run" and fbx["frames"] == 3 and fbx["up"] == "y"
    assert any("retargeted onto SMPL's skeleton" in note for note in fbx["notes"])
    assert bad["error"].startswith(f"motion '{broken}': expected an AMASS-style .npz archive")
    r = invoke(["info", moves, "--person", "all"])
    assert r.exit_code == 2 and "all (one output per tracked person) applies to bake and dataset only" in r.output
    # a USD of a skeleton's animations is a motion (its takes told); a USD of a mesh, a garment
    usd = rig_usd(scene["dir"] / "moves.usda", {"Walk": (walk, walk_trans), "Run": (run, run_trans)}, armature=False)
    r, (skel, cloth) = _json(usd, write_usd_mesh(scene["dir"] / "cloth.usda"))
    assert skel["kind"] == "motion" and skel["takes"] == {"Walk": 5, "Run": 3} and skel["take"] == "Walk"
    assert cloth["error"] == f"garment mesh '{scene['dir'] / 'cloth.usda'}': mesh '/garment' has no points"


def test_info_of_a_folder_tells_each_motion_in_it(scene, tmp_path):
    folder = tmp_path / "clips"
    folder.mkdir()
    for name in ("a", "b"):
        (folder / f"{name}.npz").write_bytes(Path(scene["motion"]).read_bytes())
    with open(folder / "c.pkl", "wb") as fh:  # AIST++'s pickle of the same motion
        with np.load(scene["motion"]) as m:
            pickle.dump({"smpl_poses": m["poses"][:, :72], "smpl_trans": m["trans"] * 100, "smpl_scaling": [100.0]},
                        fh)
    r, records = _json(folder, "--source-fps", 30)
    assert r.exit_code == 0, r.output
    assert [Path(rec["path"]).name for rec in records] == ["a.npz", "b.npz", "c.pkl"]
    assert {(rec["frames"], rec["fps"]) for rec in records} == {(records[0]["frames"], 30.0)}


def test_info_tells_a_bake_a_body_and_a_fit_for_what_they_are(tmp_path):
    """A bake's folder, its USD stage, its OBJ frames and one of them were read as a garment (a frame said to be
    refused, with an `unpose` that made no usable garment of it) or as a motion folder ("expected motion files");
    a body file and a psd fit as motions with no 'poses'. Each is told for what it is (exit 0)."""
    from core.body import default_body
    from core.psd import PSDFit
    from formats.psd import save_fit

    out = tmp_path / "bakes"
    r = invoke(["bake", ROOT / "examples" / "skirt.obj", WALK, "--method", "lbs", "--frames", "0:6", "--out", out])
    assert r.exit_code == 0, r.output
    bake = out / "skirt_walk"
    body = tmp_path / "body.npz"
    b = default_body()
    np.savez(body, v_template=b.v_template, shapedirs=b.shapedirs, J_regressor=b.J_regressor, weights=b.weights,
             parents=b.parents, faces=b.faces)
    fit = save_fit(tmp_path / "skirt.psd.npz", PSDFit("0" * 64, "default", 24, 10, np.zeros(6, np.float32),
                                                      np.zeros((1, 6), np.float32), np.zeros((3, 1), np.float32)))
    paths = [out, bake, bake / "skirt_walk.usd", bake / "obj", bake / "obj" / "frame_0002.obj", body, fit]
    r = invoke(["info", *paths])
    assert r.exit_code == 0, r.output
    lines = r.output.splitlines()
    for line in lines[:5]:
        assert "a baked garment sequence of 'skirt.obj' on 'walk.npz', baked with lbs" in line and "not a garment" \
               in line
    assert "3 frames at 30 fps from frame 0, 2,016 vertices" in lines[0]
    assert lines[4].endswith("obj/frame_0002.obj: a baked garment sequence of 'skirt.obj' on 'walk.npz', baked with "
                             "lbs, 1 frame at 30 fps from frame 2, 2,016 vertices (garment metrics and render read "
                             "it; not a garment to bake)")
    assert lines[5].endswith(f"body.npz: body (smpl), 13,348 vertices, 24 joints, 10 betas, sha256 "
                             f"{b.content_hash()[:12]} (give it to bake with --body)")
    assert lines[6].endswith("skirt.psd.npz: psd fit of a 2-vertex garment on body 'default', 1 shape (give it to "
                             "bake with --method psd --fit)")


def test_an_amass_motions_16_betas_are_not_fitted_to_the_embedded_body(tmp_path, caplog):
    """AMASS's SMPL+H motions carry 16 betas: `info` posed them on the embedded body to find jumps, warning twice
    (without the file's name) "16 betas given, body 'default' has 10 ...", though bake poses such a motion at the
    mean shape."""
    poses, trans = _motion(8, seed=2)
    np.savez(tmp_path / "amass.npz", poses=np.concatenate([poses.reshape(8, 72), np.zeros((8, 84))], 1), trans=trans,
             betas=np.full(16, 0.5), mocap_framerate=60.0, gender=np.array("female"))
    with caplog.at_level(logging.WARNING):
        r = invoke(["info", tmp_path / "amass.npz"])
    assert r.exit_code == 0 and "16 betas" in r.output, r.output
    assert "betas given" not in caplog.text


def test_an_smpl_pickle_body_is_a_body_and_a_body_given_as_the_motion_is_told(tmp_path):
    """SMPL's own bodies are pickles of chumpy arrays: `info` called one a damaged motion ("expected a 'poses'
    array, ..."), as `bake` did a body file (pickle or .npz) given where the motion goes."""
    from core.body import default_body
    from tests.formats.test_body import write_pkl

    b = default_body()
    arrays = dict(v_template=b.v_template, shapedirs=b.shapedirs, posedirs=np.zeros((*b.v_template.shape, 207), np.float32),
                  J_regressor=b.J_regressor, weights=b.weights, f=b.faces,
                  kintree_table=np.stack([np.r_[2**32 - 1, b.parents[1:]], np.arange(24)]).astype(np.int64))
    write_pkl(tmp_path / "SMPL_NEUTRAL.pkl", arrays)
    r = invoke(["info", tmp_path / "SMPL_NEUTRAL.pkl"])
    assert r.exit_code == 0 and "SMPL_NEUTRAL.pkl: body (smpl), 13,348 vertices, 24 joints, 10 betas" in r.output, \
        r.output
    np.savez(tmp_path / "body.npz", **arrays)
    for body in ("SMPL_NEUTRAL.pkl", "body.npz"):
        r = invoke(["bake", ROOT / "examples" / "skirt.obj", tmp_path / body, "--out", tmp_path / "out"])
        assert r.exit_code != 0 and r.output.strip().splitlines()[-1] == (
            f"Error: motion '{tmp_path / body}': an SMPL-format body file (v_template, shapedirs, ...), not a motion: "
            "give it with --body"), r.output
    assert not (tmp_path / "out").exists()


def test_info_tells_a_model_and_its_resume_state_for_what_they_are_and_a_motion_pt_still_as_a_motion(tmp_path):
    """`garment info MODEL.pt` read a trained model as a motion ("expected a 'poses' array"); a checkpoint now tells
    its training (steps, body, garments, validation), a resume state says so, and a PyTorch motion file is still
    read as a motion."""
    import torch

    from core.body import default_body
    from formats.checkpoint import save_checkpoint
    from tests.core.model_fixtures import TINY_CONFIG

    meta = {"steps": 30, "phase": 2, "body": "default", "garments": ["skirt"], "val_verts_mm": 38.1}
    model = save_checkpoint(tmp_path / "m.pt", TINY_CONFIG, {}, meta=meta)
    state = save_checkpoint(tmp_path / "m.pt.ckpt", TINY_CONFIG, {}, train={"step": 12})
    walk = dict(np.load(WALK))
    torch.save({"poses": torch.as_tensor(walk["poses"][:4]), "trans": torch.as_tensor(walk["trans"][:4]),
                "mocap_framerate": 60.0}, tmp_path / "walk.pt")
    r = invoke(["info", model, state, tmp_path / "walk.pt"])
    lines = r.output.splitlines()
    assert lines[0] == (f"{model}: garment model (give it to bake with --method model --model), {TINY_CONFIG.levels} "
                        f"pooling level{'' if TINY_CONFIG.levels == 1 else 's'}, {TINY_CONFIG.n_joints} joints; 30 steps, phase 2, on body 'default' (sha256 "
                        f"{default_body().content_hash()[:12]}), garments skirt, validation E_verts 38.1 mm")
    assert lines[1].startswith(f"{state}: training state of a garment model (`garment train --resume` continues it)")
    from garmentcli.info import model_info  # the shapes it is taken to have seen: none recorded, the default bodies

    shapes = model_info(model)["trained_betas"]
    assert not shapes["recorded"] and len(shapes["min"]) == 10 and shapes["max"][0] == pytest.approx(1.263414)
    assert lines[1].endswith("; 12 steps")
    assert lines[2].startswith(f"{tmp_path / 'walk.pt'}: motion, 4 frames at 60 fps")
    # a checkpoint of another version is a model with that wrong (it was a motion "expected a 'poses' array")
    torch.save({"format": "garment-model", "version": 9, "config": {}, "model": {}}, tmp_path / "v9.pt")
    r = invoke(["info", tmp_path / "v9.pt"])
    assert r.exit_code == 1 and r.output.strip().endswith("expected checkpoint format version 1, got version 9")
    # a damaged one (cut short in a copy): a `.ckpt` is a model's (it was "motion ...: expected an AMASS-style .npz
    # archive"); a `.pt` may be a model or a motion, so both are named
    for name in ("cut.pt", "cut.ckpt"):
        (tmp_path / name).write_bytes(Path(model).read_bytes()[:300])
    r = invoke(["info", tmp_path / "cut.pt", tmp_path / "cut.ckpt"])
    lines = r.output.splitlines()
    assert r.exit_code == 1 and len(lines) == 2, r.output
    assert lines[0].startswith(f"{tmp_path / 'cut.pt'}: error: '{tmp_path / 'cut.pt'}': expected a model checkpoint "
                               f"of `garment train` or a motion of PyTorch's format, could read it as neither (motion "
                               f"'{tmp_path / 'cut.pt'}': cannot read it as a PyTorch file"), lines[0]
    assert lines[1].startswith(f"{tmp_path / 'cut.ckpt'}: error: model '{tmp_path / 'cut.ckpt'}': expected a garment "
                               "model checkpoint, could not read it"), lines[1]
