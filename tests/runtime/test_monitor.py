"""cekm monitor: the pure view model, its 80-column rendering, and the real command."""

from __future__ import annotations

import contextlib
import json
import subprocess
import sys

import msgpack
import pytest

from cekm_swarm.protocol import DEFAULT_KEYS as K
from cekm_swarm.protocol import SenseRange, SenseTargets, Share, WheelCommand, WorldState, encode
from cekm_swarm.runtime.bridge import declare_alive
from cekm_swarm.runtime.jsonout import json_line
from cekm_swarm.runtime.logcat import key_filter
from cekm_swarm.runtime.monitor import MonitorState, render_text, snapshot
from cekm_swarm.runtime.rungraph import default_nodes

NODES = default_nodes()  # the cekm navigation graph's nodes of one robot
ALL_MODULES = {K.alive("r1", m) for m in NODES}
WORLD_TOKEN = K.alive("world", "server")


def world_state(t, x, rid="r1", **extra):
    r = {"x": x, "y": 0.5, "theta": 0.1, "in_contact": False, "goal": [2.0, 0.5]}
    r.update(extra)
    return WorldState(t, "world", {rid: r}, {}, {})


def lines_of(text: str) -> list[str]:
    return text.splitlines()


def test_view_model_poses_latency_rates_and_drops():
    st = MonitorState()
    st.observe(K.world_state(), encode(world_state(1.0, 0.3)), at=10.0)
    for j in range(12):
        st.observe(K.sense_range("r1", j), encode(SenseRange(1.024, "world", j, 0.0, None)), at=10.000 + j * 1e-4)
    st.observe(K.cmd_wheels("r1"), encode(WheelCommand(1.024, "r1/motor", 0.1, 0.12, 1)), at=10.003)
    st.observe(K.cmd_wheels("r1"), b"\x00garbage", at=10.004)
    v = st.robots["r1"]
    assert v.pose == (0.3, 0.5, 0.1) and v.goal == (2.0, 0.5) and v.status == "moving"
    assert abs(v.latency_ms(0.5) - 3.0) < 1e-6  # first sense of the tick to the command of the same stamp
    assert st.drops.total == 1  # the malformed command was dropped and counted
    st.set_alive({"cekm/r1/alive/motor", "cekm/r1/alive/target", WORLD_TOKEN})
    assert st.modules_alive("r1") == (2, [])  # the run's graph not known yet: nothing counts as missing
    st.expected = NODES  # what the monitor learns from the graph the world serves
    n, missing = st.modules_alive("r1")
    assert n == 2 and "obstacle-0" in missing
    text = render_text(st, now=10.01)
    assert lines_of(text)[0] == "cekm monitor running  sim 1.00 s  dropped 1"
    row = next(line for line in lines_of(text) if line.startswith("r1 "))
    assert row.split() == ["r1", "0.300", "0.500", "0.10", "(2.00,0.50)", "moving", "0.100", "0.120", "2/14",
                           "3.0/3.0"]
    assert "missing: obstacle-0, obstacle-1" in text
    st.observe(K.cmd_wheels("r1"), encode(WheelCommand(2.0, "r1/motor", 0.0, 0.0, 2)), at=11.0)
    assert st.robots["r1"].status == "stopped"


def test_a_monitor_open_across_two_runs_shows_only_the_current_runs_figures():
    """Left open into the next run, it kept the last run's latency for the whole new run
    and showed its robots 'moving' with 0/14 modules once the run had ended."""
    st = MonitorState()
    st.expected = NODES
    from cekm_swarm.protocol import KeySpace

    r1, r2 = KeySpace(run="run1"), KeySpace(run="run2")
    st.set_alive({r1.alive("world", "server")} | {r1.alive("r1", m) for m in NODES})
    st.observe(K.world_state(), encode(world_state(5.0, 0.3)), at=10.0)
    st.observe(K.sense_range("r1", 0), encode(SenseRange(5.12, "world", 0, 0.0, None)), at=10.0)
    st.observe(K.cmd_wheels("r1"), encode(WheelCommand(5.12, "r1/motor", 0.1, 0.1, 40)), at=10.020)
    assert st.robots["r1"].latency_ms(0.5) == pytest.approx(20.0)
    st.set_alive(set())  # the run ended: every token gone
    row = next(line for line in lines_of(render_text(st, now=20.0)) if line.startswith("r1 "))
    assert row.split()[5] == "ended" and snapshot(st, 20.0)["robots"]["r1"]["status"] == "ended"
    st.set_alive({r2.alive("world", "server")})  # the next run's world server
    assert st.robots == {} and st.run_id == "run2"
    assert lines_of(render_text(st, now=21.0))[0].startswith("cekm monitor waiting for the modules  sim -")
    st.observe(K.world_state(), encode(world_state(0.0, 0.9)), at=22.0)
    st.observe(K.cmd_wheels("r1"), encode(WheelCommand(0.0, "r1/motor", 0.1, 0.1, 0)), at=22.001)
    v = st.robots["r1"]
    assert v.pose == (0.9, 0.5, 0.1) and not v.latencies  # nothing of run1's latency
    row = next(line for line in lines_of(render_text(st, now=22.1)) if line.startswith("r1 "))
    assert row.split()[-1] == "-"  # no latency yet in this run
    st.observe(K.world_state(), encode(world_state(0.5, 0.9)), at=23.0)
    st.observe(K.world_state(), encode(world_state(0.0, 0.9)), at=24.0)  # a replay from the start: sim time back
    assert st.robots["r1"].command is None and st.sim_time == 0.0


