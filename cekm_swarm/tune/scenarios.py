"""Generated scenarios for training and judging the field policy (docs/fields.md).

Navigation: one robot, a goal behind an obstacle geometry drawn from a seed -- a U of any
width and depth (Fig. 9's family, opening toward the robot), a doorway between two blocks
with an offset goal, a corridor, or three rooms with doorways and circling movers
(Fig. 11's family) -- with the distance sensors' range drawn too. Tracking: the tracking
grid's cells and generator (:func:`cekm_swarm.experiments.grid_design.grid_scenario`).

Seeds are kept apart by purpose (:data:`SEED_BASE`): training draws from one range,
validation (the policy kept) from another, and the held-out evaluation from a third; none
of them meets a seed any other experiment reports (1-40, 100-139).
"""

from __future__ import annotations

import functools
import math
from itertools import chain
from typing import Any

import numpy as np

from world.scenario import parse_scenario

from ..errors import ParameterError
from ..experiments.grid_design import TEAM_SIZES, design, grid_scenario

KINDS = ("u", "doorway", "corridor", "movers")
"""The generated geometries judged (held out) and, by default, trained on."""
WIDE_KINDS = (*KINDS, "gaps", "wall", "u-narrow")
"""``--mix wide``: also a row of discs with narrow gaps (Fig. 12's left room), a long wall
whose end the robot rounds, and narrow deep U's (Fig. 9's stall cells); docs/fields.md."""
ROUTE_KINDS = (*WIDE_KINDS, "alcove")
"""``--mix route``: the wide mix and a goal at the bottom of a narrow alcove in a corner
(Fig. 12's last checkpoint, where learned policies stall against the alcove's wall end)."""
MOVER_KINDS = (*WIDE_KINDS, "movers", "movers")
"""``--mix movers``: the wide mix with rooms with movers three times as often (a third of
the scenarios): the geometry a closing speed is for (docs/fields.md, the third round)."""
TURNED_KINDS = (*WIDE_KINDS, "u-turned", "u-turned")
"""``--mix turned``: the wide mix and, a third of the time, a U turned any way (0.2-0.8 m wide,
0.1-0.3 m deep), so the robot meets its side, its back or its mouth at a slant (Fig. 12's U
on the checkpoint route, where the third round's first policy stalled)."""
DISC_KINDS = (*ROUTE_KINDS, "disc", "disc")
"""``--mix discs``: the route mix and, a fifth of the time, a lone small disc head-on on the
way to the goal (where the fourth round's policy can stall: its obstacle field, widened for
walls ahead, inhibits every forward neuron the map has; docs/fields.md, the fifth round)."""
STALL_KINDS = (*KINDS, "u-narrow", "u-narrow", "u-narrow", "disc", "disc")
"""``--mix stalls``: the default mix, narrow deep U's a third of the time and lone discs
head-on two ninths: the geometries where a robot stalls, for the ``stalled`` feature."""
MIXES = {"default": KINDS, "wide": WIDE_KINDS, "route": ROUTE_KINDS, "movers": MOVER_KINDS, "turned": TURNED_KINDS,
         "discs": DISC_KINDS, "lone-disc": ("disc",), "stalls": STALL_KINDS}
SEED_BASE = {"train": 1_000_000, "validation": 2_000_000, "test": 3_000_000}
"""Scenario seeds by purpose: purpose p's i-th scenario has seed SEED_BASE[p] + i."""


def seed_of(purpose: str, i: int) -> int:
    if purpose not in SEED_BASE:
        raise ParameterError(f"unknown seed purpose {purpose!r}; expected one of {list(SEED_BASE)}")
    return SEED_BASE[purpose] + int(i)


def _r(x: float) -> float:
    return round(float(x), 4)


def u_raw(width: float, depth: float, sensor_range: float, seed: int, offset: float = 0.0,
          facing: float = math.pi) -> dict[str, Any]:
    """A U (Fig. 8/9's concave obstacle) ``width`` x ``depth`` inside, opening toward the
    robot 0.5 m before it, the goal 0.36 m behind its back wall (as concave.toml)."""
    return {"name": f"gen-u-w{width:.3f}-d{depth:.3f}", "seed": int(seed), "arena": {"bounds": [0.0, 0.0, 3.0, 3.0]},
            "sensors": {"range": _r(sensor_range)},
            "robots": [{"id": "r1", "start": [1.0, _r(1.5 + offset), 0.0], "goal": "goal"}],
            "targets": [{"id": "goal", "position": [_r(1.5 + depth + 0.02 + 0.36), 1.5]}],
            "obstacles": [{"id": "u", "shape": "concave", "center": [1.5, 1.5], "width": _r(width), "depth": _r(depth),
                           "thickness": 0.02, "facing": _r(facing)}]}


