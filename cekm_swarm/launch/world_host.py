"""The launcher's world server: start it (hosting the embedded router, or joining one) and
wait for its READY line, follow its progress lines, stop it, and when it dies make its log
a complete, indexed MCAP file again (the cut one is kept as ``run.truncated.mcap``)."""

from __future__ import annotations

import asyncio
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

from cekm_swarm.errors import CekmError
from cekm_swarm.runtime.mcap_log import recover_log
from cekm_swarm.runtime.mcap_read import file_complete
from cekm_swarm.runtime.mcap_sets import log_files

from .cpu import CpuSnapshot, snapshot
from .errors import LaunchError
from .processes import child_env, server_argv

ALIVE_TIMEOUT = 180.0
"""s the launcher (and the world) wait for every node to be alive before giving up."""


def port_hint(error_text: str, port: int) -> str:
    """A hint to add to an error that says the router's port is taken."""
    if "Address already in use" in error_text or "address in use" in error_text.lower():
        return f"; port {port} is taken (another run or program listens there): choose another with --port"
    return ""


STALL_REPORT_AFTER = 5
"""Re-publishings of one stalled lockstep tick (about a second apart) after which the
launcher asks the waited-for robots' nodes where they are."""
PROGRESS_ROBOTS = 12
"""Robots a progress line names one by one; a larger team's line ends with how many more
(``cekm monitor`` shows them all)."""


def format_progress(doc: dict[str, Any]) -> str:
    parts = [f"t={doc['t']:7.2f} s"]
    robots = list(doc["robots"].items())
    for r, s in robots[:PROGRESS_ROBOTS]:
        where = f"{r} ({s['x']:.2f}, {s['y']:.2f})"
        if s["reached"]:
            where += " reached"
        elif s.get("stopped"):
            where += " STOPPED"
        elif s.get("to_goal") is not None:  # a tracking robot has no goal: its position says it all
            where += f" {s['to_goal']:.2f} m to goal"
        parts.append(where)
    if len(robots) > PROGRESS_ROBOTS:
        parts.append(f"and {len(robots) - PROGRESS_ROBOTS} more robots")
    if doc.get("republished"):
        parts.append(f"republished {doc['republished']}")
    if doc.get("deadline_misses"):
        parts.append(f"deadline misses {doc['deadline_misses']}")
    return "  ".join(parts)


def format_event(doc: dict[str, Any]) -> str:
    """A world event as a person reads it: ``world event at t=3.07 s: deadman: r1 silent for
    0.52 s (limit 0.5 s), stopped`` (no Python dict, no epoch stamp)."""
    what, t = doc.get("event"), float(doc.get("t", 0.0))
    if what == "deadman":
        said = (f"{doc.get('robot')} silent for {doc.get('silent_s')} s (limit {doc.get('limit_s')} s), stopped "
                f"until its commands come again")
    elif what == "goal" and isinstance(doc.get("goal"), list) and len(doc["goal"]) == 2:  # a ROS 2 goal_pose
        said = f"{doc.get('robot')}'s goal is now ({float(doc['goal'][0]):.2f}, {float(doc['goal'][1]):.2f})"
    elif what == "republish":
        waiting = ", ".join(map(str, doc.get("waiting") or [])) or "nobody"
        said = f"waiting for {waiting}, the tick's readings sent again"
    else:
        said = ", ".join(f"{k} {', '.join(map(str, v)) if isinstance(v, list) else v}" for k, v in doc.items()
                         if k not in ("event", "t", "wall"))
    return f"world event at t={t:.2f} s: {what}" + (f": {said}" if said else "")


