"""A launch spread over network namespaces (:mod:`.netns`) with a fault link
(:mod:`.faultlink`) between chosen robots' hosts and the router: the shape of a run on
robots that reach their router over Wi-Fi. Used by ``tests/runtime/test_bad_network.py``
and ``benchmarks/bench_network.py``.

The world host runs the Zenoh router (the world server's own, ``--listen 0.0.0.0``, or an
outside one the caller may restart: :meth:`NetRun.restart_router`) and, per faulty
robot, a fault link listening on the world host's address on that robot's veth; that
robot's host joins the router through it, the others straight."""

from __future__ import annotations

import json
import os
import signal
import sys
from pathlib import Path
from typing import Any

from cekm_swarm.protocol import DEFAULT_KEYS as K
from cekm_swarm.ticks import tick_of

from .config import RECONNECT_RETRY, _insert, embedded_router_config, open_session
from .faultlink import LinkSettings
from .mcap_log import read_messages
from .netns import Hosts, NsProcess

PORT = 7447
LINK_PORT = 7448
WORLD_UP = "serving the model"  # the world host's launcher: its router (or session) is up
ROUTER = ("import sys; from cekm_swarm.runtime.netns_run import open_router; "
          "s = open_router(int(sys.argv[1]), sys.argv[2], sys.argv[3:]); print('READY', flush=True); "
          "sys.stdin.read(); s.close()")


def open_router(port: int, host: str, connect: list[str]) -> Any:
    """A router listening on ``tcp/host:port`` (and ``udp/host:port``) that also joins the
    routers ``connect`` names (a robot host's own router joining the world's: its nodes'
    traffic to each other stays on the host), retrying a lost one as the clients do."""
    config = embedded_router_config(port, host)
    _insert(config, "listen/endpoints", [f"tcp/{host}:{port}", f"udp/{host}:{port}"])
    if connect:
        _insert(config, "connect/endpoints", connect)
        _insert(config, "connect/retry", RECONNECT_RETRY)
    return open_session(config, "router")


