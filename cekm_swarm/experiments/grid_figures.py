"""The tracking grid's pictures: one heatmap per pair of axes of cekm's A minus the best
baseline's (A-CMOMMT or local K-means, whichever is higher there), pooled over the cells
at each level pair, a star marking Welch p < 0.05; and A over the run, per controller."""

from __future__ import annotations

from typing import Any

import numpy as np

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

    cols = 5
    rows = (len(pairs) + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(3.4 * cols, 3.0 * rows + 0.6), squeeze=False)
    lim = max([abs(c["diff"]) for p in pairs for c in p["cells"]] + [0.05])
    im = None
    for ax, pair in zip(axes.flat, pairs, strict=False):
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


def over_the_run(by_part: dict[str, Any], title: str):
    """A per part of the run, one line per controller with its 95 % interval as a band."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    mids = [(lo + hi) / 2 for lo, hi in by_part["parts"]]
    for name, parts in by_part["controllers"].items():
        line, = ax.plot(mids, [p["mean"] for p in parts], marker="o", label=name)
        ax.fill_between(mids, [p["ci95"][0] for p in parts], [p["ci95"][1] for p in parts],
                        color=line.get_color(), alpha=0.15, linewidth=0)
    ax.set_xlabel("sim time (s), the middle of each part of the run")
    ax.set_ylabel("Parker's A over that part")
    ax.set_xlim(0, by_part["parts"][-1][1])
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="lower right")
    ax.set_title(title, fontsize=9)
    fig.tight_layout()
    return fig
