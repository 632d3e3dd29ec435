"""``cekm ros2 bridge``: a live run's topics in ``rmw_zenoh``'s wire format, and teleop.

A thin shell around pure parts: it joins the run's router as one Zenoh client, decodes
every message under ``cekm/**`` with the protocol's validating decoder, maps it
(:class:`.mapping.RosMapper`) and publishes the ROS 2 messages as a ROS 2 node
``/cekm_bridge`` would under ``rmw_zenoh`` (:mod:`.wire`): CDR on
``<domain>/<topic>/<type>/<hash>`` with the attachment, a liveliness token for the node
and for each publisher and subscription. A ROS 2 machine on the same router sees them in
``ros2 topic list`` and ``ros2 topic echo``.

It never slows the run it watches:

- it only subscribes to the run's keys, into Zenoh ring channels (Rust-side queues that
  keep the newest samples and drop the oldest): Zenoh's receiving thread never waits for
  this process's Python, so no router ever holds a message for it;
- it publishes only outside the run's key space (``<domain>/...``, ``@ros2_lv/...``),
  with congestion control DROP: a put never waits;
- the one exception is teleop, asked for with ``--teleop r1,...``: accepted Twists on
  ``/<robot>/cmd_vel`` become ``cekm/<robot>/cmd/wheels`` (:mod:`.teleop`), also DROP.

Two threads do the work: one for the run's keys (mapping, publishing, the world clock for
teleop), one for the Twists; the caller's thread waits for the stop.
"""

from __future__ import annotations

import contextlib
import functools
import json
import logging
import threading
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import zenoh
import zenoh.ext

from cekm_swarm.protocol import DEFAULT_ROOT, Clock, DropCounter, KeySpace, WorldState, encode, validate_robot_id
from cekm_swarm.protocol.stamps import StampWindow
from cekm_swarm.runtime.bridge import MSGPACK
from cekm_swarm.runtime.config import MAX_MESSAGE_BYTES, client_config, client_config_from_file, load_config
from cekm_swarm.runtime.record import fetch_geometry
from cekm_swarm.runtime.wait import DEFAULT_WAIT, open_when_ready, resolve_endpoint

from .interfaces import DEFAULT_DISTRO, Interfaces, interfaces
from .mapping import MARKER_ARRAY, RosMapper, RosOut, ros_name
from .teleop import TWIST, Teleop, TwistRefused, twist_command
from .wire import ATTACHMENT_SIZE, PUBLISHER, SUBSCRIPTION, Attachment, Node, Qos, gid, topic_key

log = logging.getLogger("cekm_swarm.ros2.bridge")

NODE_NAME = "cekm_bridge"
RUN_RING = 1 << 14
"""Samples of the run's keys the receiving ring holds (a few seconds of a 16-robot run)."""
TWIST_RING = 256
CDR = zenoh.Encoding("application/cdr")
GEOMETRY_RETRY_S = 2.0


@dataclass(frozen=True)
class BridgeConfig:
    """What the bridge publishes: ROS domain, robots (None: all), teleoperated robots,
    ROS 2 distribution, the run's key root, the node's name."""

    domain: int = 0
    robots: tuple[str, ...] | None = None
    teleop: tuple[str, ...] = ()
    distro: str = DEFAULT_DISTRO
    root: str = DEFAULT_ROOT
    node_name: str = NODE_NAME

    def __post_init__(self) -> None:
        for r in (self.robots or ()) + self.teleop:
            validate_robot_id(r)


@dataclass
class BridgeStats:
    """Counts for the bridge's report: run messages received, ROS messages published per
    topic, Twists received, refused by reason, and wheel commands sent."""

    received: int = 0
    published: Counter[str] = field(default_factory=Counter)
    too_large: int = 0
    twists: int = 0
    refused: Counter[str] = field(default_factory=Counter)
    commands: int = 0
    errors: int = 0

    def doc(self, drops: DropCounter) -> dict[str, Any]:
        return {"received": self.received, "dropped": drops.total, "published": sum(self.published.values()),
                "topics": len(self.published), "too_large": self.too_large, "twists": self.twists,
                "twists_refused": dict(sorted(self.refused.items())), "wheel_commands": self.commands,
                "errors": self.errors}


