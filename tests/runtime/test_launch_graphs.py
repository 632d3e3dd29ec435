"""Every controller through the runtime as its graph: a lockstep `cekm launch` equals
`cekm run` bit for bit -- the outcome, the per-tick series and every path sample and
wheel command -- for every shipped controller on every shipped scenario it applies to,
and on scenarios generated from seeds (1 to 8 robots, random starts, goals or targets,
obstacles), some with a node SIGKILLed and restarted while the world ticks."""

from __future__ import annotations

import json
import os
import random
import signal

import pytest
from scenario_gen import generated_scenario

from cekm_swarm.experiments.default_model import default_model, default_model_path
from cekm_swarm.experiments.graph_run import run_graph
from cekm_swarm.experiments.navigation_run import plan_all
from helpers.launch import LaunchProcess
from world import World, load_scenario

pytestmark = pytest.mark.slow  # starts real processes (tests/process_guard.py)

NAVIGATION = ["training", "concave", "doorway", "lone_obstacle", "crossing", "rooms", "checkpoints"]
TRACKING = ["tracking", "tracking-crowd"]
SHIPPED = ([(s, c) for s in NAVIGATION for c in ("cekm", "cekm-tuned", "fusion", "stay")]
           + [(s, c) for s in TRACKING for c in ("cekm", "acmommt", "kmeans", "kmeans-global", "stay")])
MAX_TIME = {"crossing": 15.0, "tracking-crowd": 12.0}  # s of sim time; the others 10


def launch(out, scenario: str, controller: str, max_time: float, *, seed: int | None = None, kill=None,
           extra: tuple[str, ...] = ()) -> LaunchProcess:
    args = ["--mode", "lockstep", "--controller", controller, "--max-time", str(max_time), "--no-plot",
            "--model", str(default_model_path()), *extra]
    if seed is not None:
        args += ["--seed", str(seed)]
    run = LaunchProcess(scenario, out, *args)
    try:
        run.wait_line("world started ticking", timeout=180)
        if kill is not None:
            os.kill(run.pids()[kill], signal.SIGKILL)
        code = run.finish(timeout=300)
    finally:
        run.kill()
    assert code == 0, "\n".join(run.lines[-40:])
    return run


def assert_equals_cekm_run(run: LaunchProcess, scenario: str, controller: str, max_time: float) -> None:
    outcome = run.outcome()
    sc = load_scenario(scenario)
    checkpoints = None
    if sc.name == "checkpoints":
        w = World(sc)
        checkpoints = plan_all(w, w.static_geometry())[0]
    ref = run_graph(sc, controller, model=default_model(progress=False), seed=outcome["seed"], max_time=max_time,
                    checkpoints=checkpoints)
    traj = json.loads((run.out / "trajectory.json").read_text())
    assert set(traj) == set(ref.episode.progress)
    for r, p in ref.episode.progress.items():
        t = traj[r]
        assert list(zip(t["t"], t["x"], t["y"], t["theta"], strict=True)) == [tuple(q) for q in p.path], (
            r
        )  # every path sample
        assert list(zip(t["v_l"], t["v_r"], strict=True)) == [tuple(c) for c in p.commands], r  # every wheel command
    assert outcome["robots"] == json.loads(json.dumps(ref.episode.outcome()))
    assert outcome["ticks"] == ref.ticks and outcome["controller"] == controller
    if ref.task == "tracking":  # Parker's A, per target, and every per-tick series
        assert outcome["tracking"] == json.loads(json.dumps(ref.episode.meter.summary()))
    assert outcome["reproducible"]["equals_cekm_run"] is True


@pytest.mark.parametrize("scenario, controller", SHIPPED, ids=lambda x: x)
def test_every_shipped_controller_on_every_shipped_scenario_equals_cekm_run(tmp_path, scenario, controller):
    max_time = MAX_TIME.get(scenario, 10.0)
    run = launch(tmp_path / "out", scenario, controller, max_time)
    assert_equals_cekm_run(run, scenario, controller, max_time)


def test_a_cold_start_equals_cekm_run_as_the_warm_start_does(tmp_path):
    """Every node exec'd afresh (--cold-start) instead of forked from the fork server."""
    run = launch(tmp_path / "out", "crossing", "cekm", 10.0, extra=("--cold-start",))
    assert "launch/fork-server" not in run.pids() and "warm start" not in "\n".join(run.lines)
    assert_equals_cekm_run(run, "crossing", "cekm", 10.0)


STATELESS = {"cekm": ["motor", "obstacle-3", "obstacle-0"], "fusion": ["avoid", "motor", "target"],
             "acmommt": ["motor"], "kmeans": ["motor"], "kmeans-global": ["motor"]}


@pytest.mark.parametrize("seed, robots", [(101, 1), (202, 3), (303, 5), (404, 8)])
def test_generated_scenarios_equal_cekm_run_with_a_node_killed_and_restarted(tmp_path, seed, robots):
    """Seeded: a failure names its seed, and `scenario_gen.generated_scenario(folder, seed,
    robots)` writes the same scenario again."""
    rng = random.Random(seed)
    task = rng.choice(["navigation", "tracking"])
    path = generated_scenario(tmp_path, seed, robots, task)
    controller = rng.choice(["cekm", "fusion"] if task == "navigation" else ["cekm", "acmommt"])
    team = [r.id for r in load_scenario(path).robots]
    kill = None
    if rng.random() < 0.75:  # most runs lose a node that keeps no state across ticks
        kill = f"{rng.choice(team)}/{rng.choice(STATELESS[controller])}"
    print(f"seed {seed}: {robots} robots, {task}, {controller}, kill {kill}")
    run = launch(tmp_path / "out", str(path), controller, 15.0, seed=rng.randrange(2**31), kill=kill)
    if kill is not None:
        assert run.outcome()["launcher"]["restarts"].get(kill) == 1, run.outcome()["launcher"]
    assert_equals_cekm_run(run, str(path), controller, 15.0)


@pytest.mark.slow
@pytest.mark.parametrize("seed, controller", [(505, "kmeans"), (606, "kmeans-global")])
def test_the_kmeans_baselines_on_generated_teams_equal_cekm_run_with_the_motor_killed(tmp_path, seed, controller):
    """Six robots on a generated tracking scenario; one robot's motor SIGKILLed and restarted."""
    rng = random.Random(seed)
    path = generated_scenario(tmp_path, seed, 6, "tracking")
    team = [r.id for r in load_scenario(path).robots]
    kill = f"{rng.choice(team)}/motor"
    run = launch(tmp_path / "out", str(path), controller, 15.0, seed=rng.randrange(2**31), kill=kill)
    assert run.outcome()["launcher"]["restarts"].get(kill) == 1, run.outcome()["launcher"]
    assert_equals_cekm_run(run, str(path), controller, 15.0)


def test_a_restarted_node_that_keeps_state_is_reported_as_breaking_the_equality(tmp_path):
    """The tracking target node remembers where targets were reported: killed, it restarts
    without that memory, and the outcome says the run may no longer equal cekm run."""
    run = launch(tmp_path / "out", "tracking", "cekm", 10.0, kill="r2/target")
    rep = run.outcome()["reproducible"]
    assert rep["equals_cekm_run"] is False and rep["stateful_restarts"] == ["r2/target"]
