"""The launcher: the world server, then per robot every node of the controller's graph
(cekm: 1 + 12 + 1), all separate OS processes, supervised.

Order: the world server starts first. With the embedded default (no ``--connect``) it
hosts the Zenoh router on loopback, so the world's readings and the robots' commands
cross no extra process; with ``--connect`` it joins that router. Once its session is
open (a READY line) every module starts, and the world holds tick 0 until every module's
liveliness token is up (so no tick is published before the modules listen). A robots-only
host (``--no-world``) without ``--connect`` opens an embedded router of its own. A module
that dies is restarted with back-off (0.25 s, doubling while it keeps dying within 5 s of
starting, at most 5 s), which the log shows. When the world server ends (every robot at
its goal, max time) or on SIGINT/SIGTERM everything stops: the world server first (it
writes its outcome and closes the log), then the modules (SIGTERM, SIGKILL after 5 s).

Run isolation: every run has a run id (made by the world host's launcher, printed, and
taken from the world server's token by a robots-only host unless given with
``--run-id``); every liveliness token carries it, so the world counts only its own run's
modules. Every child dies with the launcher, whatever kills it (``PR_SET_PDEATHSIG``,
:mod:`cekm_swarm.runtime.lifetime`).

Warm start: the nodes are forked from a fork server that has imported them
(:mod:`.forkserver`), each still its own process; ``--cold-start`` execs each afresh.

Each child's output goes to ``OUT/logs/<robot>-<module>.log`` (``world.log`` for the
world server, ``forkserver.log`` for the fork server); ``OUT/pids.json`` holds the live process
ids; ``OUT/launch.log`` the launcher's own record; ``outcome.json`` gets the run id and the
launcher's record.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import signal
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TextIO

from cekm_swarm.experiments.graph_run import default_max_time
from cekm_swarm.experiments.navigation_run import planned_checkpoints
from cekm_swarm.protocol import DEFAULT_ROOT, KeySpace
from cekm_swarm.runtime.bridge import LivelinessWatcher
from cekm_swarm.runtime.config import DEFAULT_HOST, DEFAULT_PORT, open_embedded_router
from cekm_swarm.runtime.errors import RuntimeTransportError
from cekm_swarm.runtime.model_service import ZENOH_MODEL, ModelServer
from cekm_swarm.runtime.wait import open_client_when_ready
from cekm_swarm.ticks import STEP_TIMEOUT, tick_of
from world import load_scenario

from .cpu import CpuSnapshot, cpu_per_tick
from .errors import LaunchError, NodeCannotStart, NodeFailed
from .plot import draw_trajectory
from .prepare import PreflightError, body_of, plan_of, preflight, resolve, run_spec
from .processes import new_run_id
from .reports import missing_by_robot, node_summary, notable, read_reports, reproducible, summary_lines
from .robot_host import RobotHost
from .supervision import Child, Supervision
from .world_host import ALIVE_TIMEOUT, WorldHost, port_hint


@dataclass
class LaunchConfig:
    scenario: str
    out: Path
    mode: str = "realtime"
    seed: int | None = None
    connect: str | None = None
    port: int = DEFAULT_PORT
    model: Path | None = None
    max_time: float | None = None  # None: the task's default (cekm_swarm.experiments.graph_run.DEFAULT_MAX_TIME)
    controller: str = "cekm"  # a controller's shipped graph (--controller)
    graph: Path | None = None  # or a graph file of the user's own (--graph)
    params: dict | None = None  # parameter overrides for the graph's nodes
    root: str = DEFAULT_ROOT
    deadman: float = 0.5
    deadline_ticks: int = 0  # real time: ticks a command may lag its tick before it is a miss
    republish: float = 1.0
    plot: bool = True
    progress_every: float = 1.0
    robots: tuple[str, ...] | None = None  # whose module processes start here (None: every robot)
    world: bool = True  # start the world server here
    listen_host: str = DEFAULT_HOST  # the embedded router's address (0.0.0.0 to serve other hosts)
    zenoh_config: Path | None = None  # client config file (credentials, TLS) for every process started here
    model_from_zenoh: bool = False  # modules fetch the model from the world host's launcher (no file here)
    run_id: str | None = None  # the run's id (None: made by a world host, learned from the world by a robots-only host)
    warm_start: bool = True  # fork the nodes from a fork server (launch.forkserver); False: exec each afresh
    hold_readings: bool = True  # the world leaves unchanged readings out (graph.plan.RunPlan.held_readings)
    max_log_size: int | None = None  # split the world's log into a set (bytes per file)
    max_log_duration: float | None = None  # ... or sim s per file
    record: str = "full"  # full, or lean (world.recorder)
    world_grace: float = 0.0  # robots-only host: s to wait for a world whose token went without its end (a cut)
    alive_timeout: float = ALIVE_TIMEOUT  # s to wait for every node of every robot to be alive
    plant: str | None = None  # "ros2": the robots live in ROS 2, no world is simulated (launch.plant_host)
    plant_domain: int = 0  # ... its ROS_DOMAIN_ID
    plant_distro: str = "jazzy"  # ... its ROS 2 distribution
    robot_description: Path | None = None  # ... its robot description file (default: the scenario's body)
    step_timeout: float | None = STEP_TIMEOUT  # lockstep: s a tick may wait on a hung step before the run fails


def _close(thing: Any) -> None:
    """``thing.close()``, for a part of the launch that may not have been made."""
    if thing is not None:
        thing.close()


class Launcher(Supervision, WorldHost, RobotHost):
    """A launch: its steps here, the supervision of its nodes (:mod:`.supervision`), its
    world server (:mod:`.world_host`) and a robots-only host's side (:mod:`.robot_host`)."""

    def __init__(self, config: LaunchConfig, echo: Callable[[str], None] = print) -> None:
        self.c = config
        self.echo = echo
        self.keys = KeySpace(config.root)
        self.children: dict[str, Child] = {}
        self.stopping = False
        self.world_proc: asyncio.subprocess.Process | None = None
        self.interrupted = False
        self._stop_waiting = threading.Event()  # set by Ctrl-C: a wait for the router ends at once
        self._log: TextIO | None = None
        self.startup_s: float | None = None
        self.run_id: str | None = None
        self.all_robots: list[str] = []
        self.router: Any = None  # a robots-only host's embedded router
        self.session: Any = None
        self.model_server: ModelServer | None = None
        self.watcher: LivelinessWatcher | None = None
        self.world_reader: asyncio.Future | None = None
        self.supervisors: list[asyncio.Future] = []
        self._cpu_start: CpuSnapshot | None = None  # when the world starts ticking
        self._cpu_end: CpuSnapshot | None = None  # when it is done
        self.checked: Any = None  # the controller's graph, checked (cekm_swarm.node.graph_check)
        self.plan: Any = None  # ... resolved for the team
        self.spec_path: Path | None = None
        self.failed_running = False  # the failure is a step's that failed or hung (exit 1), not a start's
        self.failure: str | None = None  # a node that cannot start: the launch ends with its line
        self.log_full: str | None = None  # the world's log filled its disk: the launch ends with this line

    # ------------------------------------------------------------------ logging

    def say(self, text: str) -> None:
        line = f"[{time.strftime('%H:%M:%S')}] {text}"
        self.echo(line)
        if self._log is not None:
            try:
                self._log.write(line + "\n")
                self._log.flush()
            except OSError as exc:  # a full disk: the terminal still has every line
                self._log = None
                self.echo(f"[{time.strftime('%H:%M:%S')}] cannot write {self.c.out / 'launch.log'} any more: "
                          f"{exc.strerror or exc}")

    # ------------------------------------------------------------------ world

    # ------------------------------------------------------------------ main

    async def run(self) -> dict[str, Any]:
        """The launch, as a sequence of named steps; :meth:`_teardown` runs whatever
        happens after the first process could have started."""
        self._open_out()
        try:
            self._catch_signals()
            scenario, robots = self._resolve_robots()
            self._resolve_graph(scenario)
            model = self._resolve_model()
            self._preflight(model)
            checkpoints = self._plan_checkpoints(scenario)
            endpoint = self._pick_endpoint()
            try:
                await self._bring_up(scenario, robots, model, checkpoints, endpoint)
            finally:
                await self._teardown()
            if self.failure is not None:  # the world's outcome (if any) still gets the launcher's record
                self._finish_outcome(failure=str(self.failure))
                raise (NodeFailed if self.failed_running else NodeCannotStart)(self.failure)
            outcome = self._finish_outcome()
            self._plot(scenario, outcome)
            return outcome
        finally:
            if self._log is not None:
                log, self._log = self._log, None  # a signal handled after this writes to the terminal only
                with contextlib.suppress(OSError):
                    log.close()

    # ------------------------------------------------------------------ steps

    def _open_out(self) -> None:
        """The output directory, its ``logs/`` and the launcher's own record."""
        self.c.out.mkdir(parents=True, exist_ok=True)
        (self.c.out / "logs").mkdir(exist_ok=True)
        self._log = open(self.c.out / "launch.log", "a")  # noqa: SIM115 -- open for the launch, closed in launch()

    def _catch_signals(self) -> None:
        loop = asyncio.get_running_loop()
        for sig in (signal.SIGTERM, signal.SIGINT):
            with contextlib.suppress(NotImplementedError, RuntimeError):  # pragma: no cover - not on Linux
                loop.add_signal_handler(sig, self._interrupt)

    def _resolve_robots(self) -> tuple[Any, list[str]]:
        """The scenario, and the robots whose modules start here (ValueError: an unknown one)."""
        c = self.c
        scenario = load_scenario(c.scenario)
        self.all_robots = [r.id for r in scenario.robots]
        unknown = sorted(set(c.robots or ()) - set(self.all_robots))
        if unknown:
            raise ValueError(f"{c.scenario}: no robot {', '.join(unknown)} (robots: {', '.join(self.all_robots)})")
        return scenario, [r for r in self.all_robots if c.robots is None or r in c.robots]

    def _resolve_graph(self, scenario) -> None:
        """The controller's graph, checked and resolved for the team (GraphError: refused now)."""
        c = self.c
        self.checked, self.task = resolve(scenario, c.controller, c.graph, c.params)
        self.body = body_of(scenario)
        if c.plant:  # a ROS 2 robot: its declared body, refused when the model was trained for another
            from .plant_host import plant_description  # noqa: PLC0415 -- lazy: rosbags

            self.plant_desc = plant_description(scenario, c.robot_description, self.body, self.checked.uses_model,
                                                self.task)
            self.body = self.plant_desc.body
        self.plan = plan_of(self.checked, tuple(self.all_robots), self.task, self.body, c.root)
        for w in self.plan.warnings:
            self.say(f"warning: {w}")
        if c.max_time is None:
            c.max_time = default_max_time(self.task)

    def _preflight(self, model) -> None:
        """One node of every kind built here: a bad model or parameter is refused before
        any process starts (a robot host fetching the model checks it when it has it)."""
        if model == ZENOH_MODEL:
            return
        try:
            preflight(self.checked, self.plan, self.body, None if model is None else str(model))
        except PreflightError as exc:  # the one line is the command's; the traceback goes to launch.log
            if exc.trace and self._log is not None:
                self._log.write(f"{exc}\n{exc.trace}")
                self._log.flush()
            raise

    def _write_spec(self, model, endpoint: str) -> Path:
        """``OUT/run-spec.json``: what every process of this launch reads."""
        c = self.c
        zenoh_config = None if c.zenoh_config is None else str(c.zenoh_config)
        spec = run_spec(self.checked, tuple(self.all_robots), self.task, self.body, root=c.root, run_id=self.run_id,
                        mode=c.mode, connect=endpoint, zenoh_config=zenoh_config,
                        model=None if model is None else str(model), hold_readings=c.hold_readings)
        self.spec_path = spec.write(c.out / "run-spec.json")
        return self.spec_path

    def _resolve_model(self) -> Path | str | None:
        """The model file the modules load, or ``"zenoh"`` (a robot host fetching it); None
        when no node of the graph reads a model."""
        c = self.c
        if not self.checked.uses_model:
            return None
        if c.model is not None:
            return c.model
        if c.model_from_zenoh and not c.world:
            return ZENOH_MODEL  # a robot host: the world host's launcher serves the model
        from cekm_swarm.experiments.default_model import default_model, default_model_path  # noqa: PLC0415 -- lazy: scipy

        default_model()
        return default_model_path()

    def _plan_checkpoints(self, scenario) -> Path | None:
        """Checkpoints on the known walls (Fig. 12) for a ``plan_checkpoints`` scenario, as a file."""
        if not scenario.plan_checkpoints:
            return None

        path = self.c.out / "checkpoints.json"
        path.write_text(json.dumps(planned_checkpoints(scenario)))
        return path

    def _pick_endpoint(self) -> str:
        """Where every process started here connects; a robots-only host without
        ``--connect`` opens an embedded router of its own."""
        c = self.c
        if c.connect:
            return c.connect
        endpoint = f"tcp/{self._local_host}:{c.port}"
        if not self._world_hosts_router:
            try:
                self.router = open_embedded_router(c.port, c.listen_host)
            except RuntimeTransportError as exc:
                raise LaunchError(f"{exc}{port_hint(str(exc), c.port)}") from None
            self.say(f"embedded Zenoh router on {endpoint}")
        return endpoint

    @property
    def _world_hosts_router(self) -> bool:
        return self.c.world and not self.c.connect

    @property
    def _local_host(self) -> str:
        return DEFAULT_HOST if self.c.listen_host in ("0.0.0.0", "::") else self.c.listen_host

    async def _bring_up(self, scenario, robots: list[str], model: Path | str | None, checkpoints: Path | None,
                        endpoint: str) -> None:
        """Start everything, wait for the modules, then follow the run to its end."""
        c = self.c
        t0 = time.monotonic()
        if c.world:
            self._choose_run_id()
            self._begin_fork_server(self._write_spec(model, endpoint))
            # The world first: with the embedded default it hosts the router, and it holds
            # tick 0 until every module of every robot, here or on other hosts, is alive.
            await self._start_world(f"tcp/{c.listen_host}:{c.port}" if self._world_hosts_router else endpoint,
                                    hosts_router=self._world_hosts_router, checkpoints=checkpoints)
            if self.interrupted:
                return
            assert self.world_proc is not None and self.world_proc.stdout is not None  # _start_world started it
            self.world_reader = asyncio.ensure_future(self._read_world(self.world_proc.stdout))
            if self._world_hosts_router:
                also = "" if self._local_host == c.listen_host else f" (listening on tcp/{c.listen_host}:{c.port})"
                self.say(f"the world server hosts the embedded Zenoh router on {endpoint}{also}")
        # a robot host may start first: wait for the router in a thread, so Ctrl-C ends the wait at once
        try:
            self.session = await asyncio.to_thread(open_client_when_ready, endpoint, c.zenoh_config, say=self.say,
                                                   stop=self._stop_waiting)
        except RuntimeTransportError:
            if self.interrupted:
                return
            raise
        if self.interrupted:
            return
        if not c.world:
            await self._join_run_id()
            if self.stopping:
                return
            self._begin_fork_server(self._write_spec(ZENOH_MODEL if c.model_from_zenoh else model, endpoint))
        if c.world and model is not None:  # (a world host always has the model file)
            self.model_server = ModelServer(self.session, self.keys.world_model(), model)
            self.say(f"serving the model {Path(model).name} on {self.keys.world_model()}")
        self.watcher = LivelinessWatcher(self.session, self.keys.alive_all())
        await self._spawn_modules(scenario, robots, ZENOH_MODEL if c.model_from_zenoh else model, endpoint)
        # the world starts only when every module of every robot is up, here or on other hosts
        expected = (self.plan_tokens(self.all_robots) if c.world else
                    {self.keys.alive(ch.robot, ch.name) for ch in self.children.values()})
        if not await self._wait_alive(expected):
            return
        self.startup_s = round(time.monotonic() - t0, 3)
        if not c.world:
            await self._serve_until_world_ends(self.watcher, len(expected), self.session)
            return
        if expected <= self.watcher.alive:
            self.say(f"all {len(expected)} modules alive after {self.startup_s:.1f} s; the world starts")
        assert self.world_reader is not None and self.world_proc is not None  # a world host's, started above
        await self.world_reader
        code = await self.world_proc.wait()
        if code not in (0, 3, 4):  # 4: the log's disk filled, the world closed the log and ended the run
            self._world_died(code)

    def plan_tokens(self, robots) -> set[str]:
        """The liveliness tokens of every node of ``robots`` in this run."""
        return {self.keys.alive(r, n.name) for r in robots for n in self.plan.nodes[r]}

    def _choose_run_id(self) -> None:
        """The run's id (given, or made here): every token of the run carries it."""
        self.run_id = self.c.run_id or new_run_id()
        self.keys = self.keys.with_run(self.run_id)
        self.say(f"run id {self.run_id}")

    wait_report_every = 5.0  # s between two "started ..." or "waiting for ..." lines while nodes come up

    async def _wait_alive(self, expected: set[str]) -> bool:
        """Until every token of ``expected`` is alive, saying every :attr:`wait_report_every`
        s which robots it still waits for; False when stopped. A world host gives the world
        server the first word on a timeout (it records the missing nodes as the reason the
        run stopped); either way the launch ends with one line naming the missing robots."""
        loop = asyncio.get_running_loop()
        timeout = self.c.alive_timeout
        t0 = loop.time()
        deadline = t0 + timeout + (5.0 if self.c.world else 0.0)
        next_report = loop.time() + self.wait_report_every
        watcher = self.watcher
        assert watcher is not None  # made before the modules are spawned
        while not expected <= watcher.alive and not self.stopping and not self._world_ended():
            try:
                await watcher.next_event(timeout=max(0.1, min(1.0, deadline - loop.time())))
            except TimeoutError:
                if loop.time() > deadline:
                    break
            if loop.time() >= next_report and not expected <= watcher.alive:
                self.say(f"waiting for {missing_by_robot(self.keys, self.plan, expected - watcher.alive)} ...")
                next_report = loop.time() + self.wait_report_every
        missing = expected - watcher.alive
        if missing and not self.stopping and loop.time() - t0 >= timeout - 0.5:  # (not a world that crashed)
            if self._world_ended() and self.world_reader is not None:
                await self.world_reader  # its last lines (the missing nodes, its outcome) come first
            raise LaunchError(f"not alive after {timeout:.0f} s: {missing_by_robot(self.keys, self.plan, missing)}; "
                              f"is every robot host started (cekm launch --no-world --robots ...)?")
        return not self.stopping

    async def _teardown(self) -> None:
        """Stop and close everything this launcher started, in order: the world server
        first (it writes its outcome and closes the log), then the modules, then the
        Zenoh objects. Every step runs even if one before it failed."""
        self.stopping = True
        steps: list[tuple[str, Callable[[], Any]]] = [
            ("stop the world server", self._stop_world),
            ("stop the modules", self._stop_children),
            ("cancel the supervisors", lambda: [t.cancel() for t in self.supervisors]),
            ("stop reading the world", lambda: self.world_reader is not None and self.world_reader.cancel()),
            ("close the liveliness watcher", lambda: _close(self.watcher)),
            ("close the model server", lambda: _close(self.model_server)),
            ("close the Zenoh session", lambda: self.session is not None and self.session.close()),
            ("close the embedded router", lambda: self.router is not None and self.router.close()),
        ]
        for what, step in steps:
            try:
                result = step()
                if asyncio.iscoroutine(result):
                    await result
            except Exception as exc:  # noqa: BLE001 - the rest of the teardown must still run
                self.say(f"could not {what}: {type(exc).__name__}: {exc}")
        self.say("all processes stopped")

    async def _stop_world(self) -> None:
        if self.world_proc is not None and self.world_proc.returncode is None:
            self.world_proc.send_signal(signal.SIGTERM)
            try:
                await asyncio.wait_for(self.world_proc.wait(), 15.0)
            except TimeoutError:
                self.world_proc.kill()

    def _finish_outcome(self, failure: str | None = None) -> dict[str, Any]:
        """The world's ``outcome.json`` with the launcher's record added ({} without one);
        ``failure``: the node failure that ended the launch."""
        outcome_path = self.c.out / "outcome.json"
        try:
            outcome = json.loads(outcome_path.read_text())
        except (OSError, ValueError):  # none, or a half one (a full disk)
            return {}
        outcome["run_id"] = self.run_id
        outcome["launcher"] = {
            "modules": len(self.children), "interrupted": self.interrupted,
            "restarts": {ch.label: ch.restarts for ch in self.children.values() if ch.restarts},
            "exits": {ch.label: ch.exits for ch in self.children.values() if ch.exits},
            "startup_s": self.startup_s, **({"failure": failure} if failure else {})}
        summaries = {label: node_summary(read_reports(ch.log_path)) for label, ch in self.children.items()}
        for line in summary_lines(summaries, {label: ch.log_path for label, ch in self.children.items()}):
            self.say(line)
        outcome["launcher"]["nodes"] = notable(summaries)  # nodes that failed, skipped runs or dropped messages
        if self.c.mode == "lockstep":
            outcome["reproducible"] = reproducible(self.children.values(), bool(outcome.get("aborted")), summaries)
        if self._cpu_start is not None and self._cpu_end is not None:  # where the tick loop's CPU went
            robots = len({ch.robot for ch in self.children.values()})
            ticks = tick_of(float(outcome.get("sim_seconds", 0.0)))
            outcome["launcher"]["cpu"] = cpu_per_tick(self._cpu_start, self._cpu_end, ticks, robots)
        try:
            outcome_path.write_text(json.dumps(outcome, indent=1))
        except OSError as exc:  # a full disk: the world's outcome.json stays as it wrote it
            self.say(f"cannot add the launcher's record to {outcome_path}: {exc.strerror or exc}")
        return outcome

    def _plot(self, scenario, outcome: dict[str, Any]) -> None:
        if self.c.plot:
            why = draw_trajectory(self.c.out, f"{scenario.name} ({self.c.mode}, seed {outcome.get('seed')})", outcome)
            if why is not None:
                self.say(f"could not draw trajectory.png: {why}")

    def launch(self) -> dict[str, Any]:
        """Run the launch to the end in a new event loop (from the main thread: children
        die with the thread that started them)."""
        return asyncio.run(self.run())

    def _interrupt(self) -> None:
        if self.interrupted:
            return
        self.interrupted = True
        self._stop_waiting.set()
        self.say("interrupted: stopping")
        if self.world_proc is not None and self.world_proc.returncode is None:
            self.world_proc.send_signal(signal.SIGTERM)  # writes its outcome; the rest stops after it
        else:
            self.stopping = True
            for ch in self.children.values():
                if ch.proc is not None and ch.proc.returncode is None:
                    ch.proc.send_signal(signal.SIGTERM)


def launch(config: LaunchConfig, echo: Callable[[str], None] = print) -> dict[str, Any]:
    """Run a launch to the end; the outcome (``outcome.json`` plus the launcher's record)."""
    return Launcher(config, echo).launch()
