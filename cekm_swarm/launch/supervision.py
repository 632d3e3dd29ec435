"""The launcher's supervision of its node processes: start each with its log (forked warm
from the fork server, :mod:`.spawn`), restart one that dies with back-off (0.25 s, doubling while it keeps dying within 5 s of starting, at
most 5 s; logged), end the launch at once when one cannot start (its own line), stop them
all (SIGTERM, SIGKILL after 5 s), and keep ``OUT/pids.json`` current."""

from __future__ import annotations

import asyncio
import json
import signal
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from cekm_swarm.node.process import CANNOT_START, EXIT_CANNOT_START, EXIT_STEP_FAILED, STEP_FAILED
from cekm_swarm.runtime.lifetime import child_env

from .spawn import ForkServer, exec_process

BACKOFF_MIN = 0.25
BACKOFF_MAX = 5.0
HEALTHY_AFTER = 5.0  # s: a node up this long gets its back-off reset
STOP_GRACE = 5.0


@dataclass
class Child:
    """One supervised module process."""

    robot: str
    name: str
    argv: list[str]
    log_path: Path
    proc: Any = None  # asyncio.subprocess.Process, or spawn.ForkedProcess
    started: float = 0.0
    restarts: int = 0
    backoff: float = BACKOFF_MIN
    exits: list[int] = field(default_factory=list)
    stateful: bool = False

    @property
    def label(self) -> str:
        return f"{self.robot}/{self.name}"


class Supervision:
    """The supervision part of :class:`~cekm_swarm.launch.launcher.Launcher` (it owns
    ``children``, ``world_proc``, ``stopping``, ``failure``, ``say`` and the config ``c``)."""

    children: dict[str, Child]
    world_proc: Any
    stopping: bool
    failure: str | None
    c: Any
    fork_server: ForkServer | None = None
    fork_server_start: asyncio.Future | None = None

    def say(self, text: str) -> None:  # pragma: no cover - the launcher's
        raise NotImplementedError

    def _pids(self) -> dict[str, int]:
        """Every live process this launcher started, by label."""
        pids = {c.label: c.proc.pid for c in self.children.values() if c.proc is not None and c.proc.returncode is None}
        if self.world_proc is not None and self.world_proc.returncode is None:
            pids["world/server"] = self.world_proc.pid
        if self.fork_server is not None and self.fork_server.alive:
            pids["launch/fork-server"] = self.fork_server.pid
        return pids

    def _write_pids(self) -> None:
        pids = self._pids()
        tmp = self.c.out / "pids.json.tmp"
        try:
            tmp.write_text(json.dumps(pids, indent=1))
            tmp.replace(self.c.out / "pids.json")
        except OSError:  # a full disk: the last pids.json written stays
            tmp.unlink(missing_ok=True)

    # ------------------------------------------------------------------ children

    def _begin_fork_server(self, spec_path: Path) -> None:
        """Start the fork server (it imports while the world server starts); ``--cold-start`` does not."""
        if self.c.warm_start:
            self.fork_server_start = asyncio.ensure_future(
                ForkServer.start([spec_path], self.c.out / "logs" / "forkserver.log", self.run_id))

    async def _await_fork_server(self) -> None:
        """The fork server ready, or (it could not start) every node started afresh, said once."""
        if self.fork_server_start is None or self.fork_server is not None:
            return
        try:
            self.fork_server = await self.fork_server_start
            self.say(f"warm start: nodes fork from the fork server (pid {self.fork_server.pid})")
        except OSError as exc:
            self.say(f"warm start unavailable ({exc}); every node starts afresh")
        self.fork_server_start = None

    async def _spawn(self, child: Child) -> None:
        await self._await_fork_server()
        env = child_env()
        if self.fork_server is not None and self.fork_server.alive:
            try:
                child.proc = await self.fork_server.spawn(child.argv, child.log_path, env)
            except OSError as exc:
                self.say(f"fork server: {exc}; {child.label} starts afresh")
                child.proc = await exec_process(child.argv, child.log_path, env)
        else:
            child.proc = await exec_process(child.argv, child.log_path, env)
        child.started = time.monotonic()
        self._write_pids()

    async def _supervise(self, child: Child) -> None:
        while True:
            assert child.proc is not None
            code = await child.proc.wait()
            if self.stopping:
                return
            child.exits.append(code)
            if code == EXIT_CANNOT_START:  # a bad model or parameter: restarting cannot help
                self.failure = self._own_line(child, CANNOT_START, code)
                self.say(f"node {child.label} cannot start: {self.failure}; the launch ends")
                self._interrupt_for_failure()
                return
            if code == EXIT_STEP_FAILED:  # lockstep cannot go on without that run's outputs
                self.failure = self._own_line(child, STEP_FAILED, code)
                self.say(f"node {child.label} failed: {self.failure}; the launch ends")
                self._interrupt_for_failure()
                return
            up = time.monotonic() - child.started
            if up >= HEALTHY_AFTER:
                child.backoff = BACKOFF_MIN
            delay = child.backoff
            child.backoff = min(BACKOFF_MAX, child.backoff * 2)
            why = f"signal {-code}" if code < 0 else f"exit code {code}"
            self.say(f"module {child.label} died ({why}) after {up:.1f} s; restarting in {delay:.2f} s "
                     f"(restart #{child.restarts + 1})")
            self._write_pids()
            await asyncio.sleep(delay)
            if self.stopping:
                return
            child.restarts += 1
            await self._spawn(child)
            self.say(f"module {child.label} restarted (pid {child.proc.pid})")

    @staticmethod
    def _own_line(child: Child, marker: str, code: int) -> str:
        """The node's own one-line reason (its log's last line starting with ``marker``)."""
        try:
            lines = child.log_path.read_text(errors="replace").splitlines()
        except OSError:
            lines = []
        for line in reversed(lines):
            if line.startswith(marker):
                return line[len(marker):].strip()
        return f"exit code {code} (see {child.log_path})"

    def _interrupt_for_failure(self) -> None:
        """End the run: the world first (it writes what it has), then everything else."""
        self.stopping = True
        if self.world_proc is not None and self.world_proc.returncode is None:
            self.world_proc.send_signal(signal.SIGTERM)
        for ch in self.children.values():
            if ch.proc is not None and ch.proc.returncode is None:
                ch.proc.send_signal(signal.SIGTERM)

    async def _stop_children(self) -> None:
        procs = [c.proc for c in self.children.values() if c.proc is not None and c.proc.returncode is None]
        for p in procs:
            try:
                p.send_signal(signal.SIGTERM)
            except ProcessLookupError:
                pass
        if procs:
            _, pending = await asyncio.wait([asyncio.ensure_future(p.wait()) for p in procs], timeout=STOP_GRACE)
            for p in procs:
                if p.returncode is None:
                    try:
                        p.kill()
                    except ProcessLookupError:
                        pass
            if pending:
                await asyncio.wait(pending, timeout=STOP_GRACE)
        await self._close_fork_server()

    async def _close_fork_server(self) -> None:
        if self.fork_server_start is not None:  # still starting: let it finish, then close it
            try:
                self.fork_server = await self.fork_server_start
            except OSError:
                pass
            self.fork_server_start = None
        if self.fork_server is not None:
            await self.fork_server.close()

