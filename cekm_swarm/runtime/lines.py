"""A process's output lines read by a thread into a queue, so that every wait for a line
has a timeout (a pipe's ``readline`` has none). The one home of this concept: the network
namespace hosts (:mod:`.netns`), ``benchmarks/bench_network.py`` and the tests' process
helpers (``tests/helpers``) all wait on it."""

from __future__ import annotations

import queue
import threading
import time
from collections.abc import Callable, Iterable


class LineReader:
    """The lines of ``stream`` (newline stripped), read on a daemon thread; every line
    handed out is kept in :attr:`seen`. ``ended`` adds text (a process's stderr, say) to
    the error when the stream ends before the line waited for."""

    def __init__(self, stream: Iterable[str], ended: Callable[[], str] | None = None) -> None:
        self.seen: list[str] = []
        self._ended = ended
        self._q: queue.Queue[str | None] = queue.Queue()
        self._thread = threading.Thread(target=self._read, args=(stream,), daemon=True)
        self._thread.start()

    def _read(self, stream: Iterable[str]) -> None:
        for line in stream:
            self._q.put(line.rstrip("\n"))
        self._q.put(None)

    def _tail(self, n: int) -> str:
        extra = self._ended() if self._ended else ""
        return "\n".join(self.seen[-n:]) + (f"\n{extra}" if extra else "")

    def next(self, deadline: float, waiting_for: str) -> str | None:
        """The next line, or None once the stream has ended; AssertionError (naming
        ``waiting_for`` and the last lines) if none comes by ``deadline`` (monotonic)."""
        try:
            line = self._q.get(timeout=max(0.0, deadline - time.monotonic()))
        except queue.Empty:
            raise AssertionError(f"no {waiting_for} in time; output so far:\n" + "\n".join(self.seen[-30:])) from None
        if line is not None:
            self.seen.append(line)
        return line

    def drain(self) -> list[str]:
        """Every line read so far and not yet handed out, without waiting (kept in
        :attr:`seen` too): what a process said, for an error about another one."""
        start = len(self.seen)
        while True:
            try:
                line = self._q.get_nowait()
            except queue.Empty:
                return self.seen[start:]
            if line is None:
                self._q.put(None)  # the end stays the end for the next reader
                return self.seen[start:]
            self.seen.append(line)

    def first(self, match: Callable[[str], bool], waiting_for: str, timeout: float) -> str:
        """The first new line for which ``match`` holds; AssertionError if the stream ends
        or ``timeout`` seconds pass first."""
        deadline = time.monotonic() + timeout
        while True:
            line = self.next(deadline, waiting_for)
            if line is None:
                raise AssertionError(f"ended without {waiting_for}; output:\n" + self._tail(40))
            if match(line):
                return line

    def wait_line(self, needle: str, timeout: float) -> str:
        """The first new line containing ``needle``."""
        return self.first(lambda line: needle in line, f"line with {needle!r}", timeout)

    def expect(self, prefix: str, timeout: float, where: Callable[[str], bool] | None = None) -> str:
        """The first new line starting with ``prefix`` (and passing ``where``)."""
        return self.first(lambda line: line.startswith(prefix) and (where is None or where(line)),
                          f"line starting {prefix!r}", timeout)

    def until(self, marker: str, timeout: float) -> list[str]:
        """The new lines before the line ``marker`` (which is read too)."""
        start = len(self.seen)
        self.first(lambda line: line == marker, f"line {marker!r}", timeout)
        return self.seen[start:-1]

    def rest(self, timeout: float) -> list[str]:
        """Every new line to the end of the stream."""
        start = len(self.seen)
        deadline = time.monotonic() + timeout
        while self.next(deadline, "end of output") is not None:
            pass
        return self.seen[start:]

    def join(self, timeout: float) -> None:
        self._thread.join(timeout)
