"""Run independent items (one bake, one dataset sequence) locally or on a Dask distributed cluster.

`run_items(task, calls, names, ...)` calls `task(*args)` once per item and yields
`(name, result)` as items finish, whichever engine runs them:

- locally in this process (`workers=1`), or in `workers` processes
  (`concurrent.futures.ProcessPoolExecutor`, no more than the items); an item
  that raises is logged at once and the others go on, as on a cluster;
- on an existing `dask.distributed` cluster (`scheduler='tcp://host:port'`):
  one Dask task per item, resubmitted up to `retries` times when it raises
  (`Client.submit(..., retries=N)`); a worker process that dies is handled by the
  scheduler itself (the task is moved to another worker, up to the scheduler's
  `distributed.scheduler.allowed-failures`, 3 by default). Items that still fail
  do not stop the others: they are gathered into one `ItemsFailed` at the end, so
  everything that finished is kept and a rerun resumes from it.

Tasks write their own outputs (atomically, under `formats.atomic`) to a path every
worker sees, and return small summaries. The task function and its arguments must
be picklable and importable on the workers (the `garment` package installed there).
Pure orchestration: no files, no printing; logging via `logging.getLogger(__name__)`.
"""

from __future__ import annotations

import logging
import os
import signal
import time
import uuid
from collections.abc import Callable, Iterator, Sequence
from contextvars import ContextVar
from typing import Any

from core.errors import InputError, counted

log = logging.getLogger(__name__)

#: Default number of re-runs of a Dask task that raised.
DEFAULT_RETRIES = 2


class Stopped(Exception):
    """A cluster task's output not written: its run was stopped (`raise_if_stopped`)."""


#: The check of the run a cluster task belongs to (`_stoppable`): true once that run was stopped. Per thread and
#: task (a Dask worker runs its tasks in threads); None outside a cluster's task.
_stop_check: ContextVar = ContextVar("garment_stop_check", default=None)


def raise_if_stopped(what) -> None:
    """Raise `Stopped` where this is a cluster's task whose run has been stopped (Ctrl-C, SIGTERM: Dask's cancel
    leaves a task a worker runs running). `formats.atomic` calls it before an output takes its place, so a stopped
    run's tasks write nothing more (their outputs appeared seconds after the command had exited and removed --out)."""
    check = _stop_check.get()
    if check is not None and check():
        raise Stopped(f"'{what}' not written: its run was stopped")


class _FailedForGood:
    """A cluster task's error that every retry would raise again, returned rather than raised: the input's own
    fault (InputError: Dask re-ran a motion whose output name its file system refused --retries times) or a
    method's failure on it (FloatingPointError: the simulator's, already retried with more substeps within the
    task, and the model's non-finite output are deterministic: a failed simulation ran three times)."""

    def __init__(self, exc: Exception):
        self.exc = exc


def _stoppable(event_name: str, task, *args):
    """`task(*args)` on a cluster's worker, its outputs written only while the Dask Event `event_name` is unset;
    an error a retry would repeat returned as `_FailedForGood` (not retried)."""
    from distributed import Event

    event = Event(event_name)
    token = _stop_check.set(event.is_set)
    try:
        return task(*args)
    except (InputError, FloatingPointError) as exc:
        return _FailedForGood(exc)
    finally:
        _stop_check.reset(token)


class ItemsFailed(Exception):
    """Items that failed on the cluster after their retries: failures is [(name, exception)], total the item count."""

    def __init__(self, failures: list[tuple[str, BaseException]], total: int):
        self.failures, self.total = failures, total
        name, exc = failures[0]
        first = str(exc).splitlines()[0][:1000] if str(exc) else type(exc).__name__  # (its cause at the end kept)
        super().__init__(f"{len(failures)} of {total} items failed; first: '{name}': {type(exc).__name__}: {first}")


def dask_available() -> bool:
    """True when `dask.distributed` can be imported."""
    try:
        import distributed  # noqa: F401
    except ImportError:
        return False
    return True


def connect(scheduler: str, timeout_s: float = 20.0):
    """A `distributed.Client` connected to `scheduler` ('tcp://host:port'); InputError naming the option otherwise."""
    try:
        from distributed import Client
    except ImportError:
        raise InputError(f"--scheduler '{scheduler}': expected the 'distributed' package (pip install "
                         f"'distributed'), found it missing") from None
    try:
        return Client(scheduler, timeout=f"{timeout_s}s")
    except Exception as exc:  # refused, timed out, a malformed address (`5:2` raised MemoryError inside distributed)
        raise InputError(f"--scheduler '{scheduler}': expected a running Dask scheduler, could not connect "
                         f"({type(exc).__name__}: {str(exc).splitlines()[0][:120] if str(exc) else ''})") from None


