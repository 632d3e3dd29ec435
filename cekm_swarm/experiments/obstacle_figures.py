"""The obstacle suite's pictures: per scenario, the first seed's runs of the controllers
side by side (command fusion, then cooperative EKMs), as the paper's Figs. 8, 10-12.
matplotlib is imported inside the function (Agg)."""

from __future__ import annotations

from .navigation_figures import plot_run
from .obstacle_run import FIGURE


def suite_figure(s: str, runs: list):
    """Scenario ``s``'s figure: ``runs`` (:class:`.navigation_run.NavigationRun`) drawn side by side."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    xmin, ymin, xmax, ymax = runs[0].geometry["bounds"]
    aspect = (ymax - ymin) / (xmax - xmin)
    fig, axes = plt.subplots(1, len(runs), figsize=(6.5 * len(runs), max(3.0, 6.5 * aspect) + 0.6), squeeze=False)
    for ax, run, letter in zip(axes[0], runs, "AB", strict=False):
        name = "command fusion" if run.controller == "fusion" else "cooperative EKMs"
        plot_run(run, ax=ax, title=f"({letter}) {name}, seed {run.seed}")
    fig_no = FIGURE[s]
    fig.suptitle(f"Fig. {fig_no}: {s}" if fig_no else s)
    fig.tight_layout()
    return fig
