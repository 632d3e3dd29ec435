"""Append-only tables of float rows whose memory stays flat however long the run: the per
tick records a run keeps for its outputs (each robot's pose and command, the tracking
metric's series). A list of tuples costs about 100 bytes a row of four floats, so an hour
of 8 robots (28,125 ticks) held 30 MB in the world server; a :class:`Rows` keeps at most
:data:`BUFFER_ROWS` rows in memory, as packed doubles in one buffer allocated when the
table is made and reused, and spills the rest to an anonymous temporary file: its memory
is the same at the first tick and after an hour. It reads like the list it replaces (``len``, iteration, indexing and
slices give tuples of Python floats, equal to the bit to what was appended)."""

from __future__ import annotations

import tempfile
from array import array
from collections.abc import Iterable, Iterator
from typing import IO, overload

BUFFER_ROWS = 256
"""Rows a table keeps in memory before it writes them to its temporary file (33 s of
ticks; 8 kB for a row of four floats, so a world of 1,024 robots holds 12 MB of them)."""


class Rows:
    """An append-only table of ``width`` floats a row (see the module's docstring)."""

    def __init__(self, width: int, rows: Iterable[Iterable[float]] = ()) -> None:
        self.width = width
        self._buf = array("d", bytes(8 * BUFFER_ROWS * width))  # allocated and touched once, reused
        self._n = 0  # values of _buf in use
        self._spilled = 0  # rows in the file
        self._file: IO[bytes] | None = None
        for row in rows:
            self.append(row)

    def append(self, row: Iterable[float]) -> None:
        values = tuple(row)
        w = self.width
        if len(values) != w:
            raise ValueError(f"a row of {w} floats expected")
        buf, n = self._buf, self._n
        for j, v in enumerate(values):  # each as array('d') takes it: a float, or a TypeError
            buf[n + j] = v
        self._n = n + w
        if self._n == len(buf):
            if self._file is None:
                self._file = tempfile.TemporaryFile()  # noqa: SIM115 -- the rows' spill, open as long as they are
            self._file.seek(0, 2)
            buf.tofile(self._file)
            self._spilled += BUFFER_ROWS
            self._n = 0

    def __len__(self) -> int:
        return self._spilled + self._n // self.width

    def __bool__(self) -> bool:
        return len(self) > 0

    def _chunks(self) -> Iterator[array[float]]:
        if self._file is not None and self._spilled:
            self._file.seek(0)
            left = self._spilled * self.width
            while left:
                part = array("d")
                n = min(left, BUFFER_ROWS * self.width)
                part.fromfile(self._file, n)
                left -= n
                yield part
        yield self._buf[:self._n]

    def __iter__(self) -> Iterator[tuple[float, ...]]:
        w = self.width
        for part in self._chunks():
            for i in range(0, len(part), w):
                yield tuple(part[i:i + w])

    def column(self, j: int) -> list[float]:
        """Column ``j`` of every row, as a list."""
        w = self.width
        return [v for part in self._chunks() for v in part[j::w]]

    def _row(self, i: int) -> tuple[float, ...]:
        n = len(self)
        if i < 0:
            i += n
        if not 0 <= i < n:
            raise IndexError("row index out of range")
        w = self.width
        if i >= self._spilled:
            k = (i - self._spilled) * w
            return tuple(self._buf[k:k + w])
        assert self._file is not None
        self._file.seek(i * w * 8)
        part = array("d")
        part.fromfile(self._file, w)
        return tuple(part)

    @overload
    def __getitem__(self, i: int) -> tuple[float, ...]: ...

    @overload
    def __getitem__(self, i: slice) -> list[tuple[float, ...]]: ...

    def __getitem__(self, i: int | slice) -> tuple[float, ...] | list[tuple[float, ...]]:
        if isinstance(i, slice):
            return list(self)[i]
        return self._row(i)

    def __eq__(self, other: object) -> bool:
        if isinstance(other, Rows):
            return self.width == other.width and list(self) == list(other)
        if isinstance(other, list):
            return list(self) == [tuple(r) for r in other]
        return NotImplemented

    def __repr__(self) -> str:
        return f"Rows(width={self.width}, rows={len(self)})"
