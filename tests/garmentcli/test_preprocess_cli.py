"""`garment preprocess`: summary, cache hit/miss, render, and one-line errors for bad input."""

import logging
from pathlib import Path

import pytest
from click.testing import CliRunner

from garmentcli.main import cli


def run(*args, env=None):
    return CliRunner().invoke(cli, list(args), env=env)


def test_happy_path_miss_then_hit(scene):
    cache = scene["dir"] / "cache"
    args = ["preprocess", scene["garment"], "--body", scene["body"], "--cache-dir", str(cache), "--landmarks", "16"]
    r = run(*args)
    assert r.exit_code == 0, r.output
    assert "cache miss" in r.output and "level 2:" in r.output and "1 component(s)" in r.output
    assert "descriptor (16 eigenvalues, 16 landmarks)" in r.output
    assert len(list(cache.glob("preprocess-*.npz"))) == 1
    r2 = run(*args)
    assert r2.exit_code == 0 and "cache hit" in r2.output
    r3 = run(*args[:-2], "--landmarks", "16", "--levels", "3")
    assert "cache miss" in r3.output and "level 3:" in r3.output

    assert "self-collision" not in r.output  # bake's entry: no training neighbourhood
    r4 = run(*args, "--self-collision")
    assert r4.exit_code == 0 and "cache miss" in r4.output, r4.output
    assert "self-collision: " in r4.output and "vertex pairs within 10 cm" in r4.output
    assert len(list(cache.glob("preprocess-*.npz"))) == 3


def test_env_cache_dir_and_no_cache(scene):
    env = {"GARMENT_CACHE_DIR": str(scene["dir"] / "envcache")}
    r = run("preprocess", scene["garment"], "--body", scene["body"], "--landmarks", "8", "--levels", "1", env=env)
    assert r.exit_code == 0, r.output
    assert list((scene["dir"] / "envcache").glob("*.npz"))
    r = run("preprocess", scene["garment"], "--body", scene["body"], "--landmarks", "8", "--no-cache", env=env)
    assert r.exit_code == 0 and "cache off" in r.output


def test_render_writes_a_png(scene):
    pytest.importorskip("pyvista")
    out = scene["dir"] / "renders"
    r = run("preprocess", scene["garment"], "--body", scene["body"], "--no-cache", "--landmarks", "8",
            "--render", str(out))
    assert r.exit_code == 0, r.output
    png = out / "shell_hierarchy.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # its rerun replaced the picture without a word: --overwrite, as every other output
    png.write_bytes(b"mine")
    args = ("preprocess", scene["garment"], "--body", scene["body"], "--no-cache", "--landmarks", "8", "--render",
            str(out))
    r = run(*args)
    assert r.exit_code == 1 and f"output '{png}' exists: pass --overwrite" in r.output and png.read_bytes() == b"mine"
    assert run(*args, "--overwrite").exit_code == 0 and png.read_bytes()[:4] == b"\x89PNG"


def test_two_garments_of_one_name_are_refused_one_picture(scene, tmp_path):
    """Two garments named alike in one run drew one picture, the second over the first, without --overwrite."""
    import shutil

    (tmp_path / "other").mkdir()
    twin = shutil.copy(scene["garment"], tmp_path / "other" / Path(scene["garment"]).name)
    r = run("preprocess", scene["garment"], str(twin), "--no-cache", "--render", str(tmp_path / "r"))
    assert r.exit_code == 2 and "two garments named 'shell' would draw one picture" in r.output
    assert not (tmp_path / "r").exists()


def test_no_cache_with_a_cache_dir_is_refused(scene):
    """--no-cache --cache-dir X ignored X without a word."""
    r = run("preprocess", scene["garment"], "--no-cache", "--cache-dir", str(scene["dir"] / "c"))
    assert r.exit_code == 2 and "--no-cache and --cache-dir exclude each other" in r.output


