"""Checkpoints for Fig. 12: a planner on the known walls only (Low et al. 2002's role).

The known map is rasterized on a grid; a shortest path from start to goal is found with
A* on a cost that prefers clearance from the known walls (so the path runs through the
middle of doorways); the checkpoints are the path's narrow-passage points (local minima
of clearance below ``doorway_clearance``: the doorways) followed by the goal. Unknown
obstacles are not in the map: the robot meets them unforeseen.

The geometry is plain data (the world's ``static_geometry()``): lists of ``walls``,
``polygons`` (``vertices``) and ``discs`` (``center``, ``radius``), each with ``known``,
and ``bounds`` = [xmin, ymin, xmax, ymax].
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import CekmError
from ..robot import KHEPERA


class PlanningError(CekmError):
    """No path on the known map."""


@dataclass(frozen=True)
class Plan:
    checkpoints: list[tuple[float, float]]
    path: list[tuple[float, float]]  # the grid path, for drawing


def occupancy(geometry: Mapping[str, Any], resolution: float) -> tuple[np.ndarray, tuple[float, float]]:
    """Boolean grid (rows = y, cols = x) of cells covered by known items, and the grid origin."""
    from matplotlib.path import Path as MplPath

    xmin, ymin, xmax, ymax = geometry["bounds"]
    nx = int(math.ceil((xmax - xmin) / resolution))
    ny = int(math.ceil((ymax - ymin) / resolution))
    xs = xmin + (np.arange(nx) + 0.5) * resolution
    ys = ymin + (np.arange(ny) + 0.5) * resolution
    X, Y = np.meshgrid(xs, ys)
    pts = np.column_stack([X.ravel(), Y.ravel()])
    occ = np.zeros(pts.shape[0], dtype=bool)
    for item in list(geometry.get("walls", [])) + list(geometry.get("polygons", [])):
        if item.get("known", True):
            occ |= MplPath(np.asarray(item["vertices"])).contains_points(pts, radius=1e-9)
    for disc in geometry.get("discs", []):
        if disc.get("known", False):
            cx, cy = disc["center"]
            occ |= (pts[:, 0] - cx) ** 2 + (pts[:, 1] - cy) ** 2 <= disc["radius"] ** 2
    return occ.reshape(ny, nx), (xmin, ymin)


def plan_checkpoints(geometry: Mapping[str, Any], start: tuple[float, float], goal: tuple[float, float],
                     body_radius: float = KHEPERA.body_radius, resolution: float = 0.01,
                     doorway_clearance: float = 0.12) -> Plan:
    """Checkpoints at the doorways on the way from start to goal, then the goal."""
    from scipy.ndimage import distance_transform_edt

    occ, (x0, y0) = occupancy(geometry, resolution)
    clearance = distance_transform_edt(~occ) * resolution  # m to the nearest known wall
    free = clearance > body_radius + 0.005
    ny, nx = occ.shape

    def cell(p: tuple[float, float] | np.ndarray) -> tuple[int, int]:
        return (min(ny - 1, max(0, int((p[1] - y0) / resolution))), min(nx - 1, max(0, int((p[0] - x0) / resolution))))

    s, g = cell(start), cell(goal)
    for name, c in (("start", s), ("goal", g)):
        if not free[c]:
            where = start if name == "start" else goal
            raise PlanningError(f"the {name} {where} is inside or too close to a known wall")
    cost = 1.0 + 0.05 / np.maximum(clearance, resolution)  # prefer the middle of passages
    moves = [(-1, 0, 1.0), (1, 0, 1.0), (0, -1, 1.0), (0, 1, 1.0), (-1, -1, math.sqrt(2)), (-1, 1, math.sqrt(2)),
             (1, -1, math.sqrt(2)), (1, 1, math.sqrt(2))]
    dist = {s: 0.0}
    prev: dict[tuple[int, int], tuple[int, int]] = {}
    heap = [(0.0, s)]
    while heap:
        f, c = heapq.heappop(heap)
        if c == g:
            break
        dc = dist[c]
        for dr, dcol, step in moves:
            n = (c[0] + dr, c[1] + dcol)
            if 0 <= n[0] < ny and 0 <= n[1] < nx and free[n]:
                nd = dc + step * 0.5 * (cost[c] + cost[n])
                if nd < dist.get(n, math.inf):
                    dist[n] = nd
                    prev[n] = c
                    heapq.heappush(heap, (nd + math.hypot(n[0] - g[0], n[1] - g[1]), n))
    if g not in prev and g != s:
        raise PlanningError(f"no path from {start} to {goal} on the known walls")
    cells = [g]
    while cells[-1] != s:
        cells.append(prev[cells[-1]])
    cells.reverse()
    path = [(x0 + (c[1] + 0.5) * resolution, y0 + (c[0] + 0.5) * resolution) for c in cells]
    cl = np.array([clearance[c] for c in cells])
    checkpoints: list[tuple[float, float]] = []
    window = max(1, int(0.2 / resolution))  # one checkpoint per narrow passage
    for i in range(1, len(cl) - 1):
        lo, hi = max(0, i - window), min(len(cl), i + window + 1)
        narrowest = cl[i] < doorway_clearance and cl[i] == cl[lo:hi].min()
        if narrowest and (not checkpoints or math.dist(checkpoints[-1], path[i]) > 0.1):
            checkpoints.append(path[i])
    checkpoints.append((float(goal[0]), float(goal[1])))
    return Plan(checkpoints=[(float(x), float(y)) for x, y in checkpoints], path=path)
