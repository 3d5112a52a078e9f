"""Session-wide test settings."""

import os

# One OpenBLAS thread per process, as the command sets (garmentcli/__init__.py), before numpy loads: two xdist
# workers with two BLAS threads each on two cores made numpy products 14-400x slower.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import pytest  # noqa: E402


@pytest.fixture(scope="session", autouse=True)
def private_cache_dir(tmp_path_factory):
    """The preprocessing cache (bake --method model, preprocess) in a temporary directory, never ~/.cache."""
    from formats.cache import CACHE_ENV

    old = os.environ.get(CACHE_ENV)
    os.environ[CACHE_ENV] = str(tmp_path_factory.mktemp("garment_cache"))
    yield
    if old is None:
        os.environ.pop(CACHE_ENV, None)
    else:
        os.environ[CACHE_ENV] = old
