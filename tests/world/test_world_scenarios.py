"""Shipped scenarios load, step and have the documented geometry; bad files are refused."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import world
from world import ScenarioError, World, load_scenario, scenario_names

REPO = Path(__file__).resolve().parents[2]
SHIPPED = ["checkpoints", "concave", "crossing", "doorway", "lone_obstacle", "rooms", "tracking", "tracking-crowd",
           "training"]


def test_all_shipped_scenarios_are_listed():
    assert scenario_names() == SHIPPED


@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_scenario_loads_and_steps(name):
    sc = load_scenario(name)
    assert sc.name == name and sc.description
    assert sc.robot_ids == [f"r{i + 1}" for i in range(len(sc.robots))]
    w = World(sc)
    for rid in w.robot_ids:
        w.set_wheels(rid, 0.08, 0.1)
    w.advance(1.0)
    for rid in w.robot_ids:
        r = w.range_readings(rid)
        assert r.shape == (12,)
        st = w.stats(rid)
        assert st["collisions"] == 0 and st["min_clearance_m"] > 0.0
        assert 0.0 < st["path_length_m"] < 0.2
        if sc.robot(rid).goal is not None:
            a, d, vis = w.target_reading(rid)
            assert vis and -math.pi < a <= math.pi and d > 0
    geo = w.static_geometry()
    assert geo["bounds"] == list(sc.bounds)
    assert all(wl["known"] for wl in geo["walls"])
    assert all(not p["known"] for p in geo["polygons"] + geo["discs"])
    # by name or by path: the same scenario
    assert load_scenario(REPO / "world" / "scenarios" / f"{name}.toml") == sc


def _gap_between(p, q):
    """Smallest distance between two convex polygons that do not overlap."""

    def seg_dist(pt, a, b):
        ax, ay = a
        bx, by = b
        t = max(
            0.0, min(1.0, ((pt[0] - ax) * (bx - ax) + (pt[1] - ay) * (by - ay)) / ((bx - ax) ** 2 + (by - ay) ** 2))
        )
        return math.hypot(pt[0] - ax - t * (bx - ax), pt[1] - ay - t * (by - ay))

    best = math.inf
    for P, Q in ((p, q), (q, p)):
        for v in P:
            for i in range(len(Q)):
                best = min(best, seg_dist(v, Q[i], Q[(i + 1) % len(Q)]))
    return best


def test_concave_geometry():
    sc = load_scenario("concave")
    (u,) = sc.obstacles
    assert u.shape == "concave" and not u.known
    assert (u.params["width"], u.params["depth"]) == (0.34, 0.12)
    xs = [p[0] for p in u.outline]
    ys = [p[1] for p in u.outline]
    assert min(xs) == pytest.approx(1.5) and max(xs) == pytest.approx(1.64)  # mouth at 1.5, back 0.14 behind
    assert max(ys) - min(ys) == pytest.approx(0.34 + 0.04)
    rx, ry, rth = sc.robots[0].start
    gx, gy = sc.targets[0].position
    assert ry == gy == 1.5 and rth == 0.0 and 1.5 - rx == pytest.approx(0.5) and gx > 1.64
    # a robot just inside the mouth sees the back wall's inner face 0.12 m from the mouth
    w = World(load_scenario("concave", overrides={"robots[0].start": [1.5 + 0.03, 1.5, 0.0]}))
    assert w.true_ranges("r1")[0] == pytest.approx(0.12 - 0.03 - 0.03, abs=1e-9)
    # Fig. 9 sweeps: width and depth are overridable
    sc2 = load_scenario("concave", overrides={"obstacles[0].width": 0.8, "obstacles[0].depth": 0.3})
    ys2 = [p[1] for p in sc2.obstacles[0].outline]
    assert max(ys2) - min(ys2) == pytest.approx(0.84)


def test_doorway_gap_is_86_mm():
    sc = load_scenario("doorway")
    a, b = sc.obstacles
    assert _gap_between(a.outline, b.outline) == pytest.approx(0.086, abs=1e-9)
    w = World(load_scenario("doorway", overrides={"robots[0].start": [1.5, 1.0, math.pi / 2]}))
    t = w.true_ranges("r1")  # in the middle of the doorway: 28 mm to each side
    assert t[0] == pytest.approx(0.043 - 0.03, abs=1e-9) and t[6] == pytest.approx(0.043 - 0.03, abs=1e-9)


def test_rooms_doorways_and_movers():
    sc = load_scenario("rooms")
    walls = [w for w in sc.walls if w.source.startswith("walls")]
    gaps = []
    for x in (1.0, 2.0):
        spans = sorted((min(w.a[1], w.b[1]), max(w.a[1], w.b[1])) for w in walls if w.a[0] == w.b[0] == x)
        gaps.append(spans[1][0] - spans[0][1])
    assert gaps == [pytest.approx(0.14), pytest.approx(0.14)]
    movers = [o for o in sc.obstacles if o.motion is not None]
    assert len(movers) == 2 and all(o.motion.direction == "ccw" for o in movers)
    assert all(1.0 < o.motion.center[0] < 2.0 for o in movers)
    assert sc.robots[0].start[0] < 1.0 and sc.targets[0].position[0] > 2.0


def test_checkpoints_gaps_and_known_flags():
    sc = load_scenario("checkpoints")
    assert all(w.known for w in sc.walls)
    assert all(not o.known for o in sc.obstacles)
    discs = {o.id: o for o in sc.obstacles if o.shape == "disc"}

    def disc_gap(p, q):
        return math.dist(p.center, q.center) - p.radius - q.radius

    assert disc_gap(discs["l1"], discs["l2"]) == pytest.approx(0.095, abs=0.002)
    assert disc_gap(discs["l2"], discs["l3"]) == pytest.approx(0.10, abs=0.002)
    boxes = [o for o in sc.obstacles if o.shape == "box"]
    assert _gap_between(boxes[0].outline, boxes[1].outline) == pytest.approx(0.09, abs=0.002)
    assert [o.shape for o in sc.obstacles].count("concave") == 1
    x, y, _ = sc.robots[0].start
    assert x < 0.3 and y > 0.9  # top corner of the left room
    gx, gy = sc.targets[0].position
    assert 2.85 < gx < 3.0 and gy < 0.4  # in the 0.15 m alcove of the right room


def test_lone_obstacle_and_tracking():
    sc = load_scenario("lone_obstacle")
    (o,) = sc.obstacles
    assert o.shape == "disc" and 2 * o.radius == pytest.approx(0.1)
    sc = load_scenario("tracking")
    assert sc.robot_ids == ["r1", "r2"] and len(sc.targets) == 3
    assert sc.target_range == 0.5 and sc.bounds == (0.0, 0.0, 3.0, 2.0)
    assert all(t.motion.kind == "random_walk" for t in sc.targets)
    w = World(sc)
    w.advance(60.0)
    for t in w.state()["targets"].values():
        b = sc.targets[0].motion.bounds
        assert b[0] <= t["x"] <= b[2] and b[1] <= t["y"] <= b[3]
    moved = [
        math.dist((t["x"], t["y"]), s.position) for t, s in zip(w.state()["targets"].values(), sc.targets, strict=True)
    ]
    assert all(m > 0.1 for m in moved)


def test_state_and_geometry_are_plain_data():
    import json

    def check(v, path="state"):
        if isinstance(v, dict):
            for k, x in v.items():
                assert isinstance(k, str), path
                check(x, f"{path}.{k}")
        elif isinstance(v, list):
            for i, x in enumerate(v):
                check(x, f"{path}[{i}]")
        else:
            assert v is None or type(v) in (float, int, bool, str), f"{path}: {type(v)}"

    for name in SHIPPED:
        w = World(load_scenario(name))
        w.step()
        check(w.state())
        check(w.static_geometry(), "geometry")
        check({rid: w.stats(rid) for rid in w.robot_ids}, "stats")
        json.dumps(w.state())
        json.dumps(w.static_geometry())


@pytest.mark.slow
def test_world_never_imports_the_controller():
    """The simulation imports nothing of cekm_swarm but the project's conventions (the
    angle wrap, the tick clock, the robot's body) and the message protocol (the ids a
    scenario is checked against, the messages an episode hands out: imported at the top of
    the modules that use them, not hidden in a function); the world server only those, the
    transport, strict JSON for its files, the command line's option types and graphs as
    data (never node, controller, model or experiment code: lint-imports' contract holds
    the same over every import, function-level ones included)."""
    code = "import sys, world, world.draw, world.episode; print([m for m in sys.modules if m.startswith('cekm_swarm')])"
    out = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, check=True)
    assert {m for m in eval(out.stdout) if not m.startswith("cekm_swarm.protocol")} <= {
        "cekm_swarm", "cekm_swarm.angles", "cekm_swarm.ticks", "cekm_swarm.robot", "cekm_swarm.errors"}, out.stdout
    code = ("import sys, world.server; print(sorted({'.'.join(m.split('.')[1:3]) if m.startswith('cekm_swarm.graph') "
            "else m.split('.')[1] for m in sys.modules if m.startswith('cekm_swarm.')}))")
    out = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, check=True)
    assert set(eval(out.stdout)) <= {"protocol", "runtime", "errors", "angles", "ticks", "robot", "jsonfile",
                                     "cli_support", "graph",
                                     "graph.spec", "graph.plan", "graph.resolve", "graph.runspec"}, out.stdout


# --------------------------------------------------------------------------- bad files

GOOD = """
[arena]
bounds = [0.0, 0.0, 2.0, 2.0]

