"""Why a robot circles a target instead of stopping: one test episode, step by step.

Trains one network as ``cekm experiment target-reaching`` does, replays the final test of
one trial with every step recorded (:func:`cekm_swarm.experiments.trial.trace_test`, the
same path the test measures), picks a target that the step budget ended (or the one
asked for), and shows what drove the robot there: its path around the target, the winning
neuron and its input weights over time, the network's command beside the kinematically
exact command for the sensed input, and the lattice near d = 0.

    cekm experiment circling --network R15 --seed 2005 --trial 1 \\
        --speed-unit 0.008 --out docs/results/target-reaching-circling

docs/reproduction-4.1.md section 1 explains the episodes it finds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import jsonfile
from ..errors import ParameterError
from ..robot import KHEPERA, STEP_S
from .arena import Arena
from .reaching_config import TargetReachingConfig
from .reaching_run import run_network
from .stopping import StopRule
from .streams import Schedule, TrialStreams
from .training import convergence_mask
from .trial import TRACE_FIELDS, trace_test

COL = {name: i for i, name in enumerate(TRACE_FIELDS)}


def kinematic_command(alpha: float, d: float, backward: bool, axle: float = KHEPERA.axle,
                      step_s: float = STEP_S) -> tuple[float, float]:
    """The wheel speeds (v_l, v_r) of the one arc that moves the robot by u = (alpha, d) in one
    step, in the chord convention of the training displacement (docs/design.md section 3):
    forward, turning 2 alpha; or backward (``backward``), turning 2 (alpha -+ pi). The exact
    inverse of the plant without noise, for comparison with a network's command."""
    if backward:
        half = alpha - math.copysign(math.pi, alpha)
        sign = -1.0
    else:
        half, sign = alpha, 1.0
    arc = d if abs(half) < 1e-12 else d * half / math.sin(half)
    v, om = sign * arc / step_s, 2.0 * half / step_s
    return v - 0.5 * om * axle, v + 0.5 * om * axle


def episode(traces: np.ndarray, target: np.ndarray, index: int) -> dict[str, np.ndarray]:
    """One target's recorded steps as named arrays, with the true distance and direction."""
    rows = traces[index][~np.isnan(traces[index][:, 0])]
    out = {name: rows[:, COL[name]] for name in TRACE_FIELDS}
    dx, dy = target[0] - out["x"], target[1] - out["y"]
    out["true_d"] = np.hypot(dx, dy)
    out["true_alpha"] = np.arctan2(-np.sin(out["theta"]) * dx + np.cos(out["theta"]) * dy,
                                   np.cos(out["theta"]) * dx + np.sin(out["theta"]) * dy)
    out["winner"] = out["winner"].astype(int)
    return out


