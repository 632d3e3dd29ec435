"""A run over three "hosts": Linux network namespaces, each with its own network stack,
joined by veth pairs. The world host runs the Zenoh router of deploy/tls/router.json5
(mutual TLS, access control) and deploy/launch-hosts.sh's world launcher; robot r1's and
robot r2's hosts each run launch-hosts.sh for their robot, joining the router by its
address on their link. Each host logs in with its own deploy/tls/ config and
certificate. Once the world ticks, r1's link is cut for 2 s (shorter than Zenoh's 10 s
lease: the TLS connection survives, TCP retransmits). The lockstep outcome still equals
the one-process run bit for bit.

Topology (addresses exist only inside these namespaces; nothing leaves the machine):

    r1 host 10.199.1.2 --veth-- 10.199.1.1 world host 10.199.2.1 --veth-- 10.199.2.2 r2 host

Needs root and iproute2; skipped with the reason otherwise. Every namespace (and so its
links) is removed afterwards, and any process still in one is killed, even on failure."""

from __future__ import annotations

import json
import os
import queue
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from cekm_swarm.experiments.default_model import default_model
from cekm_swarm.experiments.navigation_run import run_scenario
from world import load_scenario

pytestmark = pytest.mark.slow  # starts real processes (tests/process_guard.py)

REPO = Path(__file__).resolve().parents[2]
DEPLOY = REPO / "deploy"
SEED = 2
MAX_TIME = 30.0
OUTAGE = 2.0
ROBOTS = ("r1", "r2")
WORLD_ADDR = {"r1": "10.199.1.1", "r2": "10.199.2.1"}
ROBOT_ADDR = {"r1": "10.199.1.2", "r2": "10.199.2.2"}

SCENARIO = """\
name = "two_hosts"
description = "two robots, each on its own host, each past a disc to a goal 0.8 m away"
seed = 5

[arena]
bounds = [0.0, 0.0, 2.0, 2.0]

[[robots]]
id = "r1"
start = [0.4, 0.6, 0.0]
goal = "g1"

[[robots]]
id = "r2"
start = [1.6, 1.4, 3.141592653589793]
goal = "g2"

[[targets]]
id = "g1"
position = [1.2, 0.6]

[[targets]]
id = "g2"
position = [0.8, 1.4]

[[obstacles]]
id = "d1"
shape = "disc"
center = [0.8, 0.62]
radius = 0.05

[[obstacles]]
id = "d2"
shape = "disc"
center = [1.2, 1.38]
radius = 0.05
"""


