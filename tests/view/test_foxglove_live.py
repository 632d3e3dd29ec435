"""``cekm view --foxglove``: the view channels served live on foxglove-sdk's WebSocket
server, read by a minimal WebSocket client speaking Foxglove's protocol (advertise,
subscribe, binary message data), fed with real encoded world states (no Zenoh)."""

from __future__ import annotations

import json
import struct
import time

import pytest

pytest.importorskip("foxglove")

from cekm_swarm.protocol import DEFAULT_KEYS as K  # noqa: E402
from cekm_swarm.protocol import WorldState, encode  # noqa: E402
from cekm_swarm.view.foxglove_live import FoxgloveLive  # noqa: E402
from cekm_swarm.view.live import LiveView  # noqa: E402
from helpers.foxglove import WsClient  # noqa: E402

GEOMETRY = {"bounds": [0.0, 0.0, 1.0, 1.0], "body_radius": 0.03, "walls": [], "polygons": [],
            "discs": [{"id": "d1", "center": [0.5, 0.5], "radius": 0.05, "known": False}],
            "moving_obstacles": [], "targets": [], "robots": [{"id": "r1", "start": [0.1, 0.1, 0.0]}]}


def test_foxglove_server_advertises_and_streams_the_scene():
    view = LiveView(GEOMETRY)
    fox = FoxgloveLive(view, port=0)
    try:
        ws = WsClient(fox.port)
        channels: dict[str, int] = {}
        deadline = time.monotonic() + 20
        x = 0.1
        while "/view/scene" not in channels or "/view/path/r1" not in channels:
            assert time.monotonic() < deadline, channels
            x += 0.01  # a moving robot: the scene, its transform and its path are published
            view.observe(K.world_state(), encode(WorldState(x, "world", {"r1": {"x": x, "y": 0.2, "theta": 0.0}},
                                                            {}, {})))
            op, data = ws.frame()
            if op == 1:
                msg = json.loads(data)
                if msg["op"] == "advertise":
                    channels.update({c["topic"]: c["id"] for c in msg["channels"]})
                    assert all(c["encoding"] == "protobuf" for c in msg["channels"])
        ws.send_json({"op": "subscribe", "subscriptions": [{"id": 7, "channelId": channels["/view/scene"]}]})
        seen = b""
        while b"robot/r1" not in seen:
            assert time.monotonic() < deadline, "no scene with robot r1"
            x += 0.01
            view.observe(K.world_state(), encode(WorldState(x, "world", {"r1": {"x": x, "y": 0.2, "theta": 0.0}},
                                                            {}, {})))
            op, data = ws.frame()
            if op == 2:  # binary: opcode 1 (message data), subscription id, log time (ns), payload
                assert data[0] == 1 and struct.unpack("<I", data[1:5])[0] == 7
                assert struct.unpack("<Q", data[5:13])[0] > 0
                seen = data[13:]
        assert fox.sink.messages > 2
    finally:
        fox.close()


def test_a_users_typed_messages_go_out_as_json_with_their_json_schema():
    """A user message type of the run (its schema from the run spec) and a parameter change:
    each on a channel named by its key, JSON encoded, its schema the type's JSON Schema;
    a message of a type the run did not declare goes nowhere, a malformed one is counted."""
    from cekm_swarm.protocol import ParamChange, UserMessage
    from cekm_swarm.protocol.user import USER_TYPES, json_schema, user_schemas

    class Gap(UserMessage):
        """The widest gap (rad, robot frame) and its width (m)."""

        TYPE = "qa.Gap"
        alpha: float
        width: float

    class Stray(UserMessage):
        TYPE = "qa.Stray"
        x: float

    fox = FoxgloveLive(LiveView(GEOMETRY), port=0)
    try:
        fox.set_schemas(user_schemas([Gap]))
        del USER_TYPES["qa.Gap"]  # as in a view without the user's module: the schema comes from the run spec
        fox.observe("cekm/r1/mine/stray", encode(Stray(0.128, "r1/x", 1.0)))  # not a type of the run: no channel
        fox.observe("cekm/r1/mine/gap", encode(Gap(0.256, "r1/gap", 0.5, 0.2)))
        fox.observe("cekm/r1/param/gap", encode(ParamChange(0.384, "r1/gap", "gap", "near", 0.3, 0.2)))
        ws = WsClient(fox.port)
        channels: dict[str, dict] = {}
        deadline = time.monotonic() + 20
        while "cekm/r1/mine/gap" not in channels or "cekm/r1/param/gap" not in channels:
            assert time.monotonic() < deadline, channels
            op, data = ws.frame()
            if op == 1 and json.loads(data)["op"] == "advertise":
                channels.update({c["topic"]: c for c in json.loads(data)["channels"]})
        gap = channels["cekm/r1/mine/gap"]
        assert gap["encoding"] == "json" and gap["schemaName"] == "cekm.data:qa.Gap"
        assert gap["schemaEncoding"] == "jsonschema" and json.loads(gap["schema"]) == json_schema(Gap)
        assert json.loads(channels["cekm/r1/param/gap"]["schema"])["title"] == "cekm.ParamChange"
        assert "cekm/r1/mine/stray" not in channels
        ws.send_json({"op": "subscribe", "subscriptions": [{"id": 3, "channelId": gap["id"]}]})
        while True:  # a message sent once subscribed reaches the app as JSON (sent again until the
            # server has taken the subscription: one observed before it goes nowhere, and no frame comes)
            fox.observe("cekm/r1/mine/gap", encode(Gap(0.512, "r1/gap", 0.25, 0.1)))
            got = ws.frame_within(0.5)
            if got is not None and got[0] == 2:
                data = got[1]
                break
            assert time.monotonic() < deadline, "no message on the user's channel"
        assert json.loads(data[13:]) == {"v": 1, "kind": "data", "type": "qa.Gap", "stamp": 0.512, "sender": "r1/gap",
                                         "alpha": 0.25, "width": 0.1}
        import msgpack

        fox.observe("cekm/r1/mine/gap", msgpack.packb({"v": 1, "kind": "data", "type": "qa.Gap", "stamp": 0.64}))
        assert fox.dropped == 1  # no sender: dropped and counted
    finally:
        fox.close()
