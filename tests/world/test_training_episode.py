"""Section 4.1's training in the world (world.training; a scenario's ``retarget``): a new
random target when a robot stops at its own, or when its budget of steps runs out."""

from __future__ import annotations

import tomllib

import numpy as np
import pytest

from cekm_swarm.experiments.learning_experiment import scenario_text
from world import World
from world.run_episode import make_episode
from world.scenario import ScenarioError, parse_scenario
from world.training import EXPLORE_ABS, EXPLORE_REL, TrainingEpisode, explore

TEXT = scenario_text(1)  # one robot in section 4.1's arena, retarget = true


def world() -> World:
    return World(parse_scenario(tomllib.loads(TEXT)))


def test_a_retarget_scenario_runs_a_training_episode_to_its_max_time():
    w = world()
    assert w.scenario.retarget and not parse_scenario(tomllib.loads(TEXT.replace("true", "false"))).retarget
    ep = make_episode(w, "navigation")
    assert isinstance(ep, TrainingEpisode) and not ep.done


def test_a_new_target_at_a_stop_at_the_target_or_when_the_budget_runs_out():
    ep = TrainingEpisode(world(), seed=3, budget_ticks=4)
    p = ep.progress["r1"]
    ep.readings()
    p.reached = True  # as Episode marks a stop at the goal
    ep.apply({"r1": (0.0, 0.0)})
    first = p.checkpoints[0]
    assert not p.reached and ep.reached_count["r1"] == 1
    assert all(-2.45 <= c <= 2.45 for c in first) and ep.world.goal_of("r1") == first
    for _ in range(4):  # no stop: the budget
        ep.advance()
        ep.readings()
        ep.apply({"r1": (0.01, 0.01)})
    assert p.checkpoints[0] != first and ep.reached_count["r1"] == 1
    again = TrainingEpisode(world(), seed=3, budget_ticks=4)
    again.readings()
    again.progress["r1"].reached = True
    again.apply({"r1": (0.0, 0.0)})
    assert again.progress["r1"].checkpoints[0] == first  # seeded
    assert ep.outcome()["r1"]["targets_reached"] == 1


def test_exploration_noise_is_on_the_executed_command_seeded_and_a_stop_stays_a_stop():
    assert world().scenario.explore
    ep, again = TrainingEpisode(world(), seed=3), TrainingEpisode(world(), seed=3)
    for e in (ep, again):
        e.readings()
        e.apply({"r1": (0.05, 0.02)})
    held = ep.world.wheel_command("r1")
    assert held != (0.05, 0.02) and held == again.world.wheel_command("r1")  # executed: the noisy one, seeded
    ep.advance()
    ep.readings()
    ep.apply({"r1": (0.0, 0.0)})
    assert ep.world.wheel_command("r1") == (0.0, 0.0)
    rng = np.random.default_rng(0)
    z = np.array([explore((0.05, -0.02), rng) for _ in range(4000)]) - [0.05, -0.02]
    assert z.std(axis=0) == pytest.approx(
        [EXPLORE_REL * 0.05 + EXPLORE_ABS, EXPLORE_REL * 0.02 + EXPLORE_ABS], rel=0.05
    )
    plain = TrainingEpisode(World(parse_scenario(tomllib.loads(TEXT.replace("explore = true", "")))), seed=3)
    plain.readings()
    plain.apply({"r1": (0.05, 0.02)})
    direct = world()
    direct.set_wheels("r1", 0.05, 0.02)
    assert plain.world.wheel_command("r1") == direct.wheel_command("r1")  # without explore: the command as sent


def test_explore_without_retarget_is_refused_naming_the_key():
    with pytest.raises(ScenarioError, match="explore"):
        parse_scenario(tomllib.loads(TEXT.replace("retarget = true", "")))