def run_items(task: Callable[..., Any], calls: Sequence[tuple], names: Sequence[str], *,
              scheduler: str | None = None, workers: int = 1, retries: int = DEFAULT_RETRIES,
              client=None) -> Iterator[tuple[str, Any]]:
    """Call `task(*args)` for every `args` in `calls`; yield `(name, result)` in completion order.

    names: one label per call (item ids; Dask task keys are built from them).
    scheduler: 'tcp://host:port' of a Dask scheduler, or None to run locally.
    workers: local processes when `scheduler` is None (1: in this process).
    retries: re-runs of a Dask task that raised (local runs do not retry).
    client: an already connected `distributed.Client` to use instead of `scheduler` (not closed here).
    Raises ItemsFailed after every other item has finished (cluster, local processes or this process; Ctrl-C
    and SIGTERM stop at once).
    """
    if len(calls) != len(names):
        raise ValueError(f"expected one name per call, got {len(names)} names for {len(calls)} calls")
    if not calls:
        return
    if client is None and scheduler is None:
        yield from _run_local(task, calls, names, workers)
        return
    own = client is None
    if own:
        client = connect(scheduler)
    try:
        yield from _run_dask(client, task, calls, names, retries)
    finally:
        if own:
            client.close()


def _run_local(task, calls, names, workers: int):
    failures = []
    if workers <= 1:  # in this process; a failing item said at once and the others run, as in processes
        for name, args in zip(names, calls):
            try:
                result = task(*args)
            except Exception as exc:
                log.warning("item '%s' failed: %s: %s", name, type(exc).__name__, exc)
                failures.append((name, exc))
                continue
            yield name, result
        if failures:
            raise ItemsFailed(failures, len(calls))
        return
    from concurrent.futures import ProcessPoolExecutor, as_completed

    # no more processes than items: a pool starts all of its processes at the first submit (forked: --workers
    # 100000 forked thousands of copies of the command, for two motions)
    with ProcessPoolExecutor(max_workers=min(workers, len(calls)), mp_context=pool_context(),
                             initializer=_worker_unwinds) as pool:
        try:  # from the first submit: a worker can start (and a SIGTERM come) before the last is made
            futures = {pool.submit(_unwound, task, *args): name for name, args in zip(names, calls)}
            for fut in as_completed(futures):
                exc = fut.exception()
                if exc is not None:  # said now, raised when the others have finished (they are kept)
                    log.warning("item '%s' failed: %s: %s", futures[fut], type(exc).__name__, exc)
                    failures.append((futures[fut], exc))
                else:
                    yield futures[fut], fut.result()
        # Ctrl-C, or SIGTERM (garmentcli.main), here or in the caller while it holds an item (the caller's frame
        # unwinds and closes this generator at its yield: GeneratorExit): stop the workers too, else the pool's
        # shutdown waits for their items.
        except (KeyboardInterrupt, SystemExit, GeneratorExit):
            _stop_workers(pool)
            raise
    if failures:
        raise ItemsFailed(failures, len(calls))


def _terminate_as_exit(signum, frame):
    """SIGTERM (`kill`, a batch scheduler stopping a job) unwinds the process as Ctrl-C does, so the outputs it
    was writing are removed (`formats.atomic`: a render's frames, a bake's folder) and its worker processes
    stopped (`_stop_workers`); exit status 143. A second SIGTERM ends the process at once."""
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    raise SystemExit(128 + signal.SIGTERM)


def unwind_on_sigterm() -> None:
    """Install `_terminate_as_exit` for SIGTERM: the `garment` command does (each local worker process installs
    its own, `_worker_unwinds`: a spawned one does not inherit it)."""
    signal.signal(signal.SIGTERM, _terminate_as_exit)


def _worker_unwinds() -> None:
    """A local worker process's SIGTERM: unwinds its item as the command does (`_terminate_as_exit`), but further
    SIGTERMs are ignored while it does (the pool, finding a stopped worker, sends each of the others one more:
    a second one killed a worker in the middle of removing its item's output, which was left behind). SIGINT is
    ignored: a terminal's Ctrl-C reaches the whole process group, and the command, interrupted, stops its workers
    with SIGTERM (`_stop_workers`); a worker unwinding its own Ctrl-C was cut short by that SIGTERM and left its
    output's hidden folder behind."""
    signal.signal(signal.SIGTERM, _terminate_worker)
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _terminate_worker(signum, frame):
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    raise SystemExit(128 + signal.SIGTERM)


def _unwound(task, *args):
    """`task(*args)` in a local worker; stopped by SIGTERM, the worker ends once the item has unwound (the pool's
    worker loop would otherwise catch the SystemExit and wait for another item, ignoring SIGTERM)."""
    try:
        return task(*args)
    except SystemExit as exc:
        if exc.code == 128 + signal.SIGTERM:
            os._exit(exc.code)
        raise


