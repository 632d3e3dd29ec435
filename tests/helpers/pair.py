"""The two-robot scenario with a small disc in r1's way (tests/runtime/test_launch_realtime.py's),
r1's start given: the realtime recovery test's, and the start where the learned widths leave
only a turn in place (tests/tune/test_field_policy.py)."""

from __future__ import annotations


def pair_toml(r1_start: tuple[float, float, float] = (0.2, 0.35, 0.0)) -> str:
    """The scenario file's text, r1 starting at ``r1_start`` (x, y, theta)."""
    x, y, th = r1_start
    return f"""
name = "pair"
description = "two robots, short trips; r1 passes a disc"
seed = 1

[arena]
bounds = [0.0, 0.0, 1.4, 1.2]

[[robots]]
id = "r1"
start = [{x}, {y}, {th}]
goal = "g1"

[[robots]]
id = "r2"
start = [0.2, 0.85, 0.0]
goal = "g2"

[[targets]]
id = "g1"
position = [1.0, 0.35]

[[targets]]
id = "g2"
position = [0.75, 0.85]

[[obstacles]]
id = "disc"
shape = "disc"
center = [0.6, 0.35]
radius = 0.04
"""
