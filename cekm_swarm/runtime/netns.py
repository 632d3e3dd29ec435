"""Hosts on one Linux machine: a network namespace for the world host and one per robot,
each robot's joined to the world's by a veth pair, and processes run inside them. The
tests and ``benchmarks/bench_network.py`` put a run's hosts here, with a fault link
(:mod:`.faultlink`) on a robot's way to the router.

Topology (addresses exist only inside these namespaces; nothing leaves the machine), for
the i-th robot (from 1)::

    robot host 10.199.i.2 --veth-- 10.199.i.1 world host

Needs root and iproute2 (:func:`namespaces_unavailable` says why not). :meth:`Hosts.remove`
kills every process left in the namespaces and deletes them (their veth ends go too)."""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

from .lines import LineReader


def ip(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(["ip", *args], capture_output=True, text=True, timeout=30)


def namespaces_unavailable(need_openssl: bool = False) -> str | None:
    """Why this machine cannot make network namespaces, or None."""
    if sys.platform != "linux":
        return "network namespaces are Linux only"
    if os.geteuid() != 0:
        return "creating network namespaces needs root"
    if shutil.which("ip") is None:
        return "the 'ip' command (iproute2) is not installed"
    if need_openssl and shutil.which("openssl") is None:
        return "openssl is not installed (deploy/make-certs.sh needs it)"
    probe = f"cekm-probe-{os.getpid()}"
    made = ip("netns", "add", probe)
    if made.returncode != 0:
        return f"'ip netns add' is not allowed here: {made.stderr.strip()}"
    ip("netns", "del", probe)
    return None


class NsProcess:
    """A command run in a namespace (``ip netns exec``), its output read by a thread so
    every wait has a timeout; :meth:`send` writes a line to its stdin (``stdin=True``)."""

    def __init__(self, ns: str, argv: list[str], env: dict[str, str], cwd: Path, stdin: bool = False) -> None:
        self.proc = subprocess.Popen(["ip", "netns", "exec", ns, *argv], cwd=cwd, env=env, text=True,
                                     stdin=subprocess.PIPE if stdin else subprocess.DEVNULL,
                                     stdout=subprocess.PIPE, stderr=subprocess.STDOUT, start_new_session=True)
        assert self.proc.stdout is not None
        self.reader = LineReader(self.proc.stdout)
        self.lines = self.reader.seen

    def send(self, line: str) -> None:
        assert self.proc.stdin is not None
        self.proc.stdin.write(line + "\n")
        self.proc.stdin.flush()

    def wait_line(self, needle: str, timeout: float) -> str:
        return self.reader.wait_line(needle, timeout)

    def finish(self, timeout: float) -> int:
        """Read the output to the end and wait for the exit code."""
        deadline = time.monotonic() + timeout
        self.reader.rest(timeout)
        return self.proc.wait(timeout=max(1.0, deadline - time.monotonic()))


class Hosts:
    """A world namespace and one per robot, named after this process (and ``tag``) so
    parallel runs never meet; :meth:`remove` undoes everything."""

    def __init__(self, robots: tuple[str, ...], tag: str = "") -> None:
        self.tag = f"{os.getpid() % 100000}{tag}"
        self.robots = robots
        self.ns = {h: f"cekm{self.tag}-{h}" for h in ("world", *robots)}
        self.world_addr = {r: f"10.199.{i}.1" for i, r in enumerate(robots, 1)}
        self.robot_addr = {r: f"10.199.{i}.2" for i, r in enumerate(robots, 1)}
        self.ifs = {r: f"ck{self.tag}{r}"[:15] for r in robots}
        self.procs: list[NsProcess] = []
        try:
            for ns in self.ns.values():
                self._ok(ip("netns", "add", ns))
                self._ok(ip("-n", ns, "link", "set", "lo", "up"))
            for r in robots:  # veth pair created straight inside the two namespaces
                w_if, r_if = f"ck{self.tag}w{r}"[:15], self.ifs[r]
                self._ok(ip("link", "add", w_if, "netns", self.ns["world"], "type", "veth", "peer", "name", r_if,
                            "netns", self.ns[r]))
                self._ok(ip("-n", self.ns["world"], "addr", "add", f"{self.world_addr[r]}/24", "dev", w_if))
                self._ok(ip("-n", self.ns[r], "addr", "add", f"{self.robot_addr[r]}/24", "dev", r_if))
                self._ok(ip("-n", self.ns["world"], "link", "set", w_if, "up"))
                self._ok(ip("-n", self.ns[r], "link", "set", r_if, "up"))
        except BaseException:
            self.remove()
            raise

    @staticmethod
    def _ok(done: subprocess.CompletedProcess[str]) -> None:
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
        listed = ip("netns", "list").stdout
        for ns in self.ns.values():
            if ns not in listed:
                continue
            for pid in ip("netns", "pids", ns).stdout.split():
                with contextlib.suppress(ProcessLookupError, ValueError):
                    os.kill(int(pid), signal.SIGKILL)
            ip("netns", "del", ns)

    def left_over(self) -> list[str]:
        """This object's namespaces that still exist (none after :meth:`remove`)."""
        listed = ip("netns", "list").stdout.split()
        return [ns for ns in self.ns.values() if ns in listed]
