"""Training/testing trials of section 4.1, in two runners that must agree:

* :func:`run_reference` steps one reference network (:mod:`cekm_swarm.models.networks`)
  in a plain Python loop: readable, slow;
* :func:`run_batch` runs the same trial for a batch of robots (one per trial) in numba,
  the trials in parallel threads: the experiments use this one.

One training step: sense the target (u), the network's command c (under the ``goal`` stop
rule its target-reaching rule, 0 at the goal state; under ``command`` its own output), add
training-only exploration noise, clip to c* and quantize to the wheels' speed unit (when
the arena has one), drive 32 noisy sub-steps, then learn from the displacement v unless the
robot touched a wall. A target is replaced when the robot stops (:mod:`.stopping`; the stop
takes that step; under ``goal`` a target whose sensed distance is already 0 is replaced
before the step) or its step budget runs out.
A test presents the fixed test targets in sequence from the centre, with no learning. The
kernels take the stop rule as one number (:attr:`StopRule.code`): 0 is ``goal``, a positive
speed is ``command`` at that motor resolution.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from ..models import fast
from .arena import A_RES, displacement, drive, executed_command, sense_target
from .stopping import GOAL_STOP, StopRule, stopped, stopped_nb
from .streams import TrialStreams, batch_train_chunk

EMPTY = np.empty(0)


@dataclass
class TestOutcome:
    """Per test target: what happened. Arrays have one row per target (eps columns for *_eps)."""

    __test__ = False  # not a pytest test class

    final_dist: np.ndarray  # m, after the stop or when the budget ran out
    stopped: np.ndarray  # bool: ended by a stop (c = 0) rather than the budget
    steps: np.ndarray  # steps taken until the stop (or the budget)
    path: np.ndarray  # m travelled until then
    straight: np.ndarray  # m, l_i: straight-line distance from the start to the target
    t_eps: np.ndarray  # s to first come within eps (NaN: never)
    path_eps: np.ndarray  # m travelled until then
    at_goal: np.ndarray | None = None  # bool: stopped with the sensed distance 0 (the goal state)

    @classmethod
    def empty(cls, m: int, n_eps: int) -> TestOutcome:
        return cls(np.zeros(m), np.zeros(m, dtype=np.bool_), np.zeros(m, dtype=np.int64), np.zeros(m), np.zeros(m),
                   np.full((m, n_eps), np.nan), np.full((m, n_eps), np.nan), np.zeros(m, dtype=np.bool_))


# ---------------------------------------------------------------- reference runner

def _explore(c: np.ndarray, z: np.ndarray, rel: float, abs_: float, v_max: float) -> np.ndarray:
    """Training-only exploration noise on the executed command, then clipped to c*."""
    return np.clip(c + z * (rel * np.abs(c) + abs_), -v_max, v_max)


def network_command(net, stop: StopRule) -> Callable[[np.ndarray], np.ndarray]:
    """What drives the robot under a stop rule: the network's own output (``command``) or its
    target-reaching rule with c = 0 at the goal state (``goal``)."""
    return net.output if stop.rule == "command" else net.command


def train_reference(net, pose: np.ndarray, cursor: list[int], streams: TrialStreams, t0: int, chunk: int,
                    nsteps: int, stop: StopRule = GOAL_STOP) -> None:
    """Train ``net`` for nsteps steps from training step t0; pose and cursor [target, steps on it] update in place."""
    arena, lp = streams.arena, net.learn_p
    av = arena.vector()
    targets = streams.train_targets
    wheel, sense, explore = streams.train_chunk(chunk, nsteps)
    budget = streams.schedule.train_budget
    command = network_command(net, stop)
    for j in range(nsteps):
        while True:
            tx, ty = targets[cursor[0]]
            alpha, d = sense_target(pose[0], pose[1], pose[2], tx, ty, sense[j, 0], sense[j, 1], av[A_RES])
            if cursor[1] < budget and (d != 0.0 or stop.code > 0.0):
                break
            cursor[0] += 1
            cursor[1] = 0
        u = np.array([alpha, d])
        c_net = command(u)
        q_net = executed_command(c_net[0], c_net[1], av)
        if stopped(c_net[0], c_net[1], q_net[0], q_net[1], stop.code):  # next target, next step
            cursor[0] += 1
            cursor[1] = 0
            continue
        c = _explore(c_net, explore[j], lp.explore_rel, lp.explore_abs, arena.v_max)
        c = np.array(executed_command(c[0], c[1], av))
        x0, y0, th0 = pose
        _, touched, dth = drive(pose, c[0], c[1], wheel[j], av, 0.0, 0.0, EMPTY, EMPTY, EMPTY, 0.0, 0.0)
        cursor[1] += 1
        if not touched and (c[0] != 0.0 or c[1] != 0.0):
            v = np.array(displacement(x0, y0, th0, pose[0], pose[1], dth))
            net.learn(v, c, float(t0 + j))


def test_reference(command: Callable[[np.ndarray], np.ndarray], streams: TrialStreams, eps: np.ndarray,
                   stop: StopRule = GOAL_STOP) -> TestOutcome:
    """The fixed test: targets in sequence from the centre, heading 0, no learning.
    ``command`` drives the robot (:func:`network_command` for a network)."""
    arena = streams.arena
    av = arena.vector()
    targets, wheel, sense = streams.test_set
    out = TestOutcome.empty(len(targets), len(eps))
    at_goal = out.at_goal
    assert at_goal is not None  # empty() makes every column
    pose = np.array([*arena.centre, 0.0])
    for i, (tx, ty) in enumerate(targets):
        out.straight[i] = math.hypot(tx - pose[0], ty - pose[1])
        t_eps, path_eps = out.t_eps[i], out.path_eps[i]
        path, steps = 0.0, wheel.shape[1]
        for j in range(wheel.shape[1]):
            u = np.array(sense_target(pose[0], pose[1], pose[2], tx, ty, sense[i, j, 0], sense[i, j, 1], av[A_RES]))
            c = command(u)
            q = executed_command(c[0], c[1], av)
            if stopped(c[0], c[1], q[0], q[1], stop.code):  # the robot has come to a stop
                out.stopped[i], at_goal[i], steps = True, u[1] == 0.0, j
                break
            ds, _, _ = drive(pose, q[0], q[1], wheel[i, j], av, tx, ty, eps, t_eps, path_eps, j * arena.step_s, path)
            path += ds
        out.steps[i], out.path[i] = steps, path
        out.final_dist[i] = math.hypot(tx - pose[0], ty - pose[1])
    return out


def run_reference(net, streams: TrialStreams, eps: np.ndarray, stop: StopRule = GOAL_STOP,
                  train_stop: StopRule = GOAL_STOP) -> list[TestOutcome]:
    """A whole trial with the reference network: a test at step 0 and after every interval
    (``stop``: the test's stop rule; ``train_stop``: training's)."""
    s = streams.schedule
    pose = np.array([*streams.arena.centre, 0.0])
    cursor = [0, 0]
    outcomes = [test_reference(network_command(net, stop), streams, eps, stop)]
    for chunk, t0 in enumerate(s.test_points[:-1]):
        train_reference(net, pose, cursor, streams, t0, chunk, s.test_interval, train_stop)
        outcomes.append(test_reference(network_command(net, stop), streams, eps, stop))
    return outcomes


# ---------------------------------------------------------------- fast batched runner

@njit(cache=True)
def _network_command(kind, alpha, d, w, P, R, p, stop_code, out):
    """The network's own output under the ``command`` rule, its target-reaching rule (0 at
    the goal state) under ``goal`` (stop_code 0)."""
    if stop_code > 0.0:
        fast.output(kind, alpha, d, w, P, R, p, out)
    else:
        fast.command(kind, alpha, d, w, P, R, p, out)


@njit(parallel=True, cache=True)
def _train_batch(kind, size, W, P, R, p, arena, poses, cursors, targets, t0, wheel, sense, explore, budget, stop_code):
    B = W.shape[0]
    n = W.shape[1]
    v_max = p[fast.P_VMAX]
    rel = p[fast.P_EXP_REL]
    abs_ = p[fast.P_EXP_ABS]
    empty = np.empty(0)
    for b in prange(B):
        idx_buf = np.empty(n, dtype=np.int64)
        g_buf = np.empty(n)
        c = np.empty(2)
        pose = poses[b]
        w, Pb, Rb = W[b], P[b], R[b]
        for j in range(wheel.shape[1]):
            while True:
                tx = targets[b, cursors[b, 0], 0]
                ty = targets[b, cursors[b, 0], 1]
                alpha, d = sense_target(pose[0], pose[1], pose[2], tx, ty, sense[b, j, 0], sense[b, j, 1], arena[A_RES])
                if cursors[b, 1] < budget and (d != 0.0 or stop_code > 0.0):
                    break
                cursors[b, 0] += 1
                cursors[b, 1] = 0
            _network_command(kind, alpha, d, w, Pb, Rb, p, stop_code, c)
            q0, q1 = executed_command(c[0], c[1], arena)
            if stopped_nb(c[0], c[1], q0, q1, stop_code):  # a stop: the next target, next step
                cursors[b, 0] += 1
                cursors[b, 1] = 0
                continue
            c0 = min(max(c[0] + explore[b, j, 0] * (rel * abs(c[0]) + abs_), -v_max), v_max)
            c1 = min(max(c[1] + explore[b, j, 1] * (rel * abs(c[1]) + abs_), -v_max), v_max)
            c0, c1 = executed_command(c0, c1, arena)
            x0, y0, th0 = pose[0], pose[1], pose[2]
            _, touched, dth = drive(pose, c0, c1, wheel[b, j], arena, 0.0, 0.0, empty, empty, empty, 0.0, 0.0)
            cursors[b, 1] += 1
            if touched:
                cursors[b, 3] += 1
            elif c0 != 0.0 or c1 != 0.0:
                cursors[b, 2] += 1
                va, vd = displacement(x0, y0, th0, pose[0], pose[1], dth)
                fast.learn(kind, va, vd, c0, c1, float(t0 + j), w, Pb, Rb, size, p, idx_buf, g_buf)


TRACE_FIELDS = ("x", "y", "theta", "alpha", "d", "winner", "c_l", "c_r", "executed_l", "executed_r")
"""Columns of a test trace (:func:`trace_test`): the pose before the step, the sensed u, the
winner for u (Eqs. 2-4), the network's command and what the wheels executed (m, rad, m/s)."""


