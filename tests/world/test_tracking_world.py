"""The world's side of tracking: what each robot's sensors give it, and Parker's A."""

import math

import pytest

from cekm_swarm.protocol.keys import DEFAULT_KEYS as K
from cekm_swarm.protocol.messages import decode, encode
from world import ScenarioError, World, load_scenario, parse_scenario
from world.tracking import ObservationMeter, is_tracking, mean_pairwise, run_kind, tracking_sense


def test_tracking_scenarios_are_tracking_and_navigation_ones_are_not():
    assert is_tracking(load_scenario("tracking")) and is_tracking(load_scenario("tracking-crowd"))
    assert not is_tracking(load_scenario("crossing")) and not is_tracking(load_scenario("concave"))


def test_run_kind_refuses_a_scenario_that_is_neither_naming_the_robot():
    assert [run_kind(load_scenario(n)) for n in ("tracking", "tracking-crowd", "crossing", "concave")] == \
        ["tracking", "tracking", "navigation", "navigation"]

    def scenario(goals: dict[str, str | None], targets: bool = True):
        return parse_scenario({"name": "s", "arena": {"bounds": [0.0, 0.0, 2.0, 2.0]}, "sensors": {"target_range": 0.5},
                               "robots": [{"id": r, "start": [0.5 + 0.5 * i, 0.5, 0.0]} | ({"goal": g} if g else {})
                                          for i, (r, g) in enumerate(goals.items())],
                               "targets": [{"id": "t1", "position": [1.0, 1.5]}] if targets else []}, source="s.toml")

    assert run_kind(scenario({"a": "t1", "b": "t1"})) == "navigation"
    assert run_kind(scenario({"a": None, "b": None})) == "tracking"
    with pytest.raises(ScenarioError, match=r"^s.toml: robots\[0\]\.goal: robot 'a' has none while 'b' has one"):
        run_kind(scenario({"a": None, "b": "t1", "c": None}))
    with pytest.raises(ScenarioError, match=r"^s.toml: robots\[1\]\.goal: robot 'b' has none and the scenario has no "
                                            "targets"):
        run_kind(scenario({"a": None, "b": None}, targets=False), checkpoints={"a": [[1.0, 1.0]]})
    assert run_kind(scenario({"a": "t1", "b": None}), checkpoints={"b": [[1.0, 1.0]]}) == "navigation"


def test_run_kind_refuses_a_tracking_scenario_whose_robots_see_every_target():
    doc = {"name": "s", "arena": {"bounds": [0.0, 0.0, 2.0, 2.0]}, "robots": [{"id": "a", "start": [0.5, 0.5, 0.0]}],
           "targets": [{"id": "t1", "position": [1.0, 1.5]}]}
    with pytest.raises(ScenarioError, match=r"^s.toml: sensors.target_range: a tracking scenario .* needs a finite"):
        run_kind(parse_scenario(doc, source="s.toml"))
    assert run_kind(parse_scenario(doc | {"sensors": {"target_range": 0.5}}, source="s.toml")) == "tracking"
    doc["robots"][0]["goal"] = "t1"  # navigation needs no target range
    assert run_kind(parse_scenario(doc, source="s.toml")) == "navigation"


def test_sense_messages_hold_the_pose_and_exactly_the_targets_in_range():
    sc = load_scenario("tracking-crowd")
    w1, w2 = World(sc, seed=5), World(sc, seed=5)
    for r in w1.robot_ids:
        pose, targets = tracking_sense(w1, r, 0.0)
        assert pose.pose == w1.pose(r)
        x, y, _ = w1.pose(r)
        st = w1.state()["targets"]
        inside = {t for t, p in st.items() if math.hypot(p["x"] - x, p["y"] - y) <= w1.target_range}
        assert set(targets.targets) == inside
        # the same noise model and stream as the target sensor, read for every target in order
        expect = {t: w2.target_reading(r, t) for t in w2.target_ids}
        assert targets.targets == {t: (a, d) for t, (a, d, v) in expect.items() if v}
        for m, key in ((pose, K.sense_pose(r)), (targets, K.sense_targets(r))):
            assert decode(key, encode(m)) == m


def test_A_on_a_hand_built_trajectory():
    """Two targets, two robots, range 1, four ticks: observed 2, 1, 0, 1 of 2 -> A = 0.5."""
    m = ObservationMeter(["a", "b"], ["r1", "r2"])
    ticks = [
        ({"r1": (0.0, 0.0), "r2": (5.0, 0.0)}, {"a": (0.5, 0.0), "b": (5.0, 1.0)}),  # both (b on the edge)
        ({"r1": (0.0, 0.0), "r2": (5.0, 0.0)}, {"a": (0.5, 0.0), "b": (5.0, 1.5)}),  # a only
        ({"r1": (0.0, 0.0), "r2": (5.0, 0.0)}, {"a": (2.0, 0.0), "b": (8.0, 0.0)}),  # none
        ({"r1": (0.0, 0.0), "r2": (5.0, 0.0)}, {"a": (4.5, 0.0), "b": (8.0, 0.0)}),  # a, by r2
    ]
    for k, (robots, targets) in enumerate(ticks):
        obs = m.sample_positions(0.128 * k, robots, targets, 1.0)
    assert obs == {"a": ["r2"], "b": []}
    s = m.summary()
    assert s["A"] == pytest.approx((1.0 + 0.5 + 0.0 + 0.5) / 4)
    assert s["A_per_target"] == {"a": 0.75, "b": 0.25}
    assert s["series"]["A"] == [1.0, 0.5, 0.0, 0.5]
    assert s["robots"] == 2 and s["targets"] == 2 and s["ticks"] == 4


def test_mean_pairwise():
    assert mean_pairwise([(0, 0)]) == 0.0
    assert mean_pairwise([(0, 0), (3, 4), (0, 4)]) == pytest.approx((5 + 4 + 3) / 3)
