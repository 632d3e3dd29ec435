"""Why contacts happen: every new contact of a generated navigation run, classified
(docs/fields.md, "Why contacts happen").

A run is the field-policy graph's (:func:`cekm_swarm.experiments.field_widths.policy_graph`; weights W = 0 are
today's constants bit for bit), stepped tick by tick so that at the tick a contact
begins we can read what the robot did and what its fields showed: where on the geometry
the contact is (:func:`place`), its bearing in the robot's frame, the robot's speed over
the last second, the target's bearing, the features of :mod:`.features` and whether the
motor EKM's winner was the target field's winner (k = s, Eq. 11's direct branch) or a
detour. For movers: whether the robot was standing still when it was hit.
"""

from __future__ import annotations

import math
from collections import Counter
from typing import Any

import numpy as np

from ..angles import wrap_scalar
from ..experiments.field_widths import policy_graph
from ..experiments.graph_run import GraphSession
from ..node.graph_check import check_graph
from ..ticks import TICK_S
from .motor import PLAIN, FieldMotor
from .policy import FieldPolicy
from .rollout import _model
from .scenarios import navigation_raw, navigation_scenario

STILL = 0.005
"""m/s: a robot slower than this over the last second before a contact stood still."""
EDGE = 0.03
"""m: a contact this close to an end of a wall or an arm is at its end (a jamb, a tip)."""


def _local(p: tuple[float, float], centre: tuple[float, float], facing: float) -> tuple[float, float]:
    dx, dy = p[0] - centre[0], p[1] - centre[1]
    c, s = math.cos(-facing), math.sin(-facing)
    return c * dx - s * dy, s * dx + c * dy


def place(raw: dict[str, Any], item: str, p: tuple[float, float]) -> str:
    """Where on a generated geometry (:func:`.scenarios.navigation_raw`'s document ``raw``)
    the contact point ``p`` with ``item`` (the world's item key) lies."""
    kind = raw["name"].split("-")[1]
    if "(m" in item and "obstacles" in item:
        return "mover"
    if kind == "u":
        u = raw["obstacles"][0]
        x, y = _local(p, tuple(u["center"]), u["facing"])  # mouth at x = 0, cavity toward -x
        w2, d = u["width"] / 2, u["depth"]
        if x > -EDGE:
            return "U arm tip (mouth)"
        if abs(y) < w2 + 0.005 and x > -d - 0.005:
            return "U inside, back wall" if x < -d + EDGE else "U inside, arm"
        return "U outside, back" if x < -d else "U outside, arm"
    if kind == "doorway":
        gap_lo = raw["obstacles"][1]["center"][1] + raw["obstacles"][1]["size"][1] / 2
        gap_hi = raw["obstacles"][0]["center"][1] - raw["obstacles"][0]["size"][1] / 2
        if min(abs(p[1] - gap_lo), abs(p[1] - gap_hi)) < EDGE or gap_lo < p[1] < gap_hi:
            return "doorway jamb"
        return "block face, before" if p[0] < 1.5 else "block face, beyond"
    if kind == "corridor":
        a, b = raw["walls"][0]["a"], raw["walls"][0]["b"]
        if p[0] < a[0] + EDGE:
            return "corridor entrance"
        if p[0] > b[0] - EDGE:
            return "corridor exit"
        return "corridor wall"
    if kind == "movers":
        if item.startswith("walls[") and min(abs(p[0] - 1.0), abs(p[0] - 2.0)) < 0.05:
            return "room doorway jamb" if _near_door(raw, p) else "room wall"
        return "arena wall"
    return item


def _near_door(raw: dict[str, Any], p: tuple[float, float]) -> bool:
    ends = [w["b"][1] for w in raw["walls"][0::2]] + [w["a"][1] for w in raw["walls"][1::2]]
    return min(abs(p[1] - e) for e in ends) < EDGE


def _contact_point(world, robot: str, item: str) -> tuple[tuple[float, float], float]:
    """The contact point (world frame) and its bearing in the robot's frame: the nearest
    true range reading (the 12 rays; for a mover between rays, its centre)."""
    x, y, th = world.pose(robot)
    if "(m" in item and "obstacles" in item:
        mid = item.split("(")[1].rstrip(")")
        m = world.state()["obstacles"][mid]
        bearing = wrap_scalar(math.atan2(m["y"] - y, m["x"] - x) - th)
    else:
        r = world.true_ranges(robot)
        if np.all(np.isnan(r)):
            return (x, y), math.nan
        bearing = float(world.sensor_angles[int(np.nanargmin(r))])
    reach = world.body_radius + 0.005
    return (x + reach * math.cos(th + bearing), y + reach * math.sin(th + bearing)), bearing


