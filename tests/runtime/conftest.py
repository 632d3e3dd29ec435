"""Fixtures: a real Zenoh router opened in-process on a free loopback port (multicast
scouting off), client sessions, and helper processes."""

from __future__ import annotations

import queue
import shutil
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
import zenoh

from cekm_swarm.runtime.config import free_port, load_config, open_client, open_embedded_router, open_session

HELPER = Path(__file__).with_name("zenoh_helper.py")


DEPLOY = Path(__file__).resolve().parents[2] / "deploy"


@pytest.fixture
def acl_endpoint(tmp_path) -> Iterator[str]:
    """A router started from deploy/router.json5 (access control) with the example
    credentials, on a free loopback port; its endpoint."""
    creds = tmp_path / "credentials.txt"
    shutil.copy(DEPLOY / "credentials.example.txt", creds)
    port = free_port()
    config = load_config(DEPLOY / "router.json5", {"listen/endpoints": [f"tcp/127.0.0.1:{port}"],
                                                    "transport/auth/usrpwd/dictionary_file": str(creds)})
    router = open_session(config, "ACL router")
    yield f"tcp/127.0.0.1:{port}"
    router.close()


@pytest.fixture
def router() -> Iterator[str]:
    """An embedded router on a free loopback port; yields its endpoint."""
    port = free_port()
    session = open_embedded_router(port)
    try:
        yield f"tcp/127.0.0.1:{port}"
    finally:
        session.close()


@pytest.fixture
def clients(router: str) -> Iterator[Callable[[], zenoh.Session]]:
    """Factory of client sessions connected to ``router``; all closed at teardown."""
    opened: list[zenoh.Session] = []

    def make() -> zenoh.Session:
        s = open_client(router)
        opened.append(s)
        return s

    yield make
    for s in opened:
        s.close()


class Helper:
    """A helper process (tests/runtime/zenoh_helper.py); its stdout lines are read by a
    thread into a queue so every wait has a timeout."""

    def __init__(self, *args: str) -> None:
        self.proc = subprocess.Popen([sys.executable, str(HELPER), *args], stdout=subprocess.PIPE,
                                     stderr=subprocess.PIPE, text=True)
        self._lines: queue.Queue[str | None] = queue.Queue()
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self._lines.put(line.rstrip("\n"))
        self._lines.put(None)

    def _next(self, deadline: float, waiting_for: str) -> str:
        try:
            line = self._lines.get(timeout=max(0.0, deadline - time.monotonic()))
        except queue.Empty:
            raise AssertionError(f"helper {self.proc.args[2:]}: no {waiting_for!r} in time") from None
        if line is None:
            err = self.proc.stderr.read() if self.proc.stderr else ""
            raise AssertionError(f"helper {self.proc.args[2:]} ended without {waiting_for!r}; stderr: {err}")
        return line

    def expect(self, prefix: str, timeout: float = 20.0) -> str:
        """The first stdout line starting with ``prefix``."""
        deadline = time.monotonic() + timeout
        while True:
            line = self._next(deadline, prefix)
            if line.startswith(prefix):
                return line

    def lines_until(self, marker: str, timeout: float = 20.0) -> list[str]:
        """stdout lines up to (not including) the line ``marker``."""
        deadline = time.monotonic() + timeout
        out = []
        while (line := self._next(deadline, marker)) != marker:
            out.append(line)
        return out

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait(timeout=10)
        self._reader.join(timeout=5)
        for f in (self.proc.stdout, self.proc.stderr):
            if f is not None:
                f.close()


@pytest.fixture
def helpers() -> Iterator[Callable[..., Helper]]:
    """Start helper processes; every one still running is killed at teardown."""
    started: list[Helper] = []

    def start(*args: str) -> Helper:
        h = Helper(*args)
        started.append(h)
        return h

    yield start
    for h in started:
        h.stop()
