"""`cekm launch` on a tracking scenario (docs/tracking.md), end to end with real
processes: the world server publishing ``sense/pose`` and ``sense/targets``, per robot
the tracking target module, 12 obstacle modules and the motor, teammates' shares over
Zenoh.

* lockstep on ``tracking.toml``, with r1's motor and an obstacle module of r2 SIGKILLed
  once the world ticks (restarted; the world re-publishes the stalled tick's readings,
  poses and targets, the tracking module answers again): Parker's A (its per-tick series included), every
  robot's path and the outcome equal ``cekm run``'s bit for bit, and the log records the
  tracking channels;
* real time on ``tracking-crowd.toml`` with every process of one robot SIGKILLed: each
  teammate's tracking module drops it from its fields within a second of its liveliness
  tokens vanishing (measured by the teammates themselves: their ``DROP`` lines), and the
  run goes on to its end.
"""

from __future__ import annotations

import json
import math
import os
import signal
import time

import pytest

from cekm_swarm.experiments.default_model import default_model, default_model_path
from cekm_swarm.experiments.tracking_run import outcome_doc, run_tracking
from cekm_swarm.protocol import DEFAULT_KEYS as K
from helpers.launch import LaunchProcess
from world import load_scenario

pytestmark = pytest.mark.slow  # starts real processes (tests/process_guard.py)

SEED = 3
MAX_TIME = 30.0


@pytest.fixture(scope="module")
def lockstep_run(tmp_path_factory):
    model = default_model(progress=False)
    out = tmp_path_factory.mktemp("tracking-lockstep")
    run = LaunchProcess("tracking", out, "--mode", "lockstep", "--seed", str(SEED), "--max-time", str(MAX_TIME),
                        "--model", str(default_model_path()), "--no-plot")
    try:
        run.wait_line("world started ticking", timeout=180)
        pids = run.pids()
        for label in ("r1/motor", "r2/obstacle-3"):  # restarted; the world re-publishes the stalled tick
            os.kill(pids[label], signal.SIGKILL)
        code = run.finish(timeout=240)
    finally:
        run.kill()
    assert code == 0, "\n".join(run.lines)
    return run, model


def test_lockstep_tracking_equals_cekm_run_bit_for_bit(lockstep_run):
    run, model = lockstep_run
    outcome = run.outcome()
    ref = run_tracking(load_scenario("tracking"), "cekm", model, SEED, MAX_TIME)
    doc = json.loads(json.dumps(outcome_doc(ref)))
    assert outcome["mode"] == "lockstep" and not outcome["aborted"]
    assert outcome["launcher"]["restarts"] == {"r1/motor": 1, "r2/obstacle-3": 1}
    assert outcome["tracking"]["ticks"] == doc["tracking"]["ticks"] == math.ceil(MAX_TIME / 0.128) + 1
    assert outcome["tracking"]["A"] == doc["tracking"]["A"]
    assert outcome["tracking"] == doc["tracking"]  # the per-tick series and the spreads too
    assert outcome["robots"] == doc["robots"]
    traj = json.loads((run.out / "trajectory.json").read_text())
    for r, path in ref.paths.items():
        assert traj[r]["t"] == [p[0] for p in path]
        assert traj[r]["x"] == [p[1] for p in path] and traj[r]["y"] == [p[2] for p in path]
        assert traj[r]["theta"] == [p[3] for p in path]


def test_lockstep_tracking_log_holds_the_tracking_channels(lockstep_run):
    from mcap.reader import make_reader

    run, _ = lockstep_run
    with open(run.out / "run.mcap", "rb") as f:
        summary = make_reader(f).get_summary()
    counts = {summary.channels[cid].topic: n for cid, n in summary.statistics.channel_message_counts.items()}
    target_ticks = math.ceil(MAX_TIME / 0.128) // 2 + 1
    for r in ("r1", "r2"):
        for key in (K.sense_pose(r), K.sense_targets(r), K.share(r), K.field_tracking(r)):
            assert counts.get(key, 0) >= target_ticks - 1, (key, counts.get(key))
    from cekm_swarm.runtime import foxglove_view

    if foxglove_view.available():  # one sensing-circle view per tick
        assert counts.get(foxglove_view.TRACKING_TOPIC, 0) == math.ceil(MAX_TIME / 0.128) + 1


