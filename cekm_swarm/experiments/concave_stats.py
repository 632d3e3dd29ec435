"""Fig. 9's statistics from the sweep's runs (:mod:`.concave_run`): every (range, depth,
width) cell's success rate over the seeds, and per (range, depth) the widths negotiated."""

from __future__ import annotations

from .concave_config import SweepConfig


def cells_of(config: SweepConfig, runs: list[dict]) -> list[dict]:
    """The success rate of every (range, depth, width) cell over the seeds."""
    cells = []
    for r in config.ranges:
        for d in config.depths:
            for w in config.widths:
                mine = [x for x in runs if x["range"] == r and x["depth"] == d and x["width"] == w]
                k = sum(x["reached"] for x in mine)
                cells.append({"range": r, "depth": d, "width": w, "reached": k, "of": len(mine),
                              "rate": k / len(mine) if mine else None})
    return cells


def grid_of(config: SweepConfig, runs: list[dict]) -> list[dict]:
    """Per (range, depth): the widths negotiated (>= ``need`` seeds), the widest of them
    (``max_width``, the paper's reading) and the widest below which every width tried is
    negotiated too (``max_width_no_hole``: a narrower U that traps the robot is a hole)."""
    grid = []
    for r in config.ranges:
        for d in config.depths:
            ok, solid = [], None
            broken = False
            for w in config.widths:
                wins = sum(x["reached"] for x in runs if x["range"] == r and x["depth"] == d and x["width"] == w)
                if wins >= config.need:
                    ok.append(w)
                    if not broken:
                        solid = w
                else:
                    broken = True
            grid.append({"range": r, "depth": d, "max_width": max(ok) if ok else None, "negotiated_widths": ok,
                         "max_width_no_hole": solid})
    return grid
