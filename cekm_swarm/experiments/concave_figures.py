"""Fig. 9's pictures from the fig9.json document: the paper's curves (:func:`plot_sweep`)
and every cell's success rate (:func:`plot_grid`); and several controllers' cells one
above the other, the cells each negotiates differently from a reference row marked
(:func:`plot_grid_rows`, Fig. 9 before and after). Each is saved to the path given;
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


def _range_panel(ax, cells: list[dict], r: float, depths: list[float], widths: list[float],
                 frames: dict[tuple[float, float, float], str] | None = None):
    """One sensing range's cells on ``ax``: each cell's share of runs reaching the goal
    (width across, depth up) with its count, and a frame of the given colour around the
    cells of ``frames``; returns the image (for the colour bar)."""
    from matplotlib.patches import Rectangle

    z = np.full((len(depths), len(widths)), np.nan)
    for c in cells:
        if c["range"] != r:
            continue
        i, j = depths.index(c["depth"]), widths.index(c["width"])
        z[i, j] = c["reached"] / c["of"] if c["of"] else np.nan
        ax.text(j, i, f"{c['reached']}/{c['of']}", ha="center", va="center", fontsize=7)
        colour = (frames or {}).get((r, c["depth"], c["width"]))
        if colour is not None:
            ax.add_patch(Rectangle((j - 0.46, i - 0.46), 0.92, 0.92, fill=False, lw=2.2, edgecolor=colour))
    im = ax.imshow(z, origin="lower", cmap="RdYlGn", vmin=0.0, vmax=1.0, aspect="auto")
    ax.set_xticks(range(len(widths)), [f"{w * 100:.0f}" for w in widths], fontsize=7)
    ax.set_yticks(range(len(depths)), [f"{d * 100:.0f}" for d in depths], fontsize=7)
    ax.set_xlabel("width (cm)", fontsize=8)
    ax.set_ylabel("depth (cm)", fontsize=8)
    ax.set_title(f"sensing range {r * 100:.0f} cm", fontsize=9)
    return im


def plot_grid(doc: dict, path: Path) -> Path:
    """Every cell's success rate: one panel per sensing range, width across, depth down."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    st = doc["settings"]
    widths, depths, ranges = st["widths"], st["depths"], st["ranges"]
    fig, axes = plt.subplots(1, len(ranges), figsize=(4.2 * len(ranges) + 1.0, 3.6), squeeze=False)
    for ax, r in zip(axes[0], ranges, strict=True):
        im = _range_panel(ax, doc["cells"], r, depths, widths)
    fig.colorbar(im, ax=axes[0].tolist(), fraction=0.03, label="success rate")
    fig.suptitle("Fig. 9 as a grid: runs that reached the goal behind the U, per cell", fontsize=10)
    fig.savefig(path, dpi=130, bbox_inches="tight")
    plt.close(fig)
    return path


def _axis(cells: list[dict], key: str) -> list[float]:
    return sorted({c[key] for c in cells})


def negotiated(cells: list[dict], need: int) -> set[tuple[float, float, float]]:
    """The (range, depth, width) of the cells reached in ``need`` runs or more."""
    return {(c["range"], c["depth"], c["width"]) for c in cells if c["reached"] >= need}


def row_summary(label: str, cells: list[dict], need: int, reference_cells: list[dict] | None = None,
                reference: str | None = None) -> str:
    """"LABEL: N cells negotiated", with the cells gained and lost against a reference row."""
    mine = negotiated(cells, need)
    text = f"{label}: {len(mine)} cells negotiated"
    if reference_cells is not None:
        ref = negotiated(reference_cells, need)
        text += f" ({len(mine - ref)} gained, {len(ref - mine)} lost against {reference})"
    return text


def plot_grid_rows(rows: dict[str, list[dict]], need: int, path: Path, reference: str | None = None) -> Path:
    """Fig. 9's cells for each labelled controller, one row of range panels each.

    ``rows`` maps a label to its cells (dicts with range, depth, width, reached, of; the
    sweep's ``cells``); a cell is negotiated at ``need`` runs or more. With a
    ``reference`` label, every other row frames the cells it negotiates and the reference
    does not (green) and the reverse (red), and its title counts both.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if not rows:
        raise ValueError("plot_grid_rows: no rows to draw")
    every = [c for cells in rows.values() for c in cells]
    ranges, depths, widths = _axis(every, "range"), _axis(every, "depth"), _axis(every, "width")

    ref = negotiated(rows[reference], need) if reference in rows else None
    fig = plt.figure(figsize=(3.9 * len(ranges) + 1.2, 3.3 * len(rows) + 0.6), layout="constrained")
    subfigs = fig.subfigures(len(rows), 1, squeeze=False).ravel()
    im = None
    for sub, (label, cells) in zip(subfigs, rows.items(), strict=True):
        mine = negotiated(cells, need)
        against = rows.get(reference) if reference is not None and reference != label else None
        sub.suptitle(row_summary(label, cells, need, against, reference), fontsize=10, fontweight="bold",
                     x=0.02, ha="left")
        row_axes = sub.subplots(1, len(ranges), squeeze=False)[0]
        frames = {} if ref is None or label == reference else \
            {key: "#1a7f37" if key in mine else "#cf222e" for key in mine ^ ref}
        for ax, r in zip(row_axes, ranges, strict=True):
            im = _range_panel(ax, cells, r, depths, widths, frames)
        sub.colorbar(im, ax=row_axes.tolist(), fraction=0.03, label="share of runs reaching the goal")
    fig.suptitle(f"Fig. 9 as a grid: a cell is negotiated at >= {need} runs"
                 + (f"\nframed: negotiated by this row and not by {reference} (green), or the reverse (red)"
                    if ref is not None else ""), fontsize=10)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
