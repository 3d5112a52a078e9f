"""core.distributed: the same items through the local engines and a Dask LocalCluster, with injected failures."""

import os
import sys
from pathlib import Path

import pytest

from core.distributed import ItemsFailed, run_items

distributed = pytest.importorskip("distributed", reason="dask.distributed is not installed")


def make_task(work_dir):
    """A task (a closure, so it is pickled by value) that writes x*x to work_dir/x.out atomically.

    Item 2 raises on its first attempt; item 3 kills its worker process on its first attempt
    (a marker file records the attempt, so the retry goes through).
    """
    work_dir = str(work_dir)

    def task(x):
        from formats.atomic import atomic_file

        attempt = Path(work_dir) / f"{x}.attempt"
        with open(Path(work_dir) / f"{x}.runs", "a") as fh:
            fh.write(".")
        if x in (2, 3) and not attempt.exists():
            attempt.touch()
            if x == 2:
                raise RuntimeError("injected failure")
            os._exit(1)
        with atomic_file(Path(work_dir) / f"{x}.out") as tmp:
            tmp.write_text(str(x * x))
        return x * x

    return task


@pytest.fixture(scope="module")
def client():
    from tests.cluster import local_cluster

    with local_cluster() as (_, c):
        yield c


def test_local_engine_in_process_and_in_order(tmp_path):
    got = list(run_items(lambda a, b: a + b, [(1, 2), (3, 4)], ["x", "y"]))
    assert got == [("x", 3), ("y", 7)]
    assert list(run_items(abs, [], [])) == []
    with pytest.raises(ValueError, match="one name per call"):
        list(run_items(abs, [(1,)], []))


def _square_but_not_one(x):
    if x == 1:
        raise ValueError("one is broken")
    return x * x


@pytest.mark.parametrize("workers", [2, 1])
def test_local_processes_keep_going_past_a_failed_item(caplog, workers):
    """In local processes, a failing item is said at once and the others still finish (a long dataset run used to
    wait silently for every other item before its error surfaced); in this process too (`dataset --workers 1`
    stopped at its first failing item with a traceback, the other garments' items never run)."""
    got = {}
    with pytest.raises(ItemsFailed, match="1 of 5 items failed; first: 'i1': ValueError: one is broken") as info:
        for name, value in run_items(_square_but_not_one, [(x,) for x in range(5)], [f"i{x}" for x in range(5)],
                                     workers=workers):
            got[name] = value
    assert got == {"i0": 0, "i2": 4, "i3": 9, "i4": 16} and info.value.total == 5
    assert "item 'i1' failed: ValueError: one is broken" in caplog.text


def test_local_processes_are_no_more_than_the_items(monkeypatch):
    """A pool starts all of its processes at the first submit: `bake --workers 100000` of two motions forked
    thousands of copies of the command."""
    import concurrent.futures

    made = []
    real = concurrent.futures.ProcessPoolExecutor

    def recording(max_workers=None, **kw):
        made.append(max_workers)
        return real(max_workers=max_workers, **kw)

    monkeypatch.setattr(concurrent.futures, "ProcessPoolExecutor", recording)
    got = dict(run_items(_square_but_not_one, [(2,), (3,)], ["a", "b"], workers=64))
    assert got == {"a": 4, "b": 9} and made == [2]


class _Pending:
    """A Dask future that never finishes (a task a worker runs)."""

    def __init__(self, key):
        self.key, self.status, self.cancelled = key, "pending", False

    def cancel(self):
        self.cancelled = True


def test_a_stopped_cluster_run_cancels_its_tasks_and_stops_those_started_writing(monkeypatch, caplog):
    """Ctrl-C while a cluster runs the items: Dask's cancel does not stop a task a worker has started, whose
    output appeared seconds after the command had exited and removed --out; the run sets its stop Event (the
    tasks check it before an output takes its place: the cluster test below), cancels every unfinished task and
    says so, and where the Event cannot be set, that the tasks started can still write."""
    import distributed as dist

    from core.distributed import _run_dask

    futures, events = [], []

    class Event:
        def __init__(self, name, client=None):
            self.name = name

        def set(self):
            if fail:
                raise OSError("scheduler gone")
            events.append(self.name)

    class Client:
        scheduler = type("S", (), {"address": "tcp://x:1"})()

        def submit(self, task, *args, key, **kw):
            futures.append(_Pending(key))
            return futures[-1]

    def interrupted(client, fs):
        raise KeyboardInterrupt
        yield

    import core.distributed

    monkeypatch.setattr(core.distributed, "_completed", interrupted)
    monkeypatch.setattr(dist, "Event", Event)
    for fail in (False, True):
        futures.clear()
        caplog.clear()
        with pytest.raises(KeyboardInterrupt):
            list(_run_dask(Client(), abs, [(1,), (2,), (3,)], ["a", "b", "c"], 0))
        assert [f.cancelled for f in futures] == [True] * 3
        assert "3 of 3 tasks unfinished on the cluster at the stop" in caplog.text
        assert ("can still write their outputs" in caplog.text) == fail
        assert ("go on but write nothing" in caplog.text) == (not fail)
    assert len(events) == 1 and events[0].startswith("garment-stop-")


