"""Multi-robot tracking with cooperative EKMs (the paper's Fig. 13 extension): pure
functions of plain values, in the style of :mod:`cekm_swarm.controller.cooperative`.

Per robot (docs/tracking.md):

* the tracking target module (every 0.256 s, on ``sense/pose``, ``sense/targets`` and the
  teammates' shares, see :mod:`.team` for which shares a tick uses) computes
  - hand-offs by K-means' assignment (:func:`assigned_group`): the targets of the team's
    that fall to this robot (nearest robot), when within assign_radius * R of their
    centroid, are one target field there, in place of their own, led assign_lead_s along
    their mean velocity (:func:`led_centroid`);
  - one target field per other sensed target t, weighted by w_t = watched_factor ** n_t (n_t:
    teammates that observe t and are nearer to it) and by its urgency (a target near
    the edge of the range pulls harder), localized at a stand-off: a target
    at distance d > standoff * R is localized at (alpha, d - standoff * R), a nearer one
    at (alpha, 0), so the robot closes in to 0.7 of its sensing range and then only turns
    to face the target; it keeps the target in range instead of driving onto it. The
    stand-off shrinks with the target's estimated speed (:func:`standoff_distance`). A
    target more than face_angle to a side is localized at (+-face_angle, 0), so the robot
    turns in place toward it first;
  - when no sensed target has full weight and none is assigned, the target field of the search goal (the
    one search behaviour, :meth:`.team.TeamView.search_goal`), weighted search_weight;
  - one inhibitory field per teammate (Eq. 8's form with wider widths), weighted 1 within
    teammate_near * R, falling linearly to 0 at teammate_far * R, so the robots spread;
  - the robot's share (its pose, the targets it sees in the world frame);
* the 12 obstacle modules, as in navigation (Eqs. 7-8);
* the motor module: e = sum_t w_t a_t - sum_r w_r b_r - sum_j b_j (Eq. 9, section 5 of
  docs/design.md), k = argmax e among the motor candidates (Eq. 10), and Eq. 11 with the
  input u of the localized target (or search goal) whose winner is k, else M_k w_k.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from ..models.networks import IndirectEKM
from ..models.params import FieldParams, TrackingParams
from .anticipation import TargetTracks, held_group
from .cooperative import CooperativeEKM, MotorOutput, ObstacleActivity, face_turn, motor_command
from .kmeans import assign
from .readings import RangeReading
from .team import TeammateShare, TeamView, observers_nearer, to_robot, to_world


def target_weight(n_watching: int, params: TrackingParams) -> float:
    """w_t = watched_factor ** n: 1 when no (nearer) teammate observes the target, falling as more do."""
    return params.watched_factor ** n_watching


def standoff_distance(speed: float | None, target_range: float, params: TrackingParams) -> float:
    """Where a sensed target is held (m): standoff * R, less standoff_speed_s times the
    target's estimated speed (m/s; None: no track yet), never below 0. A target that moves
    standoff_speed_s * speed in the time a robot needs to react is held that much nearer,
    so a fast one cannot leave the range before the robot follows."""
    held = params.standoff * target_range
    if params.standoff_speed_s > 0.0 and speed is not None:
        held = max(0.0, held - params.standoff_speed_s * speed)
    return held


def assigned_group(robot: str, pose: tuple[float, float, float], known: dict[str, tuple[float, float]],
                   team: dict[str, TeammateShare], target_range: float,
                   params: TrackingParams,
                   speeds: dict[str, float] | None = None) -> tuple[tuple[float, float], tuple[str, ...]] | None:
    """Hand-offs by K-means' assignment: each target of ``known`` (world frame) goes to its
    nearest robot (this one at ``pose``, the teammates at their shared poses); (the
    centroid, the targets) of this robot's share when there are at least assign_min and
    all lie within assign_radius * R of the centroid, else None. The targets are in sorted
    order: every sum over them has one order, whatever the process's string hashes.
    ``speeds`` (m/s, by target; from their tracks) shrink the reach by assign_speed_s times
    the share's mean speed: a fast group spreads before the robot reaches its centroid."""
    if params.assign_radius <= 0.0 or not known:
        return None
    robots = {robot: (pose[0], pose[1])} | {r: (sh.pose[0], sh.pose[1]) for r, sh in team.items()}
    labels = assign(known, robots)
    mine = [tid for tid in sorted(labels) if labels[tid] == robot]
    if len(mine) < params.assign_min:
        return None
    reach = params.assign_radius * target_range
    if params.assign_speed_s > 0.0 and speeds:
        reach -= params.assign_speed_s * sum(speeds.get(t, 0.0) for t in mine) / len(mine)
    group = fitting_group(mine, known, reach)
    if group is not None:
        return group
    if params.assign_subset <= 1 or len(mine) <= 2:
        return None
    return largest_fitting_subset(mine, known, reach, (pose[0], pose[1]), params.assign_subset)


