import math

import pytest

from cekm_swarm.controller.planner import PlanningError, plan_checkpoints

# two rooms joined by a 0.15 m doorway in a wall at x = 1 (y from 0.40 to 0.55)
GEOMETRY = {
    "bounds": [0.0, 0.0, 2.0, 1.0],
    "walls": [
        {"vertices": [[0.99, 0.0], [1.01, 0.0], [1.01, 0.40], [0.99, 0.40]], "known": True},
        {"vertices": [[0.99, 0.55], [1.01, 0.55], [1.01, 1.0], [0.99, 1.0]], "known": True},
    ],
    "polygons": [{"vertices": [[0.4, 0.4], [0.6, 0.4], [0.6, 0.6], [0.4, 0.6]], "known": False}],
    "discs": [],
}


def test_checkpoints_at_the_doorway_then_the_goal():
    plan = plan_checkpoints(GEOMETRY, (0.2, 0.8), (1.8, 0.2))
    assert len(plan.checkpoints) == 2
    door = plan.checkpoints[0]
    assert abs(door[0] - 1.0) < 0.03 and 0.44 < door[1] < 0.51  # in the middle of the doorway
    assert plan.checkpoints[-1] == (1.8, 0.2)
    # the path never enters a known wall
    for x, y in plan.path:
        assert not (0.99 - 0.03 < x < 1.01 + 0.03 and (y < 0.40 or y > 0.55))


def test_unknown_obstacles_are_not_planned_around():
    """The planner sees only the known walls: its straight line may cross the unknown box."""
    plan = plan_checkpoints(GEOMETRY, (0.2, 0.5), (0.8, 0.5))
    assert plan.checkpoints == [(0.8, 0.5)]
    assert any(0.4 < x < 0.6 and 0.4 < y < 0.6 for x, y in plan.path)


def test_no_path_and_bad_goal_are_refused():
    closed = dict(GEOMETRY, walls=GEOMETRY["walls"] + [
        {"vertices": [[0.99, 0.39], [1.01, 0.39], [1.01, 0.56], [0.99, 0.56]], "known": True}])
    with pytest.raises(PlanningError, match="no path"):
        plan_checkpoints(closed, (0.2, 0.8), (1.8, 0.2))
    with pytest.raises(PlanningError, match="goal"):
        plan_checkpoints(GEOMETRY, (0.2, 0.8), (1.0, 0.2))


def test_shipped_checkpoints_scenario_has_one_checkpoint_per_doorway():
    from world import World, load_scenario

    w = World(load_scenario("checkpoints"))
    x, y, _ = w.pose("r1")
    plan = plan_checkpoints(w.static_geometry(), (x, y), w.goal_of("r1"))
    assert math.dist(plan.checkpoints[-1], w.goal_of("r1")) < 1e-9
    xs = [c[0] for c in plan.checkpoints[:-1]]
    assert any(abs(x - 1.0) < 0.03 for x in xs) and any(abs(x - 2.0) < 0.03 for x in xs)
