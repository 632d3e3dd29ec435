"""Fixtures: a real Zenoh router opened in-process on a free loopback port (multicast
scouting off), client sessions, and helper processes."""

from __future__ import annotations

import shutil
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
import zenoh

from cekm_swarm.runtime.config import free_port, load_config, open_client, open_embedded_router, open_session
from helpers.processes import Process

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


class Helper(Process):
    """A helper process (tests/runtime/zenoh_helper.py) whose stdout lines are waited on with a timeout."""

    def __init__(self, *args: str) -> None:
        super().__init__([sys.executable, str(HELPER), *args])

    def expect(self, prefix: str, timeout: float = 20.0, where=None) -> str:
        """The first stdout line starting with ``prefix``."""
        return super().expect(prefix, timeout, where)

    def lines_until(self, marker: str, timeout: float = 20.0) -> list[str]:
        """stdout lines up to (not including) the line ``marker``."""
        return self.reader.until(marker, timeout)


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
