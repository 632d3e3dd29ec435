"""`cekm launch` in real time, end to end with two robots (28 module processes and the
world server, a real embedded router on a free loopback port), with faults injected
mid-run: SIGKILL r1's obstacle module 0 (the launcher restarts it, r1's motor drops the
stale field, r1 still reaches its goal past a disc) and SIGKILL r2's motor module (the
world stops r2 within the dead-man limit; the launcher restarts the motor and r2 goes on).

One run serves all the checks below, to keep the suite's time down (each launch costs
some 15 s of process start-up on two cores)."""

from __future__ import annotations

import os
import signal
import time
from pathlib import Path

import pytest

from cekm_swarm.experiments.default_model import default_model, default_model_path
from cekm_swarm.protocol import DEFAULT_KEYS as K
from helpers.launch import LaunchProcess
from helpers.pair import pair_toml

pytestmark = pytest.mark.slow  # starts real processes (tests/process_guard.py)

SCENARIO = pair_toml()
DEADMAN = 0.5
KILL_AT = 1.0  # s of sim time


@pytest.fixture(scope="module")
def faulty_run(tmp_path_factory):
    default_model(progress=False)
    out = tmp_path_factory.mktemp("realtime")
    scenario = out / "pair.toml"
    scenario.write_text(SCENARIO)
    # every reading every tick: each tick then has each module's field, which the checks of
    # staleness and of what is logged per tick count on (held readings: test_launch_graphs,
    # tests/node/test_held_readings.py, and the realtime runs of the other launch tests)
    # the default graph (learned widths, rear turns at speed): the ~2 s r1's forward sensor's
    # module is dead once left it swinging in front of the disc, before its motor turned at
    # speed (docs/fields.md, "The sixth round")
    run = LaunchProcess(str(scenario), out / "run", "--mode", "realtime", "--max-time", "40",
                        "--model", str(default_model_path()), "--send-every-reading")
    kills = {}
    try:
        run.wait_line("world started ticking", timeout=90)
        while True:
            line = run.wait_line(" t=", timeout=20)
            if float(line.split("t=")[1].split()[0]) >= KILL_AT:
                break
        pids = run.pids_seen = run.pids()
        task = Path(f"/proc/{pids['r1/obstacle-3']}/task")
        run.module_threads = sorted((t / "comm").read_text().strip() for t in task.iterdir())
        world = pids["world/server"]
        run.world_threads = sorted((t / "comm").read_text().strip() for t in Path(f"/proc/{world}/task").iterdir())
        run.router_owner = listening_pid(run.port, [world, run.proc.pid])
        for label in ("r1/obstacle-0", "r2/motor"):
            kills[label] = time.time()
            os.kill(pids[label], signal.SIGKILL)
        # and r1/obstacle-0 once more as soon as it is back: restarted after 0.5 s this time
        # (the back-off doubles), so its field surely outlives the motor's 2-tick staleness
        # limit (after the first kill's 0.25 s it may just not)
        back = run.wait_line("module r1/obstacle-0 restarted", timeout=20)
        os.kill(int(back.split("(pid ")[1].split(")")[0]), signal.SIGKILL)
        code = run.finish(timeout=90)
    finally:
        run.kill()
    assert code == 0, "\n".join(run.lines)
    return run, kills


def test_two_robots_in_real_time_complete_and_reach_their_goals(faulty_run):
    run, _ = faulty_run
    outcome = run.outcome()
    assert outcome["mode"] == "realtime" and not outcome["aborted"]
    assert set(outcome["robots"]) == {"r1", "r2"}
    assert all(o["reached"] for o in outcome["robots"].values()), outcome["robots"]
    # (r1 may graze the disc: its forward sensor's module is dead for about 2 s of the approach)
    # real time: sim time kept up with the wall clock
    assert outcome["wall_seconds"] >= 0.9 * outcome["sim_seconds"]
    assert (run.out / "trajectory.png").is_file()


def listening_pid(port: int, pids: list[int]) -> int | None:
    """Which of ``pids`` holds the socket listening on TCP ``port`` (from /proc/net/tcp)."""
    inodes = set()
    for line in Path("/proc/net/tcp").read_text().splitlines()[1:]:
        f = line.split()
        if f[3] == "0A" and int(f[1].rsplit(":", 1)[1], 16) == port:  # 0A: LISTEN
            inodes.add(f"socket:[{f[9]}]")
    for pid in pids:
        for fd in Path(f"/proc/{pid}/fd").iterdir():
            try:
                if os.readlink(fd) in inodes:
                    return pid
            except OSError:
                continue
    return None


def test_the_world_server_hosts_the_embedded_router_on_zenoh_app_threads(faulty_run):
    """The embedded default: the world server process, not the launcher, listens on the
    launch's port, and on loopback Zenoh's receiving, timer and accepting runtimes are
    handed to 'app', sending keeps its own thread (runtime.config.ROUTER_RUNTIME)."""
    run, _ = faulty_run
    assert run.router_owner == run.pids_seen["world/server"]
    assert any(n.startswith("app-") for n in run.world_threads), run.world_threads
    assert any(n.startswith("tx-") for n in run.world_threads), run.world_threads
    assert not any(n.startswith(("rx-", "net-", "acc-")) for n in run.world_threads), run.world_threads
    assert any("the world server hosts the embedded Zenoh router" in line for line in run.lines)


