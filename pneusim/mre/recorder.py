"""Writing a ``pneusim-recording/1`` CSV row by row while the loop runs.

The metadata and the header go to disk before the first sample; every row is
formatted as it is taken (``repr`` of the float: the same text
:func:`pneusim.recording.write_recording` writes) and the buffered rows are
flushed every ``flush_every`` samples and on :meth:`close`.  A run that is
interrupted therefore leaves a file that :func:`pneusim.recording.read_recording`
(and ``pneusim check``) accepts, holding every sample taken so far (a hard kill
loses at most the unflushed rows).
"""

from __future__ import annotations

from pathlib import Path
from typing import Mapping, Sequence

__all__ = ["RecordingWriter"]


class RecordingWriter:
    """Incremental CSV writer.

    Parameters
    ----------
    path : str or Path
        Target ``.csv`` file (overwritten).
    metadata : mapping of str to str
        ``# key: value`` lines; must include ``format`` and ``sample_time_s``.
    columns : sequence of str
        Header, in row order.
    flush_every : int
        Rows kept in memory between two writes.
    """

    def __init__(self, path: str | Path, metadata: Mapping[str, str], columns: Sequence[str], flush_every: int = 100):
        self.path = Path(path)
        self.columns = tuple(columns)
        self.flush_every = int(flush_every)
        self.rows_written = 0
        self._buf: list[str] = []
        self._file = open(self.path, "w", encoding="utf-8", newline="")
        head = [f"# {k}: {str(v).strip()}" for k, v in metadata.items()]
        head.append(",".join(self.columns))
        self._file.write("\n".join(head) + "\n")
        self._file.flush()

    def append(self, values: Sequence[float]) -> None:
        """One row, in the order of ``columns``; NaN is written as an empty cell (a gap)."""
        self._buf.append(",".join("" if v != v else repr(float(v)) for v in values))
        if len(self._buf) >= self.flush_every:
            self.flush()

    def flush(self) -> None:
        if self._buf and not self._file.closed:
            # take the rows first: a Ctrl-C between the write and the bookkeeping must never write a row twice
            rows, self._buf = self._buf, []
            self._file.write("\n".join(rows) + "\n")
            self._file.flush()
            self.rows_written += len(rows)

    def close(self) -> None:
        if not self._file.closed:
            self.flush()
            self._file.close()
