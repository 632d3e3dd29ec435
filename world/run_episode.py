"""What the world server and ``cekm run`` drive tick by tick, whatever the task: the
:class:`RunEpisode` interface, and :func:`make_episode`, the episode of a run (navigation:
:class:`world.episode.Episode`; training: :class:`world.training.TrainingEpisode`;
tracking: :class:`world.tracking.TrackingEpisode`)."""

from __future__ import annotations

from typing import Any, Protocol

from .episode import Episode
from .progress import RobotProgress
from .sense import TickReadings
from .sim import World
from .tracking import TrackingEpisode
from .training import TrainingEpisode


class RunEpisode(Protocol):
    """What the world server and ``cekm run`` drive, tick by tick, whatever the task
    (navigation: :class:`Episode`; tracking: :class:`world.tracking.TrackingEpisode`)."""

    task: str
    tick: int
    progress: dict[str, RobotProgress]

    @property
    def t(self) -> float:
        """Sim time of the current tick."""

    def readings(self) -> list[TickReadings]:
        """Step 1 of the tick: every robot's distance readings (and its target reading)."""

    def messages(self, robot: str) -> list[tuple[str, Any]]:
        """The tick's other readings of ``robot`` as (key below the robot, message)."""

    def apply(self, commands: dict[str, tuple[float, float]]) -> None:
        """Step 3: every robot's wheel command."""

    def advance(self) -> None:
        """On to the next tick."""

    @property
    def done(self) -> bool:
        """The run is over before its max time."""

    def outcome(self) -> dict[str, dict[str, Any]]:
        """Per robot, what ``outcome.json`` says of it."""

    def summary(self) -> dict[str, Any]:
        """The task's own part of ``outcome.json`` (``tracking``: Parker's A ...)."""

    def to_goal(self, robot: str) -> float | None:
        """How far the robot is from its goal now (None: it has none)."""

    def draw(self, views: Any, t: float, state: dict[str, Any]) -> None:
        """The task's own marks in the log's views (tracking: sensing circles)."""


def make_episode(world: World, task: str, checkpoints: dict[str, list[tuple[float, float]]] | None = None,
                 max_ticks: int = 0) -> RunEpisode:
    """The episode of a run of ``task`` (``world.tracking.run_kind``)."""
    if task == "tracking":
        return TrackingEpisode(world, max_ticks)
    if world.scenario.retarget:  # section 4.1's training: a new target at each stop (docs/learning.md)
        return TrainingEpisode(world, world.seed)
    return Episode(world, checkpoints)