def fitting_group(ids: Iterable[str], known: dict[str, tuple[float, float]],
                  reach: float) -> tuple[tuple[float, float], tuple[str, ...]] | None:
    """(the centroid, the targets) when every target of ``ids`` lies within ``reach`` of
    their centroid, else None."""
    ids = tuple(ids)
    cx = sum(known[t][0] for t in ids) / len(ids)
    cy = sum(known[t][1] for t in ids) / len(ids)
    if any(math.hypot(known[t][0] - cx, known[t][1] - cy) > reach for t in ids):
        return None
    return (cx, cy), ids


def largest_fitting_subset(mine: list[str], known: dict[str, tuple[float, float]], reach: float,
                           at: tuple[float, float], most: int) -> tuple[tuple[float, float], tuple[str, ...]] | None:
    """When a robot's whole share does not fit: the most of its targets (at least two; of its
    ``most`` nearest) that fit within ``reach`` of their centroid, the one nearest to the
    robot among the largest (TrackingParams.assign_subset); None when no two fit."""
    near = sorted(mine, key=lambda t: (math.hypot(known[t][0] - at[0], known[t][1] - at[1]), t))[:most]
    for size in range(min(len(near), len(mine) - 1), 1, -1):
        fits = [g for ids in itertools.combinations(sorted(near), size) if (g := fitting_group(ids, known, reach))]
        if fits:
            return min(fits, key=lambda g: (math.hypot(g[0][0] - at[0], g[0][1] - at[1]), g[1]))
    return None


def led_centroid(group: tuple[tuple[float, float], tuple[str, ...]], tracks: TargetTracks,
                 lead_s: float) -> tuple[float, float]:
    """The assigned group's centroid moved lead_s along its targets' mean velocity (their
    tracks; a target without one counts as still), so the robot meets the group where it
    is going rather than where it was (A-CMOMMT's predictive idea, for the centroid)."""
    (cx, cy), ids = group
    vx = sum(tracks.tracks[t][2] for t in ids if t in tracks.tracks) / len(ids)
    vy = sum(tracks.tracks[t][3] for t in ids if t in tracks.tracks) / len(ids)
    return cx + lead_s * vx, cy + lead_s * vy


def teammate_weight(d: float, target_range: float, params: TrackingParams) -> float:
    """A teammate's field weight at distance d: 1 within teammate_near * R, 0 beyond
    teammate_far * R, linear between."""
    near, far = params.teammate_near * target_range, params.teammate_far * target_range
    if d <= near:
        return 1.0
    if d >= far:
        return 0.0
    return (far - d) / (far - near)


def teammate_field(w: np.ndarray, s: int, params: TrackingParams) -> np.ndarray:
    """b_i for a teammate whose winner is s: Eq. 8's form, wider than an obstacle field."""
    da = np.angle(np.exp(1j * (w[s, 0] - w[:, 0])))
    dd = w[s, 1] - w[:, 1]
    sd = np.where(w[:, 1] >= w[s, 1], params.teammate_sigma_d_beyond, params.teammate_sigma_d_near)
    out: np.ndarray = np.exp(-da * da / (2.0 * params.teammate_sigma_alpha ** 2) - dd * dd / (2.0 * sd * sd))
    return out


