"""Restarts around a delayed input of the robot's own graph, and a node that dies at the
same tick every time.

A graph whose node reads, with ``delay = 1``, another node of its robot (``drive`` reads
``loop/echo``, which ``echo`` copies from ``drive``'s command) or its own previous output
(``drive`` reads ``cmd/wheels``). A lockstep launch hung for good when such a node, or the
producer of its delayed input, was SIGKILLed and restarted: only teammates' delayed
readers were sent the recent outputs again when their tokens appeared, so the restarted
node never got the value of the tick before, and the world re-published the stalled tick
forever. Now every reader's (re)appearing token makes the producer send its recent
outputs again (``NodeShell.readers``, ``LockstepGate.resend``), so the run completes and
equals ``cekm run``; a node that reads its own previous output cannot get it back, so it
starts without it (as at tick 0) and ``outcome.json`` says the run may no longer equal
``cekm run``.

A node that dies at the same tick every time (``os._exit(3)`` in its step) was restarted
forever in lockstep; now the launch ends after ``SAME_TICK_RESTARTS`` restarts died there,
with one line naming the node, its exit code and the tick. Real time keeps restarting.

The fast tests drive the gates without Zenoh; the slow ones run ``cekm launch`` with real
processes on a free loopback port (multicast scouting off) and wait on its output lines.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import threading
from pathlib import Path

import pytest

from helpers.launch import LaunchProcess

MODULES = '''
import math
import os
from dataclasses import dataclass

from cekm_swarm.node import In, Node, Out
from cekm_swarm.protocol import SenseTarget, WheelCommand


class Drive(Node):
    """Steers toward the target reading, weaving, blended with the previous command it hears back."""

    inputs = {"reading": In(SenseTarget), "prev": In(WheelCommand)}
    outputs = {"command": Out(WheelCommand)}

    def step(self, t, inputs):
        r, p = inputs["reading"], inputs["prev"]
        turn = (0.0 if r is None else 0.01 * r.alpha) + 0.012 * math.sin(0.9 * t)
        vl, vr = 0.03 - turn, 0.03 + turn
        if p is not None:
            vl, vr = 0.6 * vl + 0.4 * p.v_l, 0.6 * vr + 0.4 * p.v_r
        return {"command": WheelCommand(t, self.ctx.sender, vl, vr, 0)}


class Echo(Node):
    """Copies the command to a key of its own."""

    inputs = {"command": In(WheelCommand)}
    outputs = {"copy": Out(WheelCommand)}

    def step(self, t, inputs):
        c = inputs["command"]
        return {"copy": WheelCommand(t, self.ctx.sender, c.v_l, c.v_r, c.seq)}


class Exits(Node):
    """Drives straight; its process dies at its first step from t >= at (a crash in a C extension)."""

    inputs = {"reading": In(SenseTarget)}
    outputs = {"command": Out(WheelCommand)}

    @dataclass(frozen=True)
    class Params:
        at: float = 0.5

    def step(self, t, inputs):
        if t >= self.params.at:
            os._exit(3)
        return {"command": WheelCommand(t, self.ctx.sender, 0.05, 0.05, 0)}


class Hangs(Node):
    """Drives straight; its step from t >= 0.5 s never returns (a deadlock in a user's code)."""

    inputs = {"reading": In(SenseTarget)}
    outputs = {"command": Out(WheelCommand)}

    def step(self, t, inputs):
        if t >= 0.5:
            import time
            time.sleep(3600)
        return {"command": WheelCommand(t, self.ctx.sender, 0.05, 0.05, 0)}
'''

SCENARIO = '''
# open ground: the robot weaves after a target that circles, and hits nothing
name = "open"
seed = 5
[arena]
bounds = [0.0, 0.0, 3.0, 3.0]
[[robots]]
id = "r1"
start = [1.0, 1.5, 0.3]
goal = "mover"
[[targets]]
id = "mover"
motion = { type = "circle", center = [2.2, 1.5], radius = 0.4, angular_speed = 0.1 }
'''

HEAD = '''
[graph]
controller = "{name}"
task = "navigation"
answer = "cmd/wheels"
'''

GRAPHS = {
    # drive reads echo's copy of its command of the tick before
    "echo-loop": HEAD + '''
[[node]]
name = "drive"
program = "mine:Drive"
every = 1
inputs = { reading = "sense/target", prev = { key = "loop/echo", delay = 1 } }
outputs = { command = "cmd/wheels" }

[[node]]
name = "echo"
program = "mine:Echo"
every = 1
inputs = { command = "cmd/wheels" }
outputs = { copy = "loop/echo" }
''',
    # drive reads its own command of the tick before
    "self-loop": HEAD + '''
[[node]]
name = "drive"
program = "mine:Drive"
every = 1
inputs = { reading = "sense/target", prev = { key = "cmd/wheels", delay = 1 } }
outputs = { command = "cmd/wheels" }
''',
    "hangs": HEAD + '''
[[node]]
name = "drive"
program = "mine:Hangs"
every = 1
inputs = { reading = "sense/target" }
outputs = { command = "cmd/wheels" }
''',
    "exits": HEAD + '''
[[node]]
name = "drive"
program = "mine:Exits"
every = 1
inputs = { reading = "sense/target" }
outputs = { command = "cmd/wheels" }
''',
}


def graph(folder: Path, name: str) -> Path:
    (folder / "mine.py").write_text(textwrap.dedent(MODULES))
    (folder / "open.toml").write_text(SCENARIO)
    path = folder / f"{name}.toml"
    path.write_text(GRAPHS[name].replace("{name}", name))
    return path


# ---------------------------------------------------------------- the gates, without Zenoh


def plan_of(folder: Path, name: str):
    from cekm_swarm.node.graph_check import check_graph

    checked = check_graph(str(graph(folder, name)))
    plan = checked.plan(("r1",), "navigation")
    plan.checked = checked
    return plan


def gate_of(plan, node: str):
    """The gate the node's process would take, around a real instance of its class."""
    from cekm_swarm.node.api import Context
    from cekm_swarm.node.direct_gate import DirectGate
    from cekm_swarm.node.runner import Runner
    from cekm_swarm.node.timing import LockstepGate

    np_ = plan.node("r1", node)
    checked = plan.checked
    runner = Runner(np_, checked.classes[node](Context("r1", node, mode="lockstep"), checked.make_params(node)))
    return (DirectGate if DirectGate.fits(np_) else LockstepGate)(runner)


def target(k: int):
    from cekm_swarm.protocol import DEFAULT_KEYS as K
    from cekm_swarm.protocol import SenseTarget
    from cekm_swarm.ticks import tick_time

    return K.sense_target("r1"), SenseTarget(tick_time(k), "world", 0.5, 0.1, True)


def test_readers_of_a_nodes_outputs_are_every_other_node_that_reads_them(tmp_path):
    from cekm_swarm.node.process import outputs_readers
    from cekm_swarm.protocol import DEFAULT_KEYS as K

    plan = plan_of(tmp_path, "echo-loop")
    drive, echo = plan.node("r1", "drive"), plan.node("r1", "echo")
    assert outputs_readers(plan, drive, K) == {K.alive("r1", "echo"): frozenset({K.cmd_wheels("r1")})}
    assert outputs_readers(plan, echo, K) == {K.alive("r1", "drive"): frozenset({K.node_key("r1", "loop/echo")})}
    selfloop = plan_of(tmp_path, "self-loop")
    assert outputs_readers(selfloop, selfloop.node("r1", "drive"), K) == {}  # itself is no reader to send to


def test_only_a_nodes_own_previous_output_and_delayed_world_readings_are_lost_on_restart(tmp_path):
    from cekm_swarm.node.timing import lost_on_restart
    from cekm_swarm.protocol import DEFAULT_KEYS as K

    plan = plan_of(tmp_path, "echo-loop")
    assert lost_on_restart(plan.node("r1", "drive")) == frozenset()  # echo sends its recent copies again
    assert lost_on_restart(plan.node("r1", "echo")) == frozenset()
    selfloop = plan_of(tmp_path, "self-loop")
    assert lost_on_restart(selfloop.node("r1", "drive")) == {K.cmd_wheels("r1")}


def test_a_producer_sends_its_recent_outputs_again_on_the_keys_a_reader_reads(tmp_path):
    from cekm_swarm.protocol import DEFAULT_KEYS as K

    plan = plan_of(tmp_path, "echo-loop")
    drive, echo = gate_of(plan, "drive"), gate_of(plan, "echo")
    out = drive.put(*target(0))
    assert [m.stamp for _, m in out] == [0.0]
    for k in range(1, 7):  # echo's copy of tick k-1, then tick k's reading
        copies = echo.put(*out[0])
        assert [key for key, _ in copies] == [K.node_key("r1", "loop/echo")]
        drive.put(*copies[0])
        out = drive.put(*target(k))
        assert [tick for tick in (round(m.stamp / 0.128) for _, m in out)] == [k]
    again = drive.resend(frozenset({K.cmd_wheels("r1")}))
    assert [round(m.stamp / 0.128) for _, m in again] == [3, 4, 5, 6]  # the last runs, oldest first
    assert drive.resend(frozenset({"cekm/r1/other"})) == []
    assert [round(m.stamp / 0.128) for _, m in echo.resend()] == [2, 3, 4, 5]  # a pure node of one key too


def test_a_restarted_node_that_reads_its_own_previous_output_runs_without_it(tmp_path):
    plan = plan_of(tmp_path, "self-loop")
    fresh = gate_of(plan, "drive")
    (first,) = fresh.put(*target(40))  # a restart at tick 40: its command of tick 39 is gone for good
    assert first[1].stamp == pytest.approx(40 * 0.128) and fresh.born == 40
    assert fresh.put(*target(41)) == []  # tick 41 waits for its own command of tick 40, as always
    (second,) = fresh.put(*first)
    assert second[1].stamp == pytest.approx(41 * 0.128)


def test_a_restarted_node_gives_up_a_delayed_value_whose_producer_restarted_too(tmp_path):
    """drive and echo restarted together: echo has no copy of the tick before to send
    again, and waits for drive's command. drive runs once the world has re-published the
    stalled tick (its reading comes again), without echo's copy, and names it."""
    from cekm_swarm.protocol import DEFAULT_KEYS as K

    plan = plan_of(tmp_path, "echo-loop")
    fresh = gate_of(plan, "drive")
    assert fresh.put(*target(40)) == []  # waits for echo's copy of tick 39: the resend it normally gets
    (first,) = fresh.put(*target(40))  # the stalled tick re-published: nobody has that copy
    assert first[1].stamp == pytest.approx(40 * 0.128) and fresh.born == 40
    assert fresh.ran_without == (K.node_key("r1", "loop/echo"),)
    assert fresh.put(*target(41)) == []  # later ticks wait for echo's copies as always
    normal = gate_of(plan, "drive")
    assert [m.stamp for _, m in normal.put(*target(0))] == [0.0] and normal.ran_without == ()


def test_a_restarted_node_gives_up_at_a_later_tick_too_and_a_node_started_at_tick_0_never_does(tmp_path):
    """Restarts in waves: a restarted node's second run may need a value its producer's
    previous life sent before this node came back; a process that started with the run
    waits as always, however often a tick comes again."""
    from cekm_swarm.protocol import DEFAULT_KEYS as K
    from cekm_swarm.protocol import WheelCommand
    from cekm_swarm.ticks import tick_time

    echo_key = K.node_key("r1", "loop/echo")
    plan = plan_of(tmp_path, "echo-loop")
    fresh = gate_of(plan, "drive")
    assert fresh.put(*target(40)) == []
    fresh.put(echo_key, WheelCommand(tick_time(39), "r1/echo", 0.01, 0.01, 0))  # the catch-up came: no give-up
    assert fresh.born == 40 and fresh.ran_without == ()
    assert fresh.put(*target(41)) == []  # echo's copy of 40 was sent by echo's previous life
    (late,) = fresh.put(*target(41))  # tick 41 re-published: not coming
    assert late[1].stamp == pytest.approx(41 * 0.128) and fresh.ran_without == (echo_key,)
    original = gate_of(plan, "drive")
    original.put(*target(0))
    assert original.put(*target(1)) == [] and original.put(*target(1)) == [] and original.ran_without == ()


def test_a_run_whose_node_went_without_a_value_does_not_claim_to_equal_cekm_run():
    from types import SimpleNamespace

    from cekm_swarm.launch.reports import node_summary, reproducible

    summary = node_summary([{"runs": 3, "ran_without": ["cekm/r1/share"]}, {"runs": 9}])
    assert summary["ran_without"] == ["cekm/r1/share"]
    children = [SimpleNamespace(label="r1/target", restarts=1, stateful=False)]
    rep = reproducible(children, False, {"r1/target": summary})
    assert rep["equals_cekm_run"] is False and rep["went_without"] == ["r1/target"] and rep["stateful_restarts"] == []
    assert reproducible(children, False, {"r1/target": node_summary([{"runs": 3}])})["equals_cekm_run"] is True


# ---------------------------------------------------------------- end to end

MAX_TIME = "60"  # s of sim time: 469 ticks
TICK = 0.128


def launch(tmp_path: Path, graph_file: Path, out: str, *args: str) -> LaunchProcess:
    from cekm_swarm.experiments.default_model import default_model_path

    return LaunchProcess(str(tmp_path / "open.toml"), tmp_path / out, "--graph", str(graph_file), "--no-plot",
                         "--model", str(default_model_path()), *args, cwd=tmp_path)


def cekm_run(tmp_path: Path, graph_file: Path, max_time: str) -> dict:
    ref = subprocess.run([sys.executable, "-m", "cekm_swarm", "run", "open.toml", "--graph", str(graph_file),
                          "--max-time", max_time, "--seed", "7", "--out", str(tmp_path / "ref")], cwd=tmp_path,
                         capture_output=True, text=True, timeout=300)
    assert ref.returncode == 0, ref.stderr
    return json.loads((tmp_path / "ref" / "outcome.json").read_text())


def kill_mid_run(tmp_path: Path, name: str, node: str, at_tick: int = 20, *also: str) -> LaunchProcess:
    """A lockstep launch of graph ``name``; ``node`` (and the nodes ``also``) SIGKILLed as soon as the robot's
    command of tick ``at_tick`` is out (seen on the launch's router: the node has run
    ticks, and holds outputs of the tick before that its restart loses); run to its end."""
    from cekm_swarm.protocol import DEFAULT_KEYS as K
    from cekm_swarm.protocol import KeyKind, decode
    from cekm_swarm.runtime.config import open_client

    run = launch(tmp_path, graph(tmp_path, name), "ls", "--mode", "lockstep", "--max-time", MAX_TIME, "--seed", "7")
    killed = threading.Event()
    session = None
    try:
        run.wait_line("world started ticking", timeout=120)
        pids = [run.pids()[n] for n in (node, *also)]

        def on_command(sample) -> None:
            stamp = decode(KeyKind.CMD_WHEELS, sample.payload.to_bytes()).stamp
            if stamp >= at_tick * TICK and not killed.is_set():
                for pid in pids:
                    os.kill(pid, signal.SIGKILL)
                killed.set()

        session = open_client(f"tcp/127.0.0.1:{run.port}")
        sub = session.declare_subscriber(K.cmd_wheels("r1"), on_command)
        last = "\n".join(run.lines[-20:])
        assert killed.wait(60), f"no command of tick {at_tick} in 60 s:\n{last}"
        sub.undeclare()
        for n in (node, *also):  # in any order: a line already read while waiting for another is in run.lines
            if not any(f"module {n} restarted" in line for line in run.lines):
                run.wait_line(f"module {n} restarted", timeout=30)
        code = run.finish(timeout=120)  # it hung for good before: the world re-publishing the stalled tick
    finally:
        if session is not None:
            session.close()
        run.kill()
    assert code == 0, "\n".join(run.lines[-30:])
    outcome = run.outcome()
    assert not outcome["aborted"] and outcome["launcher"]["restarts"] == {n: 1 for n in (node, *also)}, \
        outcome["launcher"]
    assert outcome["ticks"] > at_tick + 50, outcome["ticks"]  # killed mid-run, not at its end
    return run


@pytest.mark.slow
@pytest.mark.parametrize("node", ["r1/echo", "r1/drive"])
def test_lockstep_goes_on_when_a_delayed_inputs_producer_or_reader_restarts_and_equals_cekm_run(tmp_path, node):
    """echo: the producer of drive's delayed input, which needs drive's command of the tick
    it was down; drive: the reader, which needs echo's copy of the tick before."""
    run = kill_mid_run(tmp_path, "echo-loop", node)
    outcome = run.outcome()
    ref = cekm_run(tmp_path, tmp_path / "echo-loop.toml", MAX_TIME)
    assert ref["robots"]["r1"]["collisions"] == 0 and ref["robots"]["r1"]["path_length_m"] > 1.0
    assert outcome["robots"] == ref["robots"]  # time, path length, clearance, final distance: bit for bit
    assert outcome["reproducible"]["equals_cekm_run"] is True, outcome["reproducible"]


@pytest.mark.slow
def test_lockstep_goes_on_when_a_delayed_inputs_producer_and_reader_restart_together_and_says_so(tmp_path):
    """Both killed at once: echo has no copy of the tick before to send again, and drive
    waited for it for good (the world re-publishing the stalled tick); now drive gives it
    up once the tick comes again, and the outcome says the run may differ."""
    run = kill_mid_run(tmp_path, "echo-loop", "r1/drive", 20, "r1/echo")
    outcome = run.outcome()
    rep = outcome["reproducible"]
    assert rep["equals_cekm_run"] is False and rep["went_without"] == ["r1/drive"], rep
    assert outcome["launcher"]["nodes"]["r1/drive"]["ran_without"] == ["cekm/r1/loop/echo"]
    assert any("went without cekm/r1/loop/echo" in line for line in run.lines)


@pytest.mark.slow
def test_lockstep_goes_on_when_a_node_reading_its_own_previous_output_restarts_and_says_so(tmp_path):
    run = kill_mid_run(tmp_path, "self-loop", "r1/drive")
    rep = run.outcome()["reproducible"]
    assert rep["equals_cekm_run"] is False and rep["stateful_restarts"] == ["r1/drive"], rep


@pytest.mark.slow
def test_lockstep_ends_when_a_node_keeps_dying_at_the_same_tick(tmp_path):
    from cekm_swarm.launch.supervision import SAME_TICK_RESTARTS

    run = launch(tmp_path, graph(tmp_path, "exits"), "ls", "--mode", "lockstep", "--max-time", "20")
    try:
        code = run.finish(timeout=120)  # it was restarted forever before
    finally:
        run.kill()
    assert code == 1, "\n".join(run.lines[-20:])
    last = run.lines[-1]
    assert last.startswith("cekm: failed: r1/drive: died (exit code 3) at t=0.512 s (tick 4), and again after each "
                           f"of {SAME_TICK_RESTARTS} restarts"), last
    assert "in lockstep the run cannot go on without its outputs" in last
    restarts = sum("module r1/drive restarted" in line for line in run.lines)
    assert SAME_TICK_RESTARTS <= restarts <= SAME_TICK_RESTARTS + 2, "\n".join(run.lines[-20:])
    outcome = run.outcome()  # the launcher's record is in the outcome of a launch a node ended too
    assert outcome["launcher"]["restarts"]["r1/drive"] == restarts
    assert outcome["launcher"]["failure"].startswith("r1/drive: died (exit code 3)")
    assert outcome["reproducible"]["equals_cekm_run"] is False and outcome["reproducible"]["aborted"] is True


@pytest.mark.slow
def test_real_time_keeps_restarting_a_node_that_keeps_dying(tmp_path):
    from cekm_swarm.launch.supervision import SAME_TICK_RESTARTS

    run = launch(tmp_path, graph(tmp_path, "exits"), "rt", "--mode", "realtime", "--max-time", "10")
    try:
        code = run.finish(timeout=120)
    finally:
        run.kill()
    assert code == 0, "\n".join(run.lines[-20:])
    assert run.outcome()["launcher"]["restarts"]["r1/drive"] > SAME_TICK_RESTARTS


def test_a_pure_node_of_one_key_sends_again_only_to_readers_with_a_delay():
    """An obstacle module's last runs may be old (its reading held since t = 0): sent to a
    restarted motor, which reads them at the same tick (and gets fresh ones from the
    world's refresh anyway), their stamps set its stamp window in the past, so it dropped
    the only copies of its delayed inputs and the run waited for good."""
    from cekm_swarm.graph.spec import graph_for
    from cekm_swarm.node.graph_check import check_graph
    from cekm_swarm.node.process import outputs_readers
    from cekm_swarm.protocol import DEFAULT_KEYS as K

    plan = check_graph(str(graph_for("cekm", "navigation"))).plan(("r1",), "navigation")
    obstacle = plan.node("r1", "obstacle-0")
    assert outputs_readers(plan, obstacle, K) == {K.alive("r1", "motor"): frozenset({K.field_obstacle("r1", 0)})}
    assert outputs_readers(plan, obstacle, K, delayed_only=True) == {}


@pytest.mark.slow
def test_a_robots_only_host_ends_too_when_its_node_keeps_dying_at_the_same_tick(tmp_path):
    """The host that runs r1's nodes without the world reads the world's clock through the
    router, as the world's launcher does; it restarted such a node forever before."""
    from cekm_swarm.launch.supervision import SAME_TICK_RESTARTS

    g = graph(tmp_path, "exits")
    world = launch(tmp_path, g, "world-host", "--mode", "lockstep", "--max-time", "20", "--robots", "none")
    robots = None
    try:
        world.wait_line("hosts the embedded Zenoh router", timeout=60)
        robots = launch(tmp_path, g, "robot-host", "--mode", "lockstep", "--max-time", "20", "--robots", "r1",
                        "--no-world", "--connect", f"tcp/127.0.0.1:{world.port}")
        code = robots.finish(timeout=120)
    finally:
        world.kill()
        if robots is not None:
            robots.kill()
    assert code == 1, "\n".join(robots.lines[-20:])
    assert robots.lines[-1].startswith("cekm: failed: r1/drive: died (exit code 3) at t=0.512 s (tick 4), and again "
                                       f"after each of {SAME_TICK_RESTARTS} restarts"), robots.lines[-1]


@pytest.mark.slow
def test_a_lockstep_stall_names_the_node_whose_step_hangs_and_ends_at_the_step_timeout(tmp_path):
    """The world waits at t = 0.512 s; after 5 re-publishings the launcher asks the robot's
    nodes where they are, and says which step hangs and for how long; the node's log holds
    its stack (the line of the user's code it hangs in). With --step-timeout 5 that ends the
    launch as failed (exit 1) within 10 s of the hang, on that line."""
    import time

    run = launch(tmp_path, graph(tmp_path, "hangs"), "ls", "--mode", "lockstep", "--max-time", "20",
                 "--step-timeout", "5")
    try:
        run.wait_line("world started ticking", timeout=120)
        t0 = time.monotonic()
        line = run.wait_line("the world waits at t=0.51 s", timeout=120)
        code = run.finish(timeout=60)
        took = time.monotonic() - t0
    finally:
        run.kill()
    assert code == 1 and took < 10, (code, took, run.lines[-10:])
    assert run.lines[-1].startswith("cekm: failed: the world waits at t=0.51 s: r1/drive: its step at t=0.512 s "
                                    "has run for "), run.lines[-1]
    assert run.lines[-1].endswith("; --step-timeout 5 s passed") and 'mine.py", line ' in run.lines[-1]
    assert "r1/drive: its step at t=0.512 s has run for" in line, line
    assert f'at File "{tmp_path / "mine.py"}", line ' in line and " in step (its threads' stacks: " in line, line
    log = (tmp_path / "ls" / "logs" / "r1-drive.log").read_text()
    assert "STEP-STALLED r1/drive: its step at t=0.512 s" in log and "in step" in log, log[-2000:]