def test_a_module_process_runs_zenoh_on_one_runtime(faulty_run):
    """runtime.config.ONE_THREAD_RUNTIME hands every Zenoh runtime to 'app': a live module has
    no receiving, sending or timer threads of its own (Zenoh names them rx-, tx-, net-)."""
    names = faulty_run[0].module_threads
    assert any(n.startswith("app-") for n in names), names
    assert not any(n.startswith(("rx-", "tx-", "net-", "acc-")) for n in names), names


def test_killed_modules_are_restarted_and_the_log_shows_it(faulty_run):
    run, _ = faulty_run
    restarts = run.outcome()["launcher"]["restarts"]
    assert restarts.get("r1/obstacle-0", 0) >= 1 and restarts.get("r2/motor", 0) >= 1, restarts
    text = "\n".join(run.lines)
    assert "module r1/obstacle-0 died (signal 9)" in text and "module r1/obstacle-0 restarted" in text
    assert "module r2/motor died (signal 9)" in text
    assert "restarted" in (run.out / "launch.log").read_text()


def test_motor_drops_the_dead_obstacle_modules_stale_field(faulty_run):
    run, _ = faulty_run
    log = (run.out / "logs" / "r1-motor.log").read_text()
    outages = log.count("stale input left out: cekm/r1/field/obstacle/0")
    assert outages >= 1
    # each outage counted once in the node's final report, as it was logged
    assert f'"stale": {{"cekm/r1/field/obstacle/0": {outages}}}' in log


def test_world_stops_the_robot_whose_motor_died_within_the_deadman_limit(faulty_run):
    run, kills = faulty_run
    events = [e for e in run.outcome()["events"] if e["event"] == "deadman" and e["robot"] == "r2"]
    assert events, run.outcome()["events"]
    first = events[0]
    assert first["silent_s"] <= DEADMAN
    assert first["wall"] - kills["r2/motor"] <= DEADMAN + 0.05
    assert first["t"] >= KILL_AT
    # r1's motor never went silent
    assert not [e for e in run.outcome()["events"] if e["event"] == "deadman" and e["robot"] == "r1"]
    # r2's missing commands are deadline misses, listed by tick from the kill on
    doc = run.outcome()
    ticks = {int(k): v for k, v in doc["deadline_miss_ticks"].items()}
    assert doc["deadline_misses"] >= 3 and sum(ticks.values()) == doc["deadline_misses"]
    assert any(k * 0.128 >= first["t"] - 0.2 for k in ticks)
    # the clock started once tick 0 was answered: its time is reported, and it is no miss
    assert doc["first_tick_ms"] > 0 and 0 not in ticks


def test_realtime_log_holds_every_robots_channels(faulty_run):
    from mcap.reader import make_reader

    run, _ = faulty_run
    with open(run.out / "run.mcap", "rb") as f:
        topics = {c.topic for c in make_reader(f).get_summary().channels.values()}
    for r in ("r1", "r2"):
        for key in (K.sense_target(r), K.sense_range(r, 11), K.field_target(r), K.field_obstacle(r, 0),
                    K.cmd_wheels(r)):
            assert key in topics, key


def test_no_reading_or_field_is_lost_in_transit(faulty_run):
    """Every reading the world published got its field, and the field reached the world's
    log: a burst of a tick's messages is batched, not dropped (an express message each was
    a batch of its own, overflowed the router's queue towards the world and was dropped).
    The modules that were never killed answer every tick but the last (still in flight when
    the world stops)."""
    from mcap.reader import make_reader

    run, _ = faulty_run
    stamps: dict[str, set[int]] = {}
    with open(run.out / "run.mcap", "rb") as f:
        for _, channel, message in make_reader(f).iter_messages():
            # publish time: the message's stamp (log time is the world's clock when it was recorded)
            stamps.setdefault(channel.topic, set()).add(round(message.publish_time / 1e6))  # ms of sim time
    for r in ("r1", "r2"):
        for j in range(12):
            if (r, j) == ("r1", 0):
                continue  # SIGKILLed mid-run
            read, answered = stamps[K.sense_range(r, j)], stamps[K.field_obstacle(r, j)]
            missing = sorted(read - answered)
            assert missing in ([], [max(read)]), (r, j, missing[:10], len(read))


def test_a_ticks_fields_and_commands_are_logged_within_that_tick(faulty_run):
    """In real time the world writes a tick's log once every robot's command is in (or at
    RECORD_BY of the tick), out of the burst in which the modules compute: so what the
    robots sent for a tick is recorded at that tick's sim time (log time = its stamp), not a
    tick later. Ticks of the faults (a dead motor, a restarting module) may be later."""
    from mcap.reader import make_reader

    run, _ = faulty_run
    same = late = 0
    with open(run.out / "run.mcap", "rb") as f:
        for _, channel, message in make_reader(f).iter_messages():
            if "/field/" in channel.topic or channel.topic.endswith("/cmd/wheels"):
                if message.log_time == message.publish_time:
                    same += 1
                else:
                    late += 1
    assert same + late > 1000
    assert same > 0.9 * (same + late), (same, late)