class NetRun:
    """Start with :meth:`start`; then :meth:`link` sends a robot's fault link a command
    (``cut``, ``restore``, ``set delay=0.1``, ...) and :meth:`finish` waits for the end."""

    def __init__(self, hosts: Hosts, work: Path, scenario: str | Path, mode: str, opts: list[str],
                 faulty: dict[str, LinkSettings], outside_router: bool = False, seed: int = 0,
                 host_routers: bool = False, transport: str = "tcp") -> None:
        self.hosts, self.work, self.scenario, self.mode = hosts, work, str(scenario), mode
        self.opts, self.faulty, self.outside_router, self.seed = opts, faulty, outside_router, seed
        self.host_routers = host_routers  # a router on each robot host, joined to the world's
        self.transport = transport  # the faulty robots' link to the world's router: tcp, or udp (outside router)
        assert transport == "tcp" or outside_router, "a udp link needs the outside router (it listens on udp too)"
        bindir = str(Path(sys.executable).parent)  # where the cekm console script lives
        self.env = dict(os.environ, PYTHONUNBUFFERED="1", PATH=bindir + os.pathsep + os.environ.get("PATH", ""))
        self.router: NsProcess | None = None
        self.links: dict[str, NsProcess] = {}
        self.robots: dict[str, NsProcess] = {}
        self.world: NsProcess | None = None

    @property
    def world_out(self) -> Path:
        return self.work / "world-host"

    def start_router(self) -> None:
        self.router = self.hosts.start("world", [sys.executable, "-c", ROUTER, str(PORT), "0.0.0.0"], self.env,
                                       self.work, stdin=True)
        self.router.wait_line("READY", timeout=60)

    def restart_router(self) -> None:
        """SIGKILL the outside router (its clients see their connections close) and start it again."""
        assert self.router is not None, "restart_router needs outside_router=True"
        os.killpg(self.router.proc.pid, signal.SIGKILL)
        self.router.proc.wait(10)
        self.start_router()

    def start(self, wait_ticking: float = 180.0) -> None:
        """Router, world host, fault links, robot hosts; returns once the world ticks."""
        self.work.mkdir(parents=True, exist_ok=True)
        if self.outside_router:
            self.start_router()
        where = ["--connect", f"tcp/127.0.0.1:{PORT}"] if self.outside_router else \
            ["--listen", "0.0.0.0", "--port", str(PORT)]
        argv = ["cekm", "launch", self.scenario, "--mode", self.mode, "--robots", "none",
                *where, "--out", str(self.world_out), "--no-plot", *self.opts]
        self.world = self.hosts.start("world", argv, self.env, self.work)
        self.world.wait_line(WORLD_UP, timeout=120)
        for r in self.hosts.robots:
            addr = self.hosts.world_addr[r]
            if r in self.faulty:
                s = self.faulty[r]
                argv = [sys.executable, "-m", "cekm_swarm.runtime.faultlink", f"--{self.transport}",
                        f"{addr}:{LINK_PORT}=127.0.0.1:{PORT}", "--delay", str(s.delay), "--jitter", str(s.jitter),
                        "--loss", str(s.loss), "--seed", str(self.seed), "--log", str(self.work / f"link-{r}.jsonl")]
                if s.rate is not None:
                    argv += ["--rate", str(s.rate)]
                self.links[r] = self.hosts.start("world", argv, self.env, self.work, stdin=True)
                self.links[r].wait_line("READY", timeout=60)
            faulty = r in self.faulty
            upstream = f"{self.transport if faulty else 'tcp'}/{addr}:{LINK_PORT if faulty else PORT}"
            if self.host_routers:
                self.hosts.start(r, [sys.executable, "-c", ROUTER, str(PORT), "127.0.0.1", upstream], self.env,
                                 self.work, stdin=True).wait_line("READY", timeout=60)
                upstream = f"tcp/127.0.0.1:{PORT}"
            self.robots[r] = self.hosts.start(
                r, ["cekm", "launch", self.scenario, "--mode", self.mode, "--robots", r, "--no-world", "--connect",
                    upstream, "--out", str(self.work / f"host-{r}"), *self.opts], self.env, self.work)
        self.world.wait_line("world started ticking", timeout=wait_ticking)

    def link(self, robot: str, command: str) -> dict[str, Any]:
        """Send ``robot``'s fault link a command; its answer (the logged change)."""
        p = self.links[robot]
        p.send(command)
        line = p.wait_line("{", timeout=30)
        return json.loads(line)

    def finish(self, timeout: float = 240.0) -> dict[str, Any]:
        """Wait for the world host's launcher and every robot host to end; the outcome."""
        assert self.world is not None
        code = self.world.finish(timeout)
        assert code == 0, "the world host's launcher failed:\n" + "\n".join(self.world.lines[-40:])
        for r, p in self.robots.items():
            rc = p.finish(60)
            assert rc == 0, f"{r}'s host failed:\n" + "\n".join(p.lines[-40:])
        for p in self.links.values():
            assert p.proc.stdin is not None  # started with stdin=True
            p.proc.stdin.close()  # the link prints its statistics and ends
            p.finish(30)
        return json.loads((self.world_out / "outcome.json").read_text())

    def link_stats(self, robot: str) -> dict[str, Any]:
        """The fault link's last statistics line (after :meth:`finish`)."""
        for line in reversed(self.links[robot].lines):
            if line.startswith("{") and '"stats"' in line:
                return json.loads(line)
        return {}


def world_log_gaps(log: Path, outcome: dict[str, Any], robots: list[str]) -> dict[str, int]:
    """What the world's log (``run.mcap``, or ``run_0.mcap`` of a split set: read whole) lacks of the run: per world key
    (clock, state) and per robot (its readings: any ``sense/`` message, a reading unchanged
    since it was last sent being named in the tick's ``sense/unchanged``), the ticks with
    none; and ``recorded`` the messages the world says it recorded that are not in the log.
    All zero for a whole log."""
    ticks = set(range(outcome["ticks"] + 1))
    stamps: dict[str, set[int]] = {}
    recorded = 0
    for m in read_messages(log):
        if not m.topic.startswith(K.root + "/"):
            continue
        recorded += 1
        name = m.topic if m.topic in (K.world_state(), K.world_clock()) else m.topic.split("/sense/")[0]
        stamps.setdefault(name, set()).add(tick_of(m.log_time / 1e9))
    gaps = {"recorded": outcome["recorded_messages"] - recorded}
    for name in (K.world_state(), K.world_clock(), *(f"{K.root}/{r}" for r in robots)):
        gaps[name] = len(ticks - stamps.get(name, set()))
    return gaps
