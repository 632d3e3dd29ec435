"""The field-parameter environment: Gymnasium's checker, seeding, and that its episode
is ``cekm run``'s for the same (fixed) field parameters."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from cekm_swarm.experiments.field_widths import CONSTANT_GRAPH
from cekm_swarm.experiments.graph_run import run_graph
from cekm_swarm.models.params import FieldParams
from cekm_swarm.tune.env import FieldEnv
from cekm_swarm.tune.motor import PLAIN
from world import load_scenario


def _episode(env: FieldEnv, seed: int, actions) -> tuple[list, list, dict]:
    obs, _ = env.reset(seed=seed)
    seen, rewards = [obs], []
    for a in actions():
        obs, r, term, trunc, _ = env.step(a)
        seen.append(obs)
        rewards.append(r)
        if term or trunc:
            break
    return seen, rewards, env.outcome()


@pytest.mark.parametrize("task,max_time", [("navigation", 6.0), ("tracking", 3.0)])
def test_passes_gymnasiums_check(task, max_time):
    env = FieldEnv(task, max_time=max_time)
    check_env(env, skip_render_check=True)
    env.close()


def test_same_seed_same_episode_other_seed_other_scenario():
    env = FieldEnv("navigation", max_time=8.0)
    rng = np.random.default_rng(5)
    acts = [rng.uniform(-1, 1, env.action_space.shape) for _ in range(100)]
    a = _episode(env, 7, lambda: iter(acts))
    seed_a = env.scenario_seed
    b = _episode(env, 7, lambda: iter(acts))
    assert env.scenario_seed == seed_a
    assert all(np.array_equal(x, y) for x, y in zip(a[0], b[0], strict=True)) and len(a[0]) == len(b[0])
    assert a[1] == b[1] and a[2] == b[2]
    _episode(env, 8, lambda: iter(acts))
    assert env.scenario_seed != seed_a


def test_an_action_moves_the_field_widths_within_their_span():
    env = FieldEnv("navigation", max_time=2.0)
    env.reset(seed=1)
    _, _, _, _, info = env.step(np.array([1.0, -1.0, 0.0, 1.0, -1.0], dtype=np.float32))
    f = info["fields"]
    base = FieldParams()
    assert f["sigma_b_alpha"] == pytest.approx(2 * base.sigma_b_alpha)
    assert f["sigma_b_d_beyond"] == pytest.approx(base.sigma_b_d_beyond / 4)
    assert f["sigma_b_d_near"] == base.sigma_b_d_near and f["sigma_a_d"] == pytest.approx(2 * base.sigma_a_d)
    assert f["sigma_a_alpha"] == pytest.approx(base.sigma_a_alpha / 4)


@pytest.mark.parametrize("name,max_time", [("concave", None), ("doorway", None), ("tracking", 8.0)])
def test_the_zero_action_episode_is_cekm_runs(name, max_time):
    """Action 0 is today's constants; stepping to the end gives ``cekm run --fields tuned``'s
    outcome exactly (the constant-width graph: navigation's cekm-tuned, tracking's cekm;
    navigation's motor with Eq. 11's turns as they are and no trail field, PLAIN)."""
    sc = load_scenario(name)
    task = "tracking" if name == "tracking" else "navigation"
    env = FieldEnv(task, sc, max_time=max_time or 600.0, **(PLAIN if task == "navigation" else {}))
    zero = np.zeros(env.action_space.shape, dtype=np.float32)
    _, rewards, outcome = _episode(env, 0, lambda: itertools.repeat(zero))
    run = run_graph(sc, CONSTANT_GRAPH[env.task], max_time=max_time)
    assert outcome == run.episode.outcome()
    if name == "tracking":  # the return is the run's Parker's A
        assert sum(rewards) == pytest.approx(run.episode.meter.A, abs=1e-12)
    else:
        assert outcome["r1"]["reached"]
