"""formats.atomic: outputs appear whole or not at all."""

import os

import pytest

from core.errors import InputError
from formats.atomic import atomic_dir, atomic_file


def test_atomic_dir_replaces_a_folder_or_a_file_and_leaves_nothing_beside(tmp_path):
    out = tmp_path / "out"
    with atomic_dir(out, overwrite=False) as tmp:
        (tmp / "a.txt").write_text("1")
    with pytest.raises(InputError, match="--overwrite"):
        with atomic_dir(out, overwrite=False):
            pass
    with atomic_dir(out, overwrite=True) as tmp:
        (tmp / "b.txt").write_text("2")
    assert sorted(p.name for p in out.iterdir()) == ["b.txt"]
    # --overwrite over a file of that name: replaced by the folder, no hidden '.out.old' left behind
    out.with_name("file").write_text("x")
    with atomic_dir(tmp_path / "file", overwrite=True) as tmp:
        (tmp / "c.txt").write_text("3")
    assert (tmp_path / "file" / "c.txt").read_text() == "3"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file", "out"]
    # a failure inside leaves the earlier output as it was and no partial folder
    with pytest.raises(RuntimeError):
        with atomic_dir(out, overwrite=True) as tmp:
            (tmp / "d.txt").write_text("4")
            raise RuntimeError("stop")
    assert sorted(p.name for p in out.iterdir()) == ["b.txt"] and sorted(p.name for p in tmp_path.iterdir()) == [
        "file", "out"]


def test_an_output_another_run_wrote_meanwhile_is_not_replaced_without_overwrite(tmp_path):
    """Two runs writing one output at once (two bakes into one --out): the one finishing second found no output
    when it started; it is refused then (it replaced the first's output without a word), and nothing of it is
    left. With --overwrite the last one wins, leaving nothing beside."""
    out = tmp_path / "out"

    def two_runs(overwrite):
        with atomic_dir(out, overwrite=overwrite) as first:
            (first / "first.txt").write_text("1")
            with atomic_dir(out, overwrite=overwrite) as second:
                (second / "second.txt").write_text("2")

    with pytest.raises(InputError, match="'.*out' was written by another run while this one worked: pass "
                                         "--overwrite to replace it, or give each run its own --out"):
        two_runs(overwrite=False)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]
    assert sorted(p.name for p in out.iterdir()) == ["second.txt"]
    two_runs(overwrite=True)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]
    assert sorted(p.name for p in out.iterdir()) == ["first.txt"]


def _overwrite_many(args):
    out, worker = args
    failures = []
    for k in range(40):
        try:
            with atomic_dir(out, overwrite=True) as tmp:
                for j in range(5):
                    (tmp / f"f{j}").write_text(f"{worker} {k}")
        except Exception as exc:  # noqa: BLE001 - counted, the test's point
            failures.append(f"{type(exc).__name__}: {exc}")
    return failures


def test_runs_overwriting_one_output_at_once_neither_fail_nor_leave_folders(tmp_path):
    """Four processes replacing one output 40 times each with --overwrite: every write lands whole (the last one's
    five files, of one writer and one round) and no hidden folder is left (one shared '.out.old' name made 81 of 800
    writes fail with FileNotFoundError or 'Directory not empty' and left their '.partial' folders)."""
    import multiprocessing

    out = tmp_path / "out"
    with multiprocessing.get_context("fork").Pool(4) as pool:
        failures = [f for part in pool.map(_overwrite_many, [(out, w) for w in range(4)]) for f in part]
    assert failures == []
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]
    assert len({(out / f"f{j}").read_text() for j in range(5)}) == 1


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="named pipes")
def test_a_device_or_pipe_is_never_renamed_over(tmp_path):
    """Outputs are renamed into place: `--out /dev/null` once replaced the device with a regular file. A pipe (as a
    device, which tests cannot make without root) at the target is refused, and stays what it was."""
    import stat

    pipe = tmp_path / "pipe"
    os.mkfifo(pipe)
    for write in (lambda: atomic_file(pipe), lambda: atomic_dir(pipe, overwrite=True)):
        with pytest.raises(InputError, match=f"output '{pipe}' is a pipe: expected a file or folder to write"):
            with write():
                pass
        assert stat.S_ISFIFO(os.stat(pipe).st_mode)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["pipe"]  # no temporary left
    if os.path.exists("/dev/null"):
        with pytest.raises(InputError, match="is a device"):
            with atomic_file("/dev/null"):
                pass


