"""Router and world restarts, end to end with ``cekm launch --connect`` to an outside
router (a separate process, killed and started again on the same port) and real module
processes:

- lockstep: the router is SIGKILLed as the world starts ticking; the world re-publishes
  the waiting tick until the restarted router carries the modules' answers, and the
  trajectory still equals the in-process run bit for bit;
- real time: the router is SIGKILLed mid-run; the dead-man stops the robot during the gap,
  every process reconnects by itself, and the robot drives on; then the world server is
  SIGKILLed: the launcher ends the run with a clear message and a recovered, indexed log;
- a robots-only host (``--no-world --connect``) waits out a router restart instead of
  taking the world's token going with the router for the end of the run.
"""

from __future__ import annotations

import json
import math
import os
import re
import signal

import pytest

from cekm_swarm.experiments.default_model import default_model, default_model_path
from cekm_swarm.runtime.config import free_port
from cekm_swarm.runtime.mcap_log import is_complete, read_messages
from helpers.launch import LaunchProcess

pytestmark = pytest.mark.slow  # starts real processes (tests/process_guard.py)

SEED = 1
PROGRESS = re.compile(r" t=\s*([0-9.]+) s\s+r1 \(([-0-9.]+), ([-0-9.]+)\) (STOPPED|reached|([0-9.]+) m to goal)")


def progress(line: str) -> tuple[float, str, float | None, tuple[float, float]] | None:
    """(t, state, m to goal, (x, y)) of a launcher progress line of r1, None for other lines."""
    m = PROGRESS.search(line)
    if m is None:
        return None
    return float(m.group(1)), m.group(4), float(m.group(5)) if m.group(5) else None, \
        (float(m.group(2)), float(m.group(3)))


def test_clients_retry_a_lost_router_unless_their_config_file_says_otherwise(tmp_path):
    from cekm_swarm.runtime.config import RECONNECT_RETRY, client_config, client_config_from_file

    assert json.loads(client_config("tcp/127.0.0.1:7447").get_json("connect/retry")) == RECONNECT_RETRY
    plain = tmp_path / "plain.json5"
    plain.write_text('{mode: "client"}')
    assert json.loads(client_config_from_file(plain, "tcp/127.0.0.1:7447").get_json("connect/retry")) == \
        RECONNECT_RETRY
    own = tmp_path / "own.json5"
    own.write_text('{mode: "client", connect: {retry: {period_init_ms: 2000, period_max_ms: 8000, '
                   'period_increase_factor: 2}}}')
    assert json.loads(client_config_from_file(own, "tcp/127.0.0.1:7447").get_json("connect/retry"))[
        "period_max_ms"] == 8000


def test_lockstep_resumes_after_a_router_restart_and_equals_the_in_process_run(tmp_path, helpers):
    from cekm_swarm.experiments.navigation_run import run_scenario
    from world import load_scenario

    model = default_model(progress=False)
    port = free_port()
    endpoint = f"tcp/127.0.0.1:{port}"
    router = helpers("router", str(port))
    router.expect("READY")
    run = LaunchProcess("concave", tmp_path / "run", "--connect", endpoint, "--mode", "lockstep", "--seed", str(SEED),
                        "--max-time", "10", "--model", str(default_model_path()), "--no-plot")
    try:
        run.wait_line("world started ticking", timeout=90)
        os.kill(router.proc.pid, signal.SIGKILL)
        router.proc.wait(timeout=10)
        # the world waits for the tick's commands, then re-publishes its readings (into the void)
        run.wait_line("republish", timeout=30)
        helpers("router", str(port)).expect("READY")
        code = run.finish(timeout=120)
    finally:
        run.kill()
    assert code == 0, "\n".join(run.lines)
    outcome = run.outcome()
    assert outcome["republished"] >= 1 and not outcome["aborted"]
    assert not outcome["launcher"]["restarts"]  # no process died: they reconnected
    ref = run_scenario(load_scenario("concave"), "cekm", model, SEED, max_time=10)
    traj = json.loads((run.out / "trajectory.json").read_text())["r1"]
    log = ref.logs["r1"]
    assert traj["t"] == log.t and traj["x"] == log.x and traj["y"] == log.y and traj["theta"] == log.theta
    assert traj["v_l"] == log.v_l and traj["v_r"] == log.v_r


