"""A Gymnasium environment over the in-process graph runner (docs/fields.md).

The world and the controller are ``cekm run``'s: a :class:`~cekm_swarm.experiments.graph_run.GraphSession`
of the shipped cooperative-EKM graph whose motor node is the field-policy motor
(:mod:`.motor`). Every :meth:`FieldEnv.step` sets every robot's field parameters from the
action (in [-1, 1]^k, mapped by :meth:`.policy.FieldPolicy.choice`: 0 is today's hand-tuned
values) and runs ``ticks_per_action`` ticks.

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

from typing import Any

import gymnasium as gym  # noqa: TID253 -- the environment subclasses gym.Env; only `cekm tune` imports it
import numpy as np

from ..experiments.graph_run import GraphSession
from ..node.graph_check import check_graph
from .features import N_FEATURES
from .graphs import policy_graph
from .motor import FieldMotor, FieldTrackingMotor
from .policy import FieldPolicy, check_task
from .scenarios import scenario as generated
from .scenarios import seed_of

SCENARIOS_PER_PURPOSE = 1_000_000


def _policy_motor(node: object) -> FieldMotor | FieldTrackingMotor:
    """A robot's motor node of the policy graph (the one whose field parameters the actions set)."""
    if not isinstance(node, FieldMotor | FieldTrackingMotor):
        raise TypeError(f"the policy graph's motor node is a {type(node).__name__}, not a field-policy motor")
    return node


class FieldEnv(gym.Env):
    """Field parameters as actions over a ``cekm run`` of one scenario (see the module docstring)."""

    metadata = {"render_modes": []}

    def __init__(self, task: str = "navigation", scenario: Any = None, *, ticks_per_action: int = 8,
                 max_time: float | None = None, purpose: str = "train", model: Any = None,
                 contact_penalty: float = 0.5) -> None:
        self.task = check_task(task)
        self.fixed_scenario = scenario
        self.ticks_per_action = int(ticks_per_action)
        if self.ticks_per_action < 1:
            raise ValueError("ticks_per_action must be at least 1")
        self.max_time = max_time if max_time is not None else (120.0 if task == "navigation" else 60.0)
        self.purpose = purpose
        seed_of(purpose, 0)  # checks the purpose
        if model is None:
            from ..experiments.default_model import default_model  # noqa: PLC0415 -- lazy: scipy

            model = default_model()
        self.model = model
        self.contact_penalty = float(contact_penalty)
        self.policy = FieldPolicy(task)
        self.checked = check_graph(policy_graph(task))
        self.action_space = gym.spaces.Box(-1.0, 1.0, (len(self.policy.outputs),), dtype=np.float32)
        self.observation_space = gym.spaces.Box(0.0, 1.0, (N_FEATURES,), dtype=np.float32)
        self.session: GraphSession | None = None
        self.scenario_seed: int | None = None

    # ------------------------------------------------------------------ helpers
    def _scenario(self):
        if self.fixed_scenario is not None:
            return self.fixed_scenario
        self.scenario_seed = seed_of(self.purpose, int(self.np_random.integers(SCENARIOS_PER_PURPOSE)))
        return generated(self.task, self.scenario_seed)

    @property
    def _live(self) -> Any:
        """The episode's session (made by :meth:`reset`)."""
        assert self.session is not None, "reset() first"
        return self.session

    def _observation(self) -> np.ndarray:
        feats = [m.last_features for m in self.motors if m.last_features is not None]
        f = np.mean(feats, axis=0) if feats else np.zeros(N_FEATURES)
        return np.clip(f, 0.0, 1.0).astype(np.float32)

    def _distance(self) -> float:
        ep = self._live.episode
        return sum(float(ep.to_goal(r)) for r in self.robots)

    def _contacts(self) -> int:
        w = self._live.world
        return sum(int(w.stats(r)["collisions"]) for r in self.robots)

    def _observed(self) -> float:
        return float(sum(self._live.episode.meter.fraction))

    def _run(self, ticks: int) -> bool:
        """Up to ``ticks`` ticks; True as soon as the session ends (the rest are not run)."""
        return any(self._live.step() for _ in range(ticks))

    # ------------------------------------------------------------------ Gymnasium API
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        sc = self._scenario()
        self.session = GraphSession(sc, graph=self.checked, model=self.model, max_time=self.max_time,
                                    params={"weights": (0.0,) * FieldPolicy.size(self.task)})  # the actions rule
        self.robots = tuple(self.session.world.robot_ids)
        self.motors = [_policy_motor(self.session.executor.node(r, "motor")) for r in self.robots]
        self.choice = self.policy.choice(np.zeros(len(self.policy.outputs)))
        for m in self.motors:
            m.override = self.choice
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
        for m in self.motors:
            m.override = self.choice
        self.done = self._run(self.ticks_per_action)
        contacts = self._contacts()
        new_contacts, self.last_contacts = contacts - self.last_contacts, contacts
        if self.task == "navigation":
            d = self._distance()
            reward = (self.last_distance - d) / self.start_distance - self.contact_penalty * new_contacts
            self.last_distance = d
            reached = all(p.reached for p in self.session.episode.progress.values())
            reward += 1.0 if reached else 0.0
            terminated = reached
        else:
            seen = self._observed()
            reward = (seen - self.last_observed) / (self.session.max_ticks + 1)
            self.last_observed = seen
            terminated = False
        truncated = self.done and not terminated
        return self._observation(), float(reward), terminated, truncated, self._info()

    def _info(self) -> dict[str, Any]:
        return {"t": self._live.episode.t, "tick": self._live.episode.tick, "scenario_seed": self.scenario_seed,
                "fields": dict(zip(self.policy.outputs, (
                    self.choice.fields.sigma_b_alpha, self.choice.fields.sigma_b_d_beyond,
                    self.choice.fields.sigma_b_d_near, self.choice.teammate_gain), strict=False))}

    def outcome(self) -> dict[str, dict]:
        """The run's outcome as ``cekm run`` reports it (per robot)."""
        return self._live.episode.outcome()

    def close(self) -> None:
        if self.session is not None:
            self.session.executor.close()
            self.session = None
