"""The team environment (PettingZoo, one agent per robot): PettingZoo's API test, seeding,
that it is FieldEnv's world and controller (the zero action gives FieldEnv's and ``cekm
run``'s outcome; one robot gets FieldEnv's rewards), agents leaving as they reach their
goals, and each agent's action reaching its own robot's motor."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from pettingzoo.test import parallel_api_test

from cekm_swarm.errors import ParameterError
from cekm_swarm.experiments.field_widths import CONSTANT_GRAPH
from cekm_swarm.experiments.graph_run import run_graph
from cekm_swarm.tune.env import FieldEnv
from cekm_swarm.tune.motor import PLAIN
from cekm_swarm.tune.team_env import FieldTeamEnv
from world import load_scenario


def _random_actions(env: FieldTeamEnv, seed: int):
    rng = np.random.default_rng(seed)
    k = len(env.policy.outputs)
    while True:
        yield {a: rng.uniform(-1, 1, k).astype(np.float32) for a in env.possible_agents}


def _episode(env: FieldTeamEnv, seed: int, actions) -> tuple[list, list, list, dict]:
    """Observations, rewards and the agents left, step by step, and the outcome."""
    obs, _ = env.reset(seed=seed)
    seen, rewards, left = [obs], [], [list(env.agents)]
    for acts in actions:
        obs, r, _, _, _ = env.step({a: acts[a] for a in env.agents})
        seen.append(obs)
        rewards.append(r)
        left.append(list(env.agents))
        if not env.agents:
            break
    return seen, rewards, left, env.outcome()


@pytest.mark.filterwarnings("error")  # the API test's complaints are warnings: they fail here
@pytest.mark.parametrize("task,scenario,robots,max_time", [
    ("navigation", None, None, 4.0),  # generated: one robot
    ("navigation", "crossing", None, 4.0),  # three robots
    ("tracking", None, 2, 2.0),  # generated grid cells of two robots
])
def test_passes_pettingzoos_parallel_api_test(task, scenario, robots, max_time):
    env = FieldTeamEnv(task, scenario and load_scenario(scenario), max_time=max_time, robots=robots)
    parallel_api_test(env, num_cycles=100)
    env.close()


def test_same_seed_same_episode_other_seed_other_scenario():
    env = FieldTeamEnv("tracking", max_time=3.0, robots=2)
    a = _episode(env, 7, _random_actions(env, 5))
    seed_a = env.scenario_seed
    b = _episode(env, 7, _random_actions(env, 5))
    assert env.scenario_seed == seed_a and env.possible_agents == ["r1", "r2"]
    assert len(a[0]) == len(b[0]) > 2
    for x, y in zip(a[0], b[0], strict=True):
        assert x.keys() == y.keys() and all(np.array_equal(x[k], y[k]) for k in x)
    assert a[1] == b[1] and a[3] == b[3]
    _episode(env, 8, _random_actions(env, 5))
    assert env.scenario_seed != seed_a
    env.close()


def test_one_robot_gets_field_envs_rewards_and_observations():
    """On a one-robot scenario the agent's observation and reward are FieldEnv's (same world, same terms)."""
    team, single = FieldTeamEnv("navigation", max_time=10.0), FieldEnv("navigation", max_time=10.0)
    acts = list(itertools.islice(_random_actions(team, 3), 200))
    seen, rewards, _, outcome = _episode(team, 11, acts)
    obs, _ = single.reset(seed=11)
    assert single.scenario_seed == team.scenario_seed and np.array_equal(obs, seen[0]["r1"])
    for i, a in enumerate(acts[:len(rewards)]):
        obs, r, term, trunc, _ = single.step(a["r1"])
        assert np.array_equal(obs, seen[i + 1]["r1"]) and r == rewards[i]["r1"]
    assert term or trunc
    assert single.outcome() == outcome
    team.close()
    single.close()


def _zero_action_episodes(task: str, name: str, max_time: float):
    """The team env's episode and FieldEnv's, every action 0, on shipped scenario ``name``, seed 0."""
    sc = load_scenario(name)
    plain = PLAIN if task == "navigation" else {}  # Eq. 11's turns as they are, no trail: the constants' motor
    team = FieldTeamEnv(task, sc, max_time=max_time, **plain)
    zero = np.zeros(len(team.policy.outputs), dtype=np.float32)
    _, rewards, left, outcome = _episode(team, 0, itertools.repeat(dict.fromkeys(team.possible_agents, zero)))
    team.close()
    single = FieldEnv(task, sc, max_time=max_time, **plain)
    single.reset(seed=0)
    single_rewards = []
    while True:
        _, r, term, trunc, _ = single.step(zero)
        single_rewards.append(r)
        if term or trunc:
            break
    assert outcome == single.outcome() == run_graph(sc, CONSTANT_GRAPH[task], max_time=max_time).episode.outcome()
    single.close()
    return team, rewards, left, single_rewards


def test_the_zero_action_episode_is_field_envs_and_cekm_runs_and_agents_leave_at_their_goals():
    team, rewards, left, _ = _zero_action_episodes("navigation", "crossing", 60.0)
    # the robots reach their goals at different times: each leaves `agents` on its own step, the others go on
    gone = {r: next(i for i, names in enumerate(left) if r not in names) for r in team.possible_agents}
    assert len(set(gone.values())) > 1 and left[-1] == []
    first = min(gone, key=gone.get)
    assert left[gone[first]] and first not in left[gone[first]]
    for r, i in gone.items():  # +1 on the step it reached its goal, and no reward after it
        assert rewards[i - 1][r] > 1.0 - 0.5 and all(r not in rw for rw in rewards[i:])


def test_tracking_every_agent_gets_the_teams_parker_a():
    team, rewards, left, single_rewards = _zero_action_episodes("tracking", "tracking", 8.0)
    assert left[-2] == team.possible_agents and left[-1] == []
    for r in team.possible_agents:  # FieldEnv's reward, step by step: the run's Parker's A in all
        assert [rw[r] for rw in rewards] == single_rewards


@pytest.mark.parametrize("task,name", [("navigation", "crossing"), ("tracking", "tracking")])
def test_each_agents_action_reaches_its_own_robots_motor(task, name):
    env = FieldTeamEnv(task, load_scenario(name), max_time=5.0)
    env.reset(seed=0)
    k = len(env.policy.outputs)
    actions = {a: np.full(k, v, dtype=np.float32) for a, v in zip(env.agents, (1.0, -1.0, 0.5), strict=False)}
    _, _, _, _, infos = env.step(actions)
    chosen = {a: env.motor_of[a].last_choice for a in actions}
    for a, act in actions.items():
        assert chosen[a] == env.policy.choice(act)  # the parameters its motor used at its last tick
        assert list(infos[a]["fields"].values()) == pytest.approx(list(env.policy.values(act).values()))
    assert len({c.fields.sigma_b_alpha for c in chosen.values()}) == len(actions)  # not one robot's for all
    env.close()


def test_bad_use_is_refused_naming_it():
    env = FieldTeamEnv("navigation", load_scenario("crossing"), max_time=2.0)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="r9"):
        env.step({"r9": np.zeros(3, dtype=np.float32)})
    env.close()
    with pytest.raises(ParameterError, match="robots="):
        FieldTeamEnv("navigation", load_scenario("crossing"), robots=3)
    with pytest.raises(ParameterError, match="one robot"):
        FieldTeamEnv("navigation", robots=3)
    with pytest.raises(ParameterError, match="no cell of 5 robots"):
        FieldTeamEnv("tracking", robots=5, max_time=1.0).reset(seed=0)