def test_real_time_goes_on_after_a_router_restart_and_a_killed_world_ends_the_run(tmp_path, helpers):
    from cekm_swarm.protocol import DEFAULT_KEYS as K

    default_model(progress=False)
    port = free_port()
    endpoint = f"tcp/127.0.0.1:{port}"
    router = helpers("router", str(port))
    router.expect("READY")
    run = LaunchProcess("lone_obstacle", tmp_path / "run", "--connect", endpoint, "--mode", "realtime",
                        "--max-time", "60", "--model", str(default_model_path()), "--no-plot")
    try:
        run.wait_line("world started ticking", timeout=90)
        while (p := progress(run.wait_line(" t=", timeout=20))) is None or p[0] < 1.0 or p[2] is None:
            pass
        os.kill(router.proc.pid, signal.SIGKILL)
        router.proc.wait(timeout=10)
        stopped_at = float(re.search(r"world event at t=([0-9.]+) s: deadman", run.wait_line("deadman", 30)).group(1))
        while (p := progress(run.wait_line(" t=", timeout=20))) is None or p[1] != "STOPPED":
            pass
        where = p[3]
        helpers("router", str(port)).expect("READY")
        # the robot drives on: a progress line not STOPPED, 2 cm or more from where it stopped
        while (p := progress(run.wait_line(" t=", timeout=30))) is None or p[1] == "STOPPED" or \
                math.dist(p[3], where) < 0.02:
            pass
        os.kill(run.pids()["world/server"], signal.SIGKILL)
        code = run.finish(timeout=60)
    finally:
        run.kill()
    text = "\n".join(run.lines)
    assert code != 0, text
    assert "the world server was killed by signal 9; the run ends" in text
    assert "recovered the world's log" in text and "the run left no outcome" in text
    log, cut = run.out / "run.mcap", run.out / "run.truncated.mcap"
    assert is_complete(log) and not is_complete(cut)
    # the world heard the robot's commands again after the gap: its subscriptions came back
    stamps = [m.log_time / 1e9 for m in read_messages(log, topics=[K.cmd_wheels("r1")])]
    assert any(t > stopped_at + 0.5 for t in stamps), (stopped_at, stamps[-5:])


def test_a_robots_only_host_waits_out_a_router_restart(tmp_path, helpers):
    """``Launcher._serve_until_world_ends`` of a robots-only host with ``--connect``, with a
    real session, liveliness watcher and router: a helper process holds the world server's
    token; the router is SIGKILLed (the token's DELETE comes with no router: keep waiting)
    and started again (the token's PUT: the world is back); then the helper is killed with
    the router up, which ends the wait."""
    import asyncio

    from cekm_swarm.launch.launcher import LaunchConfig, Launcher
    from cekm_swarm.protocol import DEFAULT_KEYS as K
    from cekm_swarm.runtime.bridge import LivelinessWatcher
    from cekm_swarm.runtime.config import open_client

    port = free_port()
    endpoint = f"tcp/127.0.0.1:{port}"
    router = helpers("router", str(port))
    router.expect("READY")
    world = helpers("token", endpoint, K.alive("world", "server"))
    world.expect("READY")
    said: list[str] = []
    session = open_client(endpoint)

    async def scenario() -> None:
        said_more = asyncio.Event()

        def echo(line: str) -> None:
            said.append(line)
            said_more.set()

        async def until_said(needle: str) -> None:  # each wait bounded by the scenario's timeout
            while not any(needle in line for line in said):
                said_more.clear()
                await said_more.wait()

        launcher = Launcher(LaunchConfig("lone_obstacle", tmp_path, connect=endpoint), echo=echo)
        launcher.startup_s = 1.0
        with LivelinessWatcher(session, K.alive_all()) as watcher:
            await watcher.wait_for(K.alive("world", "server"), True, 20)
            task = asyncio.ensure_future(launcher._serve_until_world_ends(watcher, 14, session))
            os.kill(router.proc.pid, signal.SIGKILL)
            await asyncio.to_thread(router.proc.wait, 10)
            await until_said("lost the Zenoh router")
            assert not task.done(), said
            await asyncio.to_thread(lambda: helpers("router", str(port)).expect("READY"))
            await until_said("reconnected")
            assert not task.done(), said
            world.proc.kill()
            await asyncio.wait_for(task, 20)

    try:
        asyncio.run(asyncio.wait_for(scenario(), 60))
    finally:
        session.close()
    lines = [s.split("] ", 1)[1] for s in said[1:]]
    assert lines[0] == "the world server is up"
    assert lines[1].startswith("lost the Zenoh router; waiting up to 10 s")
    assert lines[2].startswith("reconnected: the world server is up again after")
    assert lines[3] == "the world server has ended" and len(lines) == 4