def check_mix(mix: str) -> tuple[str, ...]:
    """The kinds of geometry mix ``mix``."""
    if mix not in MIXES:
        raise ParameterError(f"unknown geometry mix {mix!r}; expected one of {list(MIXES)}")
    return MIXES[mix]


def navigation_raw(seed: int, kind: str | None = None, mix: str = "default") -> dict[str, Any]:
    """The scenario document of generated navigation scenario ``seed`` (its kind drawn
    from the seed among ``mix``'s kinds unless given; the default mix's scenarios are
    those of every earlier version)."""
    rng = np.random.default_rng([int(seed), 41])
    kinds = check_mix(mix)
    kind = kind or kinds[int(rng.integers(len(kinds)))]
    rs = float(rng.uniform(0.12, 0.25))
    if kind == "u-narrow":  # Fig. 9's narrow deep U's: 0.15-0.4 m wide, 0.12-0.3 m deep
        return u_raw(float(rng.uniform(0.15, 0.4)), float(rng.uniform(0.12, 0.30)), rs, seed,
                     float(rng.uniform(-0.1, 0.1)), math.pi + float(rng.uniform(-0.3, 0.3)))
    if kind == "u-turned":  # any orientation: the robot meets its side, back or mouth
        width, depth = float(rng.uniform(0.2, 0.8)), float(rng.uniform(0.10, 0.30))
        raw = u_raw(width, depth, rs, seed, float(rng.uniform(-0.15, 0.15)), float(rng.uniform(-math.pi, math.pi)))
        reach = math.hypot(width / 2 + 0.02, depth + 0.02)  # the U's farthest point from its mouth's centre
        raw["robots"][0]["start"][0] = _r(1.5 - reach - 0.15)  # clear of the U whichever way it is turned
        raw["targets"][0]["position"][0] = _r(1.5 + reach + 0.36)
        return raw
    if kind == "disc":  # a lone disc 0.04-0.16 m across, head-on (0-3 cm off the way), the start turned a little
        radius, dist = float(rng.uniform(0.02, 0.08)), float(rng.uniform(0.8, 1.2))
        at, off = float(rng.uniform(0.35, 0.6)), float(rng.uniform(-0.03, 0.03))
        y = 1.0 + float(rng.uniform(-0.2, 0.2))
        return {"name": f"gen-disc-{radius:.3f}", "seed": int(seed), "arena": {"bounds": [0.0, 0.0, 3.0, 2.0]},
                "sensors": {"range": _r(rs)},
                "robots": [{"id": "r1", "start": [0.8, _r(y), _r(rng.uniform(-0.3, 0.3))], "goal": "goal"}],
                "targets": [{"id": "goal", "position": [_r(0.8 + dist), _r(y)]}],
                "obstacles": [{"id": "disc", "shape": "disc", "center": [_r(0.8 + at * dist), _r(y + off)],
                               "radius": _r(radius)}]}
    if kind in ("gaps", "wall", "alcove"):
        return _extra_raw(kind, rng, rs, seed)
    if kind == "u":
        return u_raw(float(rng.uniform(0.10, 1.0)), float(rng.uniform(0.06, 0.30)), rs, seed,
                     float(rng.uniform(-0.1, 0.1)), math.pi + float(rng.uniform(-0.3, 0.3)))
    if kind == "doorway":
        gap = float(rng.uniform(0.086, 0.2))
        half = 0.125
        off = float(rng.uniform(-0.4, 0.4))
        return {"name": f"gen-doorway-{gap:.3f}", "seed": int(seed), "arena": {"bounds": [0.0, 0.0, 3.0, 2.0]},
                "sensors": {"range": _r(rs)},
                "robots": [{"id": "r1", "start": [1.0, _r(1.0 - off / 2), 0.0], "goal": "goal"}],
                "targets": [{"id": "goal", "position": [2.0, _r(1.0 + off)]}],
                "obstacles": [{"id": "block_n", "shape": "box", "center": [1.5, _r(1.0 + gap / 2 + half)],
                               "size": [0.10, 2 * half]},
                              {"id": "block_s", "shape": "box", "center": [1.5, _r(1.0 - gap / 2 - half)],
                               "size": [0.10, 2 * half]}]}
    if kind == "corridor":
        gap = float(rng.uniform(0.13, 0.3))
        length = float(rng.uniform(0.3, 0.9))
        y0 = 1.0 + float(rng.uniform(-0.2, 0.2))
        x0 = 1.2
        return {"name": f"gen-corridor-{gap:.3f}-{length:.2f}", "seed": int(seed),
                "arena": {"bounds": [0.0, 0.0, 3.0, 2.0]}, "sensors": {"range": _r(rs)},
                "robots": [{"id": "r1", "start": [0.5, _r(1.0 + float(rng.uniform(-0.3, 0.3))), 0.0], "goal": "goal"}],
                "targets": [{"id": "goal", "position": [_r(x0 + length + 0.4), _r(y0)]}],
                "walls": [{"a": [x0, _r(y0 + gap / 2)], "b": [_r(x0 + length), _r(y0 + gap / 2)]},
                          {"a": [x0, _r(y0 - gap / 2)], "b": [_r(x0 + length), _r(y0 - gap / 2)]}]}
    if kind == "movers":
        d1, d2 = float(rng.uniform(0.12, 0.2)), float(rng.uniform(0.12, 0.2))
        y1, y2 = float(rng.uniform(0.2, 0.8 - d1)), float(rng.uniform(0.2, 0.8 - d2))
        walls = [{"a": [1.0, 0.0], "b": [1.0, _r(y1)]}, {"a": [1.0, _r(y1 + d1)], "b": [1.0, 1.0]},
                 {"a": [2.0, 0.0], "b": [2.0, _r(y2)]}, {"a": [2.0, _r(y2 + d2)], "b": [2.0, 1.0]}]
        movers = []
        for k in range(int(rng.integers(1, 4))):
            movers.append({"id": f"m{k + 1}", "shape": "disc", "radius": 0.04,
                           "motion": {"type": "circle", "center": [1.5, 0.5], "radius": _r(rng.uniform(0.15, 0.3)),
                                      "angular_speed": _r(rng.uniform(0.2, 0.6)),
                                      "phase": _r(rng.uniform(0, 2 * math.pi)),
                                      "direction": "ccw" if rng.random() < 0.5 else "cw"}})
        return {"name": f"gen-movers-{len(movers)}", "seed": int(seed), "arena": {"bounds": [0.0, 0.0, 3.0, 1.0],
                                                                                   "wall_thickness": 0.02},
                "sensors": {"range": _r(rs)},
                "robots": [{"id": "r1", "start": [0.25, _r(rng.uniform(0.3, 0.7)), 0.0], "goal": "goal"}],
                "targets": [{"id": "goal", "position": [2.75, _r(rng.uniform(0.3, 0.7))]}],
                "walls": walls, "obstacles": movers}
    raise ParameterError(f"unknown geometry kind {kind!r}; expected one of {sorted(set(chain(*MIXES.values())))}")