def test_phases_waiting_running_stale_ended_and_replay():
    st = MonitorState()
    text = render_text(st, now=0.0)
    assert lines_of(text)[0].startswith("cekm monitor waiting for the world  sim -")
    assert "waiting for the world server's first state" in text
    st.set_alive({WORLD_TOKEN})
    assert st.phase(1.0) == "waiting for the modules"  # the world is up and holds tick 0
    assert "(0 alive now)" in render_text(st, now=1.0)
    st.set_alive(ALL_MODULES | {WORLD_TOKEN})
    assert st.phase(1.0) == "waiting for the modules"  # modules up, tick 0 not yet
    assert f"({len(ALL_MODULES)} alive now)" in render_text(st, now=1.0)
    st.observe(K.world_state(), encode(world_state(0.0, 0.3)), at=2.0)
    assert st.phase(2.5) == "running"
    assert st.phase(6.0) == "no world state for 4 s"  # still alive, but silent
    st.set_alive(ALL_MODULES)  # the world server left
    assert st.phase(6.0) == "run ended"
    assert lines_of(render_text(st, now=6.0))[0].startswith("cekm monitor run ended  sim 0.00 s")
    st.set_alive(set())  # then the modules
    assert st.phase(6.0) == "run ended"
    st.observe(K.world_state(), encode(world_state(9.0, 0.4)), at=7.0)  # a replay: states, no tokens
    assert st.phase(7.5) == "replay" and st.phase(20.0) == "run ended"
    quiet = MonitorState()
    quiet.observe(K.world_state(), encode(world_state(0.0, 0.3)), at=0.0)
    assert quiet.phase(5.0) == "run ended"  # no token ever, states stopped: a replay that finished


def test_every_line_fits_80_columns_whatever_the_values():
    st = MonitorState()
    long_id = "r" + "x" * 63
    st.observe(K.world_state(), encode(WorldState(1e9, "world", {
        long_id: {"x": -1234567.891, "y": 1e300, "theta": -3.14159, "goal": [-1e6, 1e6]},
        "r2": {"x": 0.1, "y": 0.2, "theta": 0.3, "goal": None}}, {}, {})), at=1.0)
    st.observe(K.cmd_wheels(long_id), encode(WheelCommand(1e9, "m", -0.15625, 0.15625, 1)), at=1.0)
    for j in range(12):
        st.observe(K.field_obstacle(long_id, j), b"\x80", at=1.0)  # malformed, counted
    st.set_alive({K.alive(long_id, "motor")})
    for kw in ({}, {"key_filter": key_filter(["cekm/**"])}):
        text = render_text(st, now=1.5, endpoint="tcp/[fe80::1234:5678:9abc:def0]:7447", **kw)
        assert max(len(line) for line in lines_of(text)) <= 80, text
    assert "dropped 12" in text and "cekm/rxxxxxxx" in text
    assert sum(1 for line in lines_of(text) if line.startswith(("rxxxx", "r2 "))) == 2


