"""``cekm launch --plant ros2``: what the launcher gives the plant, and the runs it refuses
before anything starts (one line, exit code 2, nothing written)."""

from __future__ import annotations

import pytest

from cekm_swarm.cli import main
from cekm_swarm.cli_support import run_cli
from cekm_swarm.launch.plant_host import goals_of, plant_description
from cekm_swarm.robot import RobotBody
from world import load_scenario


def test_goals_come_from_the_scenario():
    assert goals_of(load_scenario("lone_obstacle")) == ({"r1": [1.5, 1.0]}, {"r1": "goal"})
    crossing = load_scenario("crossing")
    goals, ids = goals_of(crossing)
    assert set(goals) == {r.id for r in crossing.robots} and all(len(g) == 2 for g in goals.values())


def test_the_description_defaults_to_the_scenarios_body(tmp_path):
    desc = plant_description(load_scenario("lone_obstacle"), None, RobotBody(), True, "navigation")
    assert desc.body == RobotBody() and desc.sensors == "scan"
    f = tmp_path / "bot.toml"
    f.write_text("axle = 0.16\n")
    assert plant_description(load_scenario("lone_obstacle"), f, RobotBody(), False, "navigation").body.axle == 0.16


@pytest.mark.parametrize("args, says", [
    (["--mode", "lockstep"], "--plant ros2 runs in real time"),
    (["--robot-description", "{bot}"], "bot.toml: the robot's body differs from the one the model was trained for: "
                                        "axle 0.16 m (the model's: 0.053 m)"),
])
def test_a_plant_run_that_cannot_work_is_refused_before_anything_starts(capsys, tmp_path, args, says):
    bot = tmp_path / "bot.toml"
    bot.write_text("axle = 0.16\n")
    out = tmp_path / "run"
    argv = ["launch", "lone_obstacle", "--plant", "ros2", "--out", str(out)] + [a.format(bot=bot) for a in args]
    assert run_cli(main, argv) == 2
    err = capsys.readouterr().err
    assert says in err and "Traceback" not in err
    assert not out.exists()


def test_a_description_without_the_plant_is_refused(capsys, tmp_path):
    bot = tmp_path / "bot.toml"
    bot.write_text("")
    assert (
        run_cli(main, ["launch", "lone_obstacle", "--robot-description", str(bot), "--out", str(tmp_path / "r")]) == 2
    )
    assert "use it with --plant ros2" in capsys.readouterr().err
