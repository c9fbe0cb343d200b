"""Local batches stop when interrupted: a Ctrl-C or SIGTERM during :func:`pneusim.parallel.executor_map` ends the
workers and cancels the runs not started, instead of ``ProcessPoolExecutor``'s exit running every one queued."""

import os
import time

import pytest

from pneusim.parallel import executor_map


def _lost(task, exc):
    return ("lost", task, repr(exc))


@pytest.mark.slow
def test_an_interrupted_local_batch_starts_no_more_runs(tmp_path):
    """Eight runs of 2 s on two workers; the consumer is interrupted after the first result.  Each run marks its
    start with a file: after the interruption no run starts, so the eight are never all started (without the stop
    the pool's exit waits for all eight)."""
    tasks = [(f"touch {tmp_path / str(i)}; sleep 2",) for i in range(8)]
    runs = executor_map(os.system, tasks, _lost, workers=2)
    assert next(runs) == 0
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
