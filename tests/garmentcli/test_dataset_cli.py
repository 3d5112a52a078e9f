"""`garment dataset` (and `bake --method sim`) end to end on a tiny body, a small garment and two 3-frame motions."""

import json
import os
from pathlib import Path

os.environ.setdefault("WARP_CACHE_PATH", str(Path.home() / ".cache" / "garment" / "warp"))

import numpy as np

from formats.dataset import read_sequence
from tests.garmentcli.cli import invoke
from tests.garmentcli.conftest import write_motion


def run(*args):
    return invoke(args)


def still_motions(d):
    poses = np.zeros((3, 72), np.float32)
    poses[:, :3] = [np.pi / 2, 0, 0]
    poses[:, 3 * 16 + 2] = np.linspace(0.0, 0.1, 3)  # a little left-shoulder motion
    write_motion(d / "a.npz", n_frames=3, fps=30.0, poses=poses)
    write_motion(d / "b.npz", n_frames=3, fps=30.0, poses=poses[::-1].copy())
    return d / "a.npz", d / "b.npz"


def test_dataset_builds_resumes_and_refuses_other_settings(scene, monkeypatch):
    a, b = still_motions(scene["dir"])
    out = scene["dir"] / "data"
    args = ["dataset", "--garments", scene["garment"], "--motions", a, "--motions", b, "--body", scene["body"],
            "--bodies", 2, "--betas-range", 0.5, "--settle", 1, "--substeps", 5, "--out", out]
    r = run(*args)
    assert r.exit_code == 0, r.output
    m = json.loads((out / "manifest.json").read_text())
    assert m["totals"]["items"] == 4 and len(m["items"]) == 4
    assert set(m["inputs"]["garments"]) == {"shell"} and len(m["inputs"]["motions"]["a"]["sha256"]) == 64
    assert m["settings"]["material"]["density_kg_m2"] > 0 and m["settings"]["solver"]["substeps"] == 5
    assert "newton" in m["software"] and "warp-lang" in m["software"]
    train, test = set(m["splits"]["motions"]["train"]), set(m["splits"]["motions"]["test"])
    assert train and test and not train & test
    assert (out / "garments" / "shell.obj").read_bytes() == Path(scene["garment"]).read_bytes()
    import hashlib  # the template as written, which training compares (a USD garment's is written anew)

    assert m["inputs"]["garments"]["shell"]["template_sha256"] == hashlib.sha256(
        (out / "garments" / "shell.obj").read_bytes()).hexdigest()
    files = sorted((out / "sequences").glob("*.npz"))
    assert len(files) == 4
    s = read_sequence(files[0])
    assert s.positions.shape == (4, 642, 3) and s.positions.dtype == np.float32  # 1 settle + 3 frames
    assert s.poses.shape == (4, 24, 3) and s.trans.shape == (4, 3) and s.n_settle == 1 and s.fps == 30.0
    assert s.garment == "shell" and len(s.garment_sha256) == 64 and s.body == "tiny_body.npz"
    assert np.all(np.isfinite(s.positions))
    assert len(m["item_stats"]) == 4
    assert "dataset: 4/4 " in r.output and "s/frame" in r.output  # no terminal: one line per sequence
    lines = [line for line in r.output.splitlines() if line.startswith("dataset: ")]
    assert len(lines) == 4 and all(" left" in line for line in lines[:3]) and " left" not in lines[3]
    # Resume: nothing to do, files untouched.
    mtime = files[0].stat().st_mtime_ns
    r = run(*args)
    assert r.exit_code == 0 and "0 to simulate" in r.output and files[0].stat().st_mtime_ns == mtime
    # A deleted item is redone.
    files[1].unlink()
    files[1].mkdir()  # a folder at an item's sequence path: refused before any work (it was simulated, then the
    (files[1] / "x").touch()  # rename failed naming the hidden temporary file; on a cluster three times)
    manifest = (out / "manifest.json").read_bytes()
    r = run(*args)
    assert r.exit_code == 1 and r.output.strip().splitlines()[-1] == \
        f"Error: output '{files[1]}' is a folder: expected the item's sequence file or nothing there; remove it"
    assert (out / "manifest.json").read_bytes() == manifest and sorted(files[1].iterdir()) == [files[1] / "x"]
    (files[1] / "x").unlink()
    files[1].rmdir()
    r = run(*args)
    assert r.exit_code == 0 and "1 to simulate" in r.output and files[1].is_file()
    # What `garment dataset` wrote is what `garment train` reads (the split is a field of each item).
    r = run("train", "--data", out, "--out", scene["dir"] / "models" / "m.pt", "--steps", 2, "--body", scene["body"],
            "--config", _tiny_config(scene["dir"]), "--cache-dir", scene["dir"] / "cache")
    assert r.exit_code == 0, r.output
    rows = (scene["dir"] / "models" / "m.pt.csv").read_text().splitlines()  # its folder made on the way
    assert len(rows) == 3  # header + 2 steps
    # A template edited since (a vertex moved 1 cm): its sequences are of another mesh, refused (trained on before)
    template = out / "garments" / "shell.obj"
    original = template.read_bytes()
    lines = original.decode().splitlines()
    first = next(k for k, line in enumerate(lines) if line.startswith("v "))
    x, y, z = map(float, lines[first].split()[1:4])
    lines[first] = f"v {x + 0.01:.6f} {y:.6f} {z:.6f}"
    template.write_text("\n".join(lines) + "\n")
    r = run("train", "--data", out, "--out", scene["dir"] / "edited.pt", "--steps", 1, "--body", scene["body"],
            "--config", _tiny_config(scene["dir"]), "--cache-dir", scene["dir"] / "cache")
    assert r.exit_code == 1 and f"dataset garment '{template}': expected the file its sequences were simulated " \
        "with" in r.output.splitlines()[-1], r.output
    assert not (scene["dir"] / "edited.pt").exists()
    template.write_bytes(original)
    # A sequence missing (an unfinished dataset run) is refused by training with one line.
    files[1].unlink()
    r = run("train", "--data", out, "--out", scene["dir"] / "m2.pt", "--steps", 1, "--body", scene["body"])
    assert r.exit_code != 0 and "missing" in r.output and "rerun it to resume" in r.output
    r = run(*args)
    assert r.exit_code == 0 and files[1].is_file()
    # Other settings into the same directory: refused with one line.
    r = run(*args[:-2], "--seed", 3, "--out", out)
    assert r.exit_code != 0 and "other settings" in r.output and "Traceback" not in r.output
    assert "(seed: 0 -> 3)" in r.output  # the refusal names what differs
    assert m["settings"]["solver"]["floor"] == "auto"
    r = run(*args[:-2], "--floor", "none", "--out", out)
    assert r.exit_code != 0 and "(solver.floor: auto -> none)" in r.output
    # A dataset made before a stop check existed (its manifest without it) is resumed: its sequences are kept.
    from core.dataset import plan_key

    old = json.loads((out / "manifest.json").read_text())
    del old["settings"]["solver"]["fail_off_place_m"]
    old["plan_key"] = plan_key(old["settings"])
    (out / "manifest.json").write_text(json.dumps(old))
    mtime = files[0].stat().st_mtime_ns
    r = run(*args)
    assert r.exit_code == 0 and "resuming with other stop checks (solver.fail_off_place_m: absent -> 0.5)" in r.output
    assert "0 to simulate" in r.output and files[0].stat().st_mtime_ns == mtime
    assert json.loads((out / "manifest.json").read_text())["plan_key"] == m["plan_key"]
    # ... but not when something that shapes the cloth changed with it.
    (out / "manifest.json").write_text(json.dumps(old))
    r = run(*args[:-2], "--floor", "none", "--out", out)
    assert r.exit_code != 0 and "other settings" in r.output
    (out / "manifest.json").write_text(json.dumps(m))
    # Another simulator version is another plan: one dataset never mixes two versions' cloth.
    import core.sim

    assert m["settings"]["simulator_version"] == core.sim.SIMULATOR_VERSION
    monkeypatch.setattr(core.sim, "SIMULATOR_VERSION", core.sim.SIMULATOR_VERSION + 1)
    r = run(*args)
    assert r.exit_code != 0 and f"simulator_version: {m['settings']['simulator_version']} -> " in r.output
    monkeypatch.undo()
    # An edited garment (same file name) is another plan too: its old sequences are not kept.
    garment = Path(scene["garment"])
    lines = garment.read_text().splitlines()
    first_v = next(i for i, line in enumerate(lines) if line.startswith("v "))
    x, y, z = map(float, lines[first_v].split()[1:4])
    lines[first_v] = f"v {x + 0.001:.6f} {y:.6f} {z:.6f}"
    garment.write_text("\n".join(lines) + "\n")
    r = run(*args)
    assert r.exit_code != 0 and "other settings" in r.output and "Traceback" not in r.output
    assert "garment_meshes.shell: " in r.output


