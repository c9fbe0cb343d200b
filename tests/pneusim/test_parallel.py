"""Local batches stop when interrupted: a Ctrl-C or SIGTERM during :func:`pneusim.parallel.executor_map` ends the
workers and cancels the runs not started, instead of ``ProcessPoolExecutor``'s exit running every one queued."""

import os
import signal
import time

import pytest

from pneusim.parallel import executor_map, local_pool
from pneusim.shutdown import sigterm_raises


def _lost(task, exc):
    return ("lost", task, repr(exc))


def _mark_and_sleep(path, seconds):
    path.touch()
    time.sleep(seconds)


@pytest.mark.slow
def test_an_interrupted_local_batch_starts_no_more_runs(tmp_path):
    """Eight runs of 2 s on two workers; the consumer is interrupted after the first result.  Each run marks its
    start with a file: after the interruption no run starts, so the eight are never all started (without the stop
    the pool's exit waits for all eight)."""
    tasks = [(tmp_path / str(i), 2) for i in range(8)]    # marked by the worker itself, not by a shell it leaves
    runs = executor_map(_mark_and_sleep, tasks, _lost, workers=2)
    assert next(runs) is None
    with pytest.raises(KeyboardInterrupt):
        runs.throw(KeyboardInterrupt)
    started = len(list(tmp_path.iterdir()))
    assert 1 <= started <= 5, started     # the first, the runs under way and those already handed to a worker
    time.sleep(3.0)                          # longer than a run: a worker still taking runs would have started one
    assert len(list(tmp_path.iterdir())) == started


@pytest.mark.slow
def test_a_local_batch_returns_every_result():
    """Not interrupted, every run's result comes back, each once."""
    tasks = [(f"exit {i}",) for i in range(5)]
    results = sorted(os.waitstatus_to_exitcode(r) for r in executor_map(os.system, tasks, _lost, workers=2))
    assert results == [0, 1, 2, 3, 4]


@pytest.mark.slow
def test_stopped_workers_end_on_sigterm(tmp_path):
    """A batch started inside a command's SIGTERM handling (:func:`sigterm_raises`) and interrupted: its workers end on
    the stop's SIGTERM (exit by signal 15), where a worker that inherited the command's handler turned it into an
    exception that failed its run only, ignored the second and was killed (signal 9)."""
    with sigterm_raises(), pytest.raises(KeyboardInterrupt):
        with local_pool(2) as pool:
            for i in range(4):
                pool.submit(_mark_and_sleep, tmp_path / str(i), 60)
            for _ in range(400):                    # both workers in a run (at most 20 s)
                if len(list(tmp_path.iterdir())) >= 2:
                    break
                time.sleep(0.05)
            processes = list(pool._processes.values())
            raise KeyboardInterrupt
    assert len(processes) == 2
    for _ in range(200):   # the pool's own thread may reap a worker first and record its status a moment later
        if all(p.exitcode is not None for p in processes):
            break
        time.sleep(0.05)
    assert [p.exitcode for p in processes] == [-signal.SIGTERM] * 2
