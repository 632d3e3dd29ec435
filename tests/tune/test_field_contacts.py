"""Why contacts happen (``cekm tune contacts``): a contact point is placed on its geometry,
and a run's contact rows are its contacts, one each, classified."""

from __future__ import annotations

import math

from cekm_swarm.tune.contacts import contact_events, place, tally
from cekm_swarm.tune.scenarios import navigation_raw, seed_of


def test_a_contact_point_is_placed_on_its_geometry():
    u = navigation_raw(5, "u")
    o = u["obstacles"][0]
    cx, cy, f, w2, d = *o["center"], o["facing"], o["width"] / 2, o["depth"]

    def at(lx: float, ly: float) -> tuple[float, float]:  # U frame -> world
        return cx + lx * math.cos(f) - ly * math.sin(f), cy + lx * math.sin(f) + ly * math.cos(f)

    assert place(u, "obstacles[0] (u)", at(-0.005, w2 + 0.01)) == "U arm tip (mouth)"
    assert place(u, "obstacles[0] (u)", at(-d + 0.01, 0.0)) == "U inside, back wall"
    assert place(u, "obstacles[0] (u)", at(-d / 2 - 0.02, w2 - 0.002)) == "U inside, arm"
    assert place(u, "obstacles[0] (u)", at(-d - 0.04, 0.0)) == "U outside, back"
    door = navigation_raw(5, "doorway")
    assert place(door, "obstacles[0] (block_n)", (1.45, 1.0)) == "doorway jamb"
    assert place(door, "obstacles[0] (block_n)", (1.45, 1.9)) == "block face, before"
    corr = navigation_raw(5, "corridor")
    (ax, ay), (bx, _) = corr["walls"][0]["a"], corr["walls"][0]["b"]
    assert place(corr, "walls[0]", (ax + 0.01, ay)) == "corridor entrance"
    assert place(corr, "walls[0]", ((ax + bx) / 2, ay)) == "corridor wall"
    rooms = navigation_raw(5, "movers")
    assert place(rooms, "obstacles[0] (m1)", (1.5, 0.5)) == "mover"
    assert place(rooms, "walls[0]", (1.0, rooms["walls"][0]["b"][1] - 0.01)) == "room doorway jamb"
    assert place(rooms, "walls[0]", (1.0, 0.02)) == "room wall"


def test_every_contact_of_a_run_is_one_row():
    seed = seed_of("validation", 0)  # rooms with movers: the robot clips a doorway's jamb once (today's constants)
    run, rows = contact_events(seed)
    assert run["reached"] and run["collisions"] == len(rows) >= 1
    r = rows[0]
    assert r["kind"] == "movers" and r["place"] in ("room doorway jamb", "room wall", "mover")
    assert abs(r["bearing_deg"]) <= 180 and r["speed_mps"] >= 0 and r["detour"] in (True, False, None)
    counts = tally(rows)
    assert all(sum(c.values()) == len(rows) for c in counts.values())