class _RosPublisher:
    """One ROS 2 publisher: its Zenoh publisher, liveliness token, GID and sequence."""

    def __init__(self, session: zenoh.Session, node: Node, entity_id: int, out: RosOut, ifc: Interfaces,
                 domain: int) -> None:
        type_hash = ifc.hash(out.ros_type)
        self.token_key = node.entity_token(entity_id, PUBLISHER, out.topic, out.ros_type, type_hash, out.qos)
        self.gid = gid(self.token_key)
        self.key = topic_key(domain, out.topic, out.ros_type, type_hash)
        drop = zenoh.CongestionControl.DROP
        self.pub: Any  # a Zenoh publisher, advanced (with a cache) or plain
        if out.qos.transient_local:  # as rmw_zenoh does: a publication cache a late subscriber queries
            self.pub = zenoh.ext.declare_advanced_publisher(
                session, self.key, encoding=CDR, congestion_control=drop,
                cache=zenoh.ext.CacheConfig(max_samples=out.qos.depth), publisher_detection=True)
        else:
            self.pub = session.declare_publisher(self.key, encoding=CDR, congestion_control=drop)
        self.token = session.liveliness().declare_token(self.token_key)
        self.sequence = 0

    def put(self, payload: bytes) -> None:
        self.sequence += 1
        self.pub.put(payload, attachment=Attachment(self.sequence, time.time_ns(), self.gid).encode())

    def close(self) -> None:
        self.token.undeclare()
        self.pub.undeclare()


