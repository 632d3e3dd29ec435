"""Named parameters of the EKMs, with the defaults the project uses and why.

Every number the paper leaves open is resolved here (docs/design.md sections 3 and 7).
Internally the control model sees the input as (alpha, d_scale * d), so that both
components span about +-pi; ``d_scale`` is that factor.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields
from typing import Any, TypeVar

from ..errors import ParameterError

P = TypeVar("P")


def _check_positive(obj: object, *names: str) -> None:
    for name in names:
        value = getattr(obj, name)
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            raise ParameterError(f"{type(obj).__name__}.{name} must be a positive finite number, got {value!r}")


@dataclass(frozen=True)
class CompetitionParams:
    """Competition with direction priority (Eqs. 2-4).

    beta_d = (2 pi / 0.16)^2 puts alpha in [-pi, pi] and d in [0, 0.16 m] on one scale.
    direction_tolerance: neurons whose wrapped angular difference is within this of the
    smallest one form A(alpha) (Eq. 4); 0.05-0.15 rad worked, 0 ignores distance.
    """

    beta_alpha: float = 1.0
    beta_d: float = (2.0 * math.pi / 0.16) ** 2
    direction_tolerance: float = 0.1

    def __post_init__(self) -> None:
        _check_positive(self, "beta_alpha", "beta_d")
        if not (0.0 <= self.direction_tolerance < math.pi):
            raise ParameterError(f"CompetitionParams.direction_tolerance must be in [0, pi), "
                                 f"got {self.direction_tolerance!r}")


@dataclass(frozen=True)
class LearningParams:
    """Self-organized learning (section 3.5, Eqs. 12-17) and its schedule.

    sigma_*: neighbourhood width G(k, i) in lattice units, sigma(t) = final + (initial -
    final) exp(-t / tau). g_min: N_k = {i : G(k, i) >= g_min}; only these update.
    eta_w: Eq. 12. eta_m: gradient descent, Eq. 15. forgetting: lambda of Eq. 16.
    eta_c: the direct-mapping EKM's output rule. eta_bfn/eta_width: the basis-function
    network's output weights and widths. rinv_trace_cap bounds trace(R^-1) (safeguard).
    d_scale: d is multiplied by it inside the control model (docs/design.md section 7: the
    paper's R^-1 = I does not say in which units). explore_rel/explore_abs: training-only
    exploration noise on executed wheel speeds, N(0, (rel |c| + abs)^2) per wheel.
    m_init_scale: initial M entries are uniform in +- m_init_scale * v_max / pi, so random
    commands span about half the wheel range (untrained maps, as the paper's).
    """

    eta_w: float = 0.05
    eta_m: float = 0.05
    eta_c: float = 0.05
    eta_bfn: float = 0.2
    eta_width: float = 0.05
    sigma_initial: float = 1.0
    sigma_final: float = 0.3
    sigma_tau: float = 1.0e4
    g_min: float = 0.01
    forgetting: float = 0.999
    rinv_trace_cap: float = 1.0e4
    d_scale: float = math.pi / 0.16
    explore_rel: float = 0.2
    explore_abs: float = 0.005
    m_init_scale: float = 0.5

    def __post_init__(self) -> None:
        _check_positive(self, "eta_w", "eta_m", "eta_c", "eta_bfn", "eta_width", "sigma_initial", "sigma_final",
                        "sigma_tau", "g_min", "forgetting", "rinv_trace_cap", "d_scale", "m_init_scale")
        if not self.forgetting <= 1.0:
            raise ParameterError(f"LearningParams.forgetting (lambda) must be in (0, 1], got {self.forgetting!r}")
        if not self.g_min < 1.0:
            raise ParameterError(f"LearningParams.g_min must be in (0, 1), got {self.g_min!r}")
        if self.explore_rel < 0 or self.explore_abs < 0:
            raise ParameterError("LearningParams.explore_rel and explore_abs must be >= 0")

    def sigma(self, t: float) -> float:
        """Neighbourhood width at training step t."""
        return self.sigma_final + (self.sigma_initial - self.sigma_final) * math.exp(-t / self.sigma_tau)


PAPER_SIGMA_B_ALPHA = 0.495
"""The paper's obstacle-field angular width (section 4.2), rad."""


@dataclass(frozen=True)
class FieldParams:
    """Target field (Eq. 6) and obstacle field (Eq. 8) widths.

    The paper's values, except ``sigma_b_alpha``: 0.6 rad, not the paper's 0.495. Over
    seeds 1-10 of ``cekm experiment obstacles`` 0.6 took ``checkpoints`` from 5/10 to 10/10
    successes (the middle room's U is negotiated) and kept ``concave`` and ``doorway`` at
    10/10 (the 86 mm doorway still looks open); 0.55 gave 9/10 and 0.75 lost ``rooms``
    (4/10: its 0.14 m doorways start to look closed). docs/reproduction-4.2.md has the
    whole search.
    """

    sigma_a_alpha: float = 2.475
    sigma_a_d: float = 0.0495
    sigma_b_alpha: float = 0.6
    sigma_b_d_beyond: float = 2.475  # d_i >= d_s: neurons beyond the obstacle are inhibited too
    sigma_b_d_near: float = 0.02475  # d_i < d_s

    def __post_init__(self) -> None:
        _check_positive(self, *(f.name for f in fields(self)))

    @classmethod
    def paper(cls) -> FieldParams:
        """The paper's values throughout (sigma_b_alpha 0.495): what the multi-robot
        tracking controller was tuned and measured with (docs/tracking.md)."""
        return cls(sigma_b_alpha=PAPER_SIGMA_B_ALPHA)


def narrowed(obj: Any, cls: type[P]) -> P:
    """The ``cls`` parameters held by ``obj``, a parameter set that has all of its fields
    and more (a node's Params extending them): ``cls(**{its fields from obj})``."""
    return cls(**{f.name: getattr(obj, f.name) for f in fields(cls)})  # type: ignore[arg-type]  # (cls: a dataclass)


def params_to_dict(*objs: Any) -> dict[str, Any]:
    """A JSON-ready dict of several parameter dataclasses, keyed by class name."""
    return {type(o).__name__: asdict(o) for o in objs}


@dataclass(frozen=True)
class TrackingParams:
    """Multi-robot tracking with cooperative EKMs (Fig. 13; docs/tracking.md).

    Distances are fractions of the robot's target sensing range R, so one set of values
    serves any range.

    standoff: a target farther than standoff * R is localized at (alpha, d - standoff * R)
    (drive until it is standoff * R away); a nearer one at (alpha, 0), the goal state,
    whose motor command only turns the robot to face it. The robot keeps a target inside
    its sensing range instead of driving onto it.
    watched_factor: a sensed target's weight is watched_factor ** n, n = teammates that
    observe it (by their latest share) and are nearer to it than this robot: 1 when no
    nearer teammate sees it, falling as more do (A-CMOMMT's rule, with the nearest
    observer keeping full weight so that two robots on one target do not both leave it).
    urgency: a sensed target's field is also scaled by (1 - urgency) + urgency * min(d / R,
    1): a target near the edge of the sensing range, about to be lost, pulls harder than
    one close by (0: no scaling).
    teammate_near, teammate_far: a teammate's inhibitory field has weight 1 within
    teammate_near * R, falling linearly to 0 at teammate_far * R (A-CMOMMT's shape).
    teammate_sigma_alpha, teammate_sigma_d_beyond, teammate_sigma_d_near: its widths
    (Eq. 8's form), wider than an obstacle field's so the robots spread out.
    teammate_hold_gain, teammate_hold_seen: the teammate fields' gain while the robot holds a
    target (senses one at full weight, or has targets assigned) and senses at least
    teammate_hold_seen targets: below 1 the spreading pushes a robot off its targets less
    (1: the same fields searching or holding; docs/fields.md).
    search_weight: weight of the search goal's target field (see :mod:`controller.search`).
    search_reached: a last reported position is searched until the robot is within
    search_reached * R of it without seeing the target; then it is forgotten.
    wander_ahead_m: with nothing to search, the search goal is this far straight ahead.
    share_timeout_s: a teammate whose latest share is older than this drops out of the
    fields (the runtime also drops it when its liveliness tokens vanish).
    memory_s: a target's last reported position is forgotten after this long.
    predict_s: a sensed target is localized where its track (an alpha-beta filter of the
    robot's own sightings) says it will be predict_s from now (0: where it is seen).
    standoff_speed_s: a sensed target with a track (:class:`~cekm_swarm.controller.anticipation.TargetTracks`)
    is held standoff * R - standoff_speed_s * its estimated speed away, never below 0: a fast
    target is followed from nearer, so it cannot leave the range before the robot reacts
    (0: off; 2 s chosen on the tuning seeds, docs/tracking.md).
    group_weight: when two or more full-weight sensed targets all fit within group_radius
    * R of their centroid, the centroid is localized too (no stand-off), with a target
    field of weight group_weight: above 1 it wins over each target's, so one robot holds
    the group between them instead of following one (0: off).
    assign_radius, assign_min, assign_weight: hand-offs by K-means' assignment (Luke et al.
    2005). Every target the robot knows now (sensed, or in a teammate's fresh share) goes
    to its nearest robot (this one or a teammate, by their shared poses); when at least
    assign_min fall to this robot and all lie within assign_radius * R of their centroid,
    the centroid is localized (no stand-off) with weight assign_weight in place of their
    own fields, and the robot does not search. So a robot drives to a target a teammate
    sees but is nearer to, and holds two or three close targets between them (0 radius:
    off; assign_min 1 and assign_weight 1.0 chosen on the tuning seeds with a radius of 0.8
    R, docs/tracking.md; the radius 1.0 R, a share a robot at its centroid sees whole,
    since issue 41's third round, chosen on development seeds, docs/fields.md).
    assign_lead_s: the assigned group's centroid is localized assign_lead_s ahead along its
    targets' mean velocity (an alpha-beta track of every known target's reported position),
    so the robot meets a moving group where it is going (0: where it is; 1 s chosen on the
    tuning seeds, docs/tracking.md).
    assign_subset: when the robot's share does not all fit within assign_radius * R of its
    centroid, the largest part of it that does (two targets or more, from its assign_subset
    nearest; the part nearest to the robot among the largest) is held at its centroid
    instead, as K-means holds its whole share (0 or 1: off, the share or nothing).
    assign_speed_s: the share fits when within assign_radius * R - assign_speed_s * v of its
    centroid, v its targets' mean estimated speed (their alpha-beta tracks): a fast group
    spreads while the robot drives to it, so it must be tighter (0: off).
    face_angle (rad): a sensed target more than face_angle to either side of the robot's
    heading is localized at (+-face_angle, 0), a goal state on its side, whatever its
    distance, so the robot turns in place toward it before it drives (pi: off). Without it
    a target beside or behind the robot has a neuron as winner that may not win the motor
    competition (a reverse one, or one the map did not converge), and the robot drives a
    forward arc away from it; the map's turn-in-place neurons beyond about 1.1 rad turn
    slowly or the wrong way, hence the side's angle rather than the target's (1.0 rad
    chosen on the tuning seeds, docs/tracking.md).
    face_turn_gain, face_turn_only: how the motor executes Eq. 11's command when the
    winner k is the input of that turn-in-place rule (k = s, u = (+-face_angle, 0): a target
    or centroid beside or behind). The map's goal states turn slowly (0.55 rad/s left and
    0.96 rad/s right at 1 rad, where A-CMOMMT's motor turns 3.4-5.9 rad/s toward a target
    beside it; docs/fields.md), so the command's turn part (v_r - v_l) / 2 is scaled by
    min(face_turn_gain, (c* - |v|) / |turn|), keeping its mean speed v = (v_l + v_r) / 2:
    the map's turn, at up to the wheels' top speed (face_turn_only false: the whole command
    c scaled by min(face_turn_gain, c* / max |c|), its direction kept). Not a field
    parameter: the fields, the winner and the direction of its turn are unchanged, only how
    fast the winner's command is executed (1: off, Eq. 11 as it is; inf, the default since
    issue 41's second round: to c*, chosen on development seeds, docs/fields.md).
    """

    standoff: float = 0.7
    watched_factor: float = 0.25
    urgency: float = 0.5
    teammate_near: float = 0.5
    teammate_far: float = 1.5
    teammate_sigma_alpha: float = 0.99
    teammate_sigma_d_beyond: float = 2.475
    teammate_sigma_d_near: float = 0.0495
    teammate_hold_gain: float = 1.0
    teammate_hold_seen: int = 0
    search_weight: float = 0.8
    search_reached: float = 0.5
    wander_ahead_m: float = 0.3
    share_timeout_s: float = 1.0
    memory_s: float = 30.0
    predict_s: float = 0.0
    group_weight: float = 0.0
    group_radius: float = 0.6
    standoff_speed_s: float = 2.0
    face_angle: float = 1.0
    face_turn_gain: float = math.inf
    face_turn_only: bool = True
    assign_radius: float = 1.0
    assign_min: int = 1
    assign_weight: float = 1.0
    assign_lead_s: float = 1.0
    assign_subset: int = 0
    assign_speed_s: float = 0.0

    def __post_init__(self) -> None:
        if not (self.assign_radius >= 0.0 and self.assign_weight > 0.0 and self.assign_min >= 1
                and self.assign_subset >= 0):
            raise ParameterError("TrackingParams: assign_radius must be >= 0, assign_weight > 0, assign_min >= 1 "
                                 "and assign_subset >= 0")
        if not 0.0 < self.face_angle <= math.pi:
            raise ParameterError(f"TrackingParams.face_angle must be in (0, pi], got {self.face_angle!r}")
        if not self.face_turn_gain >= 1.0:
            raise ParameterError("TrackingParams.face_turn_gain must be >= 1 (inf: up to c*), "
                                 f"got {self.face_turn_gain!r}")
        if not (self.predict_s >= 0.0 and self.group_weight >= 0.0 and self.group_radius > 0.0
                and self.standoff_speed_s >= 0.0 and 0.0 <= self.assign_lead_s < math.inf
                and 0.0 <= self.assign_speed_s < math.inf):
            raise ParameterError("TrackingParams: predict_s, group_weight, standoff_speed_s, assign_lead_s and "
                                 "assign_speed_s must be >= 0 (assign_lead_s and assign_speed_s finite), "
                                 "group_radius > 0")
        _check_positive(self, "teammate_near", "teammate_far", "teammate_sigma_alpha", "teammate_sigma_d_beyond",
                        "teammate_sigma_d_near", "search_weight", "search_reached", "wander_ahead_m",
                        "share_timeout_s", "memory_s")
        if not 0.0 <= self.standoff < 1.0:
            raise ParameterError(f"TrackingParams.standoff must be in [0, 1), got {self.standoff!r}")
        if not 0.0 <= self.urgency <= 1.0:
            raise ParameterError(f"TrackingParams.urgency must be in [0, 1], got {self.urgency!r}")
        if self.teammate_hold_seen < 0:
            raise ParameterError(f"TrackingParams.teammate_hold_seen must be >= 0, got {self.teammate_hold_seen!r}")
        if not 0.0 <= self.teammate_hold_gain <= 1.0:
            raise ParameterError("TrackingParams.teammate_hold_gain must be in [0, 1], "
                                 f"got {self.teammate_hold_gain!r}")
        if not 0.0 <= self.watched_factor <= 1.0:
            raise ParameterError(f"TrackingParams.watched_factor must be in [0, 1], got {self.watched_factor!r}")
        if not self.teammate_near < self.teammate_far:
            raise ParameterError("TrackingParams.teammate_near must be below teammate_far")


@dataclass(frozen=True)
class ACMOMMTParams:
    """The A-CMOMMT baseline (Parker, Autonomous Robots 12(3), 2002), distances as
    fractions of the target sensing range R (Parker's do3 = R).

    Robot-to-target force magnitude, piecewise linear in distance d: -1 at 0, 0 at do1,
    +1 at do2, +1 up to do3, 0 at do4 (the predictive tracking range). Robot-to-robot:
    -1 up to dr1, rising to 0 at dr2. The values scale one published reimplementation's
    (0, 4, 8, 25, 30; 12.5, 20 with a sensing range of 25) by 1/25.
    watched_weight: a target's weight when another robot observes it (1 otherwise).
    obstacle_gain: repulsion from each distance sensor's obstacle, gain * (1 - r / range)
    away from it (the robot's obstacle handling). turn_gain (1/s): omega = turn_gain *
    heading error; forward speed v* |F| cos(error) when the error is below pi/2.
    """

    do1: float = 0.16
    do2: float = 0.32
    do3: float = 1.0
    do4: float = 1.2
    dr1: float = 0.5
    dr2: float = 0.8
    watched_weight: float = 0.25
    obstacle_gain: float = 2.0
    turn_gain: float = 4.0

    def __post_init__(self) -> None:
        _check_positive(self, "do1", "do2", "do3", "do4", "dr1", "dr2", "obstacle_gain", "turn_gain")
        if not (self.do1 < self.do2 <= self.do3 < self.do4):
            raise ParameterError("ACMOMMTParams: need do1 < do2 <= do3 < do4")
        if not self.dr1 < self.dr2:
            raise ParameterError("ACMOMMTParams: need dr1 < dr2")
        if not 0.0 <= self.watched_weight <= 1.0:
            raise ParameterError(f"ACMOMMTParams.watched_weight must be in [0, 1], got {self.watched_weight!r}")


@dataclass(frozen=True)
class KMeansParams:
    """The K-means tracking baselines (Luke, Sullivan, Panait and Balan, "Tunably
    decentralized algorithms for cooperative target observation", AAMAS 2005; MASON's CTO
    application, ``KMeansEngine``; docs/tracking.md).

    Each update (every target tick, 0.256 s) every known target is assigned to its nearest
    robot, and a robot with targets moves its goal toward their mean:
    goal <- (1 - alpha) goal + alpha mean (alpha: KMeansEngine's ALFA = 0.25).
    arrive_s: the goal pulls with magnitude min(d / (v* arrive_s), 1), so the robot drives
    at top speed until about arrive_s seconds away and then slows onto it.
    wander_radius: a robot with no target drives to a random waypoint, uniform in the disc
    of wander_radius * R around where it is when it draws it, and holds it for
    wander_hold_s seconds or until within wander_reached * R of it (Luke et al.'s agents
    explore to random points when they have no target).
    share_timeout_s: a teammate whose latest share is older than this is out of the
    assignment. The goal is reached by A-CMOMMT's motor (its obstacle repulsion, turn gain
    and wheel limits, ACMOMMTParams), so only the goal differs between the baselines.
    """

    alpha: float = 0.25
    arrive_s: float = 1.0
    wander_radius: float = 2.0
    wander_hold_s: float = 8.0
    wander_reached: float = 0.2
    share_timeout_s: float = 1.0

    def __post_init__(self) -> None:
        _check_positive(self, "arrive_s", "wander_radius", "wander_hold_s", "wander_reached", "share_timeout_s")
        if not 0.0 < self.alpha <= 1.0:
            raise ParameterError(f"KMeansParams.alpha must be in (0, 1], got {self.alpha!r}")
