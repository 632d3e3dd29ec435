"""The tracking experiment's pictures: one run as the paper's Fig. 13 (:func:`plot_tracking`,
also ``cekm run``'s trajectory.png) and A against team size per controller
(:func:`plot_team_sizes`). matplotlib is imported inside each function (Agg)."""

from __future__ import annotations

from typing import Any

import numpy as np

from .tracking_run import CONTROLLERS, TrackingRun


def plot_tracking(run: TrackingRun, ax=None, title: str | None = None, instants: int = 4):
    """Fig. 13: the targets' paths (grey, arrow at the end), each robot's path in its colour,
    and its sensing circle at a few instants (fainter earlier)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from world.draw import draw_paths, draw_tracking, draw_world, legend_outside, robot_colours, widen_to  # noqa: PLC0415 -- lazy: matplotlib

    own = ax is None
    if own:
        xmin, ymin, xmax, ymax = run.geometry["bounds"]
        aspect = (ymax - ymin) / max(xmax - xmin, 1e-9)
        fig, ax = plt.subplots(figsize=(6.5 + 1.7, max(3.0, 6.5 * aspect)))
    draw_world(ax, run.geometry, None)
    colours = robot_colours(sorted(run.paths))
    step = draw_paths(ax, {r: ([q[0] for q in p], [q[1] for q in p], [q[2] for q in p]) for r, p in run.paths.items()},
                      colours)
    draw_tracking(ax, {r: ([q[1] for q in p], [q[2] for q in p]) for r, p in run.paths.items()}, run.target_paths,
                  run.target_range, colours, instants)
    bx0, by0, bx1, by1 = run.geometry["bounds"]
    ax.set_xlim(bx0 - 0.05, bx1 + 0.05)
    ax.set_ylim(by0 - 0.05, by1 + 0.05)
    widen_to(ax, [q[1] for p in run.paths.values() for q in p], [q[2] for p in run.paths.values() for q in p])
    ax.set_aspect("equal")
    ax.set_title(title or f"{run.scenario}: {run.controller}, seed {run.seed}, A = {run.tracking['A']:.3f}",
                 fontsize=9)
    legend_outside(ax, time_step=step)
    if own:
        fig.tight_layout()
        return fig
    return ax


def plot_team_sizes(doc: dict[str, Any]):
    """Parker's A against team size, one curve per controller with its 95 % intervals."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4))
    sizes = [c["robots"] for c in doc["configs"]]
    for i, ctl in enumerate(CONTROLLERS):
        ms = [c["controllers"][ctl]["A"]["mean"] for c in doc["configs"]]
        lo = [c["controllers"][ctl]["A"]["ci95"][0] for c in doc["configs"]]
        hi = [c["controllers"][ctl]["A"]["ci95"][1] for c in doc["configs"]]
        x = np.array(sizes, dtype=float) * (1 + 0.02 * (i - 1))
        ax.errorbar(x, ms, yerr=[np.subtract(ms, lo), np.subtract(hi, ms)], marker="o", capsize=3, label=ctl)
    ax.set_xscale("log", base=2)
    ax.set_xticks(sizes)
    ax.set_xticklabels([str(s) for s in sizes])
    ax.set_xlabel("robots (arena and targets grow with the team)")
    ax.set_ylabel("A (fraction of targets observed)")
    ax.set_ylim(0, 1)
    ax.legend()
    ax.set_title(f"Parker's A, mean and 95 % interval over {len(doc['seeds'])} seeds")
    fig.tight_layout()
    return fig
