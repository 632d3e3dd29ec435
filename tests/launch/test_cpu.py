"""The launcher's CPU accounting (cekm_swarm.launch.cpu) on this process and on made-up snapshots."""

from __future__ import annotations

import os
import sys

import pytest

from cekm_swarm.launch.cpu import CpuSnapshot, cpu_per_tick, cpu_seconds, host_shares, host_times, kind_of, snapshot


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="/proc is Linux's")
def test_cpu_seconds_of_a_process_grows_with_work():
    before = cpu_seconds(os.getpid())
    x = 0
    for i in range(3_000_000):
        x += i
    after = cpu_seconds(os.getpid())
    assert before is not None and after is not None and after > before
    assert cpu_seconds(2**22 + 12345) is None  # no such process


def test_kinds_of_processes():
    assert kind_of("r1/obstacle-3") == "obstacle" and kind_of("r12/motor") == "motor"
    assert kind_of("launch/fork-server") == "fork-server" and kind_of("world/server") == "world"
    assert kind_of("r1/target") == "target" and kind_of("launcher") == "launcher"


def test_cpu_per_tick_sums_kinds_over_robots_and_skips_restarted_processes():
    start = CpuSnapshot({("world/server", 1): 1.0, ("r1/obstacle-0", 2): 0.5, ("r2/obstacle-0", 3): 0.5,
                         ("r1/motor", 4): 0.2, ("launcher", 9): 3.0})
    end = CpuSnapshot({("world/server", 1): 2.0, ("r1/obstacle-0", 2): 0.7, ("r2/obstacle-0", 3): 0.8,
                       ("r1/motor", 44): 9.0,  # restarted: another pid, not counted
                       ("launcher", 9): 3.1})
    doc = cpu_per_tick(start, end, ticks=10, robots=2)
    assert doc["ms_per_tick"] == {"world": 100.0, "obstacle": 50.0, "launcher": 10.0}
    assert list(doc["ms_per_tick"]) == ["world", "obstacle", "launcher"]  # largest first
    assert doc["total_ms_per_tick"] == 160.0 and doc["ms_per_robot_tick"] == 80.0
    assert doc["processes"] == {"launcher": 1, "obstacle": 2, "world": 1}
    assert doc["ms_per_process_tick"] == {"launcher": 10.0, "obstacle": 25.0, "world": 100.0}
    assert doc["not_counted"] == 2  # the motor's two lives, said beside the split
    assert doc["host"] == {}  # the made-up snapshots carry no machine reading
    assert cpu_per_tick(start, end, ticks=0, robots=2) == {}


def test_snapshot_includes_the_launcher_itself():
    snap = snapshot({"gone/motor": 2**22 + 12345})
    assert [k[0] for k in snap.seconds] == ["launcher"]


def test_a_process_that_reports_its_own_cpu_is_taken_at_its_word_even_when_gone():
    gone = 2**22 + 12345
    start = snapshot({"world/server": gone}, {("world/server", gone): 1.5})
    end = snapshot({}, {("world/server", gone): 2.0})  # exited before the launcher read its DONE line
    assert start.seconds[("world/server", gone)] == 1.5
    assert cpu_per_tick(start, end, ticks=10, robots=1)["ms_per_tick"]["world"] == 50.0


def test_host_shares_of_idle_and_stolen_time():
    # all, idle + iowait, steal clock ticks: 1000 ticks passed, 250 idle, 100 stolen
    assert host_shares((5000, 2000, 300), (6000, 2250, 400)) == {"idle": 0.25, "steal": 0.1}
    assert host_shares(None, (6000, 2250, 400)) == {} and host_shares((6000, 0, 0), (6000, 0, 0)) == {}


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="/proc is Linux's")
def test_host_times_move_forward_and_reach_the_outcome():
    a = host_times()
    x = 0
    for i in range(3_000_000):
        x += i
    b = host_times()
    assert a is not None and b is not None and b[0] > a[0] and b[1] >= a[1] and b[2] >= a[2]
    start, end = snapshot({}), None
    for i in range(3_000_000):
        x += i
    end = snapshot({})
    doc = cpu_per_tick(start, end, ticks=5, robots=1)
    assert set(doc["host"]) == {"idle", "steal"} and 0.0 <= doc["host"]["steal"] <= 1.0
