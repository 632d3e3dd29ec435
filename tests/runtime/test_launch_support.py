"""Running ``cekm launch`` as a real OS process for the launch tests: a free loopback port
for its embedded router (multicast scouting is always off), output read by a thread so
every wait has a timeout."""

from __future__ import annotations

import json
import os
import queue
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

from cekm_swarm.runtime.config import free_port


class LaunchProcess:
    def __init__(self, scenario: str, out: Path, *args: str, port: int | None = None, cwd: Path | None = None) -> None:
        self.out = out
        self.port = port or free_port()
        env = dict(os.environ, PYTHONUNBUFFERED="1")
        self.proc = subprocess.Popen([sys.executable, "-m", "cekm_swarm", "launch", scenario, "--out", str(out),
                                      "--port", str(self.port), *args],
                                     stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env,
                                     start_new_session=True, cwd=cwd)
        self.lines: list[str] = []
        self._q: queue.Queue[str | None] = queue.Queue()
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self._q.put(line.rstrip("\n"))
        self._q.put(None)

    def wait_line(self, needle: str, timeout: float) -> str:
        """The first (new) output line containing ``needle``."""
        deadline = time.monotonic() + timeout
        while True:
            try:
                line = self._q.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                raise AssertionError(f"no line with {needle!r} in {timeout} s; output so far:\n" +
                                     "\n".join(self.lines[-30:])) from None
            if line is None:
                raise AssertionError(f"launch ended without {needle!r}; output:\n" + "\n".join(self.lines[-40:]))
            self.lines.append(line)
            if needle in line:
                return line

    def finish(self, timeout: float) -> int:
        """Read the output to the end and wait for the exit code."""
        deadline = time.monotonic() + timeout
        while True:
            try:
                line = self._q.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                self.kill()
                raise AssertionError("launch did not end in time; output:\n" + "\n".join(self.lines[-40:])) from None
            if line is None:
                break
            self.lines.append(line)
        return self.proc.wait(timeout=max(1.0, deadline - time.monotonic()))

    def pids(self) -> dict[str, int]:
        return json.loads((self.out / "pids.json").read_text())

    def outcome(self) -> dict:
        return json.loads((self.out / "outcome.json").read_text())

    def kill(self) -> None:
        """Last resort at teardown: the launcher's whole process group... is only its own;
        each child has its own session, so stop them by their recorded ids."""
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
        try:
            for pid in self.pids().values():
                try:
                    os.kill(pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
        except (OSError, ValueError):
            pass


def interrupt(proc: subprocess.Popen, timeout: float = 30) -> None:
    """Stop a tool this test started (``cekm view``) as Ctrl-C would; killed if it does not end."""
    proc.send_signal(signal.SIGINT)
    try:
        proc.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
