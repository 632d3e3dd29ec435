"""``cekm view --foxglove PORT``: the same view channels as the MCAP log's (``/view/scene``,
``/view/tf``, ``/view/path/<robot>``, built by
:class:`cekm_swarm.runtime.foxglove_view.FoxgloveViews`) served live on foxglove-sdk's
WebSocket server, for the Foxglove desktop app ("Open connection", ws://HOST:PORT).

Beside them, every message of a user's own type (``cekm_swarm.protocol.UserMessage``) and
every parameter change (``cekm.ParamChange``) of the run goes out on a channel named by
its key, as JSON with the type's JSON Schema (``cekm.data:FreeDirection``, the schema the
MCAP log keeps for it; the run's world serves it in the run spec): Foxglove reads JSON with
a JSON Schema, not the key space's msgpack, so its panels plot the fields by name.

:class:`ChannelSink` stands where the views expect an MCAP recorder and logs each message
on a foxglove channel instead; :class:`FoxgloveLive` feeds the views from a
:class:`~cekm_swarm.view.live.LiveView` in its own thread.
"""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Mapping
from typing import Any

import foxglove

from cekm_swarm.protocol import ParamChange, decode, expect_of, to_plain
from cekm_swarm.protocol.codec import peek_type
from cekm_swarm.protocol.errors import ProtocolError
from cekm_swarm.protocol.user import user_schemas
from cekm_swarm.runtime.foxglove_view import FoxgloveViews
from cekm_swarm.runtime.mcap_log import SchemaSpec

from .live import LiveView

GEOMETRY_EVERY = 2.0
"""Wall seconds between re-sends of the static scene (a late-joining app gets it too)."""


class ChannelSink:
    """``write_encoded`` as :class:`McapRecorder` has it, onto live foxglove channels."""

    def __init__(self) -> None:
        self.channels: dict[str, Any] = {}
        self.messages = 0
        self._lock = threading.Lock()  # the views' thread and Zenoh's (a user's messages) both write

    def write_encoded(self, topic: str, message_encoding: str, schema: SchemaSpec, data: bytes,
                      sim_time: float, sticky: bool = False) -> None:
        with self._lock:
            ch = self.channels.get(topic)
            if ch is None:
                ch = self.channels[topic] = foxglove.Channel(
                    topic, message_encoding=message_encoding,
                    schema=foxglove.Schema(name=schema.name, encoding=schema.encoding, data=schema.data))
            ch.log(data, log_time=max(0, int(round(sim_time * 1e9))))
            self.messages += 1


class FoxgloveLive:
    """A foxglove WebSocket server on ``host:port`` (0: any free port) showing ``view``."""

    def __init__(self, view: LiveView, host: str = "127.0.0.1", port: int = 0, rate: float = 20.0) -> None:
        self.view = view
        self.rate = rate
        self.sink = ChannelSink()
        self.views = FoxgloveViews(self.sink, robot_radius=float(view.geometry.get("body_radius", 0.03)))
        self.dropped = 0  # user messages that did not decode against their type
        self.set_schemas({})
        self.server = foxglove.start_server(name="cekm view", host=host, port=port)
        self.port = self.server.port
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="view-foxglove", daemon=True)
        self._thread.start()

    def set_schemas(self, schemas: Mapping[str, Any]) -> None:
        """The run's user message types: ``{kind: JSON Schema}`` (``data:FreeDirection``), from its run spec."""
        self.schemas = {kind: SchemaSpec(f"cekm.{kind}", "jsonschema", json.dumps(doc).encode())
                        for kind, doc in {**schemas, **user_schemas([ParamChange])}.items()}

    def observe(self, key: str, payload: bytes) -> None:
        """A message of the run: one of a user's type with a schema goes out as JSON on channel ``key``."""
        name = peek_type(payload)
        spec = None if name is None else self.schemas.get(f"data:{name}")
        if spec is None:
            return
        try:
            msg = decode(key, payload, expect=expect_of(f"data:{name}"))
        except ProtocolError:
            self.dropped += 1
            return
        self.sink.write_encoded(key, "json", spec, json.dumps({"v": 1, **to_plain(msg)}).encode(), msg.stamp)

    def _run(self) -> None:
        version, sent_geometry = -1, -float("inf")
        while not self._stop.is_set():
            changed = self.view.wait_change(version, timeout=0.5)
            tick = self.view.tick()
            version = tick["version"]
            t = tick["time"] or 0.0
            if time.monotonic() - sent_geometry >= GEOMETRY_EVERY:
                self.views.write_geometry(t, self.view.geometry)
                sent_geometry = time.monotonic()
            if changed and tick["robots"]:
                self.views.write_state(t, {"robots": tick["robots"], "targets": tick["targets"],
                                           "obstacles": tick["obstacles"]})
            self._stop.wait(1.0 / self.rate)  # at most `rate` updates a second

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=5)
        self.server.stop()
