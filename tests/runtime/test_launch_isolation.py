"""Run isolation: a launcher killed with SIGKILL leaves no process of its run behind (the
kernel's parent-death signal stops its children), and the next lockstep launch on the
same port equals ``cekm run`` bit for bit, as if the killed run had never been."""

from __future__ import annotations

import json
import signal
import time
from pathlib import Path

import pytest

from cekm_swarm.experiments.default_model import default_model, default_model_path
from cekm_swarm.experiments.navigation_run import run_scenario
from helpers.launch import LaunchProcess
from world import load_scenario

pytestmark = pytest.mark.slow  # starts real processes (tests/process_guard.py)

SEED = 2


def running(pid: int) -> bool:
    """True while ``pid`` exists and is not a zombie (a reaped-later child counts as gone)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


def processes_of_run(run_id: str) -> list[int]:
    """Every live process whose command line names ``run_id`` (a node forked warm shows
    the command line it would have had as one string)."""
    found = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                argv = (d / "cmdline").read_bytes().split(b"\0")
            except OSError:
                continue
            if any(run_id.encode() in a.split(b" ") for a in argv) and running(int(d.name)):
                found.append(int(d.name))
    return found


def test_sigkill_of_the_launcher_leaves_no_process_and_the_next_run_is_clean(tmp_path):
    default_model(progress=False)
    model = str(default_model_path())
    first = LaunchProcess("lone_obstacle", tmp_path / "killed", "--mode", "realtime", "--seed", str(SEED),
                          "--model", model, "--no-plot")
    try:
        run_id = first.wait_line("run id ", timeout=60).rsplit("run id ", 1)[1].strip()
        first.wait_line("world started ticking", timeout=120)
        pids = first.pids()
        assert len(pids) == 16 and all(running(p) for p in pids.values())  # 14 nodes, world, fork server
        assert "launch/fork-server" in pids
        assert sorted(processes_of_run(run_id)) == sorted(pids.values())
        first.proc.send_signal(signal.SIGKILL)
        first.proc.wait(10)
        deadline = time.monotonic() + 2.0
        while time.monotonic() < deadline and (left := [p for p in pids.values() if running(p)]):
            time.sleep(0.05)
        left = [label for label, p in pids.items() if running(p)]
        assert not left, f"still running 2 s after the launcher's SIGKILL: {left}"
        assert processes_of_run(run_id) == []
    finally:
        first.kill()
    # the world server had SIGTERM, not SIGKILL: it closed its log and wrote its outcome
    assert json.loads((tmp_path / "killed" / "outcome.json").read_text())["aborted"]

    second = LaunchProcess("lone_obstacle", tmp_path / "next", "--mode", "lockstep", "--seed", str(SEED),
                           "--model", model, "--no-plot", "--max-time", "40", port=first.port)
    try:
        assert second.finish(timeout=120) == 0, "\n".join(second.lines[-30:])
    finally:
        second.kill()
    outcome = second.outcome()
    assert outcome["run_id"] != run_id and outcome["republished"] == 0
    ref = run_scenario(load_scenario("lone_obstacle"), "cekm", default_model(progress=False), SEED, max_time=40)
    traj = json.loads((second.out / "trajectory.json").read_text())["r1"]
    assert traj["x"] == ref.logs["r1"].x and traj["v_l"] == ref.logs["r1"].v_l
    assert outcome["robots"]["r1"]["time_s"] == ref.outcome["r1"]["time_s"]


def test_ctrl_c_stops_the_run_cleanly_and_exits_130(tmp_path):
    default_model(progress=False)
    run = LaunchProcess("lone_obstacle", tmp_path / "out", "--mode", "realtime", "--model", str(default_model_path()),
                        "--no-plot")
    try:
        run.wait_line("world started ticking", timeout=120)
        pids = run.pids()
        run.proc.send_signal(signal.SIGINT)
        code = run.finish(timeout=60)
    finally:
        run.kill()
    assert code == 130, "\n".join(run.lines[-20:])
    assert run.lines[-1] == "cekm: interrupted"
    assert not any("Traceback" in line for line in run.lines)
    outcome = run.outcome()
    assert outcome["aborted"] and outcome["launcher"]["interrupted"]
    assert not [label for label, p in pids.items() if running(p)]
