"""Independent runs in parallel: local processes or a Dask cluster, results as they complete.

:func:`executor_map` runs ``func(*task)`` for every task and yields each result as soon as it is
ready; a task whose worker does not return (it died, or the executor broke) yields ``lost(task,
exc)`` instead of stopping the others.  Sweeps (:mod:`pneusim.scenario.sweep`) and diagnosis
batches (:mod:`pneusim.diagnosis.batch`) run here.

Local workers run with one BLAS thread each: the workers are the parallelism, and BLAS threads
of every worker would share the same cores and spin on them.
"""

from __future__ import annotations

import contextlib
import signal
import time
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures import as_completed as futures_completed
from typing import Callable, Iterator, Sequence

from threadpoolctl import threadpool_limits

from .errors import PneusimError

__all__ = ["executor_map", "local_pool", "dask_client"]

#: the BLAS limit of a local worker, kept for the worker's life
_BLAS_LIMIT = []


def dask_client(dask: str, workers: int):
    """``(client, cluster)``: a loopback ``LocalCluster`` of ``workers`` processes for ``dask = "local"``
    (``cluster`` to close afterwards), else a client of the scheduler at ``dask`` (``cluster`` is None)."""
    try:
        # distributed takes seconds to import; only a Dask run needs it
        from distributed import Client, LocalCluster
    except ImportError as exc:
        raise PneusimError(f"--dask needs the 'distributed' package ({exc})") from None
    if dask == "local":
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, host="127.0.0.1", processes=True,
                               dashboard_address=None)
        return Client(cluster), cluster
    try:
        return Client(dask, timeout="15s"), None
    except (OSError, TimeoutError, ValueError, TypeError) as exc:
        raise PneusimError(f"--dask {dask}: no Dask scheduler answered there ({type(exc).__name__}: {exc}); "
                           "expected tcp://HOST:PORT of a running scheduler, or 'local'") from None


def _worker_init() -> None:
    """In each local worker process: one BLAS thread (see the module docstring), and SIGTERM's default action.

    Why the default: a worker forked from a command that turns SIGTERM into an exception (:mod:`.shutdown`)
    inherits that handler, so the SIGTERM :func:`_stop` sends only failed the worker's run; the worker took the next
    one queued, ignored the second signal and ran until it was killed.  A worker holds nothing that must be
    closed (its results go back to the parent), so it may end at once."""
    _BLAS_LIMIT.append(threadpool_limits(1))
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


@contextlib.contextmanager
def local_pool(workers: int) -> Iterator[ProcessPoolExecutor]:
    """A pool of ``workers`` local processes, each with one BLAS thread, for a ``with`` block: the block's end
    waits for the runs submitted; a Ctrl-C, a SIGTERM (:mod:`pneusim.shutdown`) or any other exception out of
    the block stops the pool at once (:func:`_stop`)."""
    pool = ProcessPoolExecutor(max_workers=workers, initializer=_worker_init)
    try:
        yield pool
    except BaseException:
        _stop(pool)
        raise
    pool.shutdown(wait=True)


#: (s) how long the stopped workers may take to end their runs after SIGTERM before they are killed
STOP_GRACE_S = 5.0


def _stop(pool: ProcessPoolExecutor) -> None:
    """Cancel the runs not started and end the workers' running ones (SIGTERM, then SIGKILL for those still running
    :data:`STOP_GRACE_S` later).

    Why: ``ProcessPoolExecutor``'s own exit waits for every run submitted, so a batch of sixty diagnoses
    interrupted after the first would go on for an hour.  The workers end on SIGTERM (:func:`_worker_init`); the
    SIGKILL is for one stuck where a signal cannot reach it.  The executor has no public way to end running
    workers: its process table is read before the shutdown clears it."""
    processes = list((getattr(pool, "_processes", None) or {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    for process in processes:
        process.terminate()
    deadline = time.monotonic() + STOP_GRACE_S
    for process in processes:
        process.join(max(0.0, deadline - time.monotonic()))
        if process.is_alive():
            process.kill()
            process.join()


def executor_map(func: Callable, tasks: Sequence[tuple], lost: Callable, workers: int, dask: str | None = None,
                 progress: bool = False, desc: str = "runs", pool: ProcessPoolExecutor | None = None) -> Iterator:
    """Yield ``func(*task)`` for every task of ``tasks``, in the order they complete.

    Parameters
    ----------
    func : callable
        Picklable; called as ``func(*task)`` in a worker.
    tasks : sequence of tuple
    lost : callable
        ``lost(task, exc)`` is yielded for a task whose worker did not return.
    workers : int
        Local processes (0: run in this process, one task after the other); with ``dask = "local"`` the
        number of Dask workers.
    dask : str or None
        ``None`` (local processes), ``"local"`` (a loopback LocalCluster) or a scheduler address.
    progress : bool
        A progress bar labelled ``desc``.
    pool : ProcessPoolExecutor or None
        A running :func:`local_pool` to use (and leave running) instead of starting one for ``workers``.
    """
    bar = None
    if progress:
        from .progress import progress_bar   # a bar on a terminal, lines in a log
        bar = progress_bar(len(tasks), desc=desc, unit="run", mininterval=0.5)
    try:
        if dask:
            yield from _dask_map(func, tasks, lost, workers, dask, bar)
        elif workers <= 0:
            for t in tasks:
                yield func(*t)
                if bar:
                    bar.update()
        else:
            with contextlib.ExitStack() as stack:
                if pool is None:
                    pool = stack.enter_context(local_pool(workers))
                futures = {pool.submit(func, *t): t for t in tasks}
                yield from _results_or_lost(futures, futures_completed(futures), lost, bar)
    finally:
        if bar:
            bar.close()


def _dask_map(func, tasks, lost, workers, dask, bar) -> Iterator:
    """:func:`executor_map` on a Dask cluster."""
    from distributed import as_completed   # seconds to import; only a Dask run needs it

    client, cluster = dask_client(dask, workers)
    try:
        futures = {client.submit(func, *t, pure=False): t for t in tasks}
        yield from _results_or_lost(futures, as_completed(futures), lost, bar)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def _results_or_lost(futures: dict, completed: Iterator, lost: Callable, bar) -> Iterator:
    """Each future's result as ``completed`` (an executor's or Dask's ``as_completed`` over ``futures``, a
    ``{future: task}`` dict) hands it over, or ``lost(task, exc)`` for a future that raised (its worker died:
    ``BrokenProcessPool``, Dask's ``KilledWorker``); the progress bar ``bar`` (or None) counts each."""
    for fut in completed:
        try:
            yield fut.result()
        except Exception as exc:  # noqa: BLE001 - e.g. BrokenProcessPool, KilledWorker
            yield lost(futures[fut], exc)
        if bar:
            bar.update()
