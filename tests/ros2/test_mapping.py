"""The key-to-ROS mapping on hand-made messages: values, frames, topics, and what it drops."""

import math

import msgpack
import numpy as np
import pytest

from cekm_swarm.protocol import (
    Clock,
    DropCounter,
    ObstacleField,
    SenseRange,
    TargetField,
    TrackingField,
    WheelCommand,
    WorldState,
    to_wire,
)
from cekm_swarm.robot import KHEPERA
from cekm_swarm.ros2.interfaces import interfaces
from cekm_swarm.ros2.mapping import TOPICS, RosMapper
from cekm_swarm.ros2.wire import check_topic

IFC = interfaces()
GEOMETRY = {"body_radius": 0.03, "sensor_range": 0.25, "target_range": 0.5,
            "walls": [{"vertices": [[0, 0], [1, 0], [1, 0.02], [0, 0.02]]}],
            "polygons": [], "discs": [{"center": [0.5, 0.5], "radius": 0.05, "known": False}],
            "moving_obstacles": [{"id": "m1", "shape": "disc", "radius": 0.04}]}


def state(t=0.256, **robots):
    rb = {
        rid: {"x": x, "y": y, "theta": th, "v_l_exec": vl, "v_r_exec": vr} for rid, (x, y, th, vl, vr) in robots.items()
    }
    return WorldState(t, "world", rb, {"g1": {"x": 1.0, "y": 1.5}}, {"m1": {"x": 0.2, "y": 0.3, "theta": 0.1}})


def by_topic(outs):
    return {o.topic: o for o in outs}


def test_world_state_gives_odometry_tf_and_markers():
    m = RosMapper(IFC, geometry=GEOMETRY)
    outs = m.feed("cekm/world/state", state(r1=(0.3, 1.0, 0.5, 0.1, 0.12), **{"r-2": (1.7, 1.3, -3.0, 0.0, 0.0)}))
    t = by_topic(outs)
    odom = t["/r1/odom"].msg
    assert t["/r1/odom"].stamp_ns == 256_000_000 and (odom.header.stamp.sec, odom.header.stamp.nanosec) == (
        0,
        256_000_000,
    )
    assert (odom.header.frame_id, odom.child_frame_id) == ("map", "r1/base_link")
    p = odom.pose.pose
    assert (p.position.x, p.position.y) == (0.3, 1.0) and 2 * math.atan2(
        p.orientation.z, p.orientation.w
    ) == pytest.approx(0.5)
    assert odom.twist.twist.linear.x == pytest.approx(0.11)
    assert odom.twist.twist.angular.z == pytest.approx(0.02 / KHEPERA.axle)
    assert "/r_2/odom" in t  # a '-' cannot be in a ROS name
    tf = t["/tf"].msg.transforms
    assert [x.child_frame_id for x in tf] == ["r1/base_link", "r_2/base_link"] and tf[1].transform.translation.x == 1.7
    markers = [o for o in outs if o.topic == "/world/markers"]
    scene, dynamic = (o.msg.markers for o in markers)
    assert {mk.ns for mk in scene} == {"walls", "discs"}
    assert {mk.ns for mk in dynamic} == {"robots", "headings", "sensing", "targets", "moving_obstacles"}
    for circle in (mk for mk in dynamic if mk.ns == "sensing"):  # the target sensing range around each robot
        cx, cy = np.mean([p.x for p in circle.points[:-1]]), np.mean([p.y for p in circle.points[:-1]])
        assert (round(cx, 9), round(cy, 9)) in {(0.3, 1.0), (1.7, 1.3)}
        assert math.hypot(circle.points[0].x - cx, circle.points[0].y - cy) == pytest.approx(0.5)
    # the static scene again only a second of sim time later
    again = m.feed("cekm/world/state", state(0.512, r1=(0.3, 1.0, 0.5, 0.1, 0.12)))
    assert sum(o.topic == "/world/markers" for o in again) == 1
    assert sum(o.topic == "/world/markers" for o in m.feed("cekm/world/state", state(1.28, r1=(0, 0, 0, 0, 0)))) == 2
    for o in outs:
        check_topic(o.topic)
        IFC.cdr(o.msg, o.ros_type)  # every message encodes


def test_a_world_state_that_does_not_decode_never_reaches_the_mapper_the_rest_is_mapped():
    """The world state is typed: a robot entry without a finite pose (or a target without
    numbers) fails the protocol's decoder, which the bag export and the bridge count as a
    drop; the mapper maps what decodes (the robots asked for)."""
    drops = DropCounter("ros2 mapping")
    wire = to_wire(state(r1=(0, 0, 0, 0, 0), r2=(0, 0, 0, 0, 0)))
    for change in ({"robots": {**wire["robots"], "r2": {"x": "left", "y": 0.0}}},
                   {"targets": {"g": {"x": None, "y": 0.0}}}):
        assert drops.decode("cekm/world/state", msgpack.packb({**wire, **change})) is None
    assert drops.count("cekm/world/state") == 2
    m = RosMapper(IFC)
    assert m.feed("not/a/cekm/key", state(r1=(0, 0, 0, 0, 0))) == []
    only_r2 = by_topic(RosMapper(IFC, robots=["r2"]).feed("cekm/world/state", state(r1=(0, 0, 0, 0, 0))))
    assert set(only_r2) == {"/world/markers"}  # the targets and obstacles, no r1
    assert {mk.ns for mk in only_r2["/world/markers"].msg.markers} == {"targets", "moving_obstacles"}


