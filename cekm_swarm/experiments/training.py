"""Train one network for use elsewhere (``cekm train``, the controller's default model)."""

from __future__ import annotations

import math

import numpy as np
from tqdm import tqdm

from .arena import Arena, displacement, drive
from .reaching_config import TargetReachingConfig
from .reaching_run import run_network
from .stopping import GOAL_STOP
from .streams import Schedule

CONVERGENCE_ABS = 0.01  # m
CONVERGENCE_REL = 0.2  # of |w_i|


def convergence_mask(net, arena: Arena | None = None, tol_abs: float = CONVERGENCE_ABS,
                     tol_rel: float = CONVERGENCE_REL) -> np.ndarray:
    """Which neurons have converged (section 3.5: "the neurons will stabilize in a state
    such that v = w_i and c = M_i w_i"): each neuron's own command c = M_i w_i (clipped to
    c*) is executed for one step on the noise-free training plant, and the displacement v
    it produces must land within tol_abs + tol_rel |w_i| of w_i. Neurons the data never
    reached (stranded between the learned clusters) fail this; the controller leaves them
    out of the motor competition."""
    arena = arena or Arena(size=100.0)
    av = arena.vector()
    empty = np.empty(0)
    ok = np.zeros(net.w.shape[0], dtype=bool)
    for i, (a_i, d_i) in enumerate(net.w):
        c = np.clip(net.M[i] @ np.array([a_i, net.learn_p.d_scale * d_i]), -net.v_max, net.v_max)
        pose = np.array([arena.size / 2, arena.size / 2, 0.0])
        _, _, dth = drive(pose, c[0], c[1], np.ones((arena.substeps, 2)), av, 0.0, 0.0, empty, empty, empty, 0.0, 0.0)
        a_v, d_v = displacement(arena.size / 2, arena.size / 2, 0.0, pose[0], pose[1], dth)
        miss = math.hypot(d_v * math.cos(a_v) - d_i * math.cos(a_i), d_v * math.sin(a_v) - d_i * math.sin(a_i))
        ok[i] = miss <= tol_abs + tol_rel * d_i
    return ok


def train_network(name: str, steps: int, seed: int, progress: bool = True):
    """Self-organized learning of one network in the obstacle-free arena from untrained maps,
    with the controllers' stop (the goal state, :data:`GOAL_STOP`), so that the default model
    stays what it was.

    Returns (trained network, its scores on the fixed test after training).
    """
    interval = 10_000 if steps % 10_000 == 0 else steps
    config = TargetReachingConfig(networks=(name,), trials=1, seed=seed, stop=GOAL_STOP, train_stop=GOAL_STOP,
                                  bfn_rule="trained-units",
                                  schedule=Schedule(steps=steps, test_interval=interval))
    with tqdm(total=steps, unit="step", unit_scale=True, disable=not progress, desc=f"training {name}") as bar:
        run = run_network(name, config, bar.update)
    last = run.scores[0][-1]
    i5 = list(config.eps_mm).index(5.0)
    score = {"E_mm": last.E_mm, "T_s_per_m": last.T_s_per_m, "D": last.D, "P5": float(last.P[i5]),
             "ended_by_budget": last.ended_by_budget}
    net = run.trained(0, config)
    if net.kind.startswith("indirect"):
        net.converged = convergence_mask(net)
        score["converged_neurons"] = int(net.converged.sum())
    return net, score