_SHARED: dict[Any, tuple[IndirectEKM, CooperativeEKM, np.ndarray]] = {}


@dataclass(frozen=True)
class TrackingActivity:
    """The tracking target module's output at one tick."""

    stamp: float
    a: np.ndarray  # sum of the weighted target fields (and the search goal's)
    b_team: np.ndarray  # sum of the weighted teammate fields
    inputs: tuple[tuple[int, float, float, float], ...]  # (winner, alpha, d, weight) per localized point
    weights: dict[str, float]  # w_t per sensed target
    searching: bool


@dataclass
class TrackingEKM:
    """The cooperative-EKM tracking controller of one robot."""

    robot: str
    model: IndirectEKM
    target_range: float
    params: TrackingParams = field(default_factory=TrackingParams)
    fields: FieldParams = field(default_factory=FieldParams.paper)  # the values tracking was tuned with
    backend: str = "numba"
    tracks: TargetTracks = field(default_factory=TargetTracks)
    known_tracks: TargetTracks = field(default_factory=TargetTracks)  # every known target's, for the lead

    def __post_init__(self) -> None:
        if not math.isfinite(self.target_range):
            raise ValueError("tracking needs a finite target sensing range (sensors.target_range)")
        key = (id(self.model), self.fields, self.params, self.backend)
        held = _SHARED.get(key)
        if held is None or held[0] is not self.model:
            ekm = CooperativeEKM(self.model, self.fields, backend=self.backend)
            T = np.stack([teammate_field(ekm.w, s, self.params) for s in range(ekm.n)])
            T.flags.writeable = False
            if len(_SHARED) >= 8:
                _SHARED.clear()
            held = _SHARED[key] = (self.model, ekm, T)
        # the EKM and the field tables are pure functions of the model and parameters:
        # the robots of one process share them (the winner memo is exact per input)
        self.ekm, self._T = held[1], held[2]

    def localize(self, t: float, pose: tuple[float, float, float], sensed: dict[str, tuple[float, float]],
                 view: TeamView) -> TrackingActivity:
        """The tracking target module (see the module docstring)."""
        p, R, ekm = self.params, self.target_range, self.ekm
        team = view.teammates(t)
        own = {tid: to_world(pose, a, d) for tid, (a, d) in sensed.items()}
        view.update_memory(t, own, team)
        a = np.zeros(ekm.n)
        inputs = []
        weights = {}
        full = False
        if p.predict_s > 0.0 or p.standoff_speed_s > 0.0:
            self.tracks.update(t, own)
        assigned = self._assigned(t, pose, own, team)
        held: dict[str, tuple[float, float]] = {}
        for tid in sorted(sensed):
            alpha, d = sensed[tid]
            wt = target_weight(observers_nearer(tid, d, team), p)
            weights[tid] = wt
            full = full or wt >= 1.0
            if wt >= 1.0:
                held[tid] = own[tid]
            if assigned is not None and tid in assigned[1]:
                continue  # held together at the centroid below
            s, la, u_d = self._aim(tid, alpha, d, pose)
            a += (wt * (1.0 - p.urgency + p.urgency * min(d / R, 1.0))) * ekm.target_activity(s)
            inputs.append((s, la, u_d, wt))
        if assigned is not None:  # this robot's share of the team's targets, at its centroid (no stand-off)
            s, ga, gd = self._toward(pose, assigned[0], face=True)
            a += p.assign_weight * ekm.target_activity(s)
            inputs.append((s, ga, gd, p.assign_weight))
            full = True  # it has targets to hold: no search
        group = held_group(held, p.group_radius * R) if p.group_weight > 0.0 and len(held) >= 2 else None
        if group is not None:  # the point between the targets this robot can hold together
            s, ga, gd = self._toward(pose, group[0])
            a += p.group_weight * ekm.target_activity(s)
            inputs.append((s, ga, gd, p.group_weight))
        if not full:
            goal = view.search_goal(t, pose, own, team, p.search_reached * R, p.wander_ahead_m)
            s, ga, gd = self._toward(pose, goal)
            a += p.search_weight * ekm.target_activity(s)
            inputs.append((s, ga, gd, p.search_weight))
        b_team = self._team_activity(pose, team)
        if full and p.teammate_hold_gain != 1.0 and len(sensed) >= p.teammate_hold_seen:  # holding: spread less
            b_team = p.teammate_hold_gain * b_team
        return TrackingActivity(t, a, b_team, tuple(inputs), weights, not full)

    def _assigned(self, t: float, pose: tuple[float, float, float], own: dict[str, tuple[float, float]],
                  team: dict[str, TeammateShare]) -> tuple[tuple[float, float], tuple[str, ...]] | None:
        """This robot's group of the targets known now (sensed, then the teammates' fresh
        shares): its centroid, led ahead when asked, and its targets; None without one."""
        p = self.params
        known = dict(own)
        for r in sorted(team):
            for tid, xy in team[r].targets.items():
                known.setdefault(tid, xy)
        if p.assign_lead_s > 0.0 or p.assign_speed_s > 0.0:
            self.known_tracks.update(t, known)
        speeds = None
        if p.assign_speed_s > 0.0:
            speeds = {tid: v for tid in sorted(known) if (v := self.known_tracks.speed(tid)) is not None}
        assigned = assigned_group(self.robot, pose, known, team, self.target_range, p, speeds)
        if p.assign_lead_s > 0.0 and assigned is not None:
            assigned = (led_centroid(assigned, self.known_tracks, p.assign_lead_s), assigned[1])
        return assigned

    def _aim(self, tid: str, alpha: float, d: float, pose: tuple[float, float, float]) -> tuple[int, float, float]:
        """The winner for a sensed target and the input it stands for: where the target will
        be (when predicting), turned toward first when beside or behind, short of it by the
        stand-off distance."""
        p = self.params
        la, ld = alpha, d
        if p.predict_s > 0.0:  # where the target will be
            ahead = self.tracks.predict(tid, p.predict_s)
            if ahead is not None:
                la, ld = to_robot(pose, ahead)
        if abs(la) > p.face_angle:  # beside or behind: turn in place toward it first
            la, u_d = math.copysign(p.face_angle, la), 0.0
        else:
            so = standoff_distance(self.tracks.speed(tid), self.target_range, p)
            u_d = ld - so if ld > so else 0.0
        return self.ekm.winner(la, u_d), la, u_d

    def _toward(self, pose: tuple[float, float, float], xy: tuple[float, float],
                face: bool = False) -> tuple[int, float, float]:
        """The winner for a point of the world and its (angle, distance) from the robot
        (``face``: turned toward first when beside or behind)."""
        ga, gd = to_robot(pose, xy)
        if face and abs(ga) > self.params.face_angle:  # beside or behind: turn in place toward it first
            ga, gd = math.copysign(self.params.face_angle, ga), 0.0
        return self.ekm.winner(ga, gd), ga, gd

    def _team_activity(self, pose: tuple[float, float, float], team: dict[str, TeammateShare]) -> np.ndarray:
        """The activity of the teammates' positions on the lattice (``b_team``: each nearby
        teammate's tabulated field at its winner, weighted by its distance)."""
        ekm = self.ekm
        b = np.zeros(ekm.n)
        for sh in team.values():
            ra, rd = to_robot(pose, (sh.pose[0], sh.pose[1]))
            wr = teammate_weight(rd, self.target_range, self.params)
            if wr > 0.0:
                b += wr * self._T[ekm.winner(ra, rd)]
        return b

    def integrate(self, act: TrackingActivity | None, obstacles: Iterable[ObstacleActivity]) -> MotorOutput:
        """The motor module (Eqs. 9-11): nothing localized yet, the robot stands still."""
        if act is None:
            return MotorOutput(0.0, 0.0, None, None)
        e = act.a - act.b_team
        for ob in obstacles:
            if ob.b is not None:
                e = e - ob.b
        ekm = self.ekm
        k = int(np.argmax(np.where(ekm.eligible, e, -np.inf)))
        match = [(wt, i) for i, (s, _, _, wt) in enumerate(act.inputs) if s == k]
        m = self.model
        if match:
            _, i = max(match)
            s, alpha, d, _ = act.inputs[i]
            v_l, v_r = motor_command(ekm._M, ekm.w, alpha, d, k, s, m.v_max, m.learn_p.d_scale)
            if self.params.face_turn_gain != 1.0 and d == 0.0 and abs(alpha) >= self.params.face_angle:
                v_l, v_r = face_turn(v_l, v_r, self.params.face_turn_gain, m.v_max, self.params.face_turn_only)
            return MotorOutput(v_l, v_r, k, s)
        v_l, v_r = motor_command(ekm._M, ekm.w, 0.0, 0.0, k, None, m.v_max, m.learn_p.d_scale)
        return MotorOutput(v_l, v_r, k, None)