class Bridge:
    """The live bridge on an open ``session`` (see the module's docstring): :meth:`start`,
    then :meth:`close`; :attr:`stats` and :meth:`report` tell what it did."""

    def __init__(self, session: zenoh.Session, config: BridgeConfig = BridgeConfig()) -> None:
        self.session = session
        self.config = config
        self.ifc = interfaces(config.distro)
        self.keys = KeySpace(config.root)
        self.drops = DropCounter("ros2 bridge", keys=self.keys)
        self.stats = BridgeStats()
        self.mapper = RosMapper(self.ifc, robots=config.robots, clock=True, keys=self.keys, drops=self.drops)
        self.node = Node(config.domain, str(session.info.zid()), 0, config.node_name)
        self._entities = 0
        self._publishers: dict[str, _RosPublisher] = {}
        self._tokens: list[Any] = []
        self._lock = threading.Lock()  # teleop state: the run thread's clock, the twist thread's Twists
        self._teleop = {r: Teleop(r) for r in config.teleop}
        self._clock = StampWindow()
        self._wheel_pubs: dict[str, Any] = {}
        self._twist_subs: dict[str, Any] = {}
        self._threads: list[threading.Thread] = []
        self._geometry_at = -GEOMETRY_RETRY_S
        self._geometry: dict[str, Any] | None = None  # a fetched scene the run thread has yet to take
        self._fetching = False
        self.run_sub: Any = None
        self._closing = False

    # ------------------------------------------------------------------ life

    def start(self) -> None:
        """Declare the node, the teleop subscriptions and the run subscription; start the threads."""
        s = self.session
        self._tokens.append(s.liveliness().declare_token(self.node.token()))
        for robot in self.config.teleop:
            topic = f"/{ros_name(robot)}/cmd_vel"
            h = self.ifc.hash(TWIST)
            self._tokens.append(s.liveliness().declare_token(
                self.node.entity_token(self._entity(), SUBSCRIPTION, topic, TWIST, h, Qos())))
            self._wheel_pubs[robot] = s.declare_publisher(self.keys.cmd_wheels(robot), encoding=MSGPACK,
                                                          congestion_control=zenoh.CongestionControl.DROP)
            self._twist_subs[robot] = s.declare_subscriber(topic_key(self.config.domain, topic, TWIST, h),
                                                           zenoh.handlers.RingChannel(TWIST_RING))
        self.run_sub = s.declare_subscriber(self.keys.everything(), zenoh.handlers.RingChannel(RUN_RING))
        self._threads.append(threading.Thread(target=self._guard(self._run_loop), name="ros2-run", daemon=True))
        for robot, sub in self._twist_subs.items():
            self._threads.append(threading.Thread(target=self._guard(functools.partial(self._twist_loop, robot, sub)),
                                                  name=f"ros2-teleop-{robot}", daemon=True))
        for t in self._threads:
            t.start()
        self._fetch_geometry()

    def close(self) -> None:
        """Undeclare everything (the ROS graph sees the node and its topics go) and join the threads."""
        self._closing = True
        for sub in [self.run_sub, *self._twist_subs.values()]:
            if sub is not None:
                sub.undeclare()
        for t in self._threads:
            t.join(timeout=5)
        with self._lock:
            for p in self._publishers.values():
                p.close()
            self._publishers.clear()
        for p in self._wheel_pubs.values():
            p.undeclare()
        for tok in self._tokens:
            tok.undeclare()
        self._tokens.clear()

    def report(self) -> dict[str, Any]:
        """The counts so far as plain data."""
        with self._lock:
            return self.stats.doc(self.drops)

    def _entity(self) -> int:
        self._entities += 1
        return self._entities

    def _guard(self, loop: Callable[[], None]) -> Callable[[], None]:
        """A thread's body: ``loop`` until its subscriber is undeclared (Zenoh then raises
        from ``recv``); anything else is logged, never silent."""

        def run() -> None:
            try:
                loop()
            except zenoh.ZError as exc:
                if not self._closing:
                    log.error("ros2 bridge: a receiving thread stopped: %s", exc)

        return run

    def _failed(self, what: str, exc: BaseException) -> None:
        """An unexpected error handling one message: counted and logged once; the bridge goes on."""
        with self._lock:
            self.stats.errors += 1
            first = self.stats.errors == 1
        if first:
            log.error("ros2 bridge: %s failed (further failures are only counted): %s: %s", what,
                      type(exc).__name__, exc)

    # ------------------------------------------------------------------ the run's keys

    def _run_loop(self) -> None:
        handler = self.run_sub.handler
        while True:
            sample = handler.recv()
            if sample.kind != zenoh.SampleKind.PUT:
                continue
            key = str(sample.key_expr)
            try:
                self.handle_run_sample(key, sample.payload.to_bytes(), time.monotonic())
            except Exception as exc:  # noqa: BLE001 - one message must not end the bridge
                self._failed(f"publishing what {key} maps to", exc)

    def handle_run_sample(self, key: str, payload: bytes, wall: float) -> None:
        """One message of the run: map and publish it; a world clock also drives teleop."""
        with self._lock:
            self.stats.received += 1
        msg = self.drops.decode(key, payload)
        if msg is None:
            return
        if isinstance(msg, Clock) and self._teleop:
            why = self._clock.check(msg.stamp)
            if why is not None:
                self.drops.drop(key, why)
            else:
                with self._lock:
                    commands = [(r, t.on_clock(msg.stamp, wall)) for r, t in self._teleop.items()]
                for robot, cmd in commands:
                    if cmd is not None:
                        self._send_command(robot, cmd)
        if isinstance(msg, WorldState) and self.mapper.geometry is None:
            geometry, self._geometry = self._geometry, None
            if geometry is not None:  # fetched on another thread; the mapper is this thread's
                self.mapper.set_geometry(geometry)
            else:
                self._fetch_geometry()
        for out in self.mapper.feed(key, msg):
            self._publish(out)

    def _publish(self, out: RosOut) -> None:
        payload = self.ifc.cdr(out.msg, out.ros_type)
        if len(payload) + ATTACHMENT_SIZE > MAX_MESSAGE_BYTES:
            markers = getattr(out.msg, "markers", None) if out.ros_type == MARKER_ARRAY else None
            if markers is not None and len(markers) > 1:  # a big scene: in parts the routers carry
                half = len(markers) // 2
                for part in (markers[:half], markers[half:]):
                    self._publish(RosOut(out.topic, out.ros_type, self.ifc.make(MARKER_ARRAY, markers=part),
                                         out.stamp_ns, out.qos))
                return
            with self._lock:
                self.stats.too_large += 1
            return
        with self._lock:
            pub = self._publishers.get(out.topic)
            if pub is None:
                pub = self._publishers[out.topic] = _RosPublisher(self.session, self.node, self._entity(), out,
                                                                  self.ifc, self.config.domain)
            pub.put(payload)
            self.stats.published[out.topic] += 1

    def _fetch_geometry(self) -> None:
        """Ask the world for its static scene (for the markers), on a thread of its own, at
        most every :data:`GEOMETRY_RETRY_S` s until it answers."""
        now = time.monotonic()
        with self._lock:
            if self._fetching or now - self._geometry_at < GEOMETRY_RETRY_S:
                return
            self._fetching, self._geometry_at = True, now

        def fetch() -> None:
            try:
                self._geometry = fetch_geometry(self.session, self.keys.world_geometry())
            finally:
                self._fetching = False

        threading.Thread(target=fetch, name="ros2-geometry", daemon=True).start()

    # ------------------------------------------------------------------ teleop

    def _twist_loop(self, robot: str, sub: Any) -> None:
        handler = sub.handler
        while True:
            sample = handler.recv()
            if sample.kind == zenoh.SampleKind.PUT:
                try:
                    self.handle_twist(robot, sample.payload.to_bytes(), time.monotonic())
                except Exception as exc:  # noqa: BLE001
                    self._failed(f"teleop of {robot}", exc)

    def handle_twist(self, robot: str, payload: bytes, wall: float) -> None:
        """One Twist for ``robot``: refused (and counted by reason) or turned into a command."""
        with self._lock:
            self.stats.twists += 1
            try:
                v_l, v_r = twist_command(self.ifc, payload)
                cmd = self._teleop[robot].on_twist(v_l, v_r, wall)
            except TwistRefused as exc:
                self.stats.refused[exc.reason] += 1
                if self.stats.refused[exc.reason] == 1:
                    log.warning("ros2 bridge: refused a Twist for %s (further ones are only counted): %s", robot, exc)
                return
        if cmd is not None:
            self._send_command(robot, cmd)

    def _send_command(self, robot: str, cmd: Any) -> None:
        self._wheel_pubs[robot].put(encode(cmd))
        with self._lock:
            self.stats.commands += 1


