"""Running ``cekm launch`` as a real OS process for the launch tests: a free loopback port
for its embedded router (multicast scouting is always off), output read by a thread so
every wait has a timeout."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from cekm_swarm.runtime.config import free_port
from cekm_swarm.runtime.lines import LineReader


class LaunchProcess:
    def __init__(self, scenario: str, out: Path, *args: str, port: int | None = None, cwd: Path | None = None) -> None:
        self.out = out
        self.port = port or free_port()
        env = dict(os.environ, PYTHONUNBUFFERED="1")
        self.proc = subprocess.Popen([sys.executable, "-m", "cekm_swarm", "launch", scenario, "--out", str(out),
                                      "--port", str(self.port), *args],
                                     stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env,
                                     start_new_session=True, cwd=cwd)
        assert self.proc.stdout is not None
        self.reader = LineReader(self.proc.stdout)
        self.lines = self.reader.seen

    def wait_line(self, needle: str, timeout: float) -> str:
        """The first (new) output line containing ``needle``."""
        return self.reader.wait_line(needle, timeout)

    def finish(self, timeout: float) -> int:
        """Read the output to the end and wait for the exit code (killed if it does not end in time)."""
        deadline = time.monotonic() + timeout
        try:
            self.reader.rest(timeout)
        except AssertionError:
            self.kill()
            raise
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
                with contextlib.suppress(ProcessLookupError):
                    os.kill(pid, signal.SIGKILL)
        except (OSError, ValueError):
            pass


def interrupt(proc: subprocess.Popen, timeout: float = 30) -> None:
    """Stop a tool this test started (``cekm view``) as Ctrl-C would; killed if it does not end."""
    proc.send_signal(signal.SIGINT)
    try:
        proc.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