class TrackingController(Protocol):
    """What a tracking robot's controller does: the target module, from what it senses
    and the team view, and the motor module, from that and its obstacle inputs."""

    def localize(self, t: float, pose: tuple[float, float, float], sensed: dict[str, tuple[float, float]],
                 view: TeamView) -> Any: ...

    def integrate(self, act: Any, obstacles: Any) -> Any: ...


@dataclass
class TrackingRobot:
    """One robot's side of a tracking run, as its module processes run it: the tracking
    target module (:meth:`on_sense`, returns the share to publish), the obstacle modules
    (:meth:`on_ranges`), the motor module (:meth:`command`), and the team view fed by
    teammates' shares (:meth:`receive`, :meth:`drop`).

    ``controller`` is a :class:`TrackingEKM`, an :class:`~.acmommt.ACMOMMT` or a
    :class:`Stay`; each has ``localize(t, pose, sensed, view)`` and ``integrate(act, x)``
    (``x``: obstacle activities for the EKM, range readings for A-CMOMMT)."""

    robot: str
    controller: TrackingController
    view: TeamView
    activity: Any = None  # what the controller's localize gave last
    obstacles: dict[int, ObstacleActivity] = field(default_factory=dict)
    ranges: list[RangeReading] = field(default_factory=list)

    def on_sense(self, t: float, pose: tuple[float, float, float],
                 sensed: dict[str, tuple[float, float]]) -> TeammateShare:
        """A target tick at sim time t: the robot's pose and the targets it senses, {id: (alpha, d)};
        returns what it shares with the team (the targets in the world frame)."""
        self.activity = self.controller.localize(t, pose, sensed, self.view)
        own = {tid: to_world(pose, a, d) for tid, (a, d) in sorted(sensed.items())}
        return TeammateShare(t, pose, own)

    def on_ranges(self, t: float, ranges: list[RangeReading]) -> None:
        self.ranges = ranges
        if isinstance(self.controller, TrackingEKM):
            for ob in self.controller.ekm.localize_obstacles(ranges, t):
                self.obstacles[ob.index] = ob

    def command(self) -> tuple[float, float]:
        if isinstance(self.controller, TrackingEKM):
            out = self.controller.integrate(self.activity, self.obstacles.values())
            return out.v_l, out.v_r
        wheels: tuple[float, float] = self.controller.integrate(self.activity, self.ranges)
        return wheels

    def receive(self, robot: str, share: TeammateShare) -> None:
        self.view.receive(robot, share)

    def drop(self, robot: str) -> None:
        self.view.drop(robot)


@dataclass
class Stay:
    """The static baseline: the robot stays where it starts."""

    robot: str

    def localize(self, t: float, pose: tuple[float, float, float], sensed: dict[str, tuple[float, float]],
                 view: TeamView) -> None:
        return None

    def integrate(self, act: None, ranges: list[RangeReading]) -> tuple[float, float]:
        return 0.0, 0.0
