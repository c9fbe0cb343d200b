"""Writing a ``pneusim-recording/1`` CSV row by row while the loop runs.

The metadata and the header go to disk before the first sample; every row is
kept as numbers when it is taken, turned into text (``repr`` of the float: the
same text :func:`pneusim.recording.write_recording` writes) while a paced loop
waits for its next deadline (:meth:`RecordingWriter.idle`), and the buffered rows
are written and flushed every ``flush_every`` samples (:func:`pneusim.mre.run.run_mre`
makes that 0.1 s of samples) and on :meth:`close`.  A run that is
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
        self._buf: list = []          # rows: lists of numbers, or their text once formatted
        self._formatted = 0           # rows of _buf already formatted
        self._file = open(self.path, "w", encoding="utf-8", newline="")
        head = [f"# {k}: {str(v).strip()}" for k, v in metadata.items()]
        head.append(",".join(self.columns))
        self._file.write("\n".join(head) + "\n")
        self._file.flush()

    @staticmethod
    def format_row(values: Sequence[float]) -> str:
        """The CSV text of one row: ``repr`` of each float, NaN as an empty cell (a gap)."""
        # repr of a Python float never contains "nan" except for NaN itself (no sign, no other letters
        # than e/inf), so one replace turns every NaN cell into an empty one
        return ",".join(map(repr, map(float, values))).replace("nan", "")

    def append(self, values: Sequence[float]) -> None:
        """One row, in the order of ``columns``; NaN is written as an empty cell (a gap).

        The row is kept as given (a list of numbers) and turned into text by :meth:`idle`, which a
        paced loop calls while it waits for its next deadline (formatting the shortest ``repr`` of
        a dozen floats costs ~10 us, a tenth of a sample's work), or at the latest by :meth:`flush`.
        """
        self._buf.append(list(values))
        if len(self._buf) >= self.flush_every:
            self.flush()

    def idle(self, max_rows: int = 8) -> None:
        """Format up to ``max_rows`` buffered rows (spare time of a paced loop); nothing is written."""
        buf, i = self._buf, self._formatted
        end = min(len(buf), i + max_rows)
        fmt = self.format_row
        while i < end:
            row = buf[i]
            if row.__class__ is not str:
                buf[i] = fmt(row)       # one store: an interrupt leaves the row either raw or text, both fine
            i += 1
            self._formatted = i

    def flush(self) -> None:
        if self._buf and not self._file.closed:
            fmt = self.format_row
            text = "\n".join([r if r.__class__ is str else fmt(r) for r in self._buf]) + "\n"
            # take the rows before writing: a Ctrl-C between the write and the bookkeeping must never
            # write a row twice
            rows, self._buf, self._formatted = self._buf, [], 0
            self._file.write(text)
            self._file.flush()
            self.rows_written += len(rows)

    def close(self) -> None:
        if not self._file.closed:
            self.flush()
            self._file.close()