def ip(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(["ip", *args], capture_output=True, text=True, timeout=30)


def namespaces_unavailable() -> str | None:
    """Why this machine cannot run the test, or None."""
    if sys.platform != "linux":
        return "network namespaces are Linux only"
    if os.geteuid() != 0:
        return "creating network namespaces needs root"
    if shutil.which("ip") is None:
        return "the 'ip' command (iproute2) is not installed"
    if shutil.which("openssl") is None:
        return "openssl is not installed (deploy/make-certs.sh needs it)"
    probe = f"cekm-probe-{os.getpid()}"
    made = ip("netns", "add", probe)
    if made.returncode != 0:
        return f"'ip netns add' is not allowed here: {made.stderr.strip()}"
    ip("netns", "del", probe)
    return None


class NsProcess:
    """A command run in a namespace (``ip netns exec``), its output read by a thread so
    every wait has a timeout."""

    def __init__(self, ns: str, argv: list[str], env: dict[str, str], cwd: Path, stdin: bool = False) -> None:
        self.proc = subprocess.Popen(["ip", "netns", "exec", ns, *argv], cwd=cwd, env=env, text=True,
                                     stdin=subprocess.PIPE if stdin else subprocess.DEVNULL,
                                     stdout=subprocess.PIPE, stderr=subprocess.STDOUT, start_new_session=True)
        self.lines: list[str] = []
        self._q: queue.Queue[str | None] = queue.Queue()
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self._q.put(line.rstrip("\n"))
        self._q.put(None)

    def wait_line(self, needle: str, timeout: float) -> str:
        deadline = time.monotonic() + timeout
        while True:
            try:
                line = self._q.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                raise AssertionError(f"no line with {needle!r} in {timeout} s:\n" + "\n".join(self.lines[-30:])) from None
            if line is None:
                raise AssertionError(f"ended without {needle!r}:\n" + "\n".join(self.lines[-40:]))
            self.lines.append(line)
            if needle in line:
                return line

    def finish(self, timeout: float) -> int:
        deadline = time.monotonic() + timeout
        while True:
            try:
                line = self._q.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                raise AssertionError("did not end in time:\n" + "\n".join(self.lines[-40:])) from None
            if line is None:
                return self.proc.wait(timeout=max(1.0, deadline - time.monotonic()))
            self.lines.append(line)


class Hosts:
    """Three namespaces (world, r1, r2) and two veth links, named after this process so
    parallel runs never meet; :meth:`remove` undoes everything."""

    def __init__(self) -> None:
        tag = f"{os.getpid() % 100000}"
        self.ns = {h: f"cekm{tag}-{h}" for h in ("world", *ROBOTS)}
        self.procs: list[NsProcess] = []
        self.ifs = {r: f"ck{tag}{r}" for r in ROBOTS}
        for ns in self.ns.values():
            self._ok(ip("netns", "add", ns))
            self._ok(ip("-n", ns, "link", "set", "lo", "up"))
        for r in ROBOTS:  # veth pair created straight inside the two namespaces
            w_if, r_if = f"ck{tag}w{r}", f"ck{tag}{r}"
            self._ok(ip("link", "add", w_if, "netns", self.ns["world"], "type", "veth", "peer", "name", r_if,
                        "netns", self.ns[r]))
            self._ok(ip("-n", self.ns["world"], "addr", "add", f"{WORLD_ADDR[r]}/24", "dev", w_if))
            self._ok(ip("-n", self.ns[r], "addr", "add", f"{ROBOT_ADDR[r]}/24", "dev", r_if))
            self._ok(ip("-n", self.ns["world"], "link", "set", w_if, "up"))
            self._ok(ip("-n", self.ns[r], "link", "set", r_if, "up"))

    @staticmethod
    def _ok(done: subprocess.CompletedProcess) -> None:
        if done.returncode != 0:
            raise RuntimeError(f"{' '.join(done.args)}: {done.stderr.strip()}")

    def link(self, robot: str, up: bool) -> None:
        """Bring robot's end of its link down or up (as a pulled cable)."""
        self._ok(ip("-n", self.ns[robot], "link", "set", self.ifs[robot], "up" if up else "down"))

    def start(self, host: str, argv: list[str], env: dict[str, str], cwd: Path, stdin: bool = False) -> NsProcess:
        p = NsProcess(self.ns[host], argv, env, cwd, stdin)
        self.procs.append(p)
        return p

    def remove(self) -> None:
        """Stop what runs in the namespaces (every process in them was started here) and
        delete them; their veth ends go with them."""
        for p in self.procs:
            if p.proc.poll() is None:
                p.proc.send_signal(signal.SIGTERM)
        for p in self.procs:
            try:
                p.proc.wait(10)
            except subprocess.TimeoutExpired:
                p.proc.kill()
        for ns in self.ns.values():
            pids = ip("netns", "pids", ns).stdout.split()
            for pid in pids:
                try:
                    os.kill(int(pid), signal.SIGKILL)
                except (ProcessLookupError, ValueError):
                    pass
            ip("netns", "del", ns)


@pytest.fixture
def hosts():
    reason = namespaces_unavailable()
    if reason:
        pytest.skip(reason)
    h = None
    try:
        h = Hosts()
        yield h
    finally:
        if h is not None:
            h.remove()
        else:  # construction failed half-way: remove what exists
            tag = f"{os.getpid() % 100000}"
            for host in ("world", *ROBOTS):
                ip("netns", "del", f"cekm{tag}-{host}")
    listed = ip("netns", "list").stdout
    assert f"cekm{os.getpid() % 100000}-" not in listed, listed


ROUTER = ("import sys; from cekm_swarm.runtime.config import load_config, open_session; "
          "s = open_session(load_config(sys.argv[1]), 'TLS router'); print('router ready', flush=True); "
          "sys.stdin.read(); s.close()")


def test_world_host_and_two_robot_hosts_in_network_namespaces_over_mutual_tls(hosts, tmp_path):
    model = default_model(progress=False)
    run = tmp_path / "run"
    run.mkdir()
    certs = subprocess.run([str(DEPLOY / "make-certs.sh"), str(run / "certs"), *WORLD_ADDR.values()],
                           capture_output=True, text=True, timeout=60,
                           env=dict(os.environ, HOSTS="world r1 r2"))
    assert certs.returncode == 0, certs.stderr
    scenario = run / "two_hosts.toml"
    scenario.write_text(SCENARIO)
    bindir = str(Path(sys.executable).parent)  # where the cekm console script lives
    base = dict(os.environ, PYTHONUNBUFFERED="1", PATH=bindir + os.pathsep + os.environ.get("PATH", ""),
                SCENARIO=str(scenario), MODE="lockstep", LINK="tls")
    opts = ["--seed", str(SEED), "--max-time", str(MAX_TIME)]
    t0 = time.monotonic()
    # The router as shipped (tls/0.0.0.0:7447; certs/ relative to its working directory).
    router = hosts.start("world", [sys.executable, "-c", ROUTER, str(DEPLOY / "tls" / "router.json5")], base, run,
                         stdin=True)
    router.wait_line("router ready", timeout=60)
    world = hosts.start("world", [str(DEPLOY / "launch-hosts.sh"), "world", WORLD_ADDR["r1"], "--no-plot", *opts],
                        dict(base, OUT=str(run / "world-host"), ZENOH_CONFIG=str(DEPLOY / "tls" / "world.json5")), run)
    world.wait_line("serving the model", timeout=90)
    robots = {r: hosts.start(r, [str(DEPLOY / "launch-hosts.sh"), r, WORLD_ADDR[r], *opts],
                             dict(base, OUT=str(run / "host"), ZENOH_CONFIG=str(DEPLOY / "tls" / f"robot-{r}.json5")),
                             run) for r in ROBOTS}
    world.wait_line("world started ticking", timeout=120)
    t_cut = time.monotonic()
    hosts.link("r1", up=False)
    time.sleep(OUTAGE)
    hosts.link("r1", up=True)
    t_up = time.monotonic()
    assert world.finish(timeout=240) == 0, "\n".join(world.lines)
    wall = time.monotonic() - t0
    for r, p in robots.items():
        assert p.finish(timeout=60) == 0, "\n".join(p.lines)
        assert any("the world server has ended" in line for line in p.lines), "\n".join(p.lines[-20:])
    outcome = json.loads((run / "world-host" / "outcome.json").read_text())
    assert outcome["launcher"]["modules"] == 0 and outcome["dropped_messages"] == 0
    ref = run_scenario(load_scenario(scenario), "cekm", model, SEED, max_time=MAX_TIME)
    traj = json.loads((run / "world-host" / "trajectory.json").read_text())
    for r in ROBOTS:
        assert outcome["robots"][r]["reached"]
        assert traj[r]["x"] == ref.logs[r].x and traj[r]["y"] == ref.logs[r].y and traj[r]["v_l"] == ref.logs[r].v_l
        # Each robot host ran its own robot's modules (one log each, OUT/logs/ROBOT-MODULE.log) and no other's.
        logs = {p.name.split("-")[0] for p in (run / f"host-{r}" / "logs").glob("*-*.log")}
        assert logs == {r}, logs
    # The cut hit the run: the lockstep world waited for r1 (and republished its readings).
    assert any("republish: waiting for r1" in line for line in world.lines), "\n".join(world.lines)
    for line in world.lines:
        if "modules alive after" in line or "world done" in line:
            print(line)
    print(f"three-namespace TLS run: {wall:.1f} s wall from router start to the world's end; "
          f"r1's link down {t_up - t_cut:.1f} s")