def _tiny_config(directory):
    from dataclasses import asdict

    from tests.core.model_fixtures import TINY_CONFIG

    path = Path(directory) / "tiny.json"
    path.write_text(json.dumps({"model": asdict(TINY_CONFIG)}))
    return path


def test_dataset_bad_material_key(scene, tmp_path):
    a, _ = still_motions(scene["dir"])
    mat = tmp_path / "m.json"
    mat.write_text('{"stiffness": 3}')
    r = run("dataset", "--garments", scene["garment"], "--motions", a, "--body", scene["body"], "--material", mat,
            "--out", tmp_path / "d")
    assert r.exit_code != 0 and "unknown key 'stiffness'" in r.output and len(r.output.strip().splitlines()) == 1
    assert not (tmp_path / "d").exists()


def test_bake_method_sim_and_sim_options_rejected_for_lbs(scene):
    a, _ = still_motions(scene["dir"])
    r = run("bake", scene["garment"], a, "--body", scene["body"], "--method", "lbs", "--substeps", 3,
            "--out", scene["out"])
    assert r.exit_code != 0 and "--substeps applies to --method sim only" in r.output
    r = run("bake", scene["garment"], a, "--body", scene["body"], "--pin", "none", "--out", scene["out"])
    assert r.exit_code != 0 and "--pin applies to --method sim only" in r.output
    r = run("bake", scene["garment"], a, "--body", scene["body"], "--method", "sim", "--pin", "belt",
            "--out", scene["out"])
    assert r.exit_code != 0 and "--pin" in r.output and "belt" in r.output
    r = run("bake", scene["garment"], a, "--body", scene["body"], "--floor", "none", "--out", scene["out"])
    assert r.exit_code != 0 and "--floor applies to --method sim only" in r.output
    r = run("bake", scene["garment"], a, "--body", scene["body"], "--method", "sim", "--floor", "off",
            "--out", scene["out"])
    assert r.exit_code != 0 and "--floor" in r.output and "'off' is not one of 'auto', 'none'" in r.output
    r = run("bake", scene["garment"], a, "--body", scene["body"], "--method", "sim", "--substeps", 4, "--no-obj",
            "--floor", "none", "--out", scene["out"])
    assert r.exit_code == 0, r.output
    summary = json.loads(next(scene["out"].glob("*/summary.json")).read_text())
    assert summary["method"] == "sim" and summary["deformer"]["options"]["substeps"] == 4
    assert summary["deformer"]["options"]["floor"] == "none" and summary["deformer"]["floor"] is None
    assert summary["scene"]["floor"] == {"skipped_work": False, "overridden": False, "reason": "floor none"}
    assert summary["deformer"]["checks"]["nan"] is False
    assert "note:" not in r.output  # a motion that starts still starts the cloth at rest rightly


