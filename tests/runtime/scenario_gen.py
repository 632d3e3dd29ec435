"""Scenarios made from a seed for the property tests: 1 to 8 robots at random starts in an
arena that grows with the team, a few discs, and per robot a goal (navigation) or a crowd
of random-walk targets (tracking). Every one is a valid scenario file (the loader checks
it; a draw it refuses is drawn again from the same generator)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from world import ScenarioError, load_scenario


def _far(p, others, d):
    return all(math.hypot(p[0] - q[0], p[1] - q[1]) >= d for q in others)


def scenario_text(seed: int, robots: int | None = None, task: str | None = None) -> str:
    rng = np.random.default_rng(seed)
    n = int(robots if robots is not None else rng.integers(1, 9))
    task = task or ("tracking" if rng.random() < 0.5 else "navigation")
    side = round(1.5 + 0.3 * n, 2)
    lines = [f'name = "gen-{seed}"', f'description = "generated from seed {seed}: {n} robots, {task}"',
             f"seed = {int(rng.integers(0, 2**31))}", "", "[arena]", f"bounds = [0.0, 0.0, {side}, {side}]"]
    if task == "tracking":
        lines += ["", "[sensors]", f"target_range = {round(float(rng.uniform(0.4, 0.7)), 3)}"]
    discs = []
    for _ in range(int(rng.integers(0, 4))):
        discs.append((float(rng.uniform(0.3, side - 0.3)), float(rng.uniform(0.3, side - 0.3)),
                      float(rng.uniform(0.04, 0.12))))
    starts: list[tuple[float, float]] = []
    while len(starts) < n:
        p = (float(rng.uniform(0.15, side - 0.15)), float(rng.uniform(0.15, side - 0.15)))
        if _far(p, starts, 0.2) and all(math.hypot(p[0] - x, p[1] - y) > r + 0.12 for x, y, r in discs):
            starts.append(p)
    goals: list[tuple[float, float]] = []
    for i, (x, y) in enumerate(starts):
        lines += ["", "[[robots]]", f'id = "r{i + 1}"', f"start = [{x:.3f}, {y:.3f}, "
                                                        f"{float(rng.uniform(-3.1, 3.1)):.3f}]"]
        if task == "navigation":
            while True:
                g = (float(rng.uniform(0.1, side - 0.1)), float(rng.uniform(0.1, side - 0.1)))
                if math.hypot(g[0] - x, g[1] - y) > 0.4 and all(math.hypot(g[0] - a, g[1] - b) > r + 0.08
                                                                for a, b, r in discs):
                    break
            goals.append(g)
            lines.append(f'goal = "g{i + 1}"')
    for i, g in enumerate(goals):
        lines += ["", "[[targets]]", f'id = "g{i + 1}"', f"position = [{g[0]:.3f}, {g[1]:.3f}]"]
    if task == "tracking":
        for i in range(n + int(rng.integers(0, n + 1))):
            lines += ["", "[[targets]]", f'id = "t{i + 1}"',
                      f"position = [{float(rng.uniform(0.2, side - 0.2)):.3f}, "
                      f"{float(rng.uniform(0.2, side - 0.2)):.3f}]",
                      "[targets.motion]", 'type = "random_walk"', f"speed = {float(rng.uniform(0.02, 0.08)):.3f}",
                      "turn_noise = 1.0", f"heading = {float(rng.uniform(-3.1, 3.1)):.3f}"]
    for i, (x, y, r) in enumerate(discs):
        lines += ["", "[[obstacles]]", f'id = "d{i + 1}"', 'shape = "disc"', f"center = [{x:.3f}, {y:.3f}]",
                  f"radius = {r:.3f}"]
    return "\n".join(lines) + "\n"


def generated_scenario(folder: Path, seed: int, robots: int | None = None, task: str | None = None) -> Path:
    """A valid generated scenario file for ``seed`` (the same file for the same arguments)."""
    for attempt in range(50):
        text = scenario_text(seed * 1000 + attempt, robots, task)
        path = folder / f"gen-{seed}.toml"
        path.write_text(text)
        try:
            load_scenario(path)
            return path
        except ScenarioError:
            continue
    raise AssertionError(f"no valid scenario from seed {seed} in 50 draws")
