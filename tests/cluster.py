"""A Dask LocalCluster for the tests of the scheduler path."""

import contextlib


@contextlib.contextmanager
def local_cluster(n_workers: int = 2):
    """(scheduler address, Client) of a Dask LocalCluster of `n_workers` single-thread processes. Its start is
    tried twice: distributed gives its IO loop 10 s to start, which the other xdist worker's load (spawning
    processes that import torch) can take on two cores (an AssertionError in distributed/utils.py once)."""
    from distributed import Client, LocalCluster

    for attempt in (1, 2):
        try:
            cluster = LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=True, dashboard_address=None)
            break
        except (AssertionError, TimeoutError, OSError):
            if attempt == 2:
                raise
    with cluster, Client(cluster) as client:
        yield cluster.scheduler_address, client
