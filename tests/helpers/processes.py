"""A process started by a test, its stdout lines read by a thread
(:class:`cekm_swarm.runtime.lines.LineReader`) so that every wait has a timeout."""

from __future__ import annotations

import subprocess
from pathlib import Path

from cekm_swarm.runtime.lines import LineReader


class Process:
    """``argv`` as a process: :meth:`expect` / :meth:`wait_line` wait for a stdout line,
    :meth:`send` writes a line to its stdin (``stdin=True``). Its stderr is kept apart
    (and shown when it ends too early) unless ``merge_stderr``."""

    def __init__(self, argv: list[str], env: dict[str, str] | None = None, cwd: Path | None = None,
                 stdin: bool = False, merge_stderr: bool = False, new_session: bool = False) -> None:
        self.proc = subprocess.Popen(argv, stdin=subprocess.PIPE if stdin else None, stdout=subprocess.PIPE,
                                     stderr=subprocess.STDOUT if merge_stderr else subprocess.PIPE,
                                     text=True, env=env, cwd=cwd, start_new_session=new_session)
        assert self.proc.stdout is not None
        self.reader = LineReader(self.proc.stdout, ended=None if merge_stderr else self._stderr)
        self.seen = self.reader.seen

    def _stderr(self) -> str:
        err = self.proc.stderr.read() if self.proc.stderr else ""
        return f"stderr: {err[-3000:]}" if err else ""

    def expect(self, prefix: str, timeout: float = 30.0, where=None) -> str:
        """The next stdout line starting with ``prefix`` (and passing ``where``)."""
        return self.reader.expect(prefix, timeout, where)

    def wait_line(self, needle: str, timeout: float = 30.0) -> str:
        """The next stdout line containing ``needle``."""
        return self.reader.wait_line(needle, timeout)

    def send(self, line: str) -> None:
        assert self.proc.stdin is not None
        self.proc.stdin.write(line + "\n")
        self.proc.stdin.flush()

    def stop(self) -> None:
        """Kill it if still running, and close its pipes."""
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait(timeout=10)
        self.reader.join(timeout=5)
        for f in (self.proc.stdin, self.proc.stdout, self.proc.stderr):
            if f is not None:
                f.close()