def summarize_episode(ep: dict, net, budget: int) -> dict:
    """What drove the robot: each winner's share of the steps, its input weights, (indirect EKM)
    its M, its own command M_s w_s and whether it has converged (training.convergence_mask),
    and how far the network's command was from the kinematically exact one."""
    winners, counts = np.unique(ep["winner"], return_counts=True)
    order = np.argsort(-counts)
    kin_rows = []
    for a, d, cl, cr in zip(ep["alpha"], ep["d"], ep["c_l"], ep["c_r"], strict=True):
        back = (cl + cr) < 0.0
        kin_rows.append(kinematic_command(a, d, back))
    kin = np.array(kin_rows)
    c = np.stack([ep["c_l"], ep["c_r"]], axis=1)
    converged = convergence_mask(net) if hasattr(net, "M") else None
    rows = []
    for k in order[:8]:
        s = int(winners[k])
        sel = ep["winner"] == s
        executed = np.stack([ep["executed_l"][sel], ep["executed_r"][sel]], 1)
        row = {"neuron": s, "steps": int(counts[k]),
               "w_alpha_rad": float(net.w[s, 0]), "w_d_mm": float(net.w[s, 1] * 1000),
               "sensed_alpha_rad_mean": float(ep["alpha"][sel].mean()),
               "sensed_d_mm_mean": float(ep["d"][sel].mean() * 1000),
               "command_mm_s_mean": (c[sel].mean(axis=0) * 1000).round(2).tolist(),
               "kinematic_mm_s_mean": (kin[sel].mean(axis=0) * 1000).round(2).tolist(),
               "executed_mm_s_mean": (executed.mean(0) * 1000).round(2).tolist()}
        if converged is not None:  # M_s w_s moves the robot by w_s (section 3.5's converged state)
            row["M"] = np.asarray(net.M[s]).round(5).tolist()
            own = net.M[s] @ [net.w[s, 0], net.learn_p.d_scale * net.w[s, 1]]
            row["own_command_mm_s"] = (own * 1000).round(2).tolist()
            row["converged"] = bool(converged[s])
        rows.append(row)
    late = slice(len(ep["d"]) // 2, None)
    near = (ep["true_d"] < 0.005) & (ep["d"] > 0.0)
    alpha_err = np.abs(np.angle(np.exp(1j * (ep["alpha"][near] - ep["true_alpha"][near]))))
    return {"steps": int(len(ep["d"])), "ended_by_budget": bool(len(ep["d"]) >= budget),
            "sensed_alpha_error_rad_within_5_mm": ({"median": float(np.median(alpha_err)),
                                                    "max": float(alpha_err.max()), "steps": int(near.sum())}
                                                   if near.any() else None),
            "final_distance_mm": float(ep["true_d"][-1] * 1000),
            "closest_mm": float(ep["true_d"].min() * 1000),
            "second_half_distance_mm": [float(ep["true_d"][late].min() * 1000), float(ep["true_d"][late].max() * 1000)],
            "second_half_sensed_d_mm": sorted({round(float(x) * 1000, 3) for x in ep["d"][late]})[:12],
            "command_error_mm_s_median": float(np.median(np.abs(c - kin)) * 1000),
            "winners": rows}


def draw_episode(ep: dict, net, target: np.ndarray, title: str, stop: StopRule, path: Path,
                 window: int = 60) -> Path:
    """The picture: (A) path around the target, (B) winner's input weights and the sensed u over
    time, (C) command, executed command and the kinematically exact command, (D) the lattice
    near d = 0 with the episode's winners."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(ep["d"])
    near = np.flatnonzero(ep["true_d"] < 0.03)
    j0 = int(near[0]) if near.size else 0
    j1 = min(n, j0 + window)
    steps = np.arange(j0, j1)
    fig, axes = plt.subplots(2, 2, figsize=(12, 9))
    ax = axes[0, 0]
    x, y = (ep["x"][j0:j1] - target[0]) * 1000, (ep["y"][j0:j1] - target[1]) * 1000
    ax.plot(x, y, "-", color="0.6", lw=0.8)
    sc = ax.scatter(x, y, c=steps, cmap="viridis", s=18, zorder=3)
    th = ep["theta"][j0:j1]
    ax.quiver(x, y, np.cos(th), np.sin(th), steps, cmap="viridis", scale=25, width=0.004, zorder=2)
    ax.plot(0, 0, "r+", ms=14, mew=2)
    ax.add_patch(plt.Circle((0, 0), 5.0, fill=False, ls=":", color="r"))
    ax.set_aspect("equal")
    ax.set_xlabel("x - target (mm)")
    ax.set_ylabel("y - target (mm)")
    ax.set_title(f"(A) path, steps {j0}-{j1 - 1} (arrows: heading; dotted: 5 mm)", loc="left", fontsize=10)
    fig.colorbar(sc, ax=ax, label="step")

    ax = axes[0, 1]
    ws = net.w[ep["winner"][j0:j1]]
    ax.step(steps, ws[:, 0], where="mid", color="tab:blue", label="winner's alpha_s")
    ax.plot(steps, ep["alpha"][j0:j1], ".", color="tab:blue", ms=4, alpha=0.5, label="sensed alpha")
    ax.set_ylabel("alpha (rad)", color="tab:blue")
    ax.set_xlabel("step")
    ax2 = ax.twinx()
    ax2.step(steps, ws[:, 1] * 1000, where="mid", color="tab:orange", label="winner's d_s")
    ax2.plot(steps, ep["d"][j0:j1] * 1000, "x", color="tab:orange", ms=4, alpha=0.6, label="sensed d")
    ax2.set_ylabel("d (mm)", color="tab:orange")
    lines = ax.get_legend_handles_labels()[0] + ax2.get_legend_handles_labels()[0]
    labels = ax.get_legend_handles_labels()[1] + ax2.get_legend_handles_labels()[1]
    ax.legend(lines, labels, fontsize=7, loc="upper right")
    ax.set_title("(B) the winning neuron's input weights w_s and the sensed u", loc="left", fontsize=10)

    ax = axes[1, 0]
    kin = np.array([kinematic_command(a, d, (cl + cr) < 0) for a, d, cl, cr in
                    zip(ep["alpha"][j0:j1], ep["d"][j0:j1], ep["c_l"][j0:j1], ep["c_r"][j0:j1], strict=True)])
    for k, (name, colour) in enumerate((("left", "tab:green"), ("right", "tab:red"))):
        ax.plot(steps, ep[f"c_{name[0]}"][j0:j1] * 1000, "-o", ms=3, color=colour, label=f"network c_{name[0]}")
        ax.plot(steps, kin[:, k] * 1000, "--", color=colour, alpha=0.6, label=f"kinematic c_{name[0]}")
        ax.plot(steps, ep[f"executed_{name[0]}"][j0:j1] * 1000, "s", mfc="none", ms=5, color=colour, alpha=0.7,
                label=f"executed c_{name[0]}")
    if stop.rule == "command":
        h = stop.motor_resolution * 500
        ax.axhspan(-h, h, color="0.85", label=f"stop band (|c| < {h:g} mm/s)")
    ax.axhline(0, color="k", lw=0.5)
    lim = max(20.0, float(np.nanpercentile(np.abs(ep["c_l"][j0:j1]), 95) * 1000) * 1.3)
    ax.set_ylim(-lim, lim)
    ax.set_xlabel("step")
    ax.set_ylabel("wheel speed (mm/s)")
    ax.legend(fontsize=7, ncol=2, loc="upper right")
    ax.set_title("(C) command, executed command, exact command for the sensed u", loc="left", fontsize=10)

    ax = axes[1, 1]
    lat = net.w[net.w[:, 1] < 0.03]
    ax.scatter(lat[:, 0], lat[:, 1] * 1000, s=10, color="0.6", label="neurons with d_i < 30 mm")
    winners, counts = np.unique(ep["winner"][j0:j1], return_counts=True)
    ax.scatter(net.w[winners, 0], net.w[winners, 1] * 1000, s=30 + 6 * counts, facecolors="none", edgecolors="tab:red",
               label="winners in (A), size: steps")
    ax.plot(ep["alpha"][j0:j1], ep["d"][j0:j1] * 1000, "k.", ms=3, alpha=0.5, label="sensed u")
    ax.set_xlim(-math.pi, math.pi)
    ax.set_ylim(-1, 30)
    ax.set_xlabel("alpha (rad)")
    ax.set_ylabel("d (mm)")
    ax.legend(fontsize=7, loc="upper right")
    ax.set_title("(D) the lattice near d = 0", loc="left", fontsize=10)
    fig.suptitle(title, fontsize=11)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


@dataclass(frozen=True)
class CirclingEpisode:
    """What :func:`run_circling` found: the summary (also written as JSON), the picture
    and the title that names the run."""

    summary: dict
    png: Path
    json: Path
    title: str


def run_circling(out: Path, network: str = "R15", seed: int = 2005, trial: int = 1, target: int | None = None,
                 pick: str = "budget", stop_rule: str = "command", train_stop: str = "goal",
                 motor_resolution: float = KHEPERA.speed_unit, speed_unit: float = 0.0,
                 target_resolution: float = KHEPERA.target_resolution, bfn: str = "paper",
                 steps: int = Schedule().steps) -> CirclingEpisode | None:
    """Train ``network`` for trial ``trial`` of master seed ``seed``, replay its final test
    step by step and draw one episode: test target ``target`` (from 1), else the first
    target the budget ended (``pick`` 'budget', None if there is none) or the one that
    stopped farthest away ('farthest-stop'). Writes the PNG and the JSON into ``out``."""
    if trial < 1:
        raise ParameterError(f"trial: counts from 1, got {trial}")
    stop = StopRule(stop_rule, motor_resolution)
    arena = Arena(speed_unit=speed_unit, target_resolution=target_resolution)
    config = TargetReachingConfig(networks=(network,), trials=trial, seed=seed, arena=arena, stop=stop,
                                  train_stop=StopRule(train_stop, motor_resolution), bfn_rule=bfn,
                                  schedule=Schedule(steps=steps))
    run = run_network(network, config)
    t = trial - 1
    streams = TrialStreams(seed, t, arena, config.schedule)
    traces = trace_test(run.batch, t, streams, stop)
    targets = streams.test_set[0]
    lengths = np.sum(~np.isnan(traces[:, :, 0]), axis=1)
    budget = config.schedule.test_budget
    ended = [int(i) for i in np.flatnonzero(lengths >= budget)]
    last = traces[np.arange(len(targets)), np.maximum(lengths - 1, 0)]
    stop_dist = np.where(lengths < budget, np.hypot(targets[:, 0] - last[:, 0], targets[:, 1] - last[:, 1]), -1.0)
    if target is not None:
        if not 1 <= target <= len(targets):
            raise ParameterError(f"target: must be 1-{len(targets)}, got {target}")
        index = target - 1
    elif pick == "farthest-stop":
        index = int(np.argmax(stop_dist))
    elif ended:
        index = ended[0]
    else:
        return None
    net = run.trained(t, config)
    ep = episode(traces, targets[index], index)
    summary = {"network": network, "seed": seed, "trial": trial, "target": index + 1,
               "settings": config.settings(), "targets_ended_by_budget": [i + 1 for i in ended],
               "final_E_mm": run.scores[t][-1].E_mm, "episode": summarize_episode(ep, net, budget)}
    stem = f"circling-{network}-seed{seed}-trial{trial}-target{index + 1}"
    plant = (f"wheels quantized to {speed_unit * 1000:g} mm/s" if speed_unit > 0 else "continuous wheels")
    title = (f"{network}, master seed {seed}, trial {trial}, test target {index + 1} after {steps:,} steps: "
             f"stop rule '{stop_rule}', {plant}")
    out.mkdir(parents=True, exist_ok=True)
    png = draw_episode(ep, net, targets[index], title, stop, out / f"{stem}.png")
    (out / f"{stem}.json").write_text(jsonfile.dumps(summary))
    return CirclingEpisode(summary, png, out / f"{stem}.json", title)