def _extra_raw(kind: str, rng: np.random.Generator, rs: float, seed: int) -> dict[str, Any]:
    """The wide mix's own kinds: ``gaps``, three or four discs 0.1 m across in a row
    across the way with gaps of 0.085-0.13 m (Fig. 12's left room); ``wall``, a wall 0.8-1.6 m
    long beside the start, the goal beyond its end and behind it (the robot rounds the end);
    ``alcove``, the goal at the bottom of an alcove 0.12-0.2 m wide and 0.3-0.5 m deep in a
    walled arena's corner (Fig. 12's goal)."""
    if kind == "gaps":
        n = int(rng.integers(3, 5))
        gaps = rng.uniform(0.085, 0.13, n - 1)
        ys = 1.0 + np.concatenate([[0.0], np.cumsum(0.1 + gaps)])
        ys = ys - (ys[-1] - ys[0]) / 2 + float(rng.uniform(-0.1, 0.1))
        x = 1.5 + float(rng.uniform(-0.1, 0.1))
        return {"name": f"gen-gaps-{n}", "seed": int(seed), "arena": {"bounds": [0.0, 0.0, 3.0, 2.0]},
                "sensors": {"range": _r(rs)},
                "robots": [{"id": "r1", "start": [1.0, _r(1.0 + rng.uniform(-0.15, 0.15)), 0.0], "goal": "goal"}],
                "targets": [{"id": "goal", "position": [2.1, _r(1.0 + rng.uniform(-0.3, 0.3))]}],
                "obstacles": [{"id": f"g{i + 1}", "shape": "disc", "center": [_r(x), _r(y)], "radius": 0.05}
                              for i, y in enumerate(ys)]}
    if kind == "alcove":
        width, depth = float(rng.uniform(0.12, 0.2)), float(rng.uniform(0.3, 0.5))
        return {"name": f"gen-alcove-{width:.3f}", "seed": int(seed), "arena": {"bounds": [0.0, 0.0, 3.0, 2.0],
                                                                              "wall_thickness": 0.02},
                "sensors": {"range": _r(rs)},
                "robots": [{"id": "r1", "start": [_r(rng.uniform(1.6, 2.3)), _r(rng.uniform(0.6, 1.6)),
                                                  _r(rng.uniform(-math.pi, math.pi))], "goal": "goal"}],
                "targets": [{"id": "goal", "position": [_r(3.0 - width / 2), _r(rng.uniform(0.08, 0.15))]}],
                "walls": [{"a": [_r(3.0 - width), 0.0], "b": [_r(3.0 - width), _r(depth)]}]}
    length = float(rng.uniform(0.8, 1.6))
    side = float(rng.uniform(0.06, 0.2))  # the start's distance from the wall
    y_wall = 1.0
    end = 0.5 + length
    return {"name": f"gen-wall-{length:.2f}", "seed": int(seed), "arena": {"bounds": [0.0, 0.0, 3.0, 2.0]},
            "sensors": {"range": _r(rs)},
            "robots": [{"id": "r1", "start": [0.4, _r(y_wall + side), _r(rng.uniform(-0.3, 0.3))], "goal": "goal"}],
            "targets": [{"id": "goal", "position": [_r(end + rng.uniform(0.1, 0.4)),
                                                     _r(y_wall - rng.uniform(0.1, 0.4))]}],
            "walls": [{"a": [0.3, y_wall], "b": [_r(end), y_wall]}]}