def test_dataset_needs_motions_and_library_loads(scene):
    r = run("dataset", "--garments", scene["garment"], "--out", scene["dir"] / "d")
    assert r.exit_code != 0 and "--library" in r.output and not (scene["dir"] / "d").exists()
    r = run("dataset", "--garments", scene["garment"], "--library", "--held-out", "nosuch", "--out", scene["dir"] / "d")
    assert r.exit_code != 0 and "--held-out" in r.output and "nosuch" in r.output and not (scene["dir"] / "d").exists()
    r = run("dataset", "--garments", scene["garment"], "--library", "--held-out", "shell", "--no-held-out",
            "--out", scene["dir"] / "d")
    assert r.exit_code != 0 and "--no-held-out" in r.output and "both" in r.output and not (scene["dir"] / "d").exists()
    for option, value in (("--source-fps", "50"), ("--take", "foo"), ("--person", "2")):  # ignored, yet recorded
        r = run("dataset", "--garments", scene["garment"], "--library", option, value, "--dry-run", "--out",
                scene["dir"] / "d")
        assert r.exit_code != 0 and f"Invalid value for {option}: applies to --motions files" in r.output, r.output
        assert not (scene["dir"] / "d").exists()
    from garmentcli.dataset import _load_motions

    motions = _load_motions([], True, 30.0)
    assert len(motions) >= 24 and all(m.fps == 30.0 for m in motions.values())


def test_dataset_dry_run_writes_the_plan_only_and_no_held_out_trains_every_garment(scene):
    a, b = still_motions(scene["dir"])
    second = scene["dir"] / "second.obj"
    second.write_bytes(Path(scene["garment"]).read_bytes())
    base = ["dataset", "--garments", scene["garment"], "--garments", second, "--motions", a, "--motions", b,
            "--body", scene["body"], "--settle", 1, "--dry-run"]
    r = run(*base, "--out", scene["dir"] / "held")
    assert r.exit_code == 0, r.output
    held = json.loads((scene["dir"] / "held" / "manifest.json").read_text())
    assert len(held["splits"]["held_out_garments"]) == 1
    r = run(*base, "--no-held-out", "--out", scene["dir"] / "all")
    assert r.exit_code == 0, r.output
    m = json.loads((scene["dir"] / "all" / "manifest.json").read_text())
    assert m["splits"]["held_out_garments"] == [] and m["settings"]["held_out"] is False
    assert set(m["splits"]["garments"]["train"]) == {"shell", "second"}
    assert "train: " in r.output and "test: " in r.output  # the plan's motions per split
    # Nothing simulated: the plan and the garment templates only.
    assert sorted(p.name for p in (scene["dir"] / "all" / "garments").iterdir()) == ["second.obj", "shell.obj"]
    assert not list((scene["dir"] / "all").glob("sequences/*.npz"))


