"""A PettingZoo parallel environment over the in-process graph runner: one agent per robot
(docs/fields.md, "A team environment (PettingZoo)").

The same episode as :class:`~cekm_swarm.tune.env.FieldEnv` (:class:`.env_core.FieldEnvCore`:
``cekm run``'s world and controller, the field-policy motor), but each robot is an agent:

* agents: the scenario's robots, by id (``possible_agents``: the fixed scenario's robots,
  or every id a generated scenario of the task can have, :func:`.scenarios.team_ids`;
  ``robots=N`` draws generated tracking scenarios among the grid's cells of N robots, so
  that every possible agent plays every episode, as PettingZoo's API test expects);
* observation: the robot's OWN features (:mod:`.features`), float32 in [0, 1];
* action: the robot's OWN field parameters, in [-1, 1]^k mapped by
  :meth:`.policy.FieldPolicy.choice` (0 is today's hand-tuned values), held for
  ``ticks_per_action`` ticks; an agent left out of a step's actions keeps its last ones;
* reward, navigation: the robot's own terms as FieldEnv computes them for the team -- the
  drop in its distance to its goal over its start's distance, minus ``contact_penalty``
  per new contact of its own, plus 1 when it reaches its goal; tracking: the team's
  Parker's A of the ticks run (over the run's ticks), the same for every agent (A is a
  team metric: no robot's share of it is defined);
* navigation: an agent whose robot reached its goal is terminated and leaves ``agents``
  while the others go on (its robot stays in the world, stopped at its goal by its
  controller, with its last field parameters, as in ``cekm run``); when the run ends at
  ``max_time`` every agent left is truncated. Tracking: every agent is truncated together
  at ``max_time``.

``reset(seed=)`` seeds ``np_random`` as Gymnasium and PettingZoo ask; the episode's
scenario is drawn from it (generated) or is the one given. The same seed gives the same
episode. With every agent at action 0 the run is ``cekm run``'s (tested).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from gymnasium import spaces  # noqa: TID253 -- the agents' spaces; only this module and `cekm tune` import it
from gymnasium.utils import seeding  # noqa: TID253 -- as above

try:
    from pettingzoo import ParallelEnv  # noqa: TID253 -- the environment subclasses ParallelEnv; nothing else imports it
except ImportError as exc:  # pettingzoo is in the `test` extra, not a runtime dependency
    raise ImportError("cekm_swarm.tune.team_env needs pettingzoo: pip install pettingzoo "
                      "(or the project's test extra, pip install -e '.[test]')") from exc

from ..errors import ParameterError
from .env_core import FieldEnvCore
from .features import N_FEATURES
from .motor import KEEP_CLEAR, TRAIL_GAIN
from .scenarios import team_ids


class FieldTeamEnv(FieldEnvCore, ParallelEnv):
    """Each robot's field parameters as its agent's action over a ``cekm run`` of one scenario
    (see the module docstring)."""

    metadata = {"name": "cekm_field_team_v0", "render_modes": [], "is_parallelizable": True}

    def __init__(self, task: str = "navigation", scenario: Any = None, *, ticks_per_action: int = 8,
                 max_time: float | None = None, purpose: str = "train", model: Any = None,
                 contact_penalty: float = 0.5, robots: int | None = None, turn_gain: float = math.inf,
                 trail_gain: float = TRAIL_GAIN, keep_clear: bool = KEEP_CLEAR) -> None:
        self.turn_gain = turn_gain  # navigation's motor: as cekm run's default graph (PLAIN: the constants' motor)
        self.trail_gain = trail_gain
        self.keep_clear = keep_clear
        self._setup(task, scenario, ticks_per_action, max_time, purpose, model, contact_penalty)
        if robots is not None and scenario is not None:
            raise ParameterError("FieldTeamEnv: robots= chooses generated scenarios; a scenario given has its own")
        self.team_size = robots
        ids = tuple(r.id for r in scenario.robots) if scenario is not None else team_ids(self.task, robots)
        self.possible_agents: list[str] = list(ids)
        self.agents: list[str] = []
        k = len(self.policy.outputs)
        self.observation_spaces = {a: spaces.Box(0.0, 1.0, (N_FEATURES,), dtype=np.float32) for a in ids}
        self.action_spaces = {a: spaces.Box(-1.0, 1.0, (k,), dtype=np.float32) for a in ids}
        self.np_random, self.np_random_seed = seeding.np_random()  # from the OS until reset(seed=) seeds it

    def observation_space(self, agent: str) -> spaces.Box:
        """The agent's space: the same object at every call, as PettingZoo asks."""
        return self.observation_spaces[agent]

    def action_space(self, agent: str) -> spaces.Box:
        return self.action_spaces[agent]

    # ------------------------------------------------------------------ PettingZoo API
    def reset(self, seed: int | None = None, options: dict | None = None):
        if seed is not None:
            self.np_random, self.np_random_seed = seeding.np_random(seed)
        self._start()
        unknown = sorted(set(self.robots) - set(self.possible_agents))
        if unknown:
            raise ParameterError(f"FieldTeamEnv: the scenario's robots {unknown} are not among its possible "
                                 f"agents {self.possible_agents}")
        zero = self.policy.choice(np.zeros(len(self.policy.outputs)))
        for r in self.robots:
            self._set(r, zero)
        self.done = self._run(1)
        self.agents = list(self.robots)
        nav = self.task == "navigation"
        self.start_distance = {r: max(self._to_goal(r), 1e-9) if nav else 1.0 for r in self.robots}
        self.last_distance = {r: self._to_goal(r) if nav else 0.0 for r in self.robots}
        self.last_contacts = {r: self._contacts_of(r) for r in self.robots}
        self.last_observed = 0.0  # the return of an episode is its A, tick 0 included
        return {r: self._observation(r) for r in self.agents}, {r: self._info(r) for r in self.agents}

    def step(self, actions: dict[str, Any]):
        if self.session is None:
            raise RuntimeError("FieldTeamEnv.step before reset")
        if not self.agents:
            raise RuntimeError("FieldTeamEnv.step after every agent is done: call reset")
        stray = sorted(set(actions) - set(self.agents))
        if stray:
            raise ValueError(f"FieldTeamEnv.step: actions for {stray}, which are not live agents {self.agents}")
        for r, a in actions.items():
            self._set(r, self.policy.choice(np.asarray(a, dtype=np.float64)))
        if not self.done:
            self.done = self._run(self.ticks_per_action)
        rewards: dict[str, float] = {}
        terminated: dict[str, bool] = {}
        if self.task == "navigation":
            for r in self.agents:
                d, c = self._to_goal(r), self._contacts_of(r)
                reward = (self.last_distance[r] - d) / self.start_distance[r]
                reward -= self.contact_penalty * (c - self.last_contacts[r])
                self.last_distance[r], self.last_contacts[r] = d, c
                terminated[r] = self._reached(r)
                rewards[r] = reward + (1.0 if terminated[r] else 0.0)
        else:
            seen = self._observed()
            team = self._a_reward(seen, self.last_observed)  # Parker's A: the team's, every agent's
            self.last_observed = seen
            rewards = dict.fromkeys(self.agents, team)
            terminated = dict.fromkeys(self.agents, False)
        truncated = {r: self.done and not terminated[r] for r in self.agents}
        obs = {r: self._observation(r) for r in self.agents}
        infos = {r: self._info(r) for r in self.agents}
        self.agents = [r for r in self.agents if not (terminated[r] or truncated[r])]
        return obs, rewards, terminated, truncated, infos

    # ------------------------------------------------------------------ helpers
    def _observation(self, robot: str) -> np.ndarray:
        return self._as_observation(self._features(robot))

    def _info(self, robot: str) -> dict[str, Any]:
        ep = self._live.episode
        choice = self.motor_of[robot].override
        assert choice is not None  # every robot's is set at reset
        return {"t": ep.t, "tick": ep.tick, "scenario_seed": self.scenario_seed, "fields": self._fields_info(choice)}