@njit(cache=True)
def _test_target(kind, w, P, R, p, arena, pose, tx, ty, wheel, sense, eps, stop_code, step_s, t_eps, path_eps, trace):
    """One test target from the pose (updated in place): returns (stopped, steps, path, stopped
    at the goal state). When trace has rows, step j's record (TRACE_FIELDS) goes into trace[j]."""
    c = np.empty(2)
    path = 0.0
    n_steps = wheel.shape[0]
    for j in range(wheel.shape[0]):
        alpha, d = sense_target(pose[0], pose[1], pose[2], tx, ty, sense[j, 0], sense[j, 1], arena[A_RES])
        _network_command(kind, alpha, d, w, P, R, p, stop_code, c)
        c0, c1 = executed_command(c[0], c[1], arena)
        if trace.shape[0] > 0:
            trace[j, 0], trace[j, 1], trace[j, 2] = pose[0], pose[1], pose[2]
            trace[j, 3], trace[j, 4], trace[j, 5] = alpha, d, float(fast.winner(alpha, d, w, p))
            trace[j, 6], trace[j, 7], trace[j, 8], trace[j, 9] = c[0], c[1], c0, c1
        if stopped_nb(c[0], c[1], c0, c1, stop_code):  # the robot has come to a stop
            return True, j, path, d == 0.0
        ds, _, _ = drive(pose, c0, c1, wheel[j], arena, tx, ty, eps, t_eps, path_eps, j * step_s, path)
        path += ds
    return False, n_steps, path, False