def test_dataset_source_fps_reads_motions_without_a_frame_rate(scene):
    """Motions without a frame-rate key: refused naming --source-fps; with it, planned at that rate (3 frames at
    10 fps, 0.2 s, are 7 at the dataset's 30), and the rate keys the plan."""
    d = scene["dir"]
    poses = np.zeros((3, 72), np.float32)
    poses[:, 0] = np.pi / 2
    for name in ("a", "b"):
        np.savez(d / f"{name}.npz", poses=poses, trans=np.zeros((3, 3), np.float32))
    args = ["dataset", "--garments", scene["garment"], "--motions", d / "a.npz", "--motions", d / "b.npz",
            "--body", scene["body"], "--settle", 0, "--dry-run", "--out", d / "plan"]
    r = run(*args)
    assert r.exit_code != 0 and "--source-fps" in r.output and not (d / "plan").exists()
    r = run(*args, "--source-fps", 10)
    assert r.exit_code == 0, r.output
    m = json.loads((d / "plan" / "manifest.json").read_text())
    assert m["settings"]["source_fps"] == 10.0 and {it["n_frames"] for it in m["items"]} == {7}


def test_dataset_motion_up_y_reads_y_up_motions_turned_and_keys_the_plan(scene):
    """A motion standing along +Y (root at rest, a Y-up world) read with --motion-up y is the Z-up one (root turned
    +90 degrees about X, the tiny body's pelvis at the origin); the plan records the option only when given."""
    from garmentcli.dataset import _load_motions
    from formats.body import load_body

    d = scene["dir"]
    poses = np.zeros((3, 72), np.float32)
    trans = np.float32([[0.0, 1.0, 0.5]] * 3)
    np.savez(d / "yup.npz", poses=poses, trans=trans, mocap_framerate=30.0)
    for up in ("y", "auto"):  # auto: the body stands along +Y
        turned = _load_motions([d / "yup.npz"], False, 30.0, motion_up=up, body=load_body(scene["body"]))["yup"]
        np.testing.assert_allclose(turned.poses[:, 0], [[np.pi / 2, 0, 0]] * 3, atol=1e-6)
        np.testing.assert_allclose(turned.trans, [[0.0, -0.5, 1.0]] * 3, atol=1e-6)
        assert turned.up == "y"  # each item is turned for its own shape (_run_item)
    library = _load_motions([], True, 30.0, motion_up="auto")
    assert library and all(m.up == "z" for m in library.values())  # the built-in clips stand along +Z
    args = ["dataset", "--garments", scene["garment"], "--motions", d / "yup.npz", "--body", scene["body"],
            "--settle", 0, "--dry-run", "--no-held-out"]
    for options, recorded in (((), None), (("--motion-up", "y"), "y")):
        r = run(*args, *options, "--out", d / f"plan{len(options)}")
        assert r.exit_code == 0, r.output
        settings = json.loads((d / f"plan{len(options)}" / "manifest.json").read_text())["settings"]
        assert settings.get("motion_up") == recorded


def test_dataset_person_plans_a_tracked_persons_frames_and_keys_the_plan(scene):
    """--person reads that track of a file of tracked people (WHAM's: person 3 tracked in 4 of 6 frames): the plan
    has its frames and records the option only when given; --person all plans each person as a motion of its
    own, named after the file and the track, as the workers read them."""
    import pickle

    d = scene["dir"]
    poses = np.zeros((6, 72), np.float32)
    with open(d / "wham_output.pkl", "wb") as fh:
        pickle.dump({0: {"pose_world": poses, "trans_world": np.zeros((6, 3), np.float32)},
                     3: {"pose_world": poses[:4], "trans_world": np.zeros((4, 3), np.float32)}}, fh)
    args = ["dataset", "--garments", scene["garment"], "--motions", d / "wham_output.pkl", "--body", scene["body"],
            "--settle", 0, "--dry-run", "--no-held-out", "--source-fps", 30]
    for options, frames in (((), 6), (("--person", "3"), 4)):
        r = run(*args, *options, "--out", d / f"plan{len(options)}")
        assert r.exit_code == 0, r.output
        manifest = json.loads((d / f"plan{len(options)}" / "manifest.json").read_text())
        assert manifest["settings"].get("person") == (options[1] if options else None)
        assert {it["n_frames"] for it in manifest["items"]} == {frames}, manifest["items"]
    from garmentcli.dataset import _load_motions  # what each worker simulates (`_worker_init`)

    assert _load_motions([d / "wham_output.pkl"], False, 30.0, 30.0, person="3")["wham_output"].n_frames == 4
    r = run(*args, "--person", "all", "--out", d / "plan_all")  # each person a motion of the plan
    assert r.exit_code == 0, r.output
    manifest = json.loads((d / "plan_all" / "manifest.json").read_text())
    frames = {it["motion"]: it["n_frames"] for it in manifest["items"]}
    assert frames == {"wham_output_person0": 6, "wham_output_person3": 4}, frames
    assert set(manifest["inputs"]["motions"]) == set(frames) and manifest["inputs"]["motion_library"] == []
    assert {n: m.n_frames for n, m in _load_motions([d / "wham_output.pkl"], False, 30.0, 30.0,
                                                     person="all").items()} == frames


