"""The world server hosting the Zenoh router (``--listen``, the launcher's embedded
default) and holding tick 0 until every module is alive (``--wait-modules``): a real
world server process on a free loopback port, and a client session playing the modules'
liveliness tokens."""

from __future__ import annotations

import json
import queue
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from cekm_swarm.protocol import DEFAULT_KEYS as K
from cekm_swarm.runtime.config import free_port, open_client
from cekm_swarm.runtime.rungraph import default_nodes
from helpers.processes import Process

pytestmark = pytest.mark.slow  # starts real processes (tests/process_guard.py)


class WorldProcess(Process):
    """``python -m world.server lone_obstacle --listen ...`` (or ``how="--connect"``) with
    its stdout lines read by a thread."""

    def __init__(self, out: Path, *args: str, how: str = "--listen") -> None:
        self.port = free_port()
        self.endpoint = f"tcp/127.0.0.1:{self.port}"
        super().__init__([sys.executable, "-m", "world.server", "lone_obstacle", how, self.endpoint,
                          "--out", str(out), *args])

    def next_kind(self, timeout: float = 30) -> tuple[str, dict]:
        line = self.reader.next(time.monotonic() + timeout, "a world server line")
        assert line is not None, f"world server ended: {self._stderr()}"
        kind, _, body = line.partition(" ")
        return kind, json.loads(body)

    def rest(self, timeout: float = 30) -> list[str]:
        return [line.partition(" ")[0] for line in self.reader.rest(timeout)]

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait(10)


@pytest.fixture
def world(tmp_path):
    made = []

    def start(*args: str) -> WorldProcess:
        w = WorldProcess(tmp_path / f"run{len(made)}", *args)
        made.append(w)
        return w

    yield start
    for w in made:
        w.close()


def test_the_world_hosts_the_router_and_reports_missing_modules_by_name(world, tmp_path):
    w = world("--mode", "lockstep", "--wait-modules", "1.5")
    kind, doc = w.next_kind()
    assert kind == "READY" and doc == {"endpoint": w.endpoint, "router": True}
    session = open_client(w.endpoint)  # nothing else listens on this port: the world server is the router
    tokens = [session.liveliness().declare_token(K.alive("r1", m)) for m in default_nodes() if m != "motor"]
    try:
        kind, doc = w.next_kind()
        assert kind == "EVENT" and doc["event"] == "modules_missing"
        assert doc["missing"] == [K.alive("r1", "motor")]
        assert "START" not in w.rest()  # tick 0 never came
        assert w.proc.wait(10) == 3
    finally:
        for t in tokens:
            t.undeclare()
        session.close()
    outcome = json.loads((tmp_path / "run0" / "outcome.json").read_text())
    assert outcome["aborted"] and outcome["ticks"] == 0
    assert outcome["events"][-1] == {"event": "stopped", "t": 0.0, "reason": "modules missing"}


def test_tick_0_comes_once_every_module_is_alive(world):
    w = world("--mode", "realtime", "--wait-modules", "60")
    assert w.next_kind()[0] == "READY"
    session = open_client(w.endpoint)
    readings = queue.Queue()
    sub = session.declare_subscriber(K.sense_range("r1", 0), lambda s: readings.put(s.payload.to_bytes()))
    tokens = []
    try:
        for m in default_nodes():
            tokens.append(session.liveliness().declare_token(K.alive("r1", m)))
        kind, doc = w.next_kind()
        assert kind == "START" and doc["robots"] == ["r1"]
        assert readings.get(timeout=10)  # the world's readings reach a client of its router
        w.proc.send_signal(signal.SIGTERM)
        assert w.proc.wait(20) == 3
    finally:
        sub.undeclare()
        for t in tokens:
            t.undeclare()
        session.close()


def test_listen_is_refused_with_a_client_config_and_a_non_tcp_endpoint(tmp_path):
    base = [sys.executable, "-m", "world.server", "lone_obstacle", "--out", str(tmp_path)]
    r = subprocess.run([*base, "--listen", "tcp/127.0.0.1:7447", "--zenoh-config", "x.json5"], capture_output=True,
                       text=True, timeout=60)
    assert r.returncode == 2 and "with --listen the world hosts the router" in r.stderr
    r = subprocess.run([*base, "--listen", "udp/127.0.0.1:7447"], capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and "listens on tcp/HOST:PORT" in r.stderr
    r = subprocess.run([*base, "--listen", "tcp/127.0.0.1:7447", "--connect", "tcp/127.0.0.1:7448"],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and "host the router, or join one, not both" in r.stderr


def test_the_world_counts_only_the_tokens_of_its_own_run(world):
    """Modules of another run (left over, or sharing the router) are never counted: with
    every module of run B alive and all but the motor of run A, the world of run A still
    misses run A's motor."""
    w = world("--mode", "lockstep", "--wait-modules", "1.5", "--run-id", "run-a")
    assert w.next_kind()[0] == "READY"
    mine, other = K.with_run("run-a"), K.with_run("run-b")
    session = open_client(w.endpoint)
    tokens = [session.liveliness().declare_token(other.alive("r1", m)) for m in default_nodes()]
    tokens += [session.liveliness().declare_token(mine.alive("r1", m)) for m in default_nodes() if m != "motor"]
    try:
        kind, doc = w.next_kind()
        assert kind == "EVENT" and doc["event"] == "modules_missing"
        assert doc["missing"] == [mine.alive("r1", "motor")]
        assert "START" not in w.rest()
    finally:
        for t in tokens:
            t.undeclare()
        session.close()


def test_a_port_already_taken_leaves_no_log_in_out(tmp_path):
    """The router cannot listen: the world server ends before opening run.mcap (it left a
    log holding the scene view alone)."""
    import socket

    out = tmp_path / "run"
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        proc = subprocess.run([sys.executable, "-m", "world.server", "lone_obstacle", "--listen",
                               f"tcp/127.0.0.1:{port}", "--out", str(out)], capture_output=True, text=True, timeout=60)
    assert proc.returncode != 0 and "Address already in use" in proc.stderr, proc.stderr[-2000:]
    assert not list(out.glob("*.mcap"))