[[robots]]
id = "r1"
start = [0.5, 0.5, 0.0]
goal = "g"

[[targets]]
id = "g"
position = [1.5, 1.5]
"""

BAD = [
    ("missing arena", GOOD.replace("[arena]\nbounds = [0.0, 0.0, 2.0, 2.0]\n", ""), ["arena", "missing"]),
    ("unknown top key", GOOD + "\nseeed = 3\n", ["seeed", "unknown key"]),
    ("unknown nested key", GOOD.replace('goal = "g"', 'goal = "g"\nstrat = 1'), ["robots[0].strat", "unknown key"]),
    ("wrong type", GOOD.replace("[0.5, 0.5, 0.0]", '[0.5, "a", 0.0]'), ["robots[0].start[1]", "must be a number"]),
    (
        "bool is not a number",
        GOOD.replace("[0.5, 0.5, 0.0]", "[0.5, true, 0.0]"),
        ["robots[0].start[1]", "must be a number"],
    ),
    ("short vector", GOOD.replace("[0.5, 0.5, 0.0]", "[0.5, 0.5]"), ["robots[0].start", "3 numbers"]),
    ("bad bounds", GOOD.replace("[0.0, 0.0, 2.0, 2.0]", "[0.0, 0.0, -2.0, 2.0]"), ["arena.bounds", "xmin < xmax"]),
    ("negative seed", "seed = -1\n" + GOOD, ["seed", "out of range"]),
    ("unknown target id", GOOD.replace('goal = "g"', 'goal = "h"'), ["robots[0].goal", "unknown target id 'h'"]),
    (
        "duplicate robot id",
        GOOD + '\n[[robots]]\nid = "r1"\nstart = [1.0, 0.5, 0.0]\n',
        ["robots[1].id", "duplicate id 'r1'"],
    ),
    (
        "duplicate across kinds",
        GOOD + '\n[[obstacles]]\nid = "g"\nshape = "disc"\ncenter = [1, 1]\nradius = 0.1\n',
        ["obstacles[0].id", "duplicate id 'g'"],
    ),
    ("bad id", GOOD.replace('id = "r1"', 'id = "r 1"'), ["robots[0].id", "invalid id"]),
    (
        "start inside a wall",
        GOOD + "\n[[walls]]\na = [0.5, 0.0]\nb = [0.5, 1.0]\n",
        ["robots[0].start", "overlaps walls[0]"],
    ),
    (
        "start overlapping an obstacle",
        GOOD + '\n[[obstacles]]\nshape = "box"\ncenter = [0.55, 0.5]\nsize = [0.05, 0.05]\n',
        ["robots[0].start", "overlaps obstacles[0]"],
    ),
    (
        "start overlapping a robot",
        GOOD + '\n[[robots]]\nid = "r2"\nstart = [0.52, 0.5, 0.0]\n',
        ["robots[1].start", "overlaps robot 'r1'"],
    ),
    (
        "start outside arena",
        GOOD.replace("[0.5, 0.5, 0.0]", "[2.5, 0.5, 0.0]"),
        ["robots[0].start", "not inside arena.bounds"],
    ),
    (
        "start's body reaching outside the arena",
        GOOD.replace("[0.5, 0.5, 0.0]", "[0.029, 1.0, 0.0]"),
        ["robots[0].start", "robot at (0.029, 1.0) with body radius 0.03 m reaches outside arena.bounds"],
    ),
    ("no robots", "robots = []\n" + GOOD.split("[[robots]]")[0], ["robots", "at least one robot"]),
    (
        "target inside obstacle",
        GOOD + '\n[[obstacles]]\nshape = "disc"\ncenter = [1.5, 1.5]\nradius = 0.1\n',
        ["targets[0].position", "inside obstacles[0]"],
    ),
    ("unknown shape", GOOD + '\n[[obstacles]]\nshape = "star"\n', ["obstacles[0].shape", "unknown value 'star'"]),
    (
        "missing shape field",
        GOOD + '\n[[obstacles]]\nshape = "disc"\ncenter = [1, 1]\n',
        ["obstacles[0].radius", "missing"],
    ),
    (
        "negative radius",
        GOOD + '\n[[obstacles]]\nshape = "disc"\ncenter = [1, 1]\nradius = -0.1\n',
        ["obstacles[0].radius", "out of range"],
    ),
    (
        "motion radius",
        GOOD + '\n[[obstacles]]\nshape = "disc"\nradius = 0.05\n[obstacles.motion]\ntype = "circle"\ncenter = [1, '
        "1]\nradius = 0\nangular_speed = 0.2\n",
        ["obstacles[0].motion.radius", "out of range"],
    ),
    (
        "second obstacle's motion",
        GOOD
        + '\n[[obstacles]]\nshape = "disc"\ncenter = [1, 0.4]\nradius = 0.05\n'
        + '\n[[obstacles]]\nshape = "disc"\nradius = 0.05\n[obstacles.motion]\ntype = "circle"\ncenter = [1, '
        '1]\nradius = 0.2\nangular_speed = 0.2\ndirection = "left"\n',
        ["obstacles[1].motion.direction", "unknown value 'left'"],
    ),
    (
        "unknown motion type",
        GOOD + '\n[[obstacles]]\nshape = "disc"\nradius = 0.05\n[obstacles.motion]\ntype = "spiral"\n',
        ["obstacles[0].motion.type", "unknown value 'spiral'"],
    ),
    (
        "moving concave",
        GOOD + '\n[[obstacles]]\nshape = "concave"\ncenter = [1, 1]\nwidth = 0.3\ndepth = '
        '0.1\n[obstacles.motion]\ntype = "line"\na = [1, 1]\nb = [1, 1.2]\nspeed = 0.1\n',
        ["obstacles[0].motion", "cannot move"],
    ),
    (
        "moving obstacle with center",
        GOOD + '\n[[obstacles]]\nshape = "disc"\nradius = 0.05\ncenter = [1, 1]\n[obstacles.motion]\ntype = "line"\na '
        "= [1, 1]\nb = [1, 1.2]\nspeed = 0.1\n",
        ["obstacles[0].center", "must not be given"],
    ),
    (
        "line phase",
        GOOD + '\n[[obstacles]]\nshape = "disc"\nradius = 0.05\n[obstacles.motion]\ntype = "line"\na = [1, 1]\nb = [1, '
        "1.2]\nspeed = 0.1\nphase = 1.0\n",
        ["obstacles[0].motion.phase", "out of range"],
    ),
    (
        "self-intersecting polygon",
        GOOD + '\n[[obstacles]]\nshape = "polygon"\nvertices = [[1, 1], [1.2, 1.2], [1.2, 1], [1, 1.2]]\n',
        ["obstacles[0].vertices", "intersect"],
    ),
    ("zero-length wall", GOOD + "\n[[walls]]\na = [1, 1]\nb = [1, 1]\n", ["walls[0].b", "zero-length"]),
    (
        "wall thickness",
        GOOD + "\n[[walls]]\na = [1, 1]\nb = [1, 1.5]\nthickness = 0\n",
        ["walls[0].thickness", "out of range"],
    ),
    (
        "known not bool",
        GOOD + '\n[[walls]]\na = [1, 1]\nb = [1, 1.5]\nknown = "yes"\n',
        ["walls[0].known", "true or false"],
    ),
    (
        "target position for circle",
        GOOD.replace(
            "position = [1.5, 1.5]",
            'position = [1.5, 1.5]\nmotion = {type = "circle", center = [1, 1], radius = 0.2, angular_speed = 0.1}',
        ),
        ["targets[0].position", "must not be given"],
    ),
    (
        "random walk missing speed",
        GOOD.replace("position = [1.5, 1.5]", 'position = [1.5, 1.5]\nmotion = {type = "random_walk"}'),
        ["targets[0].motion.speed", "missing"],
    ),
    ("sensor range", GOOD + "\n[sensors]\nrange = -1\n", ["sensors.range", "out of range"]),
    ("target range nan", GOOD + "\n[sensors]\ntarget_range = nan\n", ["sensors.target_range", "nan"]),
    ("robots not an array", 'robots = "r1"\n' + GOOD.split("[[robots]]")[0], ["robots", "array of tables"]),
    ("toml syntax", GOOD + "\nthis is not toml\n", ["TOML syntax error"]),
    # ids the key space and the messages take, checked here, not at a run's first message
    ("robot id a digit", GOOD.replace('id = "r1"', 'id = "1"'), ["robots[0].id", "must start with a letter"]),
    ("robot id world", GOOD.replace('id = "r1"', 'id = "world"'), ["robots[0].id", "'world' is reserved"]),
    ("robot id too long", GOOD.replace('id = "r1"', f'id = "{"r" * 65}"'), ["robots[0].id", "at most 64"]),
    ("target id too long", GOOD.replace('"g"', f'"{"g" * 65}"'), ["targets[0].id", "id of 65 characters: at most 64"]),
    (
        "obstacle id too long",
        GOOD + f'\n[[obstacles]]\nid = "{"o" * 257}"\nshape = "disc"\ncenter = [1.0, 1.0]\nradius = 0.1\n',
        ["obstacles[0].id", "id of 257 characters: at most 256"],
    ),
    (
        "wall wholly outside",
        GOOD + "\n[[walls]]\na = [5.0, 5.0]\nb = [6.0, 5.0]\n",
        ["walls[0]", "lies wholly outside arena.bounds"],
    ),
    (
        "disc wholly outside",
        GOOD + '\n[[obstacles]]\nshape = "disc"\ncenter = [3.0, 1.0]\nradius = 0.1\n',
        ["obstacles[0]", "lies wholly outside arena.bounds"],
    ),
    (
        "random walk leaving the arena",
        GOOD.replace(
            "position = [1.5, 1.5]",
            'position = [1.5, 1.5]\nmotion = {type = "random_walk", speed = 0.1, bounds = [-5.0, -5.0, 5.0, 5.0]}',
        ),
        ["targets[0].motion.bounds", "reach outside arena.bounds"],
    ),
    ("plan_checkpoints not a bool", "plan_checkpoints = 1\n" + GOOD, ["plan_checkpoints", "must be true or false"]),
]


@pytest.mark.parametrize("label,text,expect", BAD, ids=[b[0] for b in BAD])
def test_bad_scenario_is_refused_with_file_and_field(tmp_path, label, text, expect):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ScenarioError) as e:
        load_scenario(path)
    msg = str(e.value)
    assert str(path) in msg
    for part in expect:
        assert part in msg, msg


def test_good_base_document_loads(tmp_path):
    path = tmp_path / "good.toml"
    path.write_text(GOOD)
    sc = load_scenario(path)
    assert sc.robot_ids == ["r1"] and sc.seed == 0 and math.isinf(sc.target_range) and not sc.plan_checkpoints
    assert load_scenario("checkpoints").plan_checkpoints  # Fig. 12's planner is the file's choice, not its name's


def test_overrides_are_validated():
    with pytest.raises(ScenarioError, match=r"obstacles\[0\]\.widht: unknown key"):
        load_scenario("concave", overrides={"obstacles[0].widht": 0.5})
    with pytest.raises(ScenarioError, match=r"obstacles\[0\]\.width: out of range"):
        load_scenario("concave", overrides={"obstacles[0].width": -0.5})
    with pytest.raises(ScenarioError, match=r"index \[3\] does not exist"):
        load_scenario("concave", overrides={"obstacles[3].width": 0.5})
    with pytest.raises(ScenarioError, match="no such scenario"):
        load_scenario("no_such_scenario")
    sc = load_scenario("concave", overrides={"sensors.range": 0.3, "seed": 99})
    assert sc.sensor_range == 0.3 and sc.seed == 99


def test_concave_polygons_are_split_exactly():
    from world.geometry import convex_parts, is_convex, signed_area

    poly = [(0, 0), (4, 0), (4, 3), (3, 3), (3, 1), (1, 1), (1, 3), (0, 3)]  # a U
    parts = convex_parts(poly)
    assert all(is_convex(p) for p in parts)
    assert sum(signed_area(p) for p in parts) == pytest.approx(signed_area(poly))
    star = [
        (math.cos(k * math.pi / 5) * (1 if k % 2 == 0 else 0.4), math.sin(k * math.pi / 5) * (1 if k % 2 == 0 else 0.4))
        for k in range(10)
    ]
    parts = convex_parts(star)
    assert all(is_convex(p) for p in parts)
    assert sum(signed_area(p) for p in parts) == pytest.approx(signed_area(star))


def test_concave_polygon_obstacle_in_a_world():
    text = (
        GOOD
        + '\n[[obstacles]]\nshape = "polygon"\nvertices = [[1.0, 0.3], [1.0, 0.7], [1.3, 0.7], [1.3, 0.65], [1.05, '
          '0.65], [1.05, 0.35], [1.3, 0.35], [1.3, 0.3]]\n'
    )
    sc = world.parse_scenario(__import__("tomllib").loads(text), source="<poly>")
    w = World(
        world.parse_scenario(
            __import__("tomllib").loads(text.replace("[0.5, 0.5, 0.0]", "[0.9, 0.5, 0.0]")), source="<poly>"
        )
    )
    assert len(sc.obstacles[0].parts) >= 3
    assert w.true_ranges("r1")[0] == pytest.approx(1.0 - 0.9 - 0.03, abs=1e-9)
    # from inside the cavity, looking back at the inner face of the U's spine
    w = World(
        world.parse_scenario(
            __import__("tomllib").loads(text.replace("[0.5, 0.5, 0.0]", "[1.2, 0.5, 3.141592653589793]")),
            source="<poly>",
        )
    )
    assert w.true_ranges("r1")[0] == pytest.approx(1.2 - 1.05 - 0.03, abs=1e-9)
    assert np.isnan(w.true_ranges("r1")[6])  # the mouth is open


def test_a_directory_is_named_as_one_and_a_shipped_name_still_wins(tmp_path, monkeypatch):
    """A directory given as SCENARIO was 'no such scenario file' (QA item 7)."""
    (tmp_path / "adir").mkdir()
    (tmp_path / "concave").mkdir()  # a directory beside the user that has a shipped scenario's name
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ScenarioError, match="^adir: is a directory, not a scenario file$"):
        load_scenario("adir")
    assert load_scenario("concave").name == "concave"