def test_dataset_motion_up_y_turns_each_item_about_its_own_shapes_pelvis():
    """--motion-up y turns a file's motion about the pelvis at the file's betas; each dataset item then takes a
    body shape of its own, whose pelvis stands elsewhere, so its body stood millimetres off where the Y-up world,
    posed at that shape and turned whole, puts it. `turned_for_shape` (what each item now gets) puts every joint
    there."""
    from dataclasses import replace

    from core.body import default_body
    from core.geometry import Y_UP_TO_Z_UP_MATRIX
    from core.motion import Motion, y_up_to_z_up
    from core.rotations import axis_angle_to_matrix, matrix_to_axis_angle
    from garmentcli.common import turned_for_shape

    # The embedded body's pelvis stays at the origin for every shape; an SMPL body's moves (here: every vertex by
    # 2 cm up and 3 cm forward per unit of the first coefficient).
    body = default_body()
    shapedirs = body.shapedirs.copy()
    shapedirs[:, :, 0] += [0.0, 0.02, 0.03]
    body = replace(body, shapedirs=shapedirs)
    rng = np.random.default_rng(0)
    file_betas, item_betas = rng.uniform(-2.0, 2.0, (2, body.n_betas)).astype(np.float32)
    poses = rng.normal(0.0, 0.3, (4, 24, 3)).astype(np.float32)
    trans = rng.normal(0.0, 0.5, (4, 3)).astype(np.float32)
    q = Y_UP_TO_Z_UP_MATRIX
    pelvis = body.shaped(file_betas)[1][0].astype(np.float64)
    yup_poses = poses.copy()  # the file as a Y-up world has it: the turn undone about the file shape's pelvis
    yup_poses[:, 0] = matrix_to_axis_angle(q.T @ axis_angle_to_matrix(poses[:, 0].astype(np.float64)))
    yup_trans = (trans + pelvis) @ q - pelvis
    yup = Motion(poses=yup_poses, trans=yup_trans.astype(np.float32), fps=30.0, betas=file_betas)
    item = replace(y_up_to_z_up(yup, pelvis), betas=item_betas)  # as read, then given the item's shape
    want = body.pose(yup.poses, yup.trans, item_betas)[1] @ q.T.astype(np.float32)  # the whole world turned
    assert np.abs(body.pose(item.poses, item.trans, item_betas)[1] - want).max() > 1e-3
    fixed = turned_for_shape(item, body, file_betas)
    np.testing.assert_allclose(body.pose(fixed.poses, fixed.trans, item_betas)[1], want, atol=1e-5)


def test_dataset_motions_from_a_directory_tree(scene):
    """--motions DIR takes every motion under it (AMASS's shape.npz, a body shape only, left out); two motions of
    one file name in different folders are two items named by their folders."""
    a, _ = still_motions(scene["dir"])
    tree = scene["dir"] / "amass"
    for subject in ("s1", "s2"):
        (tree / subject).mkdir(parents=True)
        (tree / subject / "walk_poses.npz").write_bytes(a.read_bytes())
        np.savez(tree / subject / "shape.npz", betas=np.zeros(16), gender="female")
    r = run("dataset", "--garments", scene["garment"], "--motions", tree, "--body", scene["body"], "--settle", 0,
            "--dry-run", "--no-held-out", "--out", scene["dir"] / "tree")
    assert r.exit_code == 0, r.output
    m = json.loads((scene["dir"] / "tree" / "manifest.json").read_text())
    assert sorted(m["inputs"]["motions"]) == ["s1_walk_poses", "s2_walk_poses"]
    assert sorted({it["motion"] for it in m["items"]}) == ["s1_walk_poses", "s2_walk_poses"]
    r = run("dataset", "--garments", scene["garment"], "--motions", tree / "s1" / "shape.npz", "--body",
            scene["body"], "--dry-run", "--out", scene["dir"] / "shape")
    assert r.exit_code != 0 and "shape.npz': expected a 'poses' array" in r.output


def test_time_left_reads_as_a_person_would_say_it():
    from garmentcli.dataset import time_left

    assert [time_left(x) for x in (4.2, 59.4, 61, 719, 3500, 3599, 11100)] == [
        "4 s", "59 s", "1 min", "12 min", "58 min", "1 h 00 min", "3 h 05 min"]