def test_robot_filter_and_key_filter():
    st = MonitorState()
    st.observe(K.world_state(), encode(WorldState(1.0, "world", {
        "r1": {"x": 0.1, "y": 0.2, "theta": 0.0}, "r2": {"x": 1.1, "y": 1.2, "theta": 0.0}}, {}, {})), at=1.0)
    st.observe(K.cmd_wheels("r1"), encode(WheelCommand(1.0, "r1/motor", 0.1, 0.1, 1)), at=1.0)
    st.observe(K.cmd_wheels("r2"), encode(WheelCommand(1.0, "r2/motor", 0.1, 0.1, 1)), at=1.0)
    text = render_text(st, now=1.1, robots={"r2", "r9"}, key_filter=key_filter(["cekm/r2/**"]))
    rows = [line.split()[0] for line in lines_of(text)]
    assert "r2" in rows and "r1" not in rows and "r9:" in rows and "not seen" in text
    assert "cekm/r2/cmd/wheels" in text and "cekm/r1/cmd/wheels" not in text and "cekm/world/state" not in text
    summary = render_text(st, now=1.1)
    assert "3 keys active" in summary and "cekm/r1/cmd/wheels" not in summary  # no key list unless asked
    doc = json.loads(json_line(snapshot(st, 1.1, robots={"r2"}, key_filter=key_filter(["cekm/r2/**"]))))
    assert doc["phase"] == "replay" and list(doc["robots"]) == ["r2"] and doc["robots"]["r2"]["status"] == "moving"
    assert doc["robots"]["r2"]["pose"] == [1.1, 1.2, 0.0] and doc["robots"]["r2"]["latency_ms_p50"] is None
    assert [k["key"] for k in doc["keys"]] == ["cekm/r2/cmd/wheels"]


def test_a_world_state_it_cannot_draw_is_dropped_and_counted_not_a_crash():
    """The world state is typed: one whose robots lack a drawable pose does not decode, so
    the monitor drops and counts it like any malformed message and keeps the last good one."""
    st = MonitorState()
    st.observe(K.world_state(), encode(world_state(1.0, 0.3)), at=1.0)
    good = msgpack.unpackb(encode(world_state(2.0, 0.3)))
    bad_robots = [
        {"y": 0.5, "theta": 0.0},  # no x
        {"x": "left", "y": 0.5, "theta": 0.0},
        {"x": 0.1, "y": 0.5, "theta": 0.0, "goal": [1.0]},
        {"x": 0.1, "y": 0.5, "theta": 0.0, "in_contact": "yes"},
        {"x": True, "y": 0.5, "theta": 0.0},
        {"x": float("nan"), "y": 0.5, "theta": 0.0},
    ]
    for i, r in enumerate(bad_robots):
        st.observe(K.world_state(), msgpack.packb({**good, "robots": {"r1": r}}), at=2.0 + i)
    assert st.drops.total == len(bad_robots)
    assert st.robots["r1"].pose == (0.3, 0.5, 0.1) and st.sim_time == 1.0  # the last good state stays
    assert "dropped 6" in render_text(st, now=9.0)


def tracking_state(t, targets, robots=("r1", "r2", "r3")):
    rob = {r: {"x": 0.1 * i, "y": 0.2, "theta": 0.0, "goal": None} for i, r in enumerate(robots)}
    return WorldState(t, "world", rob, {tid: {"x": x, "y": y} for tid, (x, y) in targets.items()}, {})


TARGETS = {"t1": (0.5, 1.2), "t2": (1.0, 0.3), "t3": (2.0, 2.0)}


