"""World step cost per robot-step: one 0.032 s sub-step of all robots plus a read of
all 12 range sensors of every robot, for 1, 10 and 100 robots in an open arena with
some walls.

Baseline, measured in the same run: a bare pymunk space with the same bodies, shapes
and joints, stepped once per 0.032 s with no sensors, noise or bookkeeping (and, for
reference, stepped 4 x 8 ms as the world does).

Run: python benchmarks/bench_world.py [--repeat 5]
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402
import pymunk  # noqa: E402

from world import World, parse_scenario  # noqa: E402
from world.sim import PHYSICS_STEPS, ROBOT_MASS, ROBOT_RADIUS  # noqa: E402

GOAL_US = 30.0


def scenario(n: int, spacing: float = 0.5) -> dict:
    """n robots on a grid, in a walled arena with four interior walls and two static
    obstacles. With spacing 0.5 m the robots drive 0.16 m circles in the open (their
    sensors mostly see nothing); with spacing 0.15 m every robot has neighbours
    within sensor range, so every read casts all 12 rays."""
    k = math.ceil(math.sqrt(n))
    size = spacing * k + 1.0
    robots = [
        {"id": f"r{i + 1}", "start": [0.75 + spacing * (i % k), 0.6 + spacing * (i // k), 0.0]} for i in range(n)
    ]
    walls = [
        {"a": [0.15, 0.3], "b": [0.15, size - 0.3]},
        {"a": [size - 0.15, 0.3], "b": [size - 0.15, size - 0.3]},
        {"a": [0.3, 0.15], "b": [size - 0.3, 0.15]},
        {"a": [0.3, size - 0.15], "b": [size - 0.3, size - 0.15]},
    ]
    obstacles = [
        {"shape": "disc", "center": [0.35, size - 0.35], "radius": 0.05},
        {"shape": "box", "center": [size - 0.35, 0.35], "size": [0.1, 0.1]},
    ]
    return {
        "seed": 1,
        "arena": {"bounds": [0.0, 0.0, size, size]},
        "robots": robots,
        "walls": walls,
        "obstacles": obstacles,
    }


def bench_world(n: int, steps: int, dense: bool = False) -> tuple[float, float, float]:
    """(us per robot-step for step + 12 reads, step only, reads only)."""
    w = World(parse_scenario(scenario(n, 0.15 if dense else 0.5), source=f"<bench {n}>"))
    ids = w.robot_ids
    for rid in ids:
        if dense:
            w.set_wheels(rid, 0.05, -0.05)  # turn in place next to the neighbours
        else:
            w.set_wheels(rid, 0.10, 0.14)
    for _ in range(20):  # warm up
        w.step()
        for rid in ids:
            w.range_readings(rid)
    t_step = t_read = 0.0
    for _ in range(steps):
        t0 = time.perf_counter()
        w.step()
        t1 = time.perf_counter()
        for rid in ids:
            w.range_readings(rid)
        t2 = time.perf_counter()
        t_step += t1 - t0
        t_read += t2 - t1
    for rid in ids:
        assert w.stats(rid)["collisions"] == 0
    if dense and n > 1:
        assert all(not np.isnan(w.true_ranges(rid)).all() for rid in ids)
    per = 1e6 / (steps * n)
    return (t_step + t_read) * per, t_step * per, t_read * per


def bench_baseline(n: int, steps: int, dense: bool = False, substeps: int = 1) -> float:
    """us per robot-step of a bare pymunk space with the same bodies, no sensors."""
    sc = parse_scenario(scenario(n, 0.15 if dense else 0.5), source="<baseline>")
    space = pymunk.Space()
    from world._physics import add_static

    add_static(space, sc)
    moment = pymunk.moment_for_circle(ROBOT_MASS, 0.0, ROBOT_RADIUS)
    controls = []
    for r in sc.robots:
        b = pymunk.Body(ROBOT_MASS, moment)
        b.position = r.start[:2]
        s = pymunk.Circle(b, ROBOT_RADIUS)
        c = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
        c.position = b.position
        c.velocity = (0.12, 0.0)
        c.angular_velocity = 0.75
        pivot = pymunk.PivotJoint(c, b, (0, 0), (0, 0))
        pivot.max_bias, pivot.max_force = 0.0, 0.4
        gear = pymunk.GearJoint(c, b, 0.0, 1.0)
        gear.max_bias, gear.max_force = 0.0, 0.01
        space.add(b, s, c, pivot, gear)
        controls.append(c)
    h = 0.032 / substeps
    for _ in range(20):
        space.step(h)
    t0 = time.perf_counter()
    for _ in range(steps * substeps):
        space.step(h)
    return (time.perf_counter() - t0) * 1e6 / (steps * n)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5, help="best of this many runs per size")
    args = ap.parse_args()
    print(f"python {platform.python_version()}, pymunk {pymunk.version}, {os.cpu_count()} cpu(s), {platform.machine()}")
    print(f"us per robot-step (best of {args.repeat}); goal <= {GOAL_US:.0f} us at 100 robots")
    print(
        f"{'layout':>7} {'robots':>6} {'world':>8} {'step':>8} {'12 reads':>9} {'baseline':>9} {'ratio':>6} "
        f"{'base x4':>8}"
    )
    for dense in (False, True):
        for n in (1, 10, 100):
            steps = {1: 3000, 10: 600, 100: 120}[n]
            best = min((bench_world(n, steps, dense) for _ in range(args.repeat)), key=lambda r: r[0])
            base = min(bench_baseline(n, steps, dense) for _ in range(args.repeat))
            base4 = min(bench_baseline(n, steps, dense, PHYSICS_STEPS) for _ in range(args.repeat))
            layout = "dense" if dense else "open"
            print(
                f"{layout:>7} {n:>6} {best[0]:>8.1f} {best[1]:>8.1f} {best[2]:>9.1f} {base:>9.2f}"
                f" {best[0] / base:>6.1f} {base4:>8.2f}"
            )
    print("world = step (noise, kinematics, 4 pymunk steps, contacts, path, clearance) + 12 range reads per robot")
    print("open: 0.5 m apart, reads mostly skip the rays (nothing within range); dense: 0.15 m apart, all rays cast")
    print("baseline = one bare pymunk step (0.032 s) of the same bodies and joints, no sensors; ratio = world / "
          "baseline")
    print(f"base x4 = the same bare space stepped {PHYSICS_STEPS} x {0.032 / PHYSICS_STEPS * 1000:.0f} ms, as the "
          "world does")


if __name__ == "__main__":
    main()