def test_first_simulates_a_garments_sequences_before_the_others(scene, monkeypatch):
    """--first G: the items of the plan's last garment go to the workers before the other's (the plan, its key and
    each garment's own order unchanged); a garment not in the plan is refused before anything is written."""
    import core.distributed

    a, b = still_motions(scene["dir"])
    second = scene["dir"] / "second.obj"
    second.write_bytes(Path(scene["garment"]).read_bytes())
    sent = []

    def run_items(task, calls, names, **kwargs):
        sent.extend(names)
        return iter([(name, None) for name in names])

    monkeypatch.setattr(core.distributed, "run_items", run_items)
    base = ["dataset", "--garments", scene["garment"], "--garments", second, "--motions", a, "--motions", b,
            "--body", scene["body"], "--settle", 1, "--bodies", 1, "--no-held-out"]
    r = run(*base, "--out", scene["dir"] / "plain")
    assert r.exit_code == 0, r.output
    plain = list(sent)
    last = plain[-1].split("__")[0]  # the plan's last garment, asked for first
    assert [n.split("__")[0] for n in plain[2:]] == [last, last]
    sent.clear()
    r = run(*base, "--first", last, "--out", scene["dir"] / "first")
    assert r.exit_code == 0, r.output
    assert sent == plain[2:] + plain[:2]
    key = [json.loads((scene["dir"] / d / "manifest.json").read_text())["plan_key"] for d in ("plain", "first")]
    assert key[0] == key[1]
    r = run(*base, "--first", "coat", "--out", scene["dir"] / "bad")
    assert r.exit_code != 0 and "--first" in r.output and "got 'coat'" in r.output
    assert not (scene["dir"] / "bad").exists()


def stride(path, n):
    """Write an n-frame motion of a body gliding along +X at 1.5 m/s from its first frame; returns its trans."""
    poses = np.zeros((n, 72), np.float32)
    poses[:, :3] = [np.pi / 2, 0, 0]
    trans = np.zeros((n, 3), np.float32)
    trans[:, 0] = 1.5 * np.arange(n) / 30.0
    write_motion(path, n_frames=n, fps=30.0, poses=poses, trans=trans)
    return trans


def test_sim_preroll_brings_the_cloth_into_the_first_frame_moving(scene):
    """A body walking at 1.5 m/s from the first frame: with --frames 4: the cloth starts at rest at frame 4 (and
    bake says so); with --preroll 4 it was simulated from frame 0 and arrives there carried along, elsewhere."""
    n = 8
    stride(scene["dir"] / "stride.npz", n)
    common = [scene["garment"], scene["dir"] / "stride.npz", "--body", scene["body"], "--method", "sim",
              "--substeps", 4, "--floor", "none", "--no-obj", "--no-body", "--frames", "4:"]
    r = run("bake", *common, "--out", scene["out"] / "rest")
    assert r.exit_code == 0, r.output
    assert "the cloth starts at rest on the body at START; --preroll N" in r.output
    r = run("bake", *common, "--preroll", 4, "--out", scene["out"] / "led")
    assert r.exit_code == 0, r.output
    assert "--preroll N" not in r.output
    from formats.sequence import read_sequence

    rest, led = (read_sequence(scene["out"] / d / "shell_stride" / "shell_stride.usd").points for d in ("rest", "led"))
    assert rest.shape == led.shape and rest.shape[0] == n - 4
    assert np.abs(led[0] - rest[0]).max() > 1e-3  # the pre-roll's motion shows in the first frame written
    assert json.loads((scene["out"] / "led" / "shell_stride" / "summary.json").read_text())["preroll_frames"] == 4
    # From the motion's own first frame, already moving: bake says so and how to leave that start out.
    r = run("bake", *common[:-2], "--frames", "0:3", "--out", scene["out"] / "start")
    assert r.exit_code == 0, r.output
    assert "stride.npz' moves at 1.5 m/s from its first frame" in r.output and "--frames K: --preroll K" in r.output


def test_dataset_preroll_simulates_the_motion_before_a_later_clip(scene):
    """Clips of 3 frames from a 6-frame stride: the second is simulated after 2 frames of the motion before it,
    stored ahead of it and flagged with the settle blend; a plan whose clips all start their motions (one clip)
    keeps the settings it had before --preroll existed, so such a dataset still resumes."""
    n = 6
    trans = stride(scene["dir"] / "stride.npz", n)
    base = ["dataset", "--garments", scene["garment"], "--motions", scene["dir"] / "stride.npz", "--body",
            scene["body"], "--bodies", 1, "--settle", 1, "--substeps", 4, "--floor", "none", "--frames-per-clip", 3]
    out = scene["dir"] / "led"
    r = run(*base, "--preroll", 2, "--out", out)
    assert r.exit_code == 0, r.output
    m = json.loads((out / "manifest.json").read_text())
    assert m["settings"]["preroll"] == 2 and [it["preroll"] for it in m["items"]] == [0, 2]
    assert m["totals"]["frames"] == (1 + 3) + (1 + 2 + 3)
    first, second = (read_sequence(out / "sequences" / f"shell__stride__c0{c}__b00.npz") for c in (0, 1))
    assert first.positions.shape[0] == 4 and first.n_settle == 1
    assert second.positions.shape[0] == 6 and second.n_settle == 3  # settle blend + pre-roll, then the clip
    np.testing.assert_allclose(second.trans[1:], trans[1:6], atol=1e-6)  # source frames 1, 2 lead into 3..5
    # The cloth enters the clip carried along: its first frame lies elsewhere than a clip started at rest.
    r = run(*base, "--preroll", 0, "--out", scene["dir"] / "rest")
    assert r.exit_code == 0, r.output
    rest = read_sequence(scene["dir"] / "rest" / "sequences" / "shell__stride__c01__b00.npz")
    assert rest.n_settle == 1 and "preroll" not in json.loads((scene["dir"] / "rest" / "manifest.json").read_text())["settings"]
    assert np.abs(second.positions[3] - rest.positions[1]).max() > 1e-3
    # One clip per motion: no pre-roll anywhere, the plan's settings as without the option.
    r = run(*base, "--max-clips-per-motion", 1, "--dry-run", "--out", scene["dir"] / "one")
    assert r.exit_code == 0, r.output
    assert "preroll" not in json.loads((scene["dir"] / "one" / "manifest.json").read_text())["settings"]


