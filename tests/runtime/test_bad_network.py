"""A bad network between hosts, end to end: the world host (with a real Zenoh router) and
two robot hosts in their own network namespaces, robot r1 behind a fault link
(``cekm_swarm.runtime.faultlink``), every process a real one:

- real time, r1's link cut for 3 s (each robot host with its own router, joined to the
  world's: the recommended shape for a slow or flaky link, docs/faults.md): the world's
  dead-man stops r1 within its limit, r1 drives on once the link is back, r2 is never
  stopped, the run completes, and the world's log holds every tick's world messages;
- lockstep, 100 ms one-way delay and 5 % loss on r1's link (TCP: a lost segment comes a
  retransmission timeout late), host routers: the outcome equals ``cekm run``'s bit for bit;
- real time, the world host's router (an outside one, every process its client) SIGKILLed
  and started again while r1's link is cut: every process reconnects by itself, no module
  restarts, both robots drive on.

Each run is a few seconds of sim time. Needs root and iproute2; skipped with the reason
where the machine cannot make network namespaces."""

from __future__ import annotations

import json
import time

import pytest
from test_multihost_netns import SCENARIO

from cekm_swarm.experiments.default_model import default_model, default_model_path
from cekm_swarm.protocol.stamps import PAST_S
from cekm_swarm.runtime.faultlink import LinkSettings
from cekm_swarm.runtime.mcap_log import is_complete, read_messages
from cekm_swarm.runtime.netns import Hosts, namespaces_unavailable
from cekm_swarm.runtime.netns_run import NetRun, world_log_gaps
from world.deadman import DEADMAN_S

pytestmark = pytest.mark.slow  # starts real processes (tests/process_guard.py)

SEED = 2
CUT_S = 3.0
TICK_S = 0.128


@pytest.fixture
def hosts():
    reason = namespaces_unavailable()
    if reason:
        pytest.skip(reason)
    h = Hosts(("r1", "r2"), tag="b")
    try:
        yield h
    finally:
        h.remove()
    assert not h.left_over()


def netrun(hosts, tmp_path, mode: str, max_time: float, faulty: dict, outside_router: bool = False,
           host_routers: bool = False) -> NetRun:
    scenario = tmp_path / "two_hosts.toml"
    scenario.write_text(SCENARIO)
    opts = ["--seed", str(SEED), "--max-time", str(max_time), "--model", str(default_model_path())]
    return NetRun(hosts, tmp_path / "run", scenario, mode, opts, faulty, outside_router=outside_router,
                  host_routers=host_routers)


def wait_sim(run: NetRun, t: float) -> None:
    """Until the world's progress line passes sim time ``t`` (a bounded wait on the run)."""
    while True:
        line = run.world.wait_line(" t=", timeout=60)
        if float(line.split(" t=")[1].split()[0]) >= t:
            return


def events(outcome: dict, kind: str, robot: str) -> list[dict]:
    return [e for e in outcome["events"] if e["event"] == kind and e["robot"] == robot]


def assert_no_module_restarted(run: NetRun, outcome: dict) -> None:
    """No restart storm: every node rode out the fault in its own process, on every host."""
    assert outcome["launcher"]["restarts"] == {}
    for r, p in run.robots.items():
        assert not [x for x in p.lines if "restarting" in x], (r, p.lines)


def assert_log_has_every_world_message(run: NetRun, outcome: dict) -> None:
    """The log is whole and holds every message the world recorded, and the world's own of
    every tick: its clock and state, and each robot's readings (the cut robot's too: the
    world published them into the cut)."""
    path = run.world_out / "run.mcap"
    assert is_complete(path)
    gaps = world_log_gaps(path, outcome, ["r1", "r2"])
    assert set(gaps.values()) == {0}, gaps