def navigation_scenario(seed: int, kind: str | None = None, mix: str = "default"):
    """The validated scenario of :func:`navigation_raw`."""
    raw = navigation_raw(seed, kind, mix)
    return parse_scenario(raw, source=f"<generated {raw['name']}, seed {seed}>")


@functools.lru_cache(maxsize=1)
def grid_cells() -> tuple:
    """The tracking grid's cells (its design is a seeded search: made once per process)."""
    return tuple(design())


def tracking_scenario(seed: int, cell=None, robots: int | None = None):
    """A tracking grid scenario: ``cell`` (default: a cell of the grid's design drawn from
    the seed, among those of ``robots`` robots if given) with the grid's generator for ``seed``."""
    if cell is None:
        cells = tuple(c for c in grid_cells() if robots is None or c.robots == robots)
        if not cells:
            raise ParameterError(f"the tracking grid has no cell of {robots} robots; its team sizes are "
                                 f"{sorted({c.robots for c in grid_cells()})}")
        cell = cells[int(np.random.default_rng([int(seed), 43]).integers(len(cells)))]
    return grid_scenario(cell, seed)


def _one_robot(robots: int | None) -> None:
    if robots not in (None, 1):
        raise ParameterError(f"generated navigation scenarios have one robot, not {robots}")


def scenario(task: str, seed: int, robots: int | None = None, mix: str = "default"):
    """Generated scenario ``seed`` of ``task`` (tracking: of ``robots`` robots if given;
    navigation's have one, its geometry drawn from ``mix``)."""
    if task == "navigation":
        _one_robot(robots)
        return navigation_scenario(seed, mix=mix)
    if task == "tracking":
        return tracking_scenario(seed, robots=robots)
    raise ParameterError(f"unknown task {task!r}; expected navigation or tracking")


def team_ids(task: str, robots: int | None = None) -> tuple[str, ...]:
    """Every robot id a generated scenario of ``task`` (of ``robots`` robots if given) can
    have: navigation's one robot; tracking's largest team of the grid or ``robots`` (its
    generator names them r1, r2, ...)."""
    if task == "navigation":
        _one_robot(robots)
        return ("r1",)
    if task == "tracking":
        return tuple(f"r{i + 1}" for i in range(robots or max(TEAM_SIZES)))
    raise ParameterError(f"unknown task {task!r}; expected navigation or tracking")