def test_dataset_plans_without_resampling_and_refuses_absurd_options(scene, monkeypatch):
    """The plan counts frames without resampling a motion (--fps 1e6 used 14 GB to plan); an absurd --fps,
    --bodies-per-clip above --bodies, a huge or non-finite --betas-range and a duplicate garment name are refused
    in one line naming the option, and nothing is written."""
    import core.motion
    from core.motion import resample
    from formats.motion import load_motion

    a, b = still_motions(scene["dir"])
    expected = resample(load_motion(a), 70.0).n_frames

    def no_resample(*args, **kwargs):
        raise AssertionError("the plan resampled a motion")

    monkeypatch.setattr(core.motion, "resample", no_resample)
    base = ["dataset", "--garments", scene["garment"], "--motions", a, "--motions", b, "--body", scene["body"],
            "--settle", 0, "--dry-run", "--no-held-out"]
    r = run(*base, "--fps", 70, "--out", scene["dir"] / "p70")
    assert r.exit_code == 0, r.output
    m = json.loads((scene["dir"] / "p70" / "manifest.json").read_text())
    assert {it["n_frames"] for it in m["items"]} == {expected}
    twin = scene["dir"] / "twin"
    twin.mkdir()
    (twin / "shell.obj").write_bytes(Path(scene["garment"]).read_bytes())
    for extra, option, word in ((["--fps", "1e6"], "--fps", "1000"), (["--fps", "nan"], "--fps", "finite"),
                                (["--bodies", 2, "--bodies-per-clip", 5], "--bodies-per-clip", "at most --bodies (2)"),
                                (["--betas-range", "1e9"], "--betas-range", "5"),
                                (["--betas-range", "inf"], "--betas-range", "5"),
                                (["--garments", twin / "shell.obj"], "--garments", "'shell' twice"),
                                (["--seed", -1], "--seed", "0<=x<=4294967295"),  # numpy raised ValueError
                                (["--bodies", 2**31], "--bodies", "1<=x<=10000")):  # MemoryError drawing betas
        out = scene["dir"] / "refused"
        r = run(*base, *extra, "--out", out)
        assert r.exit_code != 0 and option in r.output and word in r.output, (extra, r.output)
        assert "Traceback" not in r.output and not out.exists()


def test_a_motion_given_as_garment_is_named_for_what_it_is(scene):
    """A motion .npz as GARMENT said "expected vertices ('v' lines), got none"."""
    r = run("dataset", "--garments", scene["motion"], "--motions", scene["motion"], "--body", scene["body"],
            "--dry-run", "--out", scene["dir"] / "npz")
    assert r.exit_code != 0 and "walk.npz': expected an OBJ or USD garment, got a NumPy .npz archive (a motion?)" \
        in r.output.strip().splitlines()[-1], r.output
    assert not (scene["dir"] / "npz").exists()
    binary = scene["dir"] / "blob.obj"
    binary.write_bytes(b"\x00\x01\x02binary")
    r = run("dataset", "--garments", binary, "--motions", scene["motion"], "--body", scene["body"],
            "--dry-run", "--out", scene["dir"] / "npz")
    assert r.exit_code != 0 and "blob.obj': expected an OBJ or USD garment, got binary content" in r.output