def test_a_robot_cut_off_for_3_s_is_stopped_in_time_drives_on_after_and_the_log_loses_nothing(hosts, tmp_path):
    run = netrun(hosts, tmp_path, "realtime", 6.0, {"r1": LinkSettings()}, host_routers=True)
    run.start()
    wait_sim(run, 1.0)
    cut = run.link("r1", "cut")
    time.sleep(CUT_S)  # the partition itself: how long the link stays cut, not a wait for something
    restore = run.link("r1", "restore")
    outcome = run.finish()
    assert not outcome["aborted"]
    assert_no_module_restarted(run, outcome)
    stop, = events(outcome, "deadman", "r1")  # stopped once, within the limit of its last command
    assert stop["silent_s"] <= DEADMAN_S
    assert cut["wall"] < stop["wall"] <= cut["wall"] + DEADMAN_S + 0.05
    resumed, = events(outcome, "deadman_resumed", "r1")  # and drove on once its commands were back
    assert resumed["wall"] >= restore["wall"]
    assert not events(outcome, "deadman", "r2") and not events(outcome, "deadman_resumed", "r2")
    traj = json.loads((run.world_out / "trajectory.json").read_text())["r1"]
    k_stop, k_resumed = round(stop["t"] / TICK_S), round(resumed["t"] / TICK_S)
    assert all(traj["v_l"][k] == traj["v_r"][k] == 0.0 for k in range(k_stop, k_resumed))
    assert traj["x"][-1] > traj["x"][k_resumed] + 0.05  # on its way again
    # the ticks r1 could not answer are counted (deadline misses, by tick), and nothing r1
    # sent before the cut that came after it was applied: each was dropped as stale (counted
    # by key), or superseded by a newer one; r2 lost nothing
    assert sum(outcome["deadline_miss_ticks"].values()) == outcome["deadline_misses"] >= CUT_S / TICK_S - 8
    assert all(key.startswith("cekm/r1/") for key in outcome["drops"]["commands"])
    ages = {int(k): n for k, n in outcome["command_age_ticks"].items()}
    assert max(ages) <= PAST_S / TICK_S + 1e-9 and sum(ages.values()) > 0  # never a command older than that applied
    for r in ("r1", "r2"):
        log = [m.log_time for m in read_messages(run.world_out / "run.mcap") if m.topic == f"cekm/{r}/cmd/wheels"]
        assert log == sorted(log)  # no command recorded out of order
    assert_log_has_every_world_message(run, outcome)
    assert run.link_stats("r1")["held_during_cut"]["down"] > 0  # the cut did hold the world's readings


def test_lockstep_through_a_100_ms_lossy_link_equals_the_in_process_run(hosts, tmp_path):
    from cekm_swarm.experiments.navigation_run import run_scenario
    from world import load_scenario

    max_time = 3.0
    run = netrun(hosts, tmp_path, "lockstep", max_time, {"r1": LinkSettings(delay=0.1, loss=0.05)},
                 host_routers=True)
    t0 = time.monotonic()
    run.start()
    t_ticking = time.monotonic()
    outcome = run.finish()
    wall = time.monotonic() - t_ticking
    ref = run_scenario(load_scenario(tmp_path / "two_hosts.toml"), "cekm", default_model(progress=False), SEED,
                       max_time=max_time)
    traj = json.loads((run.world_out / "trajectory.json").read_text())
    for r in ("r1", "r2"):
        assert traj[r]["x"] == ref.logs[r].x and traj[r]["y"] == ref.logs[r].y
        assert traj[r]["v_l"] == ref.logs[r].v_l and traj[r]["v_r"] == ref.logs[r].v_r
    stats = run.link_stats("r1")
    assert stats["retransmitted"]["up"] + stats["retransmitted"]["down"] > 0  # the loss did hit the run
    assert wall >= outcome["ticks"] * 2 * 0.1  # every tick waited for r1's round trip
    print(f"lockstep, 100 ms + 5 %: {outcome['ticks']} ticks in {wall:.1f} s from the first tick "
          f"({time.monotonic() - t0:.1f} s in all); link {stats}")


def test_the_router_restarted_while_a_robot_is_cut_off_every_process_reconnects_and_drives_on(hosts, tmp_path):
    run = netrun(hosts, tmp_path, "realtime", 7.0, {"r1": LinkSettings()}, outside_router=True)
    run.start()
    wait_sim(run, 1.0)
    run.link("r1", "cut")
    run.restart_router()  # SIGKILLed and started again on its port while r1 is cut off
    wait_sim(run, 1.0 + CUT_S)
    restore = run.link("r1", "restore")
    outcome = run.finish()
    assert not outcome["aborted"]
    assert_no_module_restarted(run, outcome)
    for r in ("r1", "r2"):  # both lost the router: both stopped, both drove on after
        assert events(outcome, "deadman", r), outcome["events"]
        resumed = events(outcome, "deadman_resumed", r)
        assert resumed and resumed[-1]["t"] > events(outcome, "deadman", r)[-1]["t"], outcome["events"]
    assert events(outcome, "deadman_resumed", "r1")[-1]["wall"] >= restore["wall"]
    assert_log_has_every_world_message(run, outcome)
