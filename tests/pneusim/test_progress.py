"""Progress output: a bar on a terminal, plain lines in a log (pneusim.progress)."""

import io

from pneusim.progress import LineProgress, progress_bar


class _Terminal(io.StringIO):
    def isatty(self):
        return True


def test_a_log_gets_lines_not_a_frozen_bar():
    log = io.StringIO()
    with progress_bar(4, desc="sweep", unit="run", stream=log, interval_s=0.0) as bar:
        assert isinstance(bar, LineProgress)
        for _ in range(4):
            bar.update()
    lines = log.getvalue().splitlines()
    assert "\r" not in log.getvalue()
    assert lines[0].startswith("sweep: 0/4 runs (0 %)")
    assert any(line.startswith("sweep: 2/4 runs (50 %)") and "left" in line for line in lines)
    assert lines[-1].startswith("sweep: 4/4 runs (100 %)")


def test_lines_come_at_most_every_interval():
    log = io.StringIO()
    bar = progress_bar(1000, desc="simulate", unit="sample", stream=log, interval_s=3600.0)
    for _ in range(1000):
        bar.update()
    bar.close()
    bar.close()
    assert log.getvalue().splitlines() == [log.getvalue().splitlines()[0], log.getvalue().splitlines()[-1]]
    assert log.getvalue().splitlines()[-1].startswith("simulate: 1000/1000 samples (100 %)")


def test_a_terminal_gets_the_bar():
    term = _Terminal()
    bar = progress_bar(3, desc="friction folds", unit="fold", stream=term)
    bar.update(3)
    bar.close()
    assert type(bar).__name__ == "tqdm" and "3/3" in term.getvalue()


def test_the_loop_status_in_a_log_ends_with_the_count_the_run_ended_at():
    """A run shorter than one status interval: the log gets its first line and the last count, not a '0 %' only
    (and no carriage returns)."""
    import numpy as np

    from pneusim.loop import StatusLine

    log = io.StringIO()
    status = StatusLine(log, interval_s=0.5, label="online run")
    status.show(1, 200, 0, 0, np.array([]), float("nan"), "RLS 2")
    status.close(200)
    assert "\r" not in log.getvalue()
    assert log.getvalue().splitlines() == ["online run: 1/200 samples (0 %), 1-step error (RLS 2) +nan",
                                           "online run: 200/200 samples (100 %), ended"]
