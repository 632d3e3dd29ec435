"""The Foxglove tracking view (``/view/tracking``): each robot's sensing circle and a line
to every target it observes, decoded back with the official protobuf schema."""

from __future__ import annotations

import math

import pytest

from cekm_swarm.runtime.mcap_log import McapRecorder, read_messages


def test_tracking_view_draws_sensing_circles_and_who_observes_whom(tmp_path):
    pytest.importorskip("foxglove", reason="foxglove-sdk not installed")
    pytest.importorskip("foxglove_schemas_protobuf", reason="foxglove-schemas-protobuf not installed")
    from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate

    from cekm_swarm.runtime.foxglove_view import CIRCLE_POINTS, TRACKING_TOPIC, FoxgloveViews

    state = {"robots": {"r1": {"x": 1.0, "y": 1.0, "theta": 0.0}, "r2": {"x": 2.0, "y": 1.0, "theta": 0.0}},
             "targets": {"t1": {"x": 1.3, "y": 1.0}, "t2": {"x": 1.8, "y": 1.2}, "t3": {"x": 5.0, "y": 5.0}}}
    path = tmp_path / "view.mcap"
    with McapRecorder(path) as rec:
        FoxgloveViews(rec).write_tracking(0.256, state, 0.5, {"t1": ["r1"], "t2": ["r1", "r2"], "t3": []})
    msgs = [SceneUpdate.FromString(m.data) for m in read_messages(path) if m.topic == TRACKING_TOPIC]
    assert len(msgs) == 1
    ents = {e.id: e for e in msgs[0].entities}
    assert set(ents) == {"sensing/r1", "sensing/r2"}
    circle = ents["sensing/r1"].lines[0]
    assert len(circle.points) == CIRCLE_POINTS
    centre = circle.pose.position  # the circle's points are about its centre, the robot
    assert (centre.x, centre.y) == (1.0, 1.0) and circle.pose.orientation.w == 1.0
    assert all(math.hypot(p.x + centre.x - 1.0, p.y + centre.y - 1.0) == pytest.approx(0.5) for p in circle.points)
    assert ents["sensing/r2"].lines[0].pose.position.x == 2.0
    seen_r1 = ents["sensing/r1"].lines[1].points
    assert [(p.x, p.y) for p in seen_r1[1::2]] == [(1.3, 1.0), (1.8, 1.2)]
    seen_r2 = ents["sensing/r2"].lines[1].points
    assert [(p.x, p.y) for p in seen_r2] == [(2.0, 1.0), (1.8, 1.2)]
    assert msgs[0].entities[0].timestamp.nanos == 256_000_000


def test_path_messages_are_the_bytes_of_the_whole_pose_list():
    """Each pose of a robot's path view is encoded once and a path message is joined from
    them: the same bytes as encoding the PosesInFrame of every pose, past the thinning too."""
    import math

    import foxglove.messages as fm

    from cekm_swarm.runtime import foxglove_view as fv

    class Sink:
        def __init__(self):
            self.paths = []

        def write_encoded(self, topic, encoding, schema, data, t, sticky=False):
            if topic.startswith("/view/path/"):
                self.paths.append((t, data))

    sink = Sink()
    views = fv.FoxgloveViews(sink, path_every=0.0)  # a path message whenever the path grew
    raw = []  # the path by its rule: every pose (each one a step), the older half thinned past PATH_MAX
    for k in range(fv.PATH_MAX + 300):
        t = 0.128 * k
        x, y, th = 0.01 * k, math.sin(k / 50), k / 100
        views.write_state(t, {"robots": {"r1": {"x": x, "y": y, "theta": th}}})
        raw.append((x, y, th))
        if len(raw) > fv.PATH_MAX:
            raw[:len(raw) // 2] = raw[:len(raw) // 2:2]
    assert len(sink.paths) == fv.PATH_MAX + 300 and len(raw) < fv.PATH_MAX
    assert len(views._paths["r1"]) == len(raw)
    t, data = sink.paths[-1]
    want = fm.PosesInFrame(timestamp=fv._stamp(t), frame_id=fv.WORLD_FRAME,
                           poses=[fv._pose(x, y, 0.0, th) for x, y, th in raw]).encode()
    assert data == want


def test_path_message_and_trail_draw_the_whole_path_at_every_tick():
    """Path messages come at most every PATH_EVERY_S of sim time; at every tick in between,
    the last path message's poses and the robot entity's trail are the whole path up to
    the robot, each pose once but for the one they share."""
    pytest.importorskip("foxglove_schemas_protobuf", reason="foxglove-schemas-protobuf not installed")
    from foxglove_schemas_protobuf.PosesInFrame_pb2 import PosesInFrame
    from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate

    from cekm_swarm.runtime import foxglove_view as fv

    class Sink:
        def __init__(self):
            self.last: dict[str, bytes] = {}
            self.paths: list[float] = []

        def write_encoded(self, topic, encoding, schema, data, t, sticky=False):
            self.last[topic] = data
            if topic.startswith("/view/path/"):
                self.paths.append(t)

    sink = Sink()
    views = fv.FoxgloveViews(sink)
    path = []
    ticks = 200
    for k in range(ticks):
        t = 0.128 * k
        x, y = 0.5 + 0.3 * math.cos(k / 30), 0.5 + 0.3 * math.sin(k / 30)
        if k % 7 == 3:  # still: no step, the trail ends at the last pose
            x, y = path[-1]
        views.write_state(t, {"robots": {"r1": {"x": x, "y": y, "theta": k / 30 + math.pi / 2}}})
        if not path or path[-1] != (x, y):
            path.append((x, y))
        sent = [(p.position.x, p.position.y) for p in PosesInFrame.FromString(sink.last["/view/path/r1"]).poses]
        robot = next(e for e in SceneUpdate.FromString(sink.last[fv.SCENE_TOPIC]).entities if e.id == "robot/r1")
        trail = [(p.x, p.y) for p in robot.lines[0].points]
        assert trail[0] == sent[-1] and trail[-1] == (x, y)
        drawn = sent + trail[1:]  # the robot's pose ends the trail: twice if it is the path's last
        assert [p for i, p in enumerate(drawn) if i == 0 or p != drawn[i - 1]] == path
    gaps = [
        b - a for a, b in zip(sink.paths, sink.paths[1:], strict=False)
    ]  # due after PATH_EVERY_S, sent at the next step
    assert sink.paths[0] == 0.0 and len(gaps) >= 20
    assert all(fv.PATH_EVERY_S <= g <= fv.PATH_EVERY_S + 2 * 0.128 for g in gaps)
