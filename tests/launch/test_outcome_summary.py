"""What a finished `cekm launch` prints (cekm_swarm.launch.commands.outcome_summary)."""

from __future__ import annotations

from cekm_swarm.launch.commands import outcome_summary


def _outcome(**more) -> dict:
    doc = {"robots": {"r1": {"reached": True, "time_s": 12.34, "path_length_m": 1.5, "collisions": 0},
                      "r2": {"reached": False, "time_s": 40.0, "path_length_m": 0.7, "collisions": 1}},
           "sense_to_command_ms": {"p50": 3.1, "p99": 9.8, "n": 200}, "ticks": 100, "mode": "lockstep"}
    doc.update(more)
    return doc


def test_lockstep_robots_latency_and_no_deadline_line():
    lines = outcome_summary(_outcome())
    assert lines[0] == "r1: reached in 12.3 s, path 1.50 m, 0 collisions"
    assert lines[1].startswith("r2: NOT reached")
    assert "p99 9.8 ms (200 robot-ticks)" in lines[2]
    assert not any("deadline" in x for x in lines)


def test_real_time_misses_their_ticks_cpu_and_the_hosts_steal():
    cpu = {"total_ms_per_tick": 18.64, "ms_per_tick": {"world": 7.7, "obstacle": 6.7}, "not_counted": 2,
           "host": {"idle": 0.2, "steal": 0.31}}
    doc = _outcome(mode="realtime", deadline_misses=12, first_tick_ms=171.2,
                   deadline_miss_ticks={str(k): 1 for k in (30, 4, 5, 6, 7, 8, 9, 10, 11, 12)},
                   launcher={"cpu": cpu, "restarts": {"r1/motor": 1}})
    lines = outcome_summary(doc)
    miss = next(x for x in lines if x.startswith("deadline misses"))
    assert miss.startswith("deadline misses: 12 of 200 robot-ticks, in 10 ticks (4, 5, 6, 7, 8, 9, 10, 11, ...)")
    assert "tick 0 answered after 171 ms" in miss
    cpu_line = next(x for x in lines if x.startswith("CPU per tick"))
    assert cpu_line == ("CPU per tick: 18.6 ms (world 7.7, obstacle 6.7); 2 process lives not counted (restarts: "
                        "begun or ended mid-run); the host stole 31 % of this machine's time meanwhile (timings are "
                        "slower for it)")
    assert lines[-1] == "restarts: {'r1/motor': 1}"


def test_a_tracking_run_prints_a_and_no_goal():
    spread = {"robots_start": 0.5, "robots_end": 1.25, "targets_start": 2.0, "targets_end": 2.5}
    doc = _outcome(tracking={"A": 0.8851, "robots": 1, "targets": 2, "ticks": 100,
                             "A_per_target": {"t1": 0.9, "t2": 0.87},
                             "spread": spread})
    lines = outcome_summary(doc)
    assert lines[0] == "r1: path 1.50 m, 0 collisions"
    # the line cekm run prints for the same result
    assert ("A = 0.885 (1 robot, 2 targets; per target: t1 0.90, t2 0.87); robots apart 0.50 -> 1.25 m while targets "
            "2.00 -> 2.50 m; collisions 1") in lines  # r2 touched once


def test_a_ros2_plant_run_says_collisions_are_not_known_and_its_scan_to_twist_latency():
    doc = _outcome(mode="realtime", scan_to_twist_ms={"p50": 38.7, "p99": 78.0, "n": 73})
    doc["robots"]["r1"]["collisions"] = None
    lines = outcome_summary(doc)
    assert lines[0] == "r1: reached in 12.3 s, path 1.50 m, collisions not known (a ROS 2 robot)"
    assert "scan-to-Twist latency p50 38.7 ms, p99 78.0 ms (73 Twists)" in lines
    doc["robots"]["r2"]["reached"] = None  # a tracking robot of a ROS 2 plant run: no goal
    assert outcome_summary(doc)[1] == "r2: path 0.70 m, 1 collisions"
