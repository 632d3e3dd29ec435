"""The launcher's supervision of its node processes: start each with its log (forked warm
from the fork server, :mod:`.spawn`), restart one that dies with back-off (0.25 s, doubling
while it keeps dying within 5 s of starting, at most 5 s; logged), end the launch at once
when one cannot start (its own line), stop them all (SIGTERM, SIGKILL after 5 s), and keep
``OUT/pids.json`` current.

In lockstep a node that dies at the same tick every time (a crash in a C extension, an
``os._exit`` in its step) would be restarted forever, the world waiting at that tick: the
launcher that runs the world notes the world's tick after each death (its next clock
message, sent again while it waits), and when :data:`SAME_TICK_RESTARTS` restarts in a row
died at one tick it ends the launch with one line naming the node, its exit and the tick.
Real time goes on restarting."""

from __future__ import annotations

import asyncio
import contextlib
import json
import signal
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, cast

import zenoh

from cekm_swarm.errors import CekmError
from cekm_swarm.node.process import (
    CANNOT_START,
    EXIT_CANNOT_START,
    EXIT_STEP_FAILED,
    STALL_SIGNAL,
    STALLED,
    STEP_FAILED,
)
from cekm_swarm.node.timing import lost_on_restart
from cekm_swarm.protocol import Clock, KeyKind, decode
from cekm_swarm.runtime.bridge import AsyncSubscription
from cekm_swarm.runtime.lifetime import child_env
from cekm_swarm.ticks import tick_time

from .processes import node_argv
from .spawn import ForkServer, exec_process

SAME_TICK_RESTARTS = 3
"""Restarts in a row that died at the same tick of a lockstep run, the world waiting there,
after which the launch ends (the node cannot get past that tick)."""
MEASURED_PROCESSES = 448
"""The most node processes a launch has been measured with (32 robots of 14, docs/performance.md):
a larger launch says so before it starts them."""
STALL_ANSWER_S = 0.5  # s the launcher gives asked nodes to write where they are
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
    stateful: bool = False  # restarts without what it had (node.timing.lost_on_restart, or state): not cekm run's
    died_at: int | None = None  # lockstep: the world's tick after its latest death
    same_tick: int = 0  # ... and how many restarts in a row died at that tick

    @property
    def label(self) -> str:
        return f"{self.robot}/{self.name}"