def test_lockstep_tracking_log_through_the_monitor_gives_the_runs_a(lockstep_run):
    """The run's log fed through `cekm monitor`'s own intake: at every target tick each
    target's observers are the robots whose sense/targets of that tick hold it, its
    instantaneous A is the run's per-tick A, and every message decodes (nothing dropped)."""
    import itertools

    from cekm_swarm.protocol import decode
    from cekm_swarm.runtime.mcap_log import read_messages
    from cekm_swarm.runtime.monitor import MonitorState

    run, _ = lockstep_run
    series = run.outcome()["tracking"]["series"]
    want = {round(t, 6): a for t, a in zip(series["t"], series["A"], strict=True)}
    st = MonitorState()
    got = {}
    msgs = [m for m in read_messages(run.out / "run.mcap") if m.topic.startswith("cekm/")]
    for stamp, group in itertools.groupby(msgs, key=lambda m: m.log_time):
        sensed = {}
        for m in group:
            st.observe(m.topic, m.data, stamp / 1e9)
            for r in ("r1", "r2"):
                if m.topic == K.sense_targets(r):
                    sensed[r] = set(decode(m.topic, m.data).targets)
        if len(sensed) == 2:  # a target tick: fresh observations
            assert st.is_tracking()
            tr = st.tracking()
            for tid, t in tr["targets"].items():
                assert t["observed_by"] == [r for r in ("r1", "r2") if tid in sensed[r]], (stamp, tid)
            assert {r: p["sees"] for r, p in tr["per_robot"].items()} == {r: len(v) for r, v in sensed.items()}
            got[round(st.sim_time, 6)] = tr["A"]
    assert st.drops.total == 0
    assert len(got) >= math.ceil(MAX_TIME / 0.128) // 2
    assert got == {t: want[t] for t in got}


def drop_lines(out, robot: str) -> list[dict]:
    """The ``DROP`` lines a robot's tracking target module logged."""
    path = out / "logs" / f"{robot}-target.log"
    return [json.loads(line.split("DROP ", 1)[1]) for line in path.read_text().splitlines() if "DROP {" in line]


def test_realtime_crowd_drops_a_killed_robot_within_a_second_and_goes_on(tmp_path):
    out = tmp_path / "crowd"
    run = LaunchProcess("tracking-crowd", out, "--mode", "realtime", "--max-time", "12", "--no-plot",
                        "--model", str(default_model_path()))
    try:
        run.wait_line("world started ticking", timeout=240)
        run.wait_line(" t=", timeout=60)  # a progress line: the robots are sharing
        victims = {label: pid for label, pid in run.pids().items() if label.startswith("r6/")}
        assert len(victims) == 14, victims
        killed_at = time.time()
        for pid in victims.values():
            os.kill(pid, signal.SIGKILL)
        code = run.finish(timeout=240)
    finally:
        run.kill()
    assert code == 0, "\n".join(run.lines[-40:])
    outcome = run.outcome()
    assert not outcome["aborted"] and outcome["sim_seconds"] >= 12.0 - 0.2, outcome["sim_seconds"]
    assert outcome["tracking"]["robots"] == 6
    delays = {}
    for r in ("r1", "r2", "r3", "r4", "r5"):
        drops = [d for d in drop_lines(out, r) if d["dropped"] == "r6" and d["wall"] >= killed_at]
        assert drops, f"{r} never dropped r6"
        delays[r] = drops[0]["wall"] - killed_at
    print(f"teammates dropped r6 after (s from the SIGKILL): {delays}")
    assert max(delays.values()) < 1.0, delays
    # r6's nodes came back: its next tick carried every range reading, held ones too, so its
    # restarted motor had at once the values its held fields stand on (world/publisher.py)
    from mcap.reader import make_reader

    from cekm_swarm.protocol import decode

    ranges = {K.sense_range("r6", j) for j in range(12)}
    sent: dict[float, set[str]] = {}
    with open(out / "run.mcap", "rb") as f:
        for _, channel, m in make_reader(f).iter_messages(topics=sorted(ranges)):
            msg = decode(channel.topic, m.data)
            if msg.sender == "world":
                sent.setdefault(msg.stamp, set()).add(channel.topic)
    assert [t for t, keys in sent.items() if t > 0 and keys == ranges], sorted(sent)[:20]
