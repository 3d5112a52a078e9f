"""The `garment` command line: one thin module per subcommand.

numpy's OpenBLAS gets one thread unless OPENBLAS_NUM_THREADS says otherwise (set here, before numpy loads):
with more BLAS threads than free cores (`--workers`, torchrun, any other busy process) its threads wait for
cores other processes hold, and a product such as the (24, 13348) x (13348, 24) of the model's motion features
took 1.75 s instead of 13 ms on 2 busy cores. Our numpy products are small; one thread is as fast when idle.
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
