"""A Gymnasium environment over the in-process graph runner (docs/fields.md).

The world and the controller are ``cekm run``'s: a :class:`~cekm_swarm.experiments.graph_run.GraphSession`
of the shipped cooperative-EKM graph whose motor node is the field-policy motor
(:mod:`.motor`). Every :meth:`FieldEnv.step` sets every robot's field parameters from the
action (in [-1, 1]^k, mapped by :meth:`.policy.FieldPolicy.choice`: 0 is today's hand-tuned
values) and runs ``ticks_per_action`` ticks. Navigation's motor is the default graph's: a
turn in place toward the rear executed at speed (``turn_gain``) and the trail field
(``trail_gain``) and keeping clear of detected movers (``keep_clear``, :mod:`.motor`);
``turn_gain=1, trail_gain=0, keep_clear=False`` (:data:`.motor.PLAIN`) makes action 0 exactly
``cekm run --fields tuned``.

* observation: the features of what the robots' fields see (:mod:`.features`), averaged
  over the team, float32 in [0, 1];
* reward, navigation: progress toward the goal (the drop in distance over the start's
  distance) minus ``contact_penalty`` per new contact, plus 1 on reaching the goal;
  tracking: Parker's A of the ticks run, over the run's ticks (an episode's return is its A);
* an episode ends when the run does (navigation: the goal reached; both: ``max_time``,
  a truncation).

``reset(seed=)`` seeds ``np_random`` as Gymnasium asks; the episode's scenario is then
drawn from it (generated, :mod:`.scenarios`, from the ``purpose``'s seed range), or is
the ``scenario`` given. The same seed gives the same episode.
"""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym  # noqa: TID253 -- the environment subclasses gym.Env; only `cekm tune` imports it
import numpy as np

from .env_core import FieldEnvCore
from .features import N_FEATURES
from .motor import KEEP_CLEAR, TRAIL_GAIN


class FieldEnv(FieldEnvCore, gym.Env):
    """Field parameters as actions over a ``cekm run`` of one scenario (see the module docstring)."""

    metadata = {"render_modes": []}

    def __init__(self, task: str = "navigation", scenario: Any = None, *, ticks_per_action: int = 8,
                 max_time: float | None = None, purpose: str = "train", model: Any = None,
                 contact_penalty: float = 0.5, turn_gain: float = math.inf,
                 trail_gain: float = TRAIL_GAIN, keep_clear: bool = KEEP_CLEAR) -> None:
        self.turn_gain = turn_gain  # navigation's motor: as cekm run's default graph (PLAIN: the constants' motor)
        self.trail_gain = trail_gain
        self.keep_clear = keep_clear
        self._setup(task, scenario, ticks_per_action, max_time, purpose, model, contact_penalty)
        self.action_space = gym.spaces.Box(-1.0, 1.0, (len(self.policy.outputs),), dtype=np.float32)
        self.observation_space = gym.spaces.Box(0.0, 1.0, (N_FEATURES,), dtype=np.float32)

    # ------------------------------------------------------------------ helpers
    def _observation(self) -> np.ndarray:
        feats = [f for f in map(self._features, self.robots) if f is not None]
        return self._as_observation(np.mean(feats, axis=0) if feats else None)

    def _distance(self) -> float:
        return sum(self._to_goal(r) for r in self.robots)

    def _contacts(self) -> int:
        return sum(self._contacts_of(r) for r in self.robots)

    # ------------------------------------------------------------------ Gymnasium API
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        self._start()
        self.choice = self.policy.choice(np.zeros(len(self.policy.outputs)))
        for r in self.robots:
            self._set(r, self.choice)
        self.done = self._run(1)
        self.start_distance = max(self._distance(), 1e-9) if self.task == "navigation" else 1.0
        self.last_distance = self._distance() if self.task == "navigation" else 0.0
        self.last_contacts = self._contacts()
        self.last_observed = 0.0  # the return of an episode is its A, tick 0 included
        return self._observation(), self._info()

    def step(self, action):
        if self.session is None:
            raise RuntimeError("FieldEnv.step before reset")
        if self.done:
            raise RuntimeError("FieldEnv.step after the episode ended: call reset")
        self.choice = self.policy.choice(np.asarray(action, dtype=np.float64))
        for r in self.robots:
            self._set(r, self.choice)
        self.done = self._run(self.ticks_per_action)
        contacts = self._contacts()
        new_contacts, self.last_contacts = contacts - self.last_contacts, contacts
        if self.task == "navigation":
            d = self._distance()
            reward = (self.last_distance - d) / self.start_distance - self.contact_penalty * new_contacts
            self.last_distance = d
            reached = all(self._reached(r) for r in self.robots)
            reward += 1.0 if reached else 0.0
            terminated = reached
        else:
            seen = self._observed()
            reward = self._a_reward(seen, self.last_observed)
            self.last_observed = seen
            terminated = False
        truncated = self.done and not terminated
        return self._observation(), float(reward), terminated, truncated, self._info()

    def _info(self) -> dict[str, Any]:
        return {"t": self._live.episode.t, "tick": self._live.episode.tick, "scenario_seed": self.scenario_seed,
                "fields": self._fields_info(self.choice)}