def bridge_session(connect: str | None, config_file: str | Path | None = None, *, timeout: float = DEFAULT_WAIT,
                   say: Callable[[str], None] | None = None, stop: threading.Event | None = None) -> zenoh.Session:
    """The bridge's Zenoh session: a tool's client session (:func:`cekm_swarm.runtime.wait.open_tool_session`:
    endpoint, config file, waiting for the router) with timestamping on, which a publication
    cache (``/tf_static``'s transient-local QoS) needs."""
    ep = resolve_endpoint(connect)

    def make() -> zenoh.Config:
        if config_file is not None and not ep.explicit:
            config = load_config(config_file)
        elif config_file is not None:
            config = client_config_from_file(config_file, ep.endpoint)
        else:
            config = client_config(ep.endpoint)
        config.insert_json5("timestamping/enabled", "true")
        return config

    endpoint = ep.endpoint
    if config_file is not None and not ep.explicit:
        with contextlib.suppress(Exception):  # the file's own endpoint cannot be read: say the default
            endpoint = ", ".join(json.loads(make().get_json("connect/endpoints"))) or ep.endpoint
    make()  # a bad config file fails here, before any waiting
    return open_when_ready(make, endpoint, timeout=timeout, say=say, stop=stop)


def run_bridge(session: zenoh.Session, config: BridgeConfig, stop: threading.Event,
               say: Callable[[str], None] | None = None) -> dict[str, Any]:
    """Run the bridge on ``session`` until ``stop`` is set; its report."""
    bridge = Bridge(session, config)
    bridge.start()
    if say is not None:
        teleop = f"; teleop: {', '.join(f'/{ros_name(r)}/cmd_vel' for r in config.teleop)}" if config.teleop else ""
        say(f"ros2 bridge: node /{config.node_name}, ROS 2 {config.distro}, ROS_DOMAIN_ID {config.domain}, "
            f"run keys {config.root}/**{teleop}")
    try:
        stop.wait()
    finally:
        bridge.close()
    return bridge.report()
