"""garmentcli's process settings, made when the package loads."""

import sys

import pytest

from garmentcli import keep_freed_memory


#: A new process (none of the test process's other threads allocating meanwhile) that prints how many bytes of
#: blocks mapped for their own (mallinfo2's hblkhd) a 64 MB array (a large network temporary) added, or "skip".
_MAPPED_BY_A_64_MB_ARRAY = """
import ctypes, sys
import numpy as np
import garmentcli

class Mallinfo2(ctypes.Structure):
    _fields_ = [(n, ctypes.c_size_t) for n in ("arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks",
                                                "fsmblks", "uordblks", "fordblks", "keepcost")]

libc = ctypes.CDLL(None)
if not hasattr(libc, "mallinfo2"):
    print("skip")
    sys.exit()
libc.mallinfo2.restype = Mallinfo2
before = libc.mallinfo2().hblkhd
a = np.ones(16 << 20, dtype=np.float32)
print(libc.mallinfo2().hblkhd - before)
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's malloc")
def test_large_blocks_come_from_the_heap_and_stay_for_reuse():
    """A 64 MB block is not mapped for its own, which glibc's default does for every block over 32 MB, unmapping
    it when freed so that the next one is fresh pages the kernel faults in and zeroes; with malloc's settings left
    to the environment (GLIBC_TUNABLES set) it is. In new processes: mallinfo2 counts every thread's blocks, and
    the test process's other threads (pytest's, a scheduler's) could map one meanwhile."""
    import os
    import subprocess

    env = {k: v for k, v in os.environ.items() if not (k.startswith("MALLOC_") or k == "GLIBC_TUNABLES")}

    def mapped(extra: dict) -> str:
        return subprocess.run([sys.executable, "-c", _MAPPED_BY_A_64_MB_ARRAY], env={**env, **extra}, check=True,
                              capture_output=True, text=True).stdout.strip()

    kept = mapped({})
    if kept == "skip":
        pytest.skip("not glibc's malloc (2.33 or later)")
    assert int(kept) < 1 << 20
    assert int(mapped({"GLIBC_TUNABLES": "glibc.malloc.check=0"})) >= 64 << 20  # the default, for contrast


def test_malloc_settings_of_the_environment_are_left_alone(monkeypatch):
    monkeypatch.setenv("MALLOC_MMAP_THRESHOLD_", "131072")
    assert keep_freed_memory() is False
    monkeypatch.delenv("MALLOC_MMAP_THRESHOLD_")
    monkeypatch.setenv("GLIBC_TUNABLES", "glibc.malloc.trim_threshold=0")
    assert keep_freed_memory() is False