@pytest.mark.parametrize("extra, message", [
    (["--levels", "0"], "--levels"), (["--levels", "-1"], "--levels"), (["--levels", "10"], "--levels"),
    (["--levels", "two"], "--levels"), (["--landmarks", "1"], "--landmarks"), (["--landmarks", "0"], "--landmarks"),
])
def test_bad_options(scene, extra, message):
    r = run("preprocess", scene["garment"], "--no-cache", *extra)
    assert r.exit_code != 0 and message in r.output and "Traceback" not in r.output


def test_missing_and_broken_files(scene):
    r = run("preprocess", str(scene["dir"] / "nope.obj"), "--no-cache")
    assert r.exit_code == 1 and "file not found" in r.output and len(r.output.strip().splitlines()) == 1
    # a missing second garment: refused before the first is preprocessed (its render was left behind)
    r = run("preprocess", scene["garment"], str(scene["dir"] / "nope.obj"), "--no-cache", "--render",
            str(scene["dir"] / "r2"))
    assert r.exit_code == 1 and "file not found" in r.output and not (scene["dir"] / "r2").exists()
    broken = scene["dir"] / "broken.obj"
    broken.write_text("v 0 0 0\nv 1 0 0\nf 1 2 7\n")
    r = run("preprocess", str(broken), "--no-cache")
    assert r.exit_code == 1 and "broken.obj" in r.output and len(r.output.strip().splitlines()) == 1
    r = run("preprocess")
    assert r.exit_code == 2 and "GARMENT" in r.output


def test_unwritable_cache_dir_is_one_line(scene):
    blocker = scene["dir"] / "file"
    blocker.write_text("x")
    r = run("preprocess", scene["garment"], "--body", scene["body"], "--landmarks", "8",
            "--cache-dir", str(blocker / "sub"))
    assert r.exit_code == 1 and "cache directory" in r.output and "Traceback" not in r.output


def test_a_render_folder_that_cannot_be_written_stops_before_any_work(scene):
    """--render OUT_DIR under a file: refused when the command line is read, not after the garment is
    preprocessed (nothing cached either)."""
    blocker = scene["dir"] / "file"
    blocker.write_text("x")
    cache = scene["dir"] / "cache"
    r = run("preprocess", scene["garment"], "--body", scene["body"], "--landmarks", "8", "--cache-dir", str(cache),
            "--render", str(blocker / "renders"))
    assert r.exit_code == 2 and "Invalid value for '--render'" in r.output and "is a file, not a folder" in r.output
    assert "Traceback" not in r.output and "vertices" not in r.output and not cache.exists()


def test_a_garment_facing_the_body_is_turned_as_bake_turns_it(scene, caplog):
    """The shell with its faces reversed (facing the body): turned with a warning, as `bake --method model`
    prepares it, so the entry written is the one the bake reads."""
    from core.preprocess import CACHE_KIND, preprocess_garment
    from core.skinning import oriented_outward
    from formats.body import load_body
    from formats.cache import cache_path
    from formats.obj import read_garment

    text = Path(scene["garment"]).read_text().splitlines()
    flipped = scene["dir"] / "inward.obj"
    flipped.write_text("\n".join(" ".join(["f", *line.split()[:0:-1]]) if line.startswith("f ") else line
                                 for line in text) + "\n")
    cache = scene["dir"] / "cache"
    with caplog.at_level(logging.WARNING):
        r = run("preprocess", str(flipped), "--body", scene["body"], "--landmarks", "8", "--cache-dir", str(cache))
    assert r.exit_code == 0, r.output
    assert "faces turned for the model's normals (1 of its 1 pieces faced the body)" in caplog.text
    turned = oriented_outward(read_garment(flipped), load_body(scene["body"]))
    key = preprocess_garment(turned, load_body(scene["body"]), n_landmarks=8, collision_radius_m=0.0).key
    assert cache_path(cache, CACHE_KIND, key).is_file()