def test_a_task_started_before_its_cluster_run_stopped_writes_nothing(client, tmp_path):
    """The run stops (its generator closed, as Ctrl-C unwinds the command) while a worker runs item 'slow': the
    task goes on (Dask cannot stop it) but its atomic write is not put in place; the finished item's stays."""
    import time

    work = str(tmp_path)

    def task(x):
        from formats.atomic import atomic_dir, atomic_file

        if x == 1:
            (Path(work) / "slow.started").touch()
            time.sleep(4.0)
        with atomic_dir(Path(work) / f"out{x}" / "bake", False) as tmp:  # as a bake writes into its --out
            (tmp / "summary.json").write_text("{}")
        with atomic_file(Path(work) / f"{x}.out") as tmp:
            tmp.write_text(str(x))
        (Path(work) / f"{x}.reached").touch()  # (not reached where the write raised)
        return x

    run = run_items(task, [(0,), (1,)], ["fast", "slow"], client=client, retries=0)
    assert next(run) == ("fast", 0)
    deadline = time.time() + 30
    while not (tmp_path / "slow.started").exists() and time.time() < deadline:
        time.sleep(0.1)
    assert (tmp_path / "slow.started").exists()
    run.close()  # the run stopped while 'slow' runs
    time.sleep(6.0)
    assert (tmp_path / "0.out").read_text() == "0"
    assert not (tmp_path / "1.out").exists() and not (tmp_path / "1.reached").exists()
    assert (tmp_path / "out0" / "bake" / "summary.json").exists() and not (tmp_path / "out1").exists()
    assert not list(tmp_path.glob(".*partial*"))


#: "imported" as this module is loaded; the spawn test sets it in its own process: a forked child inherits that, a
#: spawned one imports the module afresh.
_MARK = "imported"


def _mark_and_square(x):
    return _MARK, x * x


def _assert_spawned_run(monkeypatch, n: int) -> None:
    """The processes are spawned (`pool_context`), and run_items in 2 of them runs all `n` items, each in a fresh
    interpreter (this module imported afresh: its mark not the parent's)."""
    from core.distributed import pool_context

    assert pool_context().get_start_method() == "spawn"
    monkeypatch.setattr(sys.modules[__name__], "_MARK", "set in the parent")
    got = dict(run_items(_mark_and_square, [(x,) for x in range(n)], [f"i{x}" for x in range(n)], workers=2))
    assert {k: v[1] for k, v in got.items()} == {f"i{x}": x * x for x in range(n)}
    assert {mark for mark, _ in got.values()} == {"imported"}


def test_local_processes_are_spawned_once_this_process_has_started_cuda(monkeypatch):
    """A forked child cannot use CUDA once its parent has started it: the processes are then spawned (fresh
    interpreters) and still run every item; otherwise the platform's default start method (no re-import)."""
    import torch

    from core.distributed import pool_context

    monkeypatch.delitem(sys.modules, "pxr", raising=False)  # USD not loaded (another test may have)
    assert pool_context() is None or torch.cuda.is_initialized()
    monkeypatch.setattr(torch.cuda, "is_initialized", lambda: True)
    _assert_spawned_run(monkeypatch, 4)


def test_local_processes_are_spawned_once_this_process_has_loaded_usd(monkeypatch):
    """USD's TBB thread pool is not fork-safe once used (a forked child deadlocked creating a stage under
    `bake --workers 2` in the suite): with `pxr` loaded the processes are spawned and run every item."""
    import formats.usd  # noqa: F401  (loads pxr)

    _assert_spawned_run(monkeypatch, 3)


