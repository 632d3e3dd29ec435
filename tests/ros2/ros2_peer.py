"""A ROS 2 peer built on PyPI's ``zenoh-ros2-sdk`` (an implementation of ``rmw_zenoh``'s
protocol independent of this project: its own key expressions, attachments, liveliness
tokens, type-hash computation and graph discovery), driven line by line from stdin.

``python ros2_peer.py HOST:PORT MSG_DIR DOMAIN`` prints ``READY <session id>``, then
answers each command on stdin:

- ``sub TOPIC TYPE [latched]``: subscribe; each message prints ``MSG TOPIC {json}``;
- ``pub TOPIC TYPE``: a publisher; prints ``PUB TOPIC <key expression>``;
- ``twist TOPIC vx vy vz wx wy wz``: publish a Twist (``nan``, ``inf``, ``1e300`` allowed);
- ``raw TOPIC HEX``: put these bytes on the publisher's key, with the SDK's attachment;
- ``info TOPIC``: ``INFO {json}``, the topic as the SDK's graph discovery sees it
  (``ros2 topic info -v``: publishers with node, type, type hash and QoS);
- ``quit``.

MSG_DIR holds the ``.msg`` definitions (``<pkg>/msg/<Name>.msg``) the SDK reads instead
of cloning them from GitHub (the machines here reach no GitHub).
"""

from __future__ import annotations

import json
import math
import struct
import sys
import time

router, msg_dir, domain = sys.argv[1], sys.argv[2], int(sys.argv[3])
host, port = router.rsplit(":", 1)

from zenoh_ros2_sdk import ROS2Publisher, ROS2Subscriber, ZenohSession, get_message_class, get_registry  # noqa: E402
from zenoh_ros2_sdk.discovery import get_topic_info  # noqa: E402
from zenoh_ros2_sdk.qos import QosDurability, QosProfile  # noqa: E402

get_registry(msg_dir)
session = ZenohSession.get_instance(host, int(port))
out_lock = __import__("threading").Lock()


def say(*parts: str) -> None:
    with out_lock:
        print(*parts, flush=True)


def plain(x):
    """A message as JSON-able data (numbers that JSON cannot hold as strings)."""
    if hasattr(x, "__dataclass_fields__"):
        return {k: plain(getattr(x, k)) for k in x.__dataclass_fields__ if not k.startswith("__") and not k.isupper()}
    if hasattr(x, "tolist"):
        return plain(x.tolist())
    if isinstance(x, (list, tuple)):
        return [plain(v) for v in x]
    if isinstance(x, float) and not math.isfinite(x):
        return repr(x)
    return x


subs, pubs = {}, {}
say("READY", session.session_id)
for line in sys.stdin:
    cmd, *args = line.split()
    if cmd == "quit":
        break
    if cmd == "sub":
        topic, ros_type = args[0], args[1]
        qos = QosProfile(durability=QosDurability.TRANSIENT_LOCAL) if args[2:] == ["latched"] else None

        def callback(msg, topic=topic):
            say("MSG", topic, json.dumps(plain(msg)))

        subs[topic] = ROS2Subscriber(topic, ros_type, callback, domain_id=domain, router_ip=host,
                                     router_port=int(port), qos=qos)
        say("SUB", topic, subs[topic].keyexpr)
    elif cmd == "pub":
        topic, ros_type = args
        pubs[topic] = ROS2Publisher(topic, ros_type, domain_id=domain, router_ip=host, router_port=int(port))
        say("PUB", topic, pubs[topic].keyexpr)
    elif cmd == "twist":
        topic, values = args[0], [float(v) for v in args[1:]]
        vector = get_message_class("geometry_msgs/msg/Vector3")
        pubs[topic].publish(linear=vector(x=values[0], y=values[1], z=values[2]),
                            angular=vector(x=values[3], y=values[4], z=values[5]))
        say("SENT", topic)
    elif cmd == "raw":
        p = pubs[args[0]]
        data = bytes.fromhex(args[1]) if len(args) > 1 else b""
        attachment = struct.pack("<qqB", p.sequence_number, time.time_ns(), 16) + p.publisher_gid
        p.sequence_number += 1
        p.pub.put(data, attachment=attachment)
        say("SENT", args[0])
    elif cmd == "info":
        info = get_topic_info(args[0], domain_id=domain, router_ip=host, router_port=int(port), verbose=True)
        say("INFO", json.dumps(None if info is None else {
            "types": info.topic_types, "publishers": [plain(p) for p in info.publishers],
            "subscribers": [plain(s) for s in info.subscribers]}))
    else:
        say("ERROR", f"unknown command {cmd!r}")
for s in subs.values():
    s.close()
for p in pubs.values():
    p.close()
session.close()
