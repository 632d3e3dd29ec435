"""What the movers need (docs/fields.md, "The seventh round"): an upper bound, not a controller.

The default navigation graph runs as shipped, and every tick its motor's command is checked
against the moving discs the robot could sense: those whose centre is within the body
radius + the sensing range + the disc's radius. Their positions and velocities are read from
the world itself, the truth a perfect mover detector would give. If the command brings the
body within 0.01 m of such a disc in the next ``--horizon`` seconds (the robot on its command
as a unicycle, the discs on straight lines), the command is replaced by whichever of stop,
back at c*, forward at c* or a turn in place at c* keeps the most clearance. This is a
velocity-obstacle choice.

If the numbers it gives are high, the sensing range is enough, and what the controller lacks
is a detector of movers and their velocities.

Run: python docs/results/field-policy/movers/oracle_vo.py [--horizon 1.5] [--runs 100]
(validation seeds only: the movers of the default and wide mixes' first 200 seeds, and section
4.2's rooms on seeds 2,000,000 onward; about two minutes on 2 cores)
"""

from __future__ import annotations

import argparse
import math
from concurrent.futures import ProcessPoolExecutor

from cekm_swarm.experiments.field_widths import policy_graph
from cekm_swarm.experiments.graph_run import GraphSession
from cekm_swarm.node.graph_check import check_graph
from cekm_swarm.protocol import WheelCommand
from cekm_swarm.ticks import tick_of
from cekm_swarm.tune.rollout import _model
from cekm_swarm.tune.scenarios import navigation_raw, navigation_scenario
from world import load_scenario

MARGIN = 0.01  # m of clearance a command must keep
STEP = 0.064  # s between the checked instants


def clearance(pose, command, discs, reach, axle, horizon):
    """The least body-to-disc clearance over ``horizon`` s on ``command`` (m)."""
    x, y, th = pose
    v, omega = 0.5 * (command[0] + command[1]), (command[1] - command[0]) / axle
    least = math.inf
    for k in range(int(horizon / STEP) + 1):
        t = k * STEP
        for mx, my, vx, vy in discs:
            least = min(least, math.hypot(mx + vx * t - x, my + vy * t - y) - reach)
        x, y, th = x + v * STEP * math.cos(th), y + v * STEP * math.sin(th), th + omega * STEP
    return least


def one(job):
    what, seed, horizon, oracle = job
    sc = load_scenario("rooms") if what == "rooms" else navigation_scenario(seed, mix=what)
    s = GraphSession(sc, graph=check_graph(policy_graph("navigation")), model=_model(None), seed=seed,
                     max_time=300.0)
    w, motor = s.world, s.executor.node("r1", "motor")
    c_max, axle = motor.ctx.body.v_max, motor.ctx.body.axle
    sees = w.body_radius + w.sensor_range + 0.04
    step, seen = motor.step, {}

    def checked(t, inputs):
        out = step(t, inputs)
        now, pose = s.episode.t, w.pose("r1")
        discs = []
        for mid, o in w.state()["obstacles"].items():
            if math.hypot(o["x"] - pose[0], o["y"] - pose[1]) > sees:
                seen.pop(mid, None)
                continue
            if mid in seen and now > seen[mid][2]:
                px, py, pt = seen[mid]
                discs.append((o["x"], o["y"], (o["x"] - px) / (now - pt), (o["y"] - py) / (now - pt)))
            seen[mid] = (o["x"], o["y"], now)
        c = out["command"]
        reach = w.body_radius + 0.04
        base = clearance(pose, (c.v_l, c.v_r), discs, reach, axle, horizon) if discs else math.inf
        if not oracle or base >= MARGIN:
            return out
        options = [(0.0, 0.0), (-c_max, -c_max), (c_max, c_max), (-c_max, c_max), (c_max, -c_max)]
        best = max(options, key=lambda o: clearance(pose, o, discs, reach, axle, horizon))
        if clearance(pose, best, discs, reach, axle, horizon) <= base:
            return out
        motor._sent(t, *best)
        return {"command": WheelCommand(t, motor.ctx.sender, best[0], best[1], tick_of(t))}

    motor.step = checked
    while not s.step():
        pass
    o = s.episode.outcome()["r1"]
    s.executor.close()
    return what, oracle, bool(o["reached"]) and int(o["collisions"]) == 0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--horizon", type=float, default=1.5)
    ap.add_argument("--runs", type=int, default=100, help="rooms runs (seeds from 2,000,000)")
    a = ap.parse_args()
    jobs = [(mix, s) for mix in ("default", "wide") for s in range(2_000_000, 2_000_200)
            if navigation_raw(s, mix=mix)["name"].split("-")[1] == "movers"]
    jobs += [("rooms", s) for s in range(2_000_000, 2_000_000 + a.runs)]
    with ProcessPoolExecutor(2) as ex:
        rows = list(ex.map(one, [(w, s, a.horizon, o) for o in (False, True) for w, s in jobs], chunksize=4))
    for what in ("default", "wide", "rooms"):
        n = sum(1 for w, _ in jobs if w == what)
        free = {o: sum(ok for w, oo, ok in rows if w == what and oo == o) for o in (False, True)}
        label = "section 4.2's rooms" if what == "rooms" else f"movers of the {what} mix"
        print(f"{label}: contact-free {free[False]} of {n} as shipped, {free[True]} with the oracle's override")


if __name__ == "__main__":
    main()
