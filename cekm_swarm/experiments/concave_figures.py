"""Fig. 9's pictures from the fig9.json document: the paper's curves (:func:`plot_sweep`)
and every cell's success rate (:func:`plot_grid`), each saved to the path given.
matplotlib is imported inside each function (Agg)."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def plot_sweep(doc: dict, path: Path) -> Path:
    """The paper's Fig. 9: the widest negotiated width against depth, one curve per range."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4.2))
    for r in doc["settings"]["ranges"]:
        cells = [c for c in doc["grid"] if c["range"] == r]
        ax.plot([c["depth"] * 100 for c in cells], [(c["max_width"] or 0.0) * 100 for c in cells], "-o",
                label=f"sensing range {r * 100:.0f} cm")
    ax.set_xlabel("obstacle depth (cm)")
    ax.set_ylabel("maximum negotiable width (cm)")
    ax.set_title(f"Fig. 9: widest concave obstacle overcome (>= {doc['settings']['need']} of "
                 f"{len(doc['settings']['seeds'])} seeds; 0 = none)", fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)
    return path


def plot_grid(doc: dict, path: Path) -> Path:
    """Every cell's success rate: one panel per sensing range, width across, depth down."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    st = doc["settings"]
    widths, depths, ranges = st["widths"], st["depths"], st["ranges"]
    fig, axes = plt.subplots(1, len(ranges), figsize=(4.2 * len(ranges) + 1.0, 3.6), squeeze=False)
    for ax, r in zip(axes[0], ranges, strict=True):
        z = np.full((len(depths), len(widths)), np.nan)
        for c in doc["cells"]:
            if c["range"] == r and c["rate"] is not None:
                z[depths.index(c["depth"]), widths.index(c["width"])] = c["rate"]
        im = ax.imshow(z, origin="lower", cmap="RdYlGn", vmin=0.0, vmax=1.0, aspect="auto")
        for i in range(len(depths)):
            for j in range(len(widths)):
                cell = next((c for c in doc["cells"] if c["range"] == r and c["depth"] == depths[i]
                             and c["width"] == widths[j]), None)
                if cell is not None:
                    ax.text(j, i, f"{cell['reached']}/{cell['of']}", ha="center", va="center", fontsize=7)
        ax.set_xticks(range(len(widths)), [f"{w * 100:.0f}" for w in widths], fontsize=7)
        ax.set_yticks(range(len(depths)), [f"{d * 100:.0f}" for d in depths], fontsize=7)
        ax.set_xlabel("width (cm)")
        ax.set_ylabel("depth (cm)")
        ax.set_title(f"sensing range {r * 100:.0f} cm", fontsize=9)
    fig.colorbar(im, ax=axes[0].tolist(), fraction=0.03, label="success rate")
    fig.suptitle("Fig. 9 as a grid: runs that reached the goal behind the U, per cell", fontsize=10)
    fig.savefig(path, dpi=130, bbox_inches="tight")
    plt.close(fig)
    return path