def test_dataset_resume_refuses_another_body_or_motion_of_the_same_name_and_keeps_the_stats(scene):
    """Settings name the body and motions by file name: resuming into a dataset from files of the same names
    with other contents (smplh/male/model.npz, then smplh/female/model.npz; an edited motion) would mix their
    sequences, so it is refused naming the file and nothing is written; a --dry-run over a dataset keeps the
    per-item statistics its runs recorded."""
    from tests.meshes import tiny_body

    a, b = still_motions(scene["dir"])
    male, female = scene["dir"] / "male", scene["dir"] / "female"
    male.mkdir()
    female.mkdir()
    (male / "model.npz").write_bytes(Path(scene["body"]).read_bytes())
    other = tiny_body(seed=1)
    kintree = np.stack([other.parents, np.arange(other.n_joints)])
    kintree[0, 0] = 2**32 - 1
    np.savez(female / "model.npz", v_template=other.v_template * 1.05, shapedirs=other.shapedirs,
             J_regressor=other.J_regressor, weights=other.weights, kintree_table=kintree.astype(np.int64),
             f=other.faces.astype(np.uint32))
    out = scene["dir"] / "data"
    args = ["dataset", "--garments", scene["garment"], "--motions", a, "--motions", b, "--settle", 0, "--dry-run",
            "--out", out]
    assert run(*args, "--body", male / "model.npz").exit_code == 0
    manifest = json.loads((out / "manifest.json").read_text())
    manifest["item_stats"] = {manifest["items"][0]["id"]: {"seconds_per_frame": 1.5}}
    (out / "manifest.json").write_text(json.dumps(manifest))
    r = run(*args, "--body", male / "model.npz")
    assert r.exit_code == 0, r.output
    assert json.loads((out / "manifest.json").read_text())["item_stats"] == manifest["item_stats"]
    before = (out / "manifest.json").read_bytes()
    r = run(*args, "--body", female / "model.npz")
    assert r.exit_code != 0 and "Traceback" not in r.output
    assert "other files of the same name (body 'model.npz' (sha256 " in r.output and "another --out" in r.output
    assert (out / "manifest.json").read_bytes() == before
    write_motion(a, n_frames=3, fps=30.0, seed=7)
    r = run(*args, "--body", male / "model.npz")
    assert r.exit_code != 0 and "motion 'a' (sha256 " in r.output
    assert (out / "manifest.json").read_bytes() == before


def test_dataset_resume_with_motions_added_or_removed_keeps_the_splits_planned(scene):
    """Resuming with a motion added: the motions planned before keep their splits (a fresh plan of a, b, c moves
    a from train to val) and one line says where the new one went; with one removed: its items leave the plan and
    a line says so, its sequence simulated is left on disk."""
    a, b = still_motions(scene["dir"])
    c = scene["dir"] / "c.npz"
    write_motion(c, n_frames=3, fps=30.0, seed=2)
    out = scene["dir"] / "data"
    base = ["dataset", "--garments", scene["garment"], "--body", scene["body"], "--bodies", 1, "--settle", 0,
            "--dry-run", "--out", out]

    def splits():
        m = json.loads((out / "manifest.json").read_text())
        assert {(it["motion"], it["split"]) for it in m["items"]} <= {(n, s) for s, ns in m["splits"]["motions"].items()
                                                                      for n in ns}
        return {n: s for s, ns in m["splits"]["motions"].items() for n in ns}, m

    r = run(*base, "--motions", a, "--motions", b)
    assert r.exit_code == 0, r.output
    before, m = splits()
    assert before == {"a": "train", "b": "test"}
    r = run(*base, "--motions", a, "--motions", b)
    assert r.exit_code == 0 and "new motions" not in r.output and "no longer in the plan" not in r.output
    r = run(*base, "--motions", a, "--motions", b, "--motions", c)
    assert r.exit_code == 0, r.output
    assert f"{out}: new motions split among themselves, train: c (the motions planned before keep their splits)" \
        in r.output
    assert splits()[0] == {**before, "c": "train"}
    # A sequence simulated for b (the file stands in for one), then b left out of the command.
    done = out / "sequences" / f"{m['items'][1]['id']}.npz"
    assert m["items"][1]["motion"] == "b"
    done.parent.mkdir()
    done.write_bytes(b"simulated")
    r = run(*base, "--motions", a, "--motions", c)
    assert r.exit_code == 0, r.output
    assert (f"{out}: motion b no longer in the plan: left out of the manifest (1 sequence simulated for it "
            f"stays in {out / 'sequences'})") in r.output and "new motions" not in r.output
    after, m = splits()
    assert after == {"a": "train", "c": "train"} and {it["motion"] for it in m["items"]} == {"a", "c"}
    assert done.read_bytes() == b"simulated"


def test_a_dataset_stopped_keeps_the_statistics_of_the_items_it_finished(scene, monkeypatch):
    """Stopped (Ctrl-C, SIGTERM) after its first item, the run records that item's statistics in the manifest (a
    rerun skips the finished item, so they were lost for good: 6 items, 4 with statistics)."""
    import core.distributed

    a, b = still_motions(scene["dir"])
    out = scene["dir"] / "stopped"

    def first_then_stop(task, calls, names, **kwargs):
        yield names[0], (None, 4, 1.0, {"max_stretch": 1.01})
        raise KeyboardInterrupt

    monkeypatch.setattr(core.distributed, "run_items", first_then_stop)  # imported by the command when it runs
    r = run("dataset", "--garments", scene["garment"], "--motions", a, "--motions", b, "--settle", 0, "--body",
            scene["body"], "--out", out)
    assert r.exit_code != 0
    manifest = json.loads((out / "manifest.json").read_text())
    first = manifest["items"][0]["id"] if isinstance(manifest["items"], list) else next(iter(manifest["items"]))
    assert manifest["item_stats"] == {first: {"seconds_per_frame": 0.25, "max_stretch": 1.01}}
