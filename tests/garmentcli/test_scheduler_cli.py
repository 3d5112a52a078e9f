"""`garment dataset` and `garment bake` through --scheduler on a 2-worker Dask LocalCluster.

One task per item is made to fail on its first attempt (a worker-side patch: raise for `dataset`,
kill the worker process for `bake`); it is retried, nothing is lost or duplicated, and the
outputs equal those of the local path.
"""

import json
import os
from pathlib import Path

os.environ.setdefault("WARP_CACHE_PATH", str(Path.home() / ".cache" / "garment" / "warp"))

import numpy as np
import pytest

from formats.dataset import read_sequence
from tests.garmentcli.cli import invoke
from tests.garmentcli.test_dataset_cli import still_motions

pytest.importorskip("distributed", reason="dask.distributed is not installed")


def run(*args):
    return invoke(args)


@pytest.fixture(scope="module")
def cluster():
    from tests.cluster import local_cluster

    with local_cluster() as (address, client):
        yield address, client


def fail_first_attempt(module: str, name: str, match: str, marker_dir: str, kill: bool):
    """Patch `module.name` on a worker: the first call whose arguments mention `match` raises (or kills the worker)."""
    import importlib

    mod = importlib.import_module(module)
    real = getattr(mod, name)

    def patched(*args):
        marker = Path(marker_dir) / f"{match}.attempted"
        if match in repr(args) and not marker.exists():
            marker.touch()
            if kill:
                os._exit(1)
            raise RuntimeError(f"injected failure of {match}")
        return real(*args)

    setattr(mod, name, patched)


#: How far a sequence simulated on a Dask worker may lie from the same simulated in this process (metres).
SAME_SIMULATION_M = 1e-4


def test_dataset_through_scheduler_retries_and_matches_local(scene, cluster):
    address, client = cluster
    a, b = still_motions(scene["dir"])
    common = ["dataset", "--garments", scene["garment"], "--motions", a, "--motions", b, "--body", scene["body"],
              "--bodies", 2, "--betas-range", 0.5, "--settle", 1, "--substeps", 5]
    local, remote = scene["dir"] / "local", scene["dir"] / "remote"
    r = run(*common, "--out", local)
    assert r.exit_code == 0, r.output
    victim = json.loads((local / "manifest.json").read_text())["items"][1]["id"]
    client.run(fail_first_attempt, "garmentcli.dataset", "dataset_task", victim, str(scene["dir"]), False)
    r = run(*common, "--out", remote, "--scheduler", address)
    assert r.exit_code == 0, r.output
    assert (scene["dir"] / f"{victim}.attempted").exists()  # it did fail once, and was retried
    assert "4 sequences ready (4 simulated now)" in r.output
    lf, rf = sorted((local / "sequences").glob("*.npz")), sorted((remote / "sequences").glob("*.npz"))
    assert [f.name for f in lf] == [f.name for f in rf] and len(rf) == 4
    assert not list((remote / "sequences").glob(".*"))  # no partial file left
    for x, y in zip(lf, rf):
        sx, sy = read_sequence(x), read_sequence(y)
        # within 0.1 mm: a worker's threads round the inputs' sums otherwise than this process's, and the contacts
        # grow it (on an AMD EPYC one coordinate of 7,704 differed by 5.7 um; the cloth moves centimetres a frame)
        np.testing.assert_allclose(sy.positions, sx.positions, atol=SAME_SIMULATION_M)
        assert sx.garment_sha256 == sy.garment_sha256 and sx.body == sy.body and sx.n_settle == sy.n_settle
    ml, mr = (json.loads((d / "manifest.json").read_text()) for d in (local, remote))
    assert ml["plan_key"] == mr["plan_key"] and ml["items"] == mr["items"] and len(mr["item_stats"]) == 4
    # Resume from the manifest: a deleted item is the only one redone.
    rf[2].unlink()
    r = run(*common, "--out", remote, "--scheduler", address)
    assert r.exit_code == 0 and "1 to simulate" in r.output and "(1 simulated now)" in r.output, r.output
    np.testing.assert_allclose(read_sequence(rf[2]).positions, read_sequence(lf[2]).positions, atol=SAME_SIMULATION_M)


def test_bake_through_scheduler_survives_a_killed_worker_and_matches_local(scene, cluster):
    address, client = cluster
    motions = [scene["motion"], scene["motion2"]]
    local, remote = scene["dir"] / "bl", scene["dir"] / "br"
    r = run("bake", scene["garment"], *motions, "--body", scene["body"], "--method", "lbs", "--out", local)
    assert r.exit_code == 0, r.output
    client.run(fail_first_attempt, "garmentcli.bake", "bake_task", "jump.npz", str(scene["dir"]), True)
    r = run("bake", scene["garment"], *motions, "--body", scene["body"], "--method", "lbs", "--out", remote,
            "--scheduler", address)
    assert r.exit_code == 0, r.output
    assert (scene["dir"] / "jump.npz.attempted").exists()
    assert sorted(p.name for p in remote.iterdir()) == ["shell_jump", "shell_walk"]  # no partial directory
    for name in ("shell_jump", "shell_walk"):
        lo, ro = sorted((local / name / "obj").glob("*.obj")), sorted((remote / name / "obj").glob("*.obj"))
        assert [p.name for p in lo] == [p.name for p in ro] and lo
        assert all(p.read_bytes() == q.read_bytes() for p, q in zip(lo, ro))
        sl, sr = (json.loads((d / name / "summary.json").read_text()) for d in (local, remote))
        assert sl["frames"] == sr["frames"] and sl["penetration"] == sr["penetration"]
        assert (remote / name / f"{name}.usd").is_file()
    assert r.output.count("frames at 30 fps") == 2  # each motion reported once
    # Resume: existing outputs are left alone.
    mtime = (remote / "shell_walk" / "summary.json").stat().st_mtime_ns
    r = run("bake", scene["garment"], *motions, "--body", scene["body"], "--out", remote, "--skip-existing",
            "--scheduler", address)
    assert r.exit_code == 0 and "2 of 2 motions already baked" in r.output, r.output
    assert (remote / "shell_walk" / "summary.json").stat().st_mtime_ns == mtime


def test_unreachable_scheduler_is_one_line_and_writes_nothing(scene):
    out = scene["dir"] / "none"
    r = run("bake", scene["garment"], scene["motion"], "--body", scene["body"], "--out", out,
            "--scheduler", "tcp://127.0.0.1:9")
    assert r.exit_code != 0 and "expected a running Dask scheduler" in r.output and "Traceback" not in r.output
    assert not out.exists()
