"""The tracking grid's design and its scenarios (``cekm experiment tracking --grid``;
docs/tracking.md): which cells run, and the scenario of a cell for a seed.

Axes (the issue's): team size n, targets per robot m/n, target speed relative to the
robot's top speed v*, target sensing range R, obstacles or none. A full factorial is
7 x 4 x 3 x 2 x 2 = 336 cells, too many to run on 2 cores in 15 minutes, so the default
design is fractional: every (n, m/n) pair (28 cells) with speed, range and obstacles
assigned to the cells so that every level pair of every two axes occurs (a seeded search
for the most balanced assignment, :func:`design`). The heatmap of two axes averages the
cells at each level pair.

A cell's scenario for a seed (:func:`grid_scenario`) is drawn from that seed alone: a
square walled arena of side 2 m * sqrt(n / 2) (robot density the same at every n; the
targets' grows with m/n), round(m/n * n) random-walk targets at uniform starts, robots at
uniform starts, and with obstacles round(n / 2) discs and boxes; every start keeps its
clearance from walls, obstacles and the other starts (checked, then validated by the
scenario parser).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from world.scenario import parse_scenario

from ..robot import KHEPERA

TEAM_SIZES = (2, 3, 4, 6, 8, 12, 16)
TARGETS_PER_ROBOT = (1.0, 1.5, 2.0, 3.0)
SPEEDS = {"slow": 0.15, "medium": 0.35, "fast": 0.7}  # fraction of v* = 0.15625 m/s
RANGES = (0.35, 0.5)  # target sensing range R, m
OBSTACLES = (False, True)
AXES = ("robots", "targets_per_robot", "speed", "target_range", "obstacles")
LEVELS: dict[str, tuple] = {"robots": TEAM_SIZES, "targets_per_robot": TARGETS_PER_ROBOT,
                            "speed": tuple(SPEEDS), "target_range": RANGES, "obstacles": OBSTACLES}
QUICK = {"robots": (2, 4), "targets_per_robot": (1.0, 2.0), "speed": ("slow", "fast"), "target_range": (0.5,),
         "obstacles": (False, True)}
"""The ``--quick`` design's levels (CI): a few small cells."""


@dataclass(frozen=True)
class Cell:
    """One grid cell: a level of every axis."""

    robots: int
    targets_per_robot: float
    speed: str
    target_range: float
    obstacles: bool

    @property
    def targets(self) -> int:
        return max(1, round(self.targets_per_robot * self.robots))

    @property
    def label(self) -> str:
        return (f"n{self.robots}-m{self.targets_per_robot:g}-{self.speed}-R{self.target_range:g}"
                f"-{'obst' if self.obstacles else 'open'}")

    def as_dict(self) -> dict[str, Any]:
        return {**asdict(self), "targets": self.targets, "label": self.label}


def _imbalance(cells: list[tuple], levels: list[tuple]) -> float:
    """How far the design is from every level pair of every two axes occurring equally
    often; a missing pair costs most."""
    cost = 0.0
    for a, b in itertools.combinations(range(len(levels)), 2):
        counts = {pair: 0 for pair in itertools.product(levels[a], levels[b])}
        for c in cells:
            counts[(c[a], c[b])] += 1
        v = np.array(list(counts.values()), dtype=float)
        cost += 100.0 * float((v == 0).sum()) + float(v.var())
    return cost


def design(levels: dict[str, tuple] | None = None, restarts: int = 8, swaps: int = 1500, seed: int = 19) -> list[Cell]:
    """The fractional design: every (robots, targets_per_robot) pair, with the other axes'
    levels assigned (each level equally often, up to one) by a seeded local search for
    the most balanced pair coverage: swaps within a column that do not make it worse (the
    same cells every time)."""
    lv = dict(LEVELS if levels is None else levels)
    base = list(itertools.product(lv["robots"], lv["targets_per_robot"]))
    rest = [lv["speed"], lv["target_range"], lv["obstacles"]]
    rng = np.random.default_rng(seed)
    all_levels = [lv[a] for a in AXES]

    def cells_of(cols):
        return [(n, m, cols[0][i], cols[1][i], cols[2][i]) for i, (n, m) in enumerate(base)]

    best, best_cost = None, math.inf
    for _ in range(restarts):
        cols = []
        for levels_k in rest:
            col = [levels_k[i % len(levels_k)] for i in range(len(base))]
            rng.shuffle(col)
            cols.append(col)
        cost = _imbalance(cells_of(cols), all_levels)
        for _ in range(swaps):
            k = int(rng.integers(len(cols)))
            i, j = (int(x) for x in rng.integers(len(base), size=2))
            if cols[k][i] == cols[k][j]:
                continue
            cols[k][i], cols[k][j] = cols[k][j], cols[k][i]
            c = _imbalance(cells_of(cols), all_levels)
            if c <= cost:
                cost = c
            else:
                cols[k][i], cols[k][j] = cols[k][j], cols[k][i]
        if cost < best_cost:
            best, best_cost = cells_of(cols), cost
    assert best is not None  # restarts >= 1: the first always beats an infinite cost
    return [Cell(int(n), float(m), str(s), float(r), bool(o)) for n, m, s, r, o in best]