@njit(parallel=True, cache=True)
def _test_batch(kind, W, P, R, p, arena, cx, cy, step_s, targets, wheel, sense, eps, stop_code,
                final_dist, stopped_out, steps, path_out, straight, t_eps, path_eps, at_goal):
    B = W.shape[0]
    no_trace = np.empty((0, len(TRACE_FIELDS)))
    for b in prange(B):
        pose = np.array([cx, cy, 0.0])
        for i in range(targets.shape[1]):
            tx = targets[b, i, 0]
            ty = targets[b, i, 1]
            straight[b, i] = math.hypot(tx - pose[0], ty - pose[1])
            done, n, path, goal = _test_target(kind, W[b], P[b], R[b], p, arena, pose, tx, ty, wheel[b, i], sense[b, i],
                                               eps, stop_code, step_s, t_eps[b, i], path_eps[b, i], no_trace)
            stopped_out[b, i] = done
            at_goal[b, i] = goal
            steps[b, i] = n
            path_out[b, i] = path
            final_dist[b, i] = math.hypot(tx - pose[0], ty - pose[1])


@njit(cache=True)
def _trace_targets(kind, w, P, R, p, arena, cx, cy, step_s, targets, wheel, sense, eps, stop_code, traces):
    """The test of one network with every step recorded: traces[i, j] is target i's step j
    (NaN after its end). The same per-target kernel as :func:`_test_batch`, so the same path."""
    pose = np.array([cx, cy, 0.0])
    for i in range(targets.shape[0]):
        t_eps = np.full(eps.shape[0], np.nan)
        path_eps = np.full(eps.shape[0], np.nan)
        _test_target(kind, w, P, R, p, arena, pose, targets[i, 0], targets[i, 1], wheel[i], sense[i], eps, stop_code,
                     step_s, t_eps, path_eps, traces[i])


