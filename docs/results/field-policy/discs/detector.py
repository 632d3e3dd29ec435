"""What the movers' detector gets right and what an evasion needs (docs/fields.md, "The
eighth round"): section 4.2's rooms on validation seeds 2,000,000 onward.

``quality``: for every tick a disc is hit by a ray, whether the detector reports a mover
within 0.06 m of it, and the reported velocity's and centre's error against the disc's.

``bounds``: the default's keep-clear choice (`cekm_swarm.controller.movers.keep_clear`) fed
the discs' true positions and velocities, with the default's own detector off: for every
disc within reach (``truth``), from the tick a ray first hits it (``seen``), from the tick
the detector's free-space check first flags a hit on it (``flagged``), the same with the
velocity taken as zero (``flagged-still``) or only its part along the line to the robot
(``flagged-radial``); and the default itself (``detector``).

Run: python docs/results/field-policy/discs/detector.py quality|bounds [--runs 100]
(about a minute each on 2 cores)
"""

from __future__ import annotations

import argparse
import math
import statistics
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from cekm_swarm.controller.movers import MoverParams, keep_clear
from cekm_swarm.experiments.field_widths import policy_graph
from cekm_swarm.experiments.graph_run import GraphSession
from cekm_swarm.node.graph_check import check_graph
from cekm_swarm.protocol import WheelCommand
from cekm_swarm.ticks import tick_of
from cekm_swarm.tune.rollout import _model
from world import load_scenario

DISC = 0.04  # m, the rooms' discs' radius
MODES = ("detector", "truth", "seen", "flagged", "flagged-still", "flagged-radial")


def robot_frame(pose, px, py):
    x, y, th = pose
    dx, dy = px - x, py - y
    return dx * math.cos(th) + dy * math.sin(th), -dx * math.sin(th) + dy * math.cos(th)


def hits_disc(rel, readings) -> bool:
    """Whether a reading (alpha, d) ends on the disc whose centre is at ``rel`` (robot frame)."""
    for alpha, d in readings:
        if d is None:
            continue
        ux, uy = math.cos(alpha), math.sin(alpha)
        b = rel[0] * ux + rel[1] * uy
        disc = b * b - (rel[0] ** 2 + rel[1] ** 2 - DISC ** 2)
        if disc >= 0.0 and b - math.sqrt(disc) > 0.0 and abs(b - math.sqrt(disc) - d) < 0.03:
            return True
    return False


def session(seed: int, keep: bool):
    s = GraphSession(load_scenario("rooms"), graph=check_graph(policy_graph("navigation")), model=_model(None),
                     seed=seed, max_time=300.0, params={"keep_clear": keep})
    return s, s.world, s.executor.node("r1", "motor")


def disc_states(w, prev, now):
    """Each disc's position and velocity (from its last position), world frame."""
    out = {}
    for mid, o in w.state()["obstacles"].items():
        p = prev.get(mid)
        prev[mid] = (o["x"], o["y"], now)
        if p is not None and now > p[2]:
            out[mid] = (o["x"], o["y"], (o["x"] - p[0]) / (now - p[2]), (o["y"] - p[1]) / (now - p[2]))
    return out


def quality(seed: int) -> dict:
    s, w, motor = session(seed, True)
    step, prev = motor.step, {}
    st = {"ticks": 0, "found": 0, "v_err": [], "x_err": []}

    def wrapped(t, inputs):
        readings = [(r.alpha, r.d) for r in inputs["ranges"].values()]
        out = step(t, inputs)
        pose, dr = w.pose("r1"), motor.reckoning.pose
        movers = []
        for mx, my, vx, vy in motor.last_movers:
            th = dr[2]
            movers.append((*robot_frame(dr, mx, my), vx * math.cos(th) + vy * math.sin(th),
                           -vx * math.sin(th) + vy * math.cos(th)))
        for x, y, vx, vy in disc_states(w, prev, s.episode.t).values():
            rel = robot_frame(pose, x, y)
            if not hits_disc(rel, readings):
                continue
            th = pose[2]
            rv = (vx * math.cos(th) + vy * math.sin(th), -vx * math.sin(th) + vy * math.cos(th))
            st["ticks"] += 1
            near = min(movers, key=lambda m: math.hypot(m[0] - rel[0], m[1] - rel[1]), default=None)
            if near is not None and math.hypot(near[0] - rel[0], near[1] - rel[1]) < 0.06:
                st["found"] += 1
                st["x_err"].append(math.hypot(near[0] - rel[0], near[1] - rel[1]))
                st["v_err"].append(math.hypot(near[2] - rv[0], near[3] - rv[1]))
        return out

    motor.step = wrapped
    while not s.step():
        pass
    s.executor.close()
    return st


