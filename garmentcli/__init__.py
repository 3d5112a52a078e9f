"""The `garment` command line: one thin module per subcommand.

Two process settings are made here, before numpy and torch load:

- numpy's OpenBLAS gets one thread unless OPENBLAS_NUM_THREADS says otherwise: with more BLAS threads than free
  cores (`--workers`, torchrun, any other busy process) its threads wait for cores other processes hold, and a
  product such as the (24, 13348) x (13348, 24) of the model's motion features took 1.75 s instead of 13 ms on 2
  busy cores. Our numpy products are small; one thread is as fast when idle.
- glibc's malloc keeps freed memory in the process (`keep_freed_memory`).
"""

import ctypes
import os
import sys

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

#: mallopt's parameters (glibc's malloc.h).
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3
#: Free memory at the top of the heap kept rather than given back to the system.
TRIM_THRESHOLD_BYTES = 1 << 30


def keep_freed_memory() -> bool:
    """Let glibc's malloc reuse freed blocks of any size instead of giving them back to the system at once; True
    where it took the settings (glibc), False elsewhere or where MALLOC_* or GLIBC_TUNABLES set them already.

    By default every block over 128 kB-32 MB is mapped for its own and unmapped when freed, so each of the
    network's large temporaries (tens to hundreds of MB a batch for a garment of 10-50k vertices) came back as
    fresh pages the kernel faults in and zeroes: 135k page faults a frame for a 51k-vertex garment, whose network
    then ran 2.7x slower (320 against 118 ms/frame on the 2-core Zen 4; 13k vertices: 1.7x; the 4k-vertex
    examples' blocks stay under the threshold; with the threshold at glibc's largest, 32 MB: 210 ms/frame). The process's peak memory is what it was (829 against 869 MB
    there); it keeps up to TRIM_THRESHOLD_BYTES free after the work.
    """
    if not sys.platform.startswith("linux") or "GLIBC_TUNABLES" in os.environ or any(
            k.startswith("MALLOC_") and k.endswith("_") for k in os.environ):
        return False
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes, mallopt.restype = (ctypes.c_int, ctypes.c_int), ctypes.c_int
    # glibc before 2.26 or so takes at most 32 MB (on 64 bits), which leaves the largest blocks mapped: 1.5x.
    mapped_from = mallopt(_M_MMAP_THRESHOLD, 2**31 - 1) or mallopt(_M_MMAP_THRESHOLD, 32 << 20)
    return bool(mapped_from and mallopt(_M_TRIM_THRESHOLD, TRIM_THRESHOLD_BYTES))


keep_freed_memory()
