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