def test_tracking_block_who_observes_which_target_and_the_instantaneous_a():
    st = MonitorState()
    st.observe(K.world_state(), encode(world_state(1.0, 0.3)), at=1.0)
    assert not st.is_tracking() and "tracking" not in render_text(st, now=1.1)  # no targets: no block
    st.observe(K.world_state(), encode(tracking_state(1.0, TARGETS)), at=1.0)
    assert not st.is_tracking()  # targets, but nobody reports observing yet
    st.observe(K.share("r1"), encode(Share(1.0, "r1", (0.0, 0.2, 0.0), {"t1": (0.5, 1.2), "t2": (1.0, 0.3)})), at=1.0)
    st.observe(K.sense_targets("r3"), encode(SenseTargets(1.0, "world", {"t1": (0.3, 0.5)})), at=1.0)
    st.observe(K.share("r2"), b"\x00garbage", at=1.0)  # malformed: dropped and counted
    st.observe(K.share("r2"), encode(Share(0.9, "r2", (0.1, 0.2, 0.0), {"t2": (1.0, 0.3)})), at=1.0)
    # r2's sense/targets is newer than its share: it wins (the world says r2 now sees nothing)
    st.observe(K.sense_targets("r2"), encode(SenseTargets(1.0, "world", {})), at=1.0)
    text = render_text(st, now=1.1)
    lines = lines_of(text)
    assert lines[0] == "cekm monitor replay  sim 1.00 s  dropped 1"
    i = lines.index("tracking  A 0.67  observed 2/3 targets")
    assert lines[i + 1].split() == ["target", "x", "y", "observed", "by"]
    assert [line.split() for line in lines[i + 2:i + 6]] == [
        ["t1", "0.500", "1.200", "r1", "r3"], ["t2", "1.000", "0.300", "r1"], ["t3", "2.000", "2.000", "-"],
        ["sees", "r1", "2", "r2", "0", "r3", "1"]]
    tr = json.loads(json_line(snapshot(st, 1.1)))["tracking"]
    assert tr["observed"] == 2 and tr["total"] == 3 and abs(tr["A"] - 2 / 3) < 1e-12
    assert tr["targets"]["t1"] == {"x": 0.5, "y": 1.2, "observed_by": ["r1", "r3"]}
    assert tr["per_robot"] == {"r1": {"sees": 2, "source": "share"}, "r2": {"sees": 0, "source": "sense"},
                               "r3": {"sees": 1, "source": "sense"}}
    # --robot r3: its observations only, A stays the team's
    only = render_text(st, now=1.1, robots={"r3"})
    assert "A 0.67  observed 2/3" in only and "sees  r3 1" in only and "r1" not in only
    assert json.loads(json_line(snapshot(st, 1.1, robots={"r3"})))["tracking"]["targets"]["t2"]["observed_by"] == []
    # time goes on: r1 keeps sharing, r3's last sense/targets grows older than the span and stops counting
    st.observe(K.world_state(), encode(tracking_state(3.5, TARGETS)), at=3.5)
    st.observe(K.share("r1"), encode(Share(3.5, "r1", (0.0, 0.2, 0.0), {"t3": (2.0, 2.0)})), at=3.5)
    tr = st.tracking()
    assert tr["targets"]["t1"]["observed_by"] == [] and tr["targets"]["t3"]["observed_by"] == ["r1"]
    assert tr["observed"] == 1 and list(tr["per_robot"]) == ["r1"]
    # a world state with a target it cannot draw is dropped whole; the last good one stays
    wire = msgpack.unpackb(encode(tracking_state(3.6, TARGETS)))
    wire["targets"]["t1"]["x"] = "left"
    st.observe(K.world_state(), msgpack.packb(wire), at=3.6)
    assert st.drops.total == 2 and st.targets == TARGETS and st.sim_time == 3.5
    # a new run (sim time back to 0) forgets the old run's observations
    st.observe(K.world_state(), encode(tracking_state(0.0, TARGETS)), at=5.0)
    assert not st.is_tracking() and st.tracking()["observed"] == 0


def test_tracking_block_fits_80_columns_with_many_targets_and_robots():
    st = MonitorState()
    robots = [f"robot-with-a-long-name-{i:02d}" for i in range(20)]
    targets = {f"target-{'x' * 30}-{k}": (1e6 * k, -1e300) for k in range(30)}
    st.observe(K.world_state(), encode(tracking_state(1.0, targets, robots)), at=1.0)
    for r in robots:
        st.observe(K.share(r), encode(Share(1.0, r, (0.0, 0.0, 0.0), {t: (0.0, 0.0) for t in targets})), at=1.0)
    for kw in ({}, {"robots": set(robots[:3])}):
        text = render_text(st, now=1.1, **kw)
        assert max(len(line) for line in lines_of(text)) <= 80, text
        assert "A 1.00  observed 30/30 targets" in text and "… 18 more targets, 18 of them observed" in text
    sees = [line for line in lines_of(render_text(st, now=1.1)) if line.startswith(("sees  ", "      robot"))]
    assert " ".join(sees).count(" 30") == 20  # every robot's count, over as many lines as it takes


