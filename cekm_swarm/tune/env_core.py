"""What the field-parameter environments share (docs/fields.md): one place for the machinery
of :class:`~cekm_swarm.tune.env.FieldEnv` (Gymnasium, one action for the team) and
:class:`~cekm_swarm.tune.team_env.FieldTeamEnv` (PettingZoo, one action per robot).

An episode is a :class:`~cekm_swarm.experiments.graph_run.GraphSession` of the field-policy
graph (:func:`cekm_swarm.experiments.field_widths.policy_graph`: ``cekm run``'s world and controller, the motor node
swapped for the field-policy motor of :mod:`.motor`), on the scenario given or one generated
from the environment's ``np_random`` (:mod:`.scenarios`). The environments set each robot's
motor's field parameters (its ``override``) between ticks and read, per robot, the features
its fields see, its distance to the goal, its contacts and whether it has reached the goal.
The action is the widths: the motor's own schedule of the paper's widths while its trail acts
(its ``alternate``) does not replace them.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..experiments.field_widths import policy_graph
from ..experiments.graph_run import GraphSession
from ..node.graph_check import check_graph
from .features import N_FEATURES
from .motor import KEEP_CLEAR, TRAIL_GAIN, FieldMotor, FieldTrackingMotor
from .policy import FieldChoice, FieldPolicy, check_task
from .scenarios import scenario as generated
from .scenarios import seed_of

SCENARIOS_PER_PURPOSE = 1_000_000
DEFAULT_MAX_TIME = {"navigation": 120.0, "tracking": 60.0}
"""Sim seconds of an environment's episode unless told otherwise (shorter than ``cekm run``'s)."""


def _policy_motor(node: object) -> FieldMotor | FieldTrackingMotor:
    """A robot's motor node of the policy graph (the one whose field parameters the actions set)."""
    if not isinstance(node, FieldMotor | FieldTrackingMotor):
        raise TypeError(f"the policy graph's motor node is a {type(node).__name__}, not a field-policy motor")
    return node


class FieldEnvCore:
    """The settings, the scenario draw and the live session of a field-parameter environment.

    A subclass provides ``np_random`` (a seeded :class:`numpy.random.Generator`) and calls
    :meth:`_setup` from its ``__init__`` and :meth:`_start` from its ``reset``."""

    np_random: np.random.Generator
    turn_gain: float = math.inf
    """Navigation: the motor's ``turn_gain`` (:class:`.motor.FieldMotor`; 1: Eq. 11's turns as
    they are)."""
    trail_gain: float = TRAIL_GAIN
    """Navigation: the motor's ``trail_gain`` (0: no trail field)."""
    keep_clear: bool = KEEP_CLEAR
    """Navigation: whether the motor keeps clear of the movers it detects (with ``turn_gain`` 1
    and ``trail_gain`` 0, False makes action 0 ``cekm run --fields tuned``'s run exactly)."""

    def _setup(self, task: str, scenario: Any, ticks_per_action: int, max_time: float | None, purpose: str,
               model: Any, contact_penalty: float) -> None:
        self.task = check_task(task)
        self.fixed_scenario = scenario
        self.ticks_per_action = int(ticks_per_action)
        if self.ticks_per_action < 1:
            raise ValueError("ticks_per_action must be at least 1")
        self.max_time = max_time if max_time is not None else DEFAULT_MAX_TIME[task]
        self.purpose = purpose
        seed_of(purpose, 0)  # checks the purpose
        if model is None:
            from ..experiments.default_model import default_model  # noqa: PLC0415 -- lazy: scipy

            model = default_model()
        self.model = model
        self.contact_penalty = float(contact_penalty)
        self.policy = FieldPolicy(task)
        self.checked = check_graph(policy_graph(task))
        self.session: GraphSession | None = None
        self.scenario_seed: int | None = None
        self.team_size: int | None = None  # generated scenarios of this many robots (None: any)

    def _scenario(self):
        if self.fixed_scenario is not None:
            return self.fixed_scenario
        self.scenario_seed = seed_of(self.purpose, int(self.np_random.integers(SCENARIOS_PER_PURPOSE)))
        return generated(self.task, self.scenario_seed, self.team_size)

    def _start(self) -> None:
        """A new episode's session (the scenario drawn now), every robot at action 0 (today's values)."""
        self.close()
        sc = self._scenario()
        params: dict[str, Any] = {"weights": (0.0,) * FieldPolicy.size(self.task)}  # the actions rule
        if self.task == "navigation":
            params["turn_gain"] = self.turn_gain
            params["trail_gain"] = self.trail_gain
            params["keep_clear"] = self.keep_clear
        self.session = GraphSession(sc, graph=self.checked, model=self.model, max_time=self.max_time, params=params)
        self.robots = tuple(self.session.world.robot_ids)
        self.motor_of = {r: _policy_motor(self.session.executor.node(r, "motor")) for r in self.robots}

    @property
    def _live(self) -> Any:
        """The episode's session (made by ``reset``)."""
        assert self.session is not None, "reset() first"
        return self.session

    def _set(self, robot: str, choice: FieldChoice) -> None:
        """``robot``'s field parameters from its next tick on."""
        self.motor_of[robot].override = choice

    def _run(self, ticks: int) -> bool:
        """Up to ``ticks`` ticks; True as soon as the session ends (the rest are not run)."""
        return any(self._live.step() for _ in range(ticks))

    def _features(self, robot: str) -> np.ndarray | None:
        """What ``robot``'s fields saw at its last tick (:mod:`.features`), None before its first."""
        return self.motor_of[robot].last_features

    @staticmethod
    def _as_observation(f: np.ndarray | None) -> np.ndarray:
        return np.clip(np.zeros(N_FEATURES) if f is None else f, 0.0, 1.0).astype(np.float32)

    def _to_goal(self, robot: str) -> float:
        return float(self._live.episode.to_goal(robot))

    def _contacts_of(self, robot: str) -> int:
        return int(self._live.world.stats(robot)["collisions"])

    def _reached(self, robot: str) -> bool:
        return bool(self._live.episode.progress[robot].reached)

    def _observed(self) -> float:
        """The team's observations so far (the sum over ticks of the fraction of targets observed)."""
        return float(sum(self._live.episode.meter.fraction))

    def _a_reward(self, seen: float, last_seen: float) -> float:
        """Tracking's reward: Parker's A of the ticks since ``last_seen``, over the run's ticks."""
        return (seen - last_seen) / (self._live.max_ticks + 1)

    def _fields_info(self, choice: FieldChoice) -> dict[str, float]:
        return self.policy.outputs_of(choice)

    def outcome(self) -> dict[str, dict]:
        """The run's outcome as ``cekm run`` reports it (per robot)."""
        return self._live.episode.outcome()

    def close(self) -> None:
        if self.session is not None:
            self.session.executor.close()
            self.session = None
