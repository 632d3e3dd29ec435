"""`cekm launch` in lockstep, end to end, on the paper's concave obstacle (Fig. 8): a real
embedded router on a free loopback port, the world server and 14 module processes; the
trajectory equals the in-process run bit for bit, even though an obstacle module and the
motor module are SIGKILLed as soon as the world starts ticking (the launcher restarts them;
the world re-publishes the waiting tick's readings until the restarted modules answer)."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys

import pytest

from cekm_swarm.experiments.default_model import default_model, default_model_path
from cekm_swarm.experiments.navigation_run import run_scenario
from cekm_swarm.protocol import DEFAULT_KEYS as K
from cekm_swarm.protocol import decode
from helpers.launch import LaunchProcess
from world import load_scenario

pytestmark = pytest.mark.slow  # starts real processes (tests/process_guard.py)

SEED = 1  # the cooperative EKM reaches the goal behind the U on this seed (README table)


@pytest.fixture(scope="module")
def lockstep_run(tmp_path_factory):
    model = default_model(progress=False)
    out = tmp_path_factory.mktemp("lockstep")
    run = LaunchProcess("concave", out, "--mode", "lockstep", "--seed", str(SEED), "--max-time", "40",
                        "--model", str(default_model_path()))
    try:
        run.wait_line("world started ticking", timeout=90)
        pids = run.pids()
        for label in ("r1/obstacle-5", "r1/motor"):
            os.kill(pids[label], signal.SIGKILL)
        code = run.finish(timeout=120)
    finally:
        run.kill()
    assert code == 0, "\n".join(run.lines)
    return run, model


def test_lockstep_reaches_the_goal_and_equals_the_in_process_run(lockstep_run):
    run, model = lockstep_run
    outcome = run.outcome()
    assert outcome["robots"]["r1"]["reached"], outcome
    assert outcome["mode"] == "lockstep" and outcome["seed"] == SEED
    assert any("all 14 modules alive" in line for line in run.lines)
    assert outcome["republished"] >= 1
    assert outcome["launcher"]["restarts"] == {"r1/obstacle-5": 1, "r1/motor": 1}
    ref = run_scenario(load_scenario("concave"), "cekm", model, SEED, max_time=40)
    traj = json.loads((run.out / "trajectory.json").read_text())["r1"]
    log = ref.logs["r1"]
    assert len(traj["t"]) == len(log.t)
    # bit for bit: every pose and every wheel command of every tick
    assert traj["t"] == log.t
    assert traj["x"] == log.x and traj["y"] == log.y and traj["theta"] == log.theta
    assert traj["v_l"] == log.v_l and traj["v_r"] == log.v_r
    assert outcome["robots"] == json.loads(json.dumps(ref.outcome))


def test_launcher_reports_where_the_tick_loop_cpu_went(lockstep_run):
    run, _ = lockstep_run
    outcome = run.outcome()
    cpu = outcome["launcher"]["cpu"]
    assert cpu["ticks"] == round(outcome["sim_seconds"] / 0.128)
    per = cpu["ms_per_tick"]
    assert set(per) == {"world", "target", "obstacle", "launcher", "fork-server"}  # the motor was restarted: left out
    assert all(per[k] > 0 for k in ("world", "target", "obstacle"))
    assert cpu["total_ms_per_tick"] == pytest.approx(sum(per.values()), abs=0.01)
    assert cpu["ms_per_robot_tick"] == pytest.approx(cpu["total_ms_per_tick"], abs=0.01)  # one robot


def test_lockstep_log_holds_the_sense_field_and_command_channels(lockstep_run):
    from mcap.reader import make_reader

    run, _ = lockstep_run
    with open(run.out / "run.mcap", "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        topics = {c.topic for c in summary.channels.values()}
        counts = {summary.channels[cid].topic: n for cid, n in summary.statistics.channel_message_counts.items()}
        encodings = {c.topic: c.message_encoding for c in summary.channels.values()}
        ticks = len(json.loads((run.out / "trajectory.json").read_text())["r1"]["t"])
        for key in [K.sense_target("r1"), K.field_target("r1"), K.cmd_wheels("r1"), K.world_state(),
                    K.world_clock()] + [K.sense_range("r1", j) for j in range(12)] + \
                   [K.field_obstacle("r1", j) for j in range(12)]:
            assert key in topics and encodings[key] == "msgpack", key
        # lockstep: one command per tick (and repeats for the re-published tick); the default
        # graph's motor reads every raw range (the movers' detector), so a range reading is sent
        # every tick, never held (the constant-width graph's holding: tests/node/test_held_readings.py)
        assert counts[K.cmd_wheels("r1")] >= ticks
        assert counts[K.sense_range("r1", 0)] >= ticks
        if K.sense_unchanged("r1") in counts:  # the target reading may still be held
            assert encodings[K.sense_unchanged("r1")] == "msgpack"
        from cekm_swarm.runtime.foxglove_view import SCENE_TOPIC, TF_TOPIC

        assert {SCENE_TOPIC, TF_TOPIC} <= topics  # the Foxglove view channels
        # every recorded command decodes, in stamp order
        stamps = [decode(K.cmd_wheels("r1"), m.data).stamp
                  for _, ch, m in reader.iter_messages(topics=[K.cmd_wheels("r1")])]
        assert stamps == sorted(stamps) and len(set(stamps)) == ticks
        assert counts[K.sense_target("r1")] >= (ticks + 1) // 2
    assert (run.out / "trajectory.png").stat().st_size > 10_000


def test_cekm_plot_draws_the_run_from_its_log(lockstep_run, tmp_path):
    from click.testing import CliRunner

    from cekm_swarm.cli import main
    from cekm_swarm.launch.plot import read_run

    run, _ = lockstep_run
    res = CliRunner().invoke(main, ["plot", str(run.out / "run.mcap"), "--out", str(tmp_path / "fig.png")])
    assert res.exit_code == 0, res.output
    assert (tmp_path / "fig.png").stat().st_size > 10_000
    drawn = read_run(run.out / "run.mcap")
    traj = json.loads((run.out / "trajectory.json").read_text())["r1"]
    assert [p[1] for p in drawn["paths"]["r1"]] == traj["x"]  # the log's poses are the run's
    assert drawn["geometry"]["name"] == "concave"


def test_a_taken_port_stops_the_launch_with_a_clear_error_and_leaves_out_as_it_found_it(tmp_path):
    """The router cannot listen on a port another program listens on: the launch is
    refused at once, in one line naming the address, before --out is touched, so the retry
    the line suggests (--port) needs no --overwrite: it runs, into the same --out."""
    out = tmp_path / "out"
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        r = subprocess.run([sys.executable, "-m", "cekm_swarm", "launch", "lone_obstacle", "--mode", "lockstep",
                            "--out", str(out), "--port", str(port), "--no-plot"],
                           capture_output=True, text=True, timeout=120)
    assert r.returncode == 1
    assert f"cannot open the Zenoh router on 127.0.0.1:{port}: Address already in use" in r.stderr
    assert r.stderr.startswith("cekm: failed: ") and r.stderr.count("\n") == 1 and "Traceback" not in r.stderr
    assert "choose another with --port" in r.stderr
    assert not out.exists()  # as it was found: the retry needs no --overwrite
    out.mkdir()  # an empty directory stays empty
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        r = subprocess.run([sys.executable, "-m", "cekm_swarm", "launch", "lone_obstacle", "--mode", "lockstep",
                            "--out", str(out), "--port", str(s.getsockname()[1]), "--no-plot"],
                           capture_output=True, text=True, timeout=120)
    assert r.returncode == 1 and list(out.iterdir()) == []
    # the retry the line suggests: another --port, the same --out, no --overwrite
    retry = LaunchProcess("lone_obstacle", out, "--mode", "lockstep", "--max-time", "0.5", "--no-plot")
    try:
        assert retry.finish(timeout=120) == 0, "\n".join(retry.lines[-20:])
    finally:
        retry.kill()
    assert retry.outcome()["robots"] and (out / "run.mcap").exists()
