"""What the movers need (docs/fields.md, "The seventh round"): an upper bound, not a controller.

The default navigation graph runs without keeping clear of movers (``keep_clear`` false), and
every tick its motor's command is checked
against the moving discs the robot could sense: those whose centre is within the body
radius + the sensing range + the disc's radius. Their positions and velocities are read from
the world itself, the truth a perfect mover detector would give. If the command brings the
body within 0.01 m of such a disc in the next ``--horizon`` seconds (the robot on its command
as a unicycle, the discs on straight lines), the command is replaced by whichever of stop,
back at c*, forward at c* or a turn in place at c* keeps the most clearance: the default
motor's own choice (`cekm_swarm.controller.movers.keep_clear`), here fed the truth.

It prints three numbers per set of runs: not keeping clear, the default (its raw-range
detector, docs/fields.md "The movers"), and the truth. The gap between the last two is what a
better detector could still gain.

Run: python docs/results/field-policy/movers/oracle_vo.py [--horizon 1.5] [--runs 100]
(validation seeds only: the movers of the default and wide mixes' first 200 seeds, and section
4.2's rooms on seeds 2,000,000 onward; about two minutes on 2 cores)
"""

from __future__ import annotations

import argparse
import math
from concurrent.futures import ProcessPoolExecutor

from cekm_swarm.controller.movers import MoverParams, keep_clear
from cekm_swarm.experiments.field_widths import policy_graph
from cekm_swarm.experiments.graph_run import GraphSession
from cekm_swarm.node.graph_check import check_graph
from cekm_swarm.protocol import WheelCommand
from cekm_swarm.ticks import tick_of
from cekm_swarm.tune.rollout import _model
from cekm_swarm.tune.scenarios import navigation_raw, navigation_scenario
from world import load_scenario

MARGIN = 0.01  # m of clearance a command must keep


MODES = ("off", "detector", "oracle")
"""The default without keeping clear of movers, the default (its raw-range detector), and the
default without its detector but with the truth."""


def one(job):
    what, seed, horizon, mode = job
    sc = load_scenario("rooms") if what == "rooms" else navigation_scenario(seed, mix=what)
    s = GraphSession(sc, graph=check_graph(policy_graph("navigation")), model=_model(None), seed=seed,
                     max_time=300.0, params={"keep_clear": mode == "detector"})
    oracle = mode == "oracle"
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
        if not oracle or not discs:
            return out
        params = MoverParams(horizon=horizon, margin=MARGIN)
        v_l, v_r = keep_clear(pose, (c.v_l, c.v_r), discs, w.body_radius + 0.04, axle, c_max, params)
        if (v_l, v_r) == (c.v_l, c.v_r):
            return out
        motor._sent(t, v_l, v_r)
        return {"command": WheelCommand(t, motor.ctx.sender, v_l, v_r, tick_of(t))}

    motor.step = checked
    while not s.step():
        pass
    o = s.episode.outcome()["r1"]
    s.executor.close()
    return what, mode, bool(o["reached"]) and int(o["collisions"]) == 0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--horizon", type=float, default=1.5)
    ap.add_argument("--runs", type=int, default=100, help="rooms runs (seeds from 2,000,000)")
    a = ap.parse_args()
    jobs = [(mix, s) for mix in ("default", "wide") for s in range(2_000_000, 2_000_200)
            if navigation_raw(s, mix=mix)["name"].split("-")[1] == "movers"]
    jobs += [("rooms", s) for s in range(2_000_000, 2_000_000 + a.runs)]
    with ProcessPoolExecutor(2) as ex:
        rows = list(ex.map(one, [(w, s, a.horizon, m) for m in MODES for w, s in jobs], chunksize=4))
    for what in ("default", "wide", "rooms"):
        n = sum(1 for w, _ in jobs if w == what)
        free = {m: sum(ok for w, mm, ok in rows if w == what and mm == m) for m in MODES}
        label = "section 4.2's rooms" if what == "rooms" else f"movers of the {what} mix"
        print(f"{label} (of {n}): contact-free {free['off']} not keeping clear, {free['detector']} with the "
              f"default's detector, {free['oracle']} with the truth")


if __name__ == "__main__":
    main()
