"""The tracking grid's picture: one heatmap per pair of axes of cekm's A minus the best
baseline's (A-CMOMMT or local K-means, whichever is higher there), pooled over the cells
at each level pair; a star marks Welch p < 0.05."""

from __future__ import annotations

from typing import Any

NAMES = {"robots": "robots n", "targets_per_robot": "targets per robot m/n", "speed": "target speed",
         "target_range": "sensing range R (m)", "obstacles": "obstacles"}


def _tick(v) -> str:
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        return f"{v:g}"
    return str(v)


def heatmaps(pairs: list[dict[str, Any]], title: str):
    """The figure: a grid of heatmaps, one per axis pair."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    cols = 5
    rows = (len(pairs) + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(3.4 * cols, 3.0 * rows + 0.6), squeeze=False)
    lim = max([abs(c["diff"]) for p in pairs for c in p["cells"]] + [0.05])
    im = None
    for ax, pair in zip(axes.flat, pairs):
        a, b = pair["axes"]
        la, lb = pair["levels"]
        z = np.full((len(lb), len(la)), np.nan)
        for c in pair["cells"]:
            i, j = lb.index(c[b]), la.index(c[a])
            z[i, j] = c["diff"]
            star = "*" if c["p"] < 0.05 else ""
            ax.text(j, i, f"{c['diff']:+.2f}{star}", ha="center", va="center", fontsize=7,
                    color="white" if abs(c["diff"]) > 0.6 * lim else "black")
        im = ax.imshow(z, cmap="RdBu", vmin=-lim, vmax=lim, origin="lower", aspect="auto")
        ax.set_xticks(range(len(la)), [_tick(v) for v in la], fontsize=7)
        ax.set_yticks(range(len(lb)), [_tick(v) for v in lb], fontsize=7)
        ax.set_xlabel(NAMES[a], fontsize=8)
        ax.set_ylabel(NAMES[b], fontsize=8)
    for ax in list(axes.flat)[len(pairs):]:
        ax.axis("off")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout(rect=(0, 0, 0.91, 0.95))
    if im is not None:
        cax = fig.add_axes((0.925, 0.15, 0.012, 0.7))
        fig.colorbar(im, cax=cax, label="A cekm - A best baseline")
    return fig