def test_a_folder_where_a_file_is_written_is_refused_before_the_work(tmp_path):
    """The rename failed after the work (a dataset's simulation) with IsADirectoryError naming the hidden temporary
    file; now the writer refuses it at once, an InputError (not retried on a cluster), naming the output."""
    taken = tmp_path / "seq.npz"
    (taken / "inner").mkdir(parents=True)
    with pytest.raises(InputError, match=f"output '{taken}' is a folder: expected a file to write"):
        with atomic_file(taken):
            raise AssertionError("the work was done")
    assert (taken / "inner").is_dir() and sorted(p.name for p in tmp_path.iterdir()) == ["seq.npz"]


def _disk_full(*args, **kwargs):
    raise OSError(28, "No space left on device")


def test_a_write_that_runs_out_of_room_is_one_line_naming_the_output_and_leaves_nothing(tmp_path, monkeypatch):
    """ENOSPC (a full disk) while writing a file or a folder's contents: an InputError naming the final output,
    not the hidden temporary one, with the space left; nothing left beside it. Another OSError is not renamed."""
    import formats.atomic

    monkeypatch.setattr(formats.atomic, "free_space", lambda path: 8192)
    with pytest.raises(InputError) as err:
        with atomic_file(tmp_path / "a.json") as tmp:
            tmp.write_text("{")
            _disk_full()
    assert str(err.value) == f"output '{tmp_path / 'a.json'}': could not be written (No space left on device; " \
                             "8.0 kB free on its file system)"
    with pytest.raises(InputError) as err:
        with atomic_dir(tmp_path / "bake", overwrite=False) as tmp:
            raise InputError(f"USD stage '{tmp / 'bake.usd'}': could not be written")
    assert str(err.value) == f"USD stage '{tmp_path / 'bake' / 'bake.usd'}': could not be written"
    with pytest.raises(InputError, match=r"output '.*bake2': could not be written \(No space left"):
        with atomic_dir(tmp_path / "bake2", overwrite=False):
            _disk_full()
    with pytest.raises(FileNotFoundError):
        with atomic_file(tmp_path / "b.json"):
            raise FileNotFoundError(2, "No such file or directory")
    assert os.listdir(tmp_path) == []


def test_a_low_space_note_names_the_space_left_only_when_little_is(tmp_path, monkeypatch):
    """Under 64 MB free: named, for a writer that fails without saying why (USD's); the folder asked about is the
    nearest that exists."""
    from types import SimpleNamespace

    import formats.atomic
    from formats.atomic import LOW_SPACE_BYTES, low_space_note

    asked = []

    def usage(free):
        return lambda path: asked.append(path) or SimpleNamespace(free=free)

    monkeypatch.setattr(formats.atomic.shutil, "disk_usage", usage(1536))
    assert low_space_note(tmp_path / "new" / "deeper" / "a.usd") == "; 1.5 kB free on its file system (full?)"
    assert asked == [tmp_path]
    monkeypatch.setattr(formats.atomic.shutil, "disk_usage", usage(LOW_SPACE_BYTES))
    assert low_space_note(tmp_path / "a.usd") == ""


def test_leftovers_of_a_killed_run_are_removed_when_the_output_is_written_again(tmp_path):
    """A run killed outright (SIGKILL) leaves its hidden temporary folder and files: the next write of the same
    output removes those of this host's processes that no longer exist, and leaves a living process's, another
    host's and another output's alone."""
    import subprocess
    import sys

    import formats.atomic

    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    me, host = os.getpid(), formats.atomic._host()
    leftovers = {f".render.{host}@{dead.pid}.k2j3.partial": False, f".render.{host}@{me}.a1b2.partial": True,
                 f".render.other_host@{dead.pid}.x9y8.partial": True, f".renders.{host}@{dead.pid}.q1w2.partial": True,
                 f".metrics.{host}@{dead.pid}.z7.partial.json": False}
    for name in leftovers:
        (tmp_path / name).mkdir() if not name.endswith(".json") else (tmp_path / name).write_text("{")
        if not name.endswith(".json"):
            (tmp_path / name / "frame_0000.png").write_bytes(b"x")
    with atomic_dir(tmp_path / "render", overwrite=False) as tmp:
        (tmp / "frame_0000.png").write_bytes(b"y")
    with atomic_file(tmp_path / "metrics.json") as tmp:
        tmp.write_text("{}")
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        ["render", "metrics.json", *(name for name, kept in leftovers.items() if kept)])