def bounded(job) -> tuple[str, bool]:
    seed, mode = job
    s, w, motor = session(seed, mode == "detector")
    step, prev, known = motor.step, {}, set()
    c_max, axle = motor.ctx.body.v_max, motor.ctx.body.axle
    reach = w.body_radius + w.sensor_range + DISC
    det = motor._movers

    def checked(t, inputs):
        readings = [(r.alpha, r.d) for r in sorted(inputs["ranges"].values(), key=lambda r: r.index)]
        flagged = []
        if mode.startswith("flagged"):
            x, y, th = motor.reckoning.pose
            seen = [(a, d) for a, d in readings if d is not None]
            ends = np.array([(x + d * math.cos(th + a), y + d * math.sin(th + a)) for a, d in seen]).reshape(-1, 2)
            flagged = [r for r, moved in zip(seen, det._moved_in(ends), strict=True) if moved]
            det.update(t, motor.reckoning.pose, readings)
        out = step(t, inputs)
        pose = w.pose("r1")
        discs = []
        for mid, (x, y, vx, vy) in disc_states(w, prev, s.episode.t).items():
            rel = robot_frame(pose, x, y)
            if math.hypot(*rel) > reach:
                known.discard(mid)
                continue
            if mode == "truth" or (mode == "seen" and hits_disc(rel, readings)) or hits_disc(rel, flagged):
                known.add(mid)
            if mid not in known:
                continue
            if mode == "flagged-still":
                vx = vy = 0.0
            elif mode == "flagged-radial":
                ux, uy = (x - pose[0]) / math.hypot(*rel), (y - pose[1]) / math.hypot(*rel)
                along = vx * ux + vy * uy
                vx, vy = along * ux, along * uy
            discs.append((x, y, vx, vy))
        c = out["command"]
        if mode == "detector" or not discs or c.v_l == c.v_r == 0.0:
            return out
        v_l, v_r = keep_clear(pose, (c.v_l, c.v_r), discs, w.body_radius + DISC, axle, c_max, MoverParams())
        if (v_l, v_r) == (c.v_l, c.v_r):
            return out
        motor._sent(t, v_l, v_r)
        return {"command": WheelCommand(t, motor.ctx.sender, v_l, v_r, tick_of(t))}

    motor.step = checked
    while not s.step():
        pass
    o = s.episode.outcome()["r1"]
    s.executor.close()
    return mode, bool(o["reached"]) and int(o["collisions"]) == 0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("what", choices=("quality", "bounds"))
    ap.add_argument("--runs", type=int, default=100, help="rooms runs (seeds from 2,000,000)")
    a = ap.parse_args()
    seeds = range(2_000_000, 2_000_000 + a.runs)
    with ProcessPoolExecutor(2) as ex:
        if a.what == "quality":
            rows = list(ex.map(quality, seeds, chunksize=2))
            ticks, found = sum(r["ticks"] for r in rows), sum(r["found"] for r in rows)
            v = sorted(x for r in rows for x in r["v_err"])
            xs = [x for r in rows for x in r["x_err"]]
            print(f"disc hit by a ray on {ticks} ticks; a mover reported within 0.06 m on {found} "
                  f"({found / ticks:.0%}); velocity error median {statistics.median(v):.3f} m/s, "
                  f"90th percentile {v[int(0.9 * len(v))]:.3f}; centre error median {statistics.median(xs):.3f} m")
        else:
            rows = list(ex.map(bounded, [(s, m) for m in MODES for s in seeds], chunksize=4))
            for m in MODES:
                print(f"{m:15s} {sum(ok for mm, ok in rows if mm == m)} of {a.runs} rooms contact-free")


if __name__ == "__main__":
    main()
