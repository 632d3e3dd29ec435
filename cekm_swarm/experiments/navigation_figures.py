"""Section 4.2's pictures of one run: the run as in the paper's Figs. 8-12
(:func:`plot_run`; also ``cekm run``'s trajectory.png and the obstacle suite's figures)
and Fig. 4's activities at one instant (:func:`plot_fields`, from
:func:`.navigation_run.fields_at`). matplotlib is imported inside each function (Agg).
"""

from __future__ import annotations

import numpy as np

from .navigation_run import NavigationRun


def plot_run(run: NavigationRun, ax=None, title: str | None = None):
    """The run drawn like the paper's figures: walls, obstacles and their motion, robot path, goal, checkpoints."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Circle

    from world.draw import draw_paths, draw_world, figure_size, fit_bounds, legend_outside, robot_colours  # noqa: PLC0415 -- lazy: matplotlib, pymunk, world

    own = ax is None
    if own:
        fig, ax = plt.subplots(figsize=(7, 6))
    colours = robot_colours(sorted(run.logs))
    draw_world(ax, run.geometry, run.final_state, colours)
    labels = {r: f"{r} ({'reached' if log.reached else 'not reached'})" for r, log in run.logs.items()}
    step = draw_paths(ax, {r: (log.t, log.x, log.y) for r, log in run.logs.items()}, colours, labels)
    for r, log in run.logs.items():
        col = colours[r]
        n = max(1, len(log.x) // 40)
        for x, y in zip(log.x[::n], log.y[::n], strict=True):
            ax.add_patch(Circle((x, y), 0.03, fill=False, edgecolor=col, lw=0.4, alpha=0.5))
        cps = log.checkpoints
        if len(cps) > 1:
            ax.plot([c[0] for c in cps[:-1]], [c[1] for c in cps[:-1]], "o", color="k", ms=4, label="checkpoints")
    points = [p for log in run.logs.values() for p in zip(log.x, log.y, strict=True)] + [c for log in run.logs.values()
                                                                          for c in log.checkpoints]
    x0, x1, y0, y1 = fit_bounds(ax, run.geometry, points)
    ax.set_title(title or f"{run.scenario}: {run.controller}, seed {run.seed}")
    legend_outside(ax, time_step=step)
    if own:
        fig.set_size_inches(figure_size(x0, x1, y0, y1))
    if own:
        fig.tight_layout()
        return fig
    return ax


def plot_fields(f: dict, sensors: tuple[int, ...] | None = None):
    """The six panels of Fig. 4 (plus the robot's situation): darker = stronger activity."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    w = f["w"]
    angles = f["sensor_angles"]
    if sensors is None:  # the sensors at -pi/6, 0, pi/6, as in the paper
        sensors = tuple(int(np.argmin(np.abs(np.angle(np.exp(1j * (angles - a))))))
                        for a in (-np.pi / 6, 0.0, np.pi / 6))
    panels = [("(A) target localization EKM", f["a"], f["s"])]
    for letter, j in zip("BCD", sensors, strict=False):
        b = f["obstacle"].get(j, np.zeros(len(w)))
        panels.append((f"({letter}) obstacle EKM, sensor at {angles[j]:+.2f} rad", b, f["obstacle_winners"].get(j)))
    panels.append(("(E) obstacle EKMs combined", f["combined"], None))
    panels.append(("(F) integrated (motor EKM)", f["e"], f["k"]))
    fig, axes = plt.subplots(2, 4, figsize=(17, 7.5), gridspec_kw={"width_ratios": [1, 1, 1, 1.1]})
    flat = [axes[0, 0], axes[0, 1], axes[0, 2], axes[1, 0], axes[1, 1], axes[1, 2]]
    for ax, (title, act, win) in zip(flat, panels, strict=False):
        sc = ax.scatter(w[:, 0], w[:, 1], c=act, cmap="Greys", s=18, edgecolors="0.6", linewidths=0.3)
        if title.startswith("(F)") and "eligible" in f and not f["eligible"].all():
            out = ~f["eligible"]
            ax.scatter(w[out, 0], w[out, 1], marker="x", s=22, color="tab:blue", linewidths=0.8,
                       label="not in the motor competition")
            ax.legend(fontsize=7, loc="upper left")
        if win is not None:
            ax.scatter([w[win, 0]], [w[win, 1]], s=90, facecolors="none", edgecolors="red", linewidths=1.5)
        ax.set_title(title, fontsize=9, loc="left")
        ax.set_xlim(-np.pi, np.pi)
        ax.set_xlabel("alpha (rad)")
        ax.set_ylabel("d (m)")
        fig.colorbar(sc, ax=ax, fraction=0.046)
    from world.draw import draw_world  # noqa: PLC0415 -- lazy: matplotlib, pymunk, world

    for ax in (axes[0, 3], axes[1, 3]):
        ax.remove()
    ax = fig.add_subplot(1, 4, 4)
    draw_world(ax, f["geometry"], f["state"])
    x, y, th = f["pose"]
    ax.set_xlim(x - 0.4, x + 0.4)
    ax.set_ylim(y - 0.4, y + 0.4)
    ax.set_title(f"robot at t = {f['time']:.2f} s", fontsize=9)
    fig.suptitle("Fig. 4: activities of the localization and motor EKMs (red: winner)")
    fig.tight_layout()
    return fig
