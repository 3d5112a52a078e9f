"""Session-wide test settings."""

import os

import pytest

# One OpenBLAS thread per process before numpy loads, as for the command (garmentcli/__init__.py sets it): two
# xdist workers with two BLAS threads each on two cores made numpy products 14-400x slower.
import garmentcli  # noqa: F401


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