def arena_side(robots: int) -> float:
    """2 m * sqrt(robots / 2): 2 m for two robots (as tracking.toml), the same robot density at every size."""
    return 2.0 * math.sqrt(robots / 2.0)


def _free(p: tuple[float, float], taken: list[tuple[float, float, float]], clear: float) -> bool:
    return all(math.hypot(p[0] - x, p[1] - y) >= r + clear for x, y, r in taken)


def grid_raw(cell: Cell, seed: int) -> dict[str, Any]:
    """The scenario document (a dict, as a TOML file would give) of ``cell`` for ``seed``."""
    rng = np.random.default_rng([seed, cell.robots, int(cell.targets_per_robot * 10), list(SPEEDS).index(cell.speed),
                                 int(cell.target_range * 1000), int(cell.obstacles), 19])
    side = arena_side(cell.robots)
    body = KHEPERA.body_radius
    taken: list[tuple[float, float, float]] = []  # (x, y, radius) of what is placed
    obstacles = []
    if cell.obstacles:
        for k in range(max(1, round(cell.robots / 2))):
            for _ in range(200):
                if rng.random() < 0.5:
                    r = float(rng.uniform(0.06, 0.14))
                    shape = {"shape": "disc", "radius": round(r, 3)}
                else:
                    w, h = float(rng.uniform(0.1, 0.4)), float(rng.uniform(0.06, 0.12))
                    r = math.hypot(w, h) / 2
                    shape = {"shape": "box", "size": [round(w, 3), round(h, 3)],
                             "angle": round(float(rng.uniform(0, math.pi)), 3)}
                c = (float(rng.uniform(0.35 + r, side - 0.35 - r)), float(rng.uniform(0.35 + r, side - 0.35 - r)))
                if _free(c, taken, 0.3):
                    taken.append((c[0], c[1], r))
                    obstacles.append({"id": f"o{k + 1}", "center": [round(c[0], 3), round(c[1], 3)], **shape})
                    break
    robots = []
    for i in range(cell.robots):
        for _ in range(1000):
            p = (float(rng.uniform(0.15, side - 0.15)), float(rng.uniform(0.15, side - 0.15)))
            if _free(p, taken, body + 0.12):
                taken.append((p[0], p[1], body))
                robots.append({"id": f"r{i + 1}", "start": [round(p[0], 4), round(p[1], 4),
                                                            round(float(rng.uniform(-math.pi, math.pi)), 4)]})
                break
        else:
            raise RuntimeError(f"grid cell {cell.label}, seed {seed}: no room for robot r{i + 1}")
    speed = SPEEDS[cell.speed] * KHEPERA.v_max
    targets = []
    for k in range(cell.targets):
        p = (float(rng.uniform(0.1, side - 0.1)), float(rng.uniform(0.1, side - 0.1)))
        targets.append({"id": f"t{k + 1}", "position": [round(p[0], 4), round(p[1], 4)],
                        "motion": {"type": "random_walk", "speed": round(speed, 5), "turn_noise": 1.0,
                                   "heading": round(float(rng.uniform(-math.pi, math.pi)), 4)}})
    return {"name": f"grid-{cell.label}", "seed": int(seed),
            "arena": {"bounds": [0.0, 0.0, round(side, 4), round(side, 4)]},
            "sensors": {"target_range": cell.target_range}, "robots": robots, "targets": targets,
            "obstacles": obstacles}


def grid_scenario(cell: Cell, seed: int):
    """The validated scenario of ``cell`` for ``seed`` (world.scenario.parse_scenario)."""
    return parse_scenario(grid_raw(cell, seed), source=f"<grid {cell.label}, seed {seed}>")
