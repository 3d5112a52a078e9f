"""garmentcli's process settings, made when the package loads."""

import ctypes
import sys

import numpy as np
import pytest

from garmentcli import keep_freed_memory


class _Mallinfo2(ctypes.Structure):
    _fields_ = [(name, ctypes.c_size_t) for name in
                ("arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks", "fsmblks", "uordblks", "fordblks",
                 "keepcost")]


def _mapped_bytes() -> int:
    """Bytes glibc's malloc holds in blocks mapped for their own (mallinfo2's hblkhd)."""
    mallinfo2 = ctypes.CDLL(None).mallinfo2
    mallinfo2.restype = _Mallinfo2
    return int(mallinfo2().hblkhd)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's malloc")
def test_large_blocks_come_from_the_heap_and_stay_for_reuse(monkeypatch):
    """A 64 MB block (a large network temporary) is not mapped for its own, which glibc's default does for every
    block over 32 MB, unmapping it when freed so that the next one is fresh pages the kernel faults in and zeroes."""
    import os

    for key in [k for k in os.environ if k.startswith("MALLOC_") or k == "GLIBC_TUNABLES"]:
        monkeypatch.delenv(key)  # dask.distributed, imported by other tests, sets MALLOC_TRIM_THRESHOLD_ for its workers
    if not keep_freed_memory() or not hasattr(ctypes.CDLL(None), "mallinfo2"):
        pytest.skip("not glibc's malloc (2.33 or later)")
    before = _mapped_bytes()
    a = np.ones(16 << 20, dtype=np.float32)  # 64 MB
    assert _mapped_bytes() - before < 1 << 20
    del a


def test_malloc_settings_of_the_environment_are_left_alone(monkeypatch):
    monkeypatch.setenv("MALLOC_MMAP_THRESHOLD_", "131072")
    assert keep_freed_memory() is False
    monkeypatch.delenv("MALLOC_MMAP_THRESHOLD_")
    monkeypatch.setenv("GLIBC_TUNABLES", "glibc.malloc.trim_threshold=0")
    assert keep_freed_memory() is False
