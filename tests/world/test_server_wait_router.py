"""A world server that joins an outside router (``--connect``) waits for it when it is not
up yet, as every networked command does (README: "waits for the router instead of
failing"), saying so; a wait that runs out ends in one clear line; a signal ends it at once."""

from __future__ import annotations

import signal
import time
from pathlib import Path

import pytest
from test_server_router import WorldProcess

from cekm_swarm.runtime.config import open_embedded_router

pytestmark = pytest.mark.slow  # starts real processes (tests/process_guard.py)


class JoiningWorld(WorldProcess):
    """``python -m world.server lone_obstacle --connect ...`` (nothing listens there yet)."""

    def __init__(self, out: Path, *args: str) -> None:
        super().__init__(out, *args, how="--connect")

    def wait_line(self, prefix: str, timeout: float = 30) -> str:
        return self.expect(prefix, timeout)


@pytest.fixture
def world(tmp_path):
    made: list[JoiningWorld] = []

    def start(*args: str) -> JoiningWorld:
        w = JoiningWorld(tmp_path / f"run{len(made)}", *args)
        made.append(w)
        return w

    yield start
    for w in made:
        w.close()


def test_the_world_waits_for_a_router_that_comes_up_later(world):
    w = world("--wait-router", "60")
    assert w.wait_line("waiting for the router") == f"waiting for the router at {w.endpoint} ..."
    router = open_embedded_router(w.port, "127.0.0.1")
    try:
        w.wait_line("READY ")  # joined once the router is there
        w.proc.send_signal(signal.SIGTERM)
        assert w.proc.wait(30) in (0, 3)
    finally:
        router.close()


def test_a_wait_that_runs_out_ends_in_one_clear_line(world):
    w = world("--wait-router", "1")
    assert w.proc.wait(30) == 2
    err = w.proc.stderr.read()
    assert f"no Zenoh router at {w.endpoint} after waiting 1 s (--wait-router)" in err, err
    assert "Traceback" not in err


def test_a_signal_ends_the_wait_at_once(world):
    w = world("--wait-router", "60")
    w.wait_line("waiting for the router")
    t0 = time.monotonic()
    w.proc.send_signal(signal.SIGTERM)
    assert w.proc.wait(10) == 130
    assert time.monotonic() - t0 < 10
    assert "stopped while waiting for the router" in w.proc.stderr.read()