class Supervision:
    """The supervision part of :class:`~cekm_swarm.launch.launcher.Launcher` (it owns
    ``children``, ``world_proc``, ``stopping``, ``failure``, ``say`` and the config ``c``)."""

    children: dict[str, Child]
    world_proc: Any
    stopping: bool
    interrupted: bool
    failure: str | None
    failed_running: bool
    c: Any
    keys: Any
    session: Any
    supervisors: list[asyncio.Future]
    plan: Any
    checked: Any
    spec_path: Path | None
    run_id: str | None
    wait_report_every: float
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
        if self.fork_server is not None and not self.fork_server.alive and not self.stopping:
            gone, self.fork_server = self.fork_server, None  # said once
            self.say(f"the fork server (pid {gone.pid}) is gone: the nodes it forked died with it "
                     f"(signal 15), and every node starts afresh from now on")
            await gone.close()
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

    async def _spawn_modules(self, scenario, robots: list[str], model: Path | str | None, endpoint: str) -> None:
        """Start every node process of ``robots`` (the graph's node instances), each under a supervisor."""
        c = self.c
        for r in robots:
            for node in self.plan.nodes[r]:
                argv = node_argv(str(self.spec_path), r, node.name, self.run_id)
                child = Child(r, node.name, argv, c.out / "logs" / f"{r}-{node.name}.log",
                              stateful=node.stateful or bool(lost_on_restart(node)))
                self.children[child.label] = child
        self.say(f"{scenario.name}: {self.checked.graph.name} ({self.checked.graph.controller}), "
                 f"{len(robots)} robot(s), starting {len(self.children)} node processes ({c.mode})")
        if len(self.children) > MEASURED_PROCESSES:
            self.say(f"note: {len(self.children)} node processes is more than this runtime has been measured with "
                     f"({MEASURED_PROCESSES}: 32 robots on 2 cores, docs/performance.md); starting and stopping them "
                     f"may take minutes, and each takes about 7 MB of memory (PSS) when forked warm")
        loop = asyncio.get_running_loop()
        next_report = loop.time() + self.wait_report_every
        for n, child in enumerate(self.children.values()):
            if self.stopping or self.interrupted:  # Ctrl-C while they start: start no more
                return
            await self._spawn(child)
            if loop.time() >= next_report:
                self.say(f"started {n + 1} of {len(self.children)} node processes ...")
                next_report = loop.time() + self.wait_report_every
        self.supervisors = [asyncio.ensure_future(self._supervise(ch)) for ch in self.children.values()]

    async def _name_stalled(self, robots: list[str], t: float, end: bool = False) -> None:
        """The world has waited at ``t`` for ``robots``: ask their live nodes where they are
        (:data:`~cekm_swarm.node.process.STALL_SIGNAL`) and say each one's line, so a step
        that hangs is named, with the stacks in its log; or that none is in a step. ``end``:
        the wait passed ``--step-timeout``, so the run ends as failed with the first line."""
        asked = {}
        for child in self.children.values():
            if child.robot in robots and child.proc is not None and child.proc.returncode is None:
                try:
                    asked[child.label] = (child, child.log_path.stat().st_size)
                    child.proc.send_signal(STALL_SIGNAL)
                except (OSError, ProcessLookupError):
                    asked.pop(child.label, None)
        await asyncio.sleep(STALL_ANSWER_S)
        stepping = []
        for child, size in asked.values():
            try:
                with child.log_path.open("rb") as f:
                    f.seek(size)
                    lines = f.read().decode(errors="replace").splitlines()
            except OSError:
                continue
            said = [line[len(STALLED):].strip() for line in lines if line.startswith(STALLED)]
            where = next((lines[i - 1].strip() for i, line in enumerate(lines)
                          if i and "cekm_swarm/node/runner.py" in line and " in run" in line), None)
            for line in said:
                if "no step running" not in line:
                    line = line.replace("; its threads' stacks follow", f", at {where}" if where else "")
                    stepping.append(f"{line} (its threads' stacks: {child.log_path})")
        said = [f"the world waits at t={t:.2f} s: {line}" for line in stepping]
        if not stepping and asked:
            said.append(f"the world waits at t={t:.2f} s for {', '.join(robots)}: no node of "
                        f"{'it' if len(robots) == 1 else 'them'} is in a step, so each waits for an input that was "
                        f"never sent (see their logs in {self.c.out / 'logs'})")
        for line in said:
            self.say(line)
        if end and said and self.failure is None and not self.stopping:
            self.failure, self.failed_running = f"{said[0]}; --step-timeout {self.c.step_timeout:g} s passed", True
            self.say("the launch ends (--step-timeout)")
            self._interrupt_for_failure()

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
                self.failure, self.failed_running = self._own_line(child, STEP_FAILED, code), True
                self.say(f"node {child.label} failed: {self.failure}; the launch ends")
                self._interrupt_for_failure()
                return
            if self.c.mode == "lockstep" and self.session is not None:  # a robots-only host reads the clock too
                self.supervisors.append(asyncio.ensure_future(self._judge_death(child, code)))
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

    async def _judge_death(self, child: Child, code: int) -> None:
        """Lockstep: note the world's tick after ``child`` died (the world's next clock
        message: within a tick while it runs, at its next re-publishing while it waits);
        end the launch when :data:`SAME_TICK_RESTARTS` restarts in a row died at one tick.
        Runs beside the restart, which it does not delay."""
        tick = await self._world_tick()
        if tick is None or self.stopping:
            return
        if tick == child.died_at:
            child.same_tick += 1
        else:
            child.died_at, child.same_tick = tick, 0
        if child.same_tick < SAME_TICK_RESTARTS or self.failure is not None:
            return
        why = f"signal {-code}" if code < 0 else f"exit code {code}"
        self.failed_running = True
        self.failure = (f"{child.label}: died ({why}) at t={tick_time(tick):.3f} s (tick {tick}), and again after each "
                        f"of {child.same_tick} restarts, the world waiting at that tick; in lockstep the run cannot go "
                        f"on without its outputs (see {child.log_path})")
        self.say(f"node {child.label} keeps dying at tick {tick}; the launch ends")
        self._interrupt_for_failure()

    async def _world_tick(self) -> int | None:
        """The tick of the world's next clock message (None when none comes in time: the
        world ended, or its messages do not reach this launcher)."""

        try:
            with AsyncSubscription(self.session, self.keys.world_clock(), maxsize=1) as sub:
                rec = await sub.get(timeout=2 * self.c.republish + 1.0)
            return int(cast(Clock, decode(KeyKind.WORLD_CLOCK, rec.payload)).tick)
        except (TimeoutError, CekmError, ValueError, zenoh.ZError):
            return None

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
            with contextlib.suppress(ProcessLookupError):
                p.send_signal(signal.SIGTERM)
        if procs:
            _, pending = await asyncio.wait([asyncio.ensure_future(p.wait()) for p in procs], timeout=STOP_GRACE)
            for p in procs:
                if p.returncode is None:
                    with contextlib.suppress(ProcessLookupError):
                        p.kill()
            if pending:
                await asyncio.wait(pending, timeout=STOP_GRACE)
        await self._close_fork_server()

    async def _close_fork_server(self) -> None:
        if self.fork_server_start is not None:  # still starting: let it finish, then close it
            with contextlib.suppress(OSError):
                self.fork_server = await self.fork_server_start
            self.fork_server_start = None
        if self.fork_server is not None:
            await self.fork_server.close()

