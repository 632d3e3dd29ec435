"""The tracker's optional additions: a target's track predicts where it will be, and the
point between targets one robot can hold together."""

import pytest

from cekm_swarm.controller.anticipation import TargetTracks, held_group


def test_a_target_moving_steadily_is_predicted_ahead_of_where_it_is_seen():
    tr = TargetTracks()
    for k in range(40):  # 0.1 m/s along x, sighted every 0.256 s
        t = 0.256 * k
        tr.update(t, {"t1": (0.1 * t, 1.0)})
    x, y = tr.predict("t1", 1.0)
    assert x == pytest.approx(0.1 * 0.256 * 39 + 0.1, abs=0.01) and y == pytest.approx(1.0)
    assert tr.predict("t2", 1.0) is None
    tr.update(0.256 * 39 + 2.0, {})  # not seen for longer than forget_s: dropped
    assert tr.predict("t1", 1.0) is None


def test_the_held_group_drops_the_outlier_until_the_rest_fit():
    pts = {"a": (0.0, 0.0), "b": (0.4, 0.0), "c": (3.0, 0.0)}
    c, ids = held_group(pts, 0.3)
    assert ids == ["a", "b"] and c == pytest.approx((0.2, 0.0))
    assert held_group({"a": (0.0, 0.0), "b": (1.0, 0.0)}, 0.3) is None
    assert held_group({"a": (0.0, 0.0)}, 0.3) is None


def test_a_tracks_speed_is_the_targets_speed():
    tr = TargetTracks()
    assert tr.speed("t1") is None
    for k in range(60):  # 0.06 m/s along x and 0.08 along y: 0.1 m/s
        t = 0.256 * k
        tr.update(t, {"t1": (0.06 * t, 0.08 * t)})
    assert tr.speed("t1") == pytest.approx(0.1, abs=0.005)