class WorldHost:
    """The world-server part of :class:`~cekm_swarm.launch.launcher.Launcher`."""

    world_proc: Any
    c: Any
    _stall: tuple[float, int] = (-1.0, 0)  # (the stalled tick's time, how many re-publishings of it)

    failure: str | None
    log_full: str | None
    # what it shares with the rest of the launcher (declared here, set and defined there)
    say: Callable[[str], None]
    _pids: Callable[[], dict[str, int]]
    _write_pids: Callable[[], None]
    spec_path: Path | None
    run_id: str | None
    interrupted: bool
    _cpu_start: CpuSnapshot | None
    _cpu_end: CpuSnapshot | None

    def _name_stalled(self, robots: list[str], t: float, end: bool = False) -> Any:  # pragma: no cover - the launcher's
        raise NotImplementedError

    def _note_stall(self, doc: dict[str, Any]) -> None:
        """A lockstep tick re-published (about once a second while the world waits): at the
        :data:`STALL_REPORT_AFTER`-th time for one tick, ask the waited-for robots' nodes
        where they are (:meth:`~.supervision.Supervision._name_stalled`); once it has waited
        ``--step-timeout`` s, ask again and end the run with that line."""
        t = float(doc["t"])
        count = self._stall[1] + 1 if self._stall[0] == t else 1
        self._stall = (t, count)
        timeout = self.c.step_timeout
        ends = timeout is not None and count * self.c.republish >= timeout and self.failure is None
        if (count == STALL_REPORT_AFTER or ends) and doc.get("waiting"):
            asyncio.ensure_future(self._name_stalled(list(doc["waiting"]), t, end=ends))

    async def _read_world(self, stream: asyncio.StreamReader) -> None:
        while True:
            line = await stream.readline()
            if not line:
                return
            text = line.decode(errors="replace").rstrip()
            kind, _, body = text.partition(" ")
            try:
                doc = json.loads(body) if body else {}
            except json.JSONDecodeError:
                doc = None
            if kind == "PROGRESS" and doc is not None:
                self.say(format_progress(doc))
            elif kind == "EVENT" and doc is not None:
                if doc.get("event") == "log_full":
                    self.log_full = f"{doc.get('log')}; the run stopped at t={doc['t']:.2f} s of sim time"
                self.say(format_event(doc))
                if doc.get("event") == "republish":
                    self._note_stall(doc)
            elif kind == "START" and doc is not None:
                self._cpu_start, self._cpu_end = snapshot(self._pids(), self._world_cpu(doc)), None
                self.say(f"world started ticking ({doc['mode']}, seed {doc['seed']})")
            elif kind == "DONE" and doc is not None:
                if self._cpu_start is not None and self._cpu_end is None:
                    self._cpu_end = snapshot(self._pids(), self._world_cpu(doc))
                self.say(f"world done at t={doc['sim_seconds']:.2f} s of sim time, "
                         f"{doc['wall_seconds']:.1f} s of wall time")
            elif text:
                self.say(f"world: {text}")

    def _world_cpu(self, doc: dict) -> dict[tuple[str, int], float]:
        """The world server's own CPU seconds from its START or DONE line (every thread's,
        ended ones too, when it wrote the line). Read from /proc when the launcher gets to
        the line, they would miss the threads that ended meanwhile, or all of a server
        that already exited."""
        cpu = doc.get("cpu_s")
        if self.world_proc is None or not isinstance(cpu, (int, float)) or cpu < 0:
            return {}
        return {("world/server", self.world_proc.pid): float(cpu)}

    async def _start_world(self, where: str, *, hosts_router: bool, checkpoints: Path | None) -> None:
        """Start the world server (hosting the router at ``where``, or joining it, waiting
        for that router as every networked command does) and wait for its READY line: its
        session is open, so modules can join. Returns early if interrupted meanwhile."""
        c = self.c
        if c.plant:  # robots in ROS 2: the plant process in the world's place (launch.plant_host)
            from .plant_host import plant_argv  # noqa: PLC0415 -- lazy: rosbags
        world_argv = plant_argv(self, where, hosts_router) if c.plant else server_argv(
            scenario=c.scenario, spec=self.spec_path, listen=where if hosts_router else None,
            connect=None if hosts_router else where,
            root=c.root, run_id=self.run_id, out=c.out, mode=c.mode, max_time=c.max_time, deadman=c.deadman,
            deadline_ticks=c.deadline_ticks, republish=c.republish, progress_every=c.progress_every,
            wait_modules=c.alive_timeout, seed=c.seed,
            zenoh_config=None if hosts_router else c.zenoh_config, checkpoints=checkpoints,
            max_log_size=c.max_log_size, max_log_duration=c.max_log_duration,
            record=None if c.record == "full" else c.record)
        log_path = c.out / "logs" / "world.log"
        with open(log_path, "ab") as werr:
            self.world_proc = await asyncio.create_subprocess_exec(
                *world_argv, stdout=asyncio.subprocess.PIPE, stderr=werr, stdin=asyncio.subprocess.DEVNULL,
                start_new_session=True, env=child_env())
        self._write_pids()
        assert self.world_proc.stdout is not None
        while True:
            line = await self.world_proc.stdout.readline()
            if not line:
                code = await self.world_proc.wait()
                if self.interrupted:  # Ctrl-C while the world waited for the router: it stopped waiting
                    return
                last = [x for x in log_path.read_text(errors="replace").splitlines() if x.strip()][-1:]
                hint = port_hint(last[0] if last else "", c.port) if hosts_router else ""
                raise LaunchError(f"the world server ended (code {code}) before its Zenoh session opened"
                                   f"{': ' + last[0] if last else ''} (see {log_path}){hint}")
            if line.startswith(b"READY "):
                return
            self.say(f"world: {line.decode(errors='replace').rstrip()}")

    def _world_died(self, code: int) -> None:
        """The world server ended abnormally (killed, crashed): say so, and make ``run.mcap``
        a complete, indexed log again if the world could not close it (the cut file is kept
        as ``run.truncated.mcap``). The run ends: nothing else can tick the world."""
        c = self.c
        why = f"was killed by signal {-code}" if code < 0 else f"ended with exit code {code}"
        self.say(f"the world server {why}; the run ends (see {c.out / 'logs' / 'world.log'})")

        try:  # run.mcap, or each file of a log set (run_0.mcap, ...): the world had one open
            paths = log_files(c.out / "run.mcap") if (c.out / "run.mcap").is_file() else \
                log_files(c.out / "run_0.mcap") if (c.out / "run_0.mcap").is_file() else []
            for log_path in paths:
                if file_complete(log_path):
                    continue
                cut = log_path.with_name(log_path.name[:-5] + ".truncated.mcap")
                log_path.replace(cut)
                rep = recover_log(cut, log_path)
                self.say(f"recovered the world's log: {rep.messages} messages on {rep.channels} channels into "
                         f"{log_path} ({cut.name} is the file as the world left it)")
        except (CekmError, OSError) as exc:
            self.say(f"could not recover the world's log: {exc}")

    def _world_ended(self) -> bool:
        return self.world_proc is not None and self.world_proc.returncode is not None