@pytest.mark.slow
def test_monitor_command_attaches_to_a_live_run(router, clients):
    """`cekm monitor --once` in another process sees the robot, its module and the keys."""
    pub = clients()
    token = declare_alive(pub, "cekm/r1/alive/motor")
    proc = subprocess.Popen([sys.executable, "-m", "cekm_swarm", "monitor", "--connect", router, "--once", "2",
                             "--keys", "cekm/**"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    t = 0.0
    while proc.poll() is None:  # publish a steady run until the monitor has taken its snapshot
        t += 0.128
        pub.put(K.world_state(), encode(world_state(t, 0.1 + t / 100)))
        pub.put(K.cmd_wheels("r1"), encode(WheelCommand(t, "r1/motor", 0.05, 0.06, int(t / 0.128))))
        with contextlib.suppress(subprocess.TimeoutExpired):
            proc.wait(timeout=0.02)
    out, err = proc.communicate(timeout=10)
    assert proc.returncode == 0, err
    assert out.startswith("cekm monitor running") and max(len(line) for line in out.splitlines()) <= 80
    row = next(line for line in out.splitlines() if line.startswith("r1 "))
    assert "moving" in row and row.split()[-2] == "1"  # one node alive; no world serves a graph to compare with
    assert "cekm/r1/cmd/wheels" in out and "cekm/world/state" in out
    del token


def test_invented_keys_and_robots_cannot_grow_the_monitor_without_bound(monkeypatch):
    from cekm_swarm.runtime import monitor_state

    monkeypatch.setattr(monitor_state, "MAX_KEYS", 5)
    monkeypatch.setattr(monitor_state, "MAX_ROBOTS", 3)
    st = MonitorState()
    for i in range(10):
        st.observe(K.cmd_wheels(f"r{i}"), encode(WheelCommand(1.0, "m", 0.1, 0.1, 1)), at=1.0)
    assert len(st.arrivals) == 5 and len(st.robots) == 3 and st.untracked == 5 + 2
    assert "untracked 7" in render_text(st, now=1.0)


def test_tokens_with_a_run_id_count_as_the_world_and_modules():
    from cekm_swarm.protocol import KeySpace

    run = KeySpace(run="run-7")
    st = MonitorState()
    st.expected = NODES
    st.set_alive({run.alive("r1", m) for m in NODES} | {run.alive("world", "server")})
    st.observe(K.world_state(), encode(world_state(0.5, 0.3)), at=1.0)
    assert st.phase(1.2) == "running" and st.modules_alive("r1") == (14, [])
    assert "  run run-7" in lines_of(render_text(st, now=1.2))[0]
    st.set_alive({run.alive("r1", m) for m in NODES})
    assert st.phase(2.5) == "run ended"  # the world's token went away


def test_targets_and_robots_are_listed_as_a_person_counts():
    from cekm_swarm.runtime.monitor_state import natural_key

    assert sorted(["t10", "t2", "t1", "r10", "r9", "a"], key=natural_key) == ["a", "r9", "r10", "t1", "t2", "t10"]
    st = MonitorState()
    targets = {f"t{i}": (0.1 * i, 0.5) for i in (1, 2, 10)}
    st.observe(K.world_state(), encode(tracking_state(1.0, targets, robots=("r1", "r2", "r10"))), at=1.0)
    st.observe(K.share("r10"), encode(Share(1.0, "r10", (0.0, 0.2, 0.0), {"t10": (1.0, 0.5)})), at=1.0)
    st.observe(K.share("r2"), encode(Share(1.0, "r2", (0.0, 0.2, 0.0), {"t1": (0.1, 0.5)})), at=1.0)
    tr = json.loads(json_line(snapshot(st, 1.1)))["tracking"]
    assert list(tr["targets"]) == ["t1", "t2", "t10"] and list(tr["per_robot"]) == ["r2", "r10"]


def test_a_learning_robots_map_version_is_shown():
    """docs/learning.md: the monitor shows each learning robot's map version, steps and error."""
    import numpy as np

    from cekm_swarm.protocol import MapVersion

    st = MonitorState()
    st.observe(K.world_state(), encode(world_state(1.0, 0.3)), at=10.0)
    w, M = np.zeros(18), np.zeros(36)
    from cekm_swarm.models.learning import map_digest

    msg = MapVersion(1.024, "r1/learner", 3, 24, 20, 4, map_digest(w, M), w, M, 0.0125)
    st.observe(K.node_key("r1", "model/update"), encode(msg), at=10.1)
    assert st.robots["r1"].map == (3, 20, 0.0125)
    text = render_text(st, now=10.2)
    assert "map v3, 20 steps learned, error 0.0125 m/s" in text
    assert all(len(line) <= 80 for line in lines_of(text))
    assert snapshot(st, now=10.2)["robots"]["r1"]["map"] == {"version": 3, "steps": 20, "error_m_s": 0.0125}