def contact_events(seed: int, max_time: float = 300.0, model_path: str | None = None,
                   weights: tuple[float, ...] | None = None,
                   mix: str = "default") -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """The run of generated navigation scenario ``seed`` of geometry mix ``mix`` with the
    policy ``weights`` (default W = 0 and the plain motor, :data:`.motor.PLAIN`: today's constants, the
    ``cekm-tuned`` graph's run): its outcome row, and every new contact, one row each."""
    raw = navigation_raw(seed, mix=mix)
    kind = raw["name"].split("-")[1]
    params: dict[str, Any] = {"weights": tuple(weights)} if weights is not None else \
        {"weights": (0.0,) * FieldPolicy.size("navigation"), **PLAIN}
    s = GraphSession(navigation_scenario(seed, mix=mix), graph=check_graph(policy_graph("navigation")),
                     model=_model(model_path), max_time=max_time, params=params)
    motor = s.executor.node("r1", "motor")
    assert isinstance(motor, FieldMotor)
    outs: list[Any] = []
    integrate = motor.ekm.integrate

    def watched(*a, **k):
        outs.append(integrate(*a, **k))
        return outs[-1]

    motor.ekm.integrate = watched  # type: ignore[method-assign]  # read each tick's winner k
    world = s.world
    seen: dict[str, int] = {}
    path: list[tuple[float, float]] = []
    rows: list[dict[str, Any]] = []
    done = False
    while not done:
        done = s.step()
        path.append(world.pose("r1")[:2])
        now = world.stats("r1")["collisions_with"]
        for item, c in now.items():
            if c <= seen.get(item, 0):
                continue
            seen[item] = c
            p, bearing = _contact_point(world, "r1", item)
            gx, gy = world.goal_of("r1")
            x, y, th = world.pose("r1")
            back = path[-9] if len(path) > 8 else path[0]
            speed = math.hypot(x - back[0], y - back[1]) / (min(len(path) - 1, 8) * TICK_S or 1.0)
            o = outs[-1] if outs else None
            f = motor.last_features if motor.last_features is not None else np.zeros(9)
            rows.append({"seed": seed, "kind": kind, "t": s.episode.t, "item": item,
                         "place": place(raw, item, p), "bearing_deg": round(math.degrees(bearing), 1),
                         "speed_mps": round(speed, 4), "still": speed < STILL,
                         "target_deg": round(math.degrees(wrap_scalar(math.atan2(gy - y, gx - x) - th)), 1),
                         "front": round(float(f[1]), 3), "left": round(float(f[2]), 3),
                         "right": round(float(f[3]), 3),
                         "detour": None if o is None or o.k is None else bool(o.k != o.s)})
    o = s.episode.outcome()["r1"]
    s.executor.close()
    return {"seed": seed, "kind": kind, "reached": bool(o["reached"]),
            "collisions": int(o["collisions"])}, rows


def diagnose(seeds: list[int], max_time: float = 300.0, model_path: str | None = None,
             weights: tuple[float, ...] | None = None, progress=None, mix: str = "default") -> dict[str, Any]:
    """:func:`contact_events` of every seed: {"runs": outcome rows, "contacts": contact rows,
    "tally": :func:`tally` of the contacts, "by_kind": runs, reached, contact-free per kind}."""
    runs, contacts = [], []
    for seed in seeds:
        run, rows = contact_events(seed, max_time, model_path, weights, mix)
        runs.append(run)
        contacts.extend(rows)
        if progress:
            progress()
    by_kind = {k: {"runs": sum(r["kind"] == k for r in runs),
                   "reached": sum(r["kind"] == k and r["reached"] for r in runs),
                   "contact_free": sum(r["kind"] == k and r["reached"] and r["collisions"] == 0 for r in runs)}
               for k in sorted({r["kind"] for r in runs})}
    return {"runs": runs, "contacts": contacts, "by_kind": by_kind,
            "tally": {k: dict(v) for k, v in tally(contacts).items()}}


def tally(rows: list[dict[str, Any]]) -> dict[str, Counter]:
    """Counts by place, by contact bearing (front |b| < 45 deg, side, rear), by speed
    (still or moving) and by the motor winner (direct or detour)."""
    def side(b: float) -> str:
        if math.isnan(b):
            return "unknown"
        return "front" if abs(b) < 45 else "side" if abs(b) < 135 else "rear"

    return {"place": Counter(r["place"] for r in rows), "bearing": Counter(side(r["bearing_deg"]) for r in rows),
            "still": Counter("still" if r["still"] else "moving" for r in rows),
            "winner": Counter({None: "stopped", True: "detour (k != s)", False: "direct (k = s)"}[r["detour"]]
                              for r in rows)}
