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
    assert all(math.hypot(p.x - 1.0, p.y - 1.0) == pytest.approx(0.5) for p in circle.points)
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
    views = fv.FoxgloveViews(sink)
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