def test_range_readings_become_ranges_from_the_surface_and_static_frames():
    m = RosMapper(IFC, geometry=GEOMETRY)
    a = 2 * math.pi / 12
    outs = m.feed("cekm/r1/sense/range/1", SenseRange(0.128, "world", 1, a, 0.1))
    t = by_topic(outs)
    rng = t["/r1/range_1"].msg
    assert rng.header.frame_id == "r1/range_1" and rng.radiation_type == 1
    assert (rng.min_range, rng.max_range, rng.range) == (0.0, 0.25, 0.1 - 0.03)
    (tr,) = t["/tf_static"].msg.transforms
    assert (tr.header.frame_id, tr.child_frame_id) == ("r1/base_link", "r1/range_1")
    assert (tr.transform.translation.x, tr.transform.translation.y) == pytest.approx(
        (0.03 * math.cos(a), 0.03 * math.sin(a))
    )
    assert t["/tf_static"].qos.transient_local
    blind = by_topic(m.feed("cekm/r1/sense/range/1", SenseRange(0.256, "world", 1, a, None)))
    assert blind["/r1/range_1"].msg.range == math.inf and "/tf_static" not in blind  # the frame is known already
    more = by_topic(m.feed("cekm/r2/sense/range/0", SenseRange(0.256, "world", 0, 0.0, None)))
    assert [x.child_frame_id for x in more["/tf_static"].msg.transforms] == ["r1/range_1", "r2/range_0"]  # cumulative
    # the round trip through CDR keeps the float32 range
    data = IFC.cdr(rng, "sensor_msgs/msg/Range")
    assert IFC.from_cdr(data, "sensor_msgs/msg/Range").range == np.float32(0.1 - 0.03)


def test_fields_and_the_wheel_command_give_arrays_motor_activity_and_winners():
    m = RosMapper(IFC)
    n = 9
    a = np.linspace(0.0, 1.0, n)
    b3 = np.full(n, 0.25)
    b5 = np.zeros(n)
    b5[8] = 2.0
    assert (
        m.feed("cekm/r1/cmd/wheels", WheelCommand(0.0, "r1/motor", 0.0, 0.0, 1))[-1].topic == "/r1/wheel_speeds"
    )  # no field yet
    tf = by_topic(m.feed("cekm/r1/field/target", TargetField(0.256, "r1/target", 8, a, 0.1, 0.2)))
    arr = tf["/r1/ekm/target_field"].msg
    assert [(d.label, d.size, d.stride) for d in arr.layout.dim] == [("row", 3, 9), ("col", 3, 3)]
    assert np.array_equal(arr.data, a)
    m.feed("cekm/r1/field/obstacle/3", ObstacleField(0.256, "r1/obstacle-3", 3, 0, b3))
    m.feed("cekm/r1/field/obstacle/5", ObstacleField(0.256, "r1/obstacle-5", 5, 8, b5))
    m.feed("cekm/r1/field/obstacle/7", ObstacleField(0.128, "r1/obstacle-7", 7, 1, b3))  # an older tick: not summed
    empty = by_topic(m.feed("cekm/r1/field/obstacle/6", ObstacleField(0.256, "r1/obstacle-6", 6, None, None)))
    assert (
        len(empty["/r1/ekm/obstacle_field_6"].msg.data) == 0 and empty["/r1/ekm/obstacle_field_6"].msg.layout.dim == []
    )
    t = by_topic(m.feed("cekm/r1/cmd/wheels", WheelCommand(0.256, "r1/motor", 0.1, 0.12, 2)))
    twist = t["/r1/cmd_vel_out"].msg
    assert twist.linear.x == pytest.approx(0.11) and twist.angular.z == pytest.approx(0.02 / KHEPERA.axle)
    assert list(t["/r1/wheel_speeds"].msg.data) == [0.1, 0.12]
    e = a - b3 - b5  # Eq. 9
    assert np.array_equal(t["/r1/ekm/motor_activity"].msg.data, e)
    winners = list(t["/r1/ekm/winners"].msg.data)
    assert winners[:2] == [8, int(np.argmax(e))] and len(winners) == 2 + 12
    assert winners[2 + 3] == 0 and winners[2 + 5] == 8 and winners[2 + 6] == -1 and winners[2 + 7] == -1
    # tracking: a - b_teammates - sum b_j, and no target winner
    tr = TrackingField(0.384, "r1/target", a, b3, ((2, 0.1, 0.2, 1.0),), {"g1": 1.0}, False)
    arr = by_topic(m.feed("cekm/r1/field/tracking", tr))["/r1/ekm/tracking_field"].msg
    assert arr.layout.dim[0].label == "field" and np.array_equal(arr.data, np.concatenate([a, b3]))
    t = by_topic(m.feed("cekm/r1/cmd/wheels", WheelCommand(0.384, "r1/motor", 0.0, 0.0, 3)))
    assert np.array_equal(t["/r1/ekm/motor_activity"].msg.data, a - b3 - b3 - b5)
    assert list(t["/r1/ekm/winners"].msg.data)[0] == -1


def test_clock_only_when_asked_and_every_topic_is_in_the_table():
    assert RosMapper(IFC).feed("cekm/world/clock", Clock(1.28, "world", 10)) == []
    (c,) = RosMapper(IFC, clock=True).feed("cekm/world/clock", Clock(1.28, "world", 10))
    assert c.topic == "/clock" and (c.msg.clock.sec, c.msg.clock.nanosec) == (1, 280_000_000)
    for row in TOPICS:
        check_topic(row.name.format(robot="r1", j=3))
        IFC.hash(row.ros_type)


def test_docs_have_the_mapping_table():
    from pathlib import Path

    doc = (Path(__file__).resolve().parents[2] / "docs" / "ros2.md").read_text()
    for row in TOPICS:
        name = row.name.replace("{robot}", "<robot>").replace("{j}", "<j>")
        assert f"| `{name}` | `{row.ros_type}` |" in doc, name