def test_cluster_retries_failed_and_killed_tasks(client, tmp_path):
    task = make_task(tmp_path)
    calls = [(x,) for x in range(6)]
    got = dict(run_items(task, calls, [f"item{x}" for x in range(6)], client=client, retries=2))
    assert got == {f"item{x}": x * x for x in range(6)}  # nothing lost, nothing duplicated
    for x in range(6):
        assert (tmp_path / f"{x}.out").read_text() == str(x * x)
    assert (tmp_path / "2.runs").read_text() == ".."  # raised once, retried once
    assert len((tmp_path / "3.runs").read_text()) == 2  # worker killed once, rescheduled once
    assert not list(tmp_path.glob(".*partial*"))  # no half-written file left


def test_cluster_reports_items_that_keep_failing(client, tmp_path):
    def task(x):
        if x == 1:
            raise ValueError("always broken")
        return x

    with pytest.raises(ItemsFailed, match="1 of 3 items failed.*'b'.*always broken") as info:
        got = []
        for name, value in run_items(task, [(0,), (1,), (2,)], ["a", "b", "c"], client=client, retries=1):
            got.append(name)
    assert sorted(got) == ["a", "c"] and info.value.total == 3  # the others finished


@pytest.mark.parametrize("error", ["InputError", "SimulationError"])
def test_cluster_does_not_retry_an_error_a_retry_repeats(client, tmp_path, error):
    """An InputError is the input's own fault, a FloatingPointError (the simulator's SimulationError, retried with
    more substeps within the task; the model's non-finite output) the method's on it: the same on every retry (a
    motion whose output name the file system refused was baked three times; a failed simulation ran three times),
    so it is a failure at once, said as what it is."""
    from core.errors import InputError
    from core.sim import SimulationError

    runs = tmp_path / "runs"
    kind = {"InputError": InputError, "SimulationError": SimulationError}[error]

    def task(x):
        with open(runs, "a") as fh:
            fh.write(".")
        raise kind(f"motion '{x}.npz': expected poses, got none")

    with pytest.raises(ItemsFailed, match=f"1 of 1 items failed; first: 'a': {error}: motion '0.npz': expected"):
        list(run_items(task, [(0,)], ["a"], client=client, retries=2))
    assert runs.read_text() == "."


def test_a_cluster_without_workers_is_said_and_a_task_its_workers_died_on_is_said_so(monkeypatch, caplog):
    """A cluster whose workers were all gone (killed, or none started) left the run waiting without a word, for
    ever; a task whose workers died as often as the scheduler allows was said to have failed 'after 2 retries'
    (--retries played no part)."""
    import threading
    import time

    import dask
    from distributed import Client, LocalCluster

    import core.distributed

    monkeypatch.setattr(core.distributed, "IDLE_CHECK_S", 0.3)

    def dies(x):
        os._exit(1)

    outcome = []

    def run(client):
        try:
            outcome.append(list(run_items(dies, [(0,)], ["a"], client=client, retries=2)))
        except ItemsFailed as exc:
            outcome.append(exc)

    with dask.config.set({"distributed.scheduler.allowed-failures": 0}), \
            LocalCluster(n_workers=0, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
            Client(cluster) as client, caplog.at_level("WARNING", logger="core.distributed"):
        thread = threading.Thread(target=run, args=(client,))
        thread.start()
        deadline = time.monotonic() + 30
        while "has no workers" not in caplog.text and time.monotonic() < deadline:
            time.sleep(0.1)
        assert f"the cluster at {cluster.scheduler_address} has no workers: 1 task waiting until workers join" \
            in caplog.text
        assert thread.is_alive() and not outcome
        cluster.scale(1)
        thread.join(120)
    assert not thread.is_alive()
    assert "has 1 worker again" in caplog.text or isinstance(outcome[0], ItemsFailed)
    failed = outcome[0]
    assert isinstance(failed, ItemsFailed) and "the workers running it died" in str(failed), failed
    assert "after 2 retries" not in caplog.text


def test_cluster_threads_count_what_a_cluster_runs_at_once(client):
    """`dataset --scheduler`'s time left counted one task at a time (--workers, ignored there): 3 min said, 1 left."""
    from core.distributed import cluster_threads

    assert cluster_threads(client) == 2  # tests.cluster: two single-thread workers


def test_bad_scheduler_address_is_one_line():
    from core.distributed import connect
    from core.errors import InputError

    with pytest.raises(InputError, match="--scheduler 'tcp://127.0.0.1:9': expected a running Dask scheduler"):
        connect("tcp://127.0.0.1:9", timeout_s=1.0)
    # `5:2` made distributed allocate exabytes (MemoryError): whatever connecting raises is the same one line
    with pytest.raises(InputError, match="--scheduler '5:2': expected a running Dask scheduler, could not connect"):
        connect("5:2", timeout_s=1.0)
