"""The cooperative-EKM nodes of a learning robot (docs/learning.md): target localization,
obstacle localization and motor integration as shipped, each with one more input, ``map``
(the robot's learner's latest map version, read with ``delay = 1``), whose version it uses
from that tick on (:class:`cekm_swarm.modules.learner.MapFollower`)."""

from __future__ import annotations

from cekm_swarm.node import In
from cekm_swarm.protocol import MapVersion

from .learner import MapFollower
from .motor_integration import MotorIntegration
from .obstacle_localization import ObstacleLocalization
from .target_localization import TargetLocalization

MAP_INPUT = In(MapVersion, doc="the robot's map version of the learner's latest run before this tick")


class LearningTargetLocalization(MapFollower, TargetLocalization):
    """Target localization (Eqs. 2-6) on the robot's current map version."""

    inputs = {**TargetLocalization.inputs, "map": MAP_INPUT}
    pure = True  # a function of the reading and the map version (the world refreshes readings as a version starts)


class LearningObstacleLocalization(MapFollower, ObstacleLocalization):
    """Obstacle localization j (Eqs. 2-8) on the robot's current map version."""

    inputs = {**ObstacleLocalization.inputs, "map": MAP_INPUT}
    pure = True  # a function of the reading and the map version (the world refreshes readings as a version starts)


class LearningMotorIntegration(MapFollower, MotorIntegration):
    """Motor integration (Eqs. 9-11) on the robot's current map version."""

    inputs = {**MotorIntegration.inputs, "map": MAP_INPUT}