def _stop_workers(pool) -> None:
    """Cancel `pool`'s waiting items and send its worker processes SIGTERM: they unwind as the command does
    (`_worker_unwinds`), removing what they were writing, and end, instead of finishing their items while the
    command waits in the pool's shutdown."""
    for fut in list(getattr(pool, "_pending_work_items", {}).values()):
        fut.future.cancel()
    for process in list((getattr(pool, "_processes", None) or {}).values()):
        if process.is_alive():
            process.terminate()


def pool_context():
    """The local processes' start method: spawn where this process has started CUDA (a forked child cannot use it:
    "Cannot re-initialize CUDA in forked subprocess", so `bake --workers N` on a GPU would fail) or has loaded USD
    (`pxr`: its TBB thread pool, once used, is not fork-safe: a forked child writing its stage waited forever in
    tbb's market lock, inherited held, in UsdStage.CreateInMemory), else the platform's default (None; fork on
    Linux, which imports nothing again)."""
    import multiprocessing
    import sys

    torch = sys.modules.get("torch")
    if (torch is not None and torch.cuda.is_initialized()) or "pxr" in sys.modules:
        return multiprocessing.get_context("spawn")
    return None


def _run_dask(client, task, calls, names, retries: int):
    token = uuid.uuid4().hex[:8]  # keys unique to this run: a shared scheduler may hold another run's results
    stop = f"garment-stop-{token}"  # a Dask Event: set, the run's tasks write nothing more (`raise_if_stopped`)
    futures = {}
    for name, args in zip(names, calls):
        fut = client.submit(_stoppable, stop, task, *args, key=f"{name}-{token}", retries=retries, pure=False)
        futures[fut.key] = (name, fut)
    log.info("submitted %d tasks to %s (retries %d)", len(futures), client.scheduler.address, retries)
    failures = []
    try:
        for fut in _completed(client, [f for _, f in futures.values()]):
            name = futures[fut.key][0]
            if fut.status == "error":
                exc = fut.exception()
                if type(exc).__name__ == "KilledWorker":  # (the scheduler's allowed-failures, not --retries)
                    exc = RuntimeError("the workers running it died (killed? out of memory?) as often as the "
                                       "scheduler allows (distributed.scheduler.allowed-failures): given up")
                    log.warning("item '%s' failed: %s", name, exc)
                else:
                    log.warning("item '%s' failed after %d retries: %s", name, retries, exc)
                failures.append((name, exc))
            elif isinstance(result := fut.result(), _FailedForGood):
                log.warning("item '%s' failed: %s", name, result.exc)
                failures.append((name, result.exc))
            else:
                yield name, result
            fut.release()
    finally:
        pending = [f for _, f in futures.values() if f.status == "pending"]
        if pending:  # stopped (Ctrl-C, SIGTERM, the caller's error): a task a worker runs is not stopped by cancel
            said = "those its workers had started go on but write nothing"
            try:
                from distributed import Event

                Event(stop, client=client).set()
            except Exception as exc:  # the scheduler gone: they may still write
                said = (f"those its workers had started go on and can still write their outputs (whole), the stop "
                        f"not said to them ({type(exc).__name__}); wait for them before rerunning with --overwrite")
            for f in pending:
                f.cancel()
            log.warning("%d of %d tasks unfinished on the cluster at the stop: %s", len(pending), len(futures), said)
    if failures:
        raise ItemsFailed(failures, len(calls))


#: Seconds between looks at a cluster while none of its tasks finishes (`_completed`).
IDLE_CHECK_S = 30.0


def _completed(client, futures, idle_check_s: float | None = None):
    """The futures as they complete (`distributed.as_completed`, looked at as its own iterator does, every 0.1 s),
    saying where the cluster has no worker while some wait (every worker killed or gone, or none started: the run
    waited without a word, for ever) and when workers are back; the run goes on once workers join."""
    from distributed import as_completed

    idle_check_s = IDLE_CHECK_S if idle_check_s is None else idle_check_s
    waiting, idle, looked = as_completed(futures), False, time.monotonic()
    while not waiting.is_empty():
        batch = waiting.next_batch(block=False)
        if batch:
            yield from batch
            continue
        if time.monotonic() - looked < idle_check_s:
            time.sleep(0.1)
            continue
        looked = time.monotonic()
        workers = len(client.nthreads())
        if workers == 0 and not idle:
            log.warning("the cluster at %s has no workers: %s waiting until workers join (start them, or stop "
                        "this run: the finished outputs are kept)", client.scheduler.address,
                        counted(waiting.count(), "task"))
        elif workers and idle:
            log.warning("the cluster at %s has %s again", client.scheduler.address, counted(workers, "worker"))
        idle = workers == 0


def cluster_threads(client) -> int:
    """The tasks a cluster runs at once (its workers' threads), at least 1."""
    return max(1, sum(client.nthreads().values()))