@dataclass
class NetworkBatch:
    """The fast path's state for one network kind across a batch of trials."""

    kind: str
    size: int
    W: np.ndarray  # (B, n, 2)
    P: np.ndarray  # (B, n, 2, 2)
    R: np.ndarray  # (B, n, 2, 2)
    params: np.ndarray

    @property
    def code(self) -> int:
        return fast.KIND_CODE[self.kind]


def trace_test(batch: NetworkBatch, trial: int, streams: TrialStreams, stop: StopRule = GOAL_STOP) -> np.ndarray:
    """Every step of one trial's fixed test: (targets, budget, len(TRACE_FIELDS)), NaN after
    each target's end. The path is the one :func:`test_batch` measures, bit for bit."""
    arena = streams.arena
    targets, wheel, sense = streams.test_set
    traces = np.full((len(targets), wheel.shape[1], len(TRACE_FIELDS)), np.nan)
    cx, cy = arena.centre
    _trace_targets(batch.code, batch.W[trial], batch.P[trial], batch.R[trial], batch.params, arena.vector(), cx, cy,
                   arena.step_s, targets, wheel, sense, np.empty(0), stop.code, traces)
    return traces


def test_batch(batch: NetworkBatch, streams: list[TrialStreams], eps: np.ndarray,
               stop: StopRule = GOAL_STOP) -> list[TestOutcome]:
    """The fixed test for every trial of the batch."""
    arena = streams[0].arena
    targets = np.stack([s.test_set[0] for s in streams])
    wheel = np.stack([s.test_set[1] for s in streams])
    sense = np.stack([s.test_set[2] for s in streams])
    B, m = targets.shape[:2]
    o = [np.zeros((B, m)), np.zeros((B, m), dtype=np.bool_), np.zeros((B, m), dtype=np.int64), np.zeros((B, m)),
         np.zeros((B, m)), np.full((B, m, len(eps)), np.nan), np.full((B, m, len(eps)), np.nan),
         np.zeros((B, m), dtype=np.bool_)]
    cx, cy = arena.centre
    _test_batch(batch.code, batch.W, batch.P, batch.R, batch.params, arena.vector(), cx, cy, arena.step_s, targets,
                wheel, sense, np.ascontiguousarray(eps, dtype=np.float64), stop.code, *o)
    return [TestOutcome(*(a[b] for a in o)) for b in range(B)]


def run_batch(batch: NetworkBatch, streams: list[TrialStreams], eps: np.ndarray,
              on_progress: Callable[[int], None] | None = None, stop: StopRule = GOAL_STOP,
              train_stop: StopRule = GOAL_STOP) -> list[list[TestOutcome]]:
    """Whole trials for the batch (one trial per robot); returns outcomes[trial][test point].

    ``stop``: the test's stop rule; ``train_stop``: training's. ``on_progress(steps)`` is
    called after each training interval.
    """
    arena, s = streams[0].arena, streams[0].schedule
    B = len(streams)
    poses = np.tile(np.array([*arena.centre, 0.0]), (B, 1))
    cursors = np.zeros((B, 4), dtype=np.int64)  # target index, steps on it, steps learned, steps at a wall
    targets = np.stack([st.train_targets for st in streams])
    results = [[o] for o in test_batch(batch, streams, eps, stop)]
    for chunk, t0 in enumerate(s.test_points[:-1]):
        wheel, sense, explore = batch_train_chunk(streams, chunk, s.test_interval)
        _train_batch(batch.code, batch.size, batch.W, batch.P, batch.R, batch.params, arena.vector(), poses, cursors,
                     targets, t0, wheel, sense, explore, s.train_budget, train_stop.code)
        for r, o in zip(results, test_batch(batch, streams, eps, stop), strict=True):
            r.append(o)
        if on_progress:
            on_progress(s.test_interval)
    return results
