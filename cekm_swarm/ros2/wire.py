"""``rmw_zenoh``'s wire format (its docs/design.md, ROS 2 Jazzy and later): the key
expression of a topic, the attachment every publication carries, the liveliness tokens
through which ROS 2's graph (``ros2 topic list``, ``ros2 node list``) sees nodes,
publishers and subscriptions, the compact QoS text in those tokens, and entity GIDs.
Pure functions; the bridge process (:mod:`cekm_swarm.ros2.bridge`) puts them on Zenoh.

- topic key: ``<domain>/<topic without its leading slash>/<DDS type>/<type hash>``, e.g.
  ``0/r1/odom/nav_msgs::msg::dds_::Odometry_/RIHS01_3cc9...``;
- attachment (33 bytes): sequence number (int64 LE, from 1), source timestamp (int64 LE,
  ns since the UNIX epoch), the GID's length (one byte, 16), the 16-byte GID: what
  ``zenoh::ext::Serializer`` writes for (int64, int64, std::array<uint8_t, 16>);
- node token: ``@ros2_lv/<domain>/<session id>/<node id>/<node id>/NN/<enclave>/<namespace>/<node>``;
- publisher / subscription token: ``@ros2_lv/<domain>/<session id>/<node id>/<entity id>/MP|MS/
  <enclave>/<namespace>/<node>/<topic>/<DDS type>/<type hash>/<qos>``, names mangled
  (``/`` -> ``%``, an empty name is ``%``);
- GID: XXH3-128 of the entity's token key expression, low 64 bits then high 64 bits,
  little-endian (how ``rmw_zenoh`` derives it, so the GID in an attachment is the one
  ROS 2 computes from the token).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

import xxhash

from .interfaces import dds_type_name

ADMIN_SPACE = "@ros2_lv"
"""The prefix of every ROS 2 liveliness token (a Zenoh hermetic chunk: ``**`` never matches it)."""
NODE, PUBLISHER, SUBSCRIPTION = "NN", "MP", "MS"
GID_SIZE = 16
ATTACHMENT_SIZE = 8 + 8 + 1 + GID_SIZE
_ATTACHMENT = struct.Struct("<qqB")
MAX_DOMAIN = 232
"""ROS_DOMAIN_ID is 0..232 (ROS 2's documented range)."""


class WireError(ValueError):
    """Bytes or names that do not follow the format; the message says what is wrong."""


def mangle(name: str) -> str:
    """A name as a single key chunk: every ``/`` becomes ``%``; the empty or root name is ``%``."""
    return "%" if name in ("", "/") else name.replace("/", "%")


def check_domain(domain: int) -> int:
    """``domain`` if it is a ROS domain id."""
    if isinstance(domain, bool) or not isinstance(domain, int) or not 0 <= domain <= MAX_DOMAIN:
        raise WireError(f"ROS domain id {domain!r}: expected an integer 0..{MAX_DOMAIN}")
    return domain


def check_topic(topic: str) -> str:
    """``topic`` if it is a fully qualified ROS topic name (``/a/b``: letters, digits, ``_``)."""
    parts = topic.split("/")
    if (not topic.startswith("/") or len(parts) < 2
            or not all(p and (p[0].isalpha() or p[0] == "_") and p.replace("_", "").isalnum() and p.isascii()
                       for p in parts[1:])):
        raise WireError(f"topic {topic!r}: expected a fully qualified ROS name such as /r1/odom")
    return topic


def topic_key(domain: int, topic: str, ros_type: str, type_hash: str) -> str:
    """The Zenoh key expression of ``topic`` (see the module's docstring)."""
    return f"{check_domain(domain)}/{check_topic(topic).strip('/')}/{dds_type_name(ros_type)}/{type_hash}"


@dataclass(frozen=True)
class Qos:
    """The QoS a token announces: reliable or best effort, volatile or transient local, and
    the history depth (KEEP_LAST); deadline, lifespan and liveliness are the defaults."""

    reliable: bool = True
    transient_local: bool = False
    depth: int = 10

    def keyexpr(self) -> str:
        """``rmw_zenoh``'s compact text: a field equal to the default is empty; reliability
        BEST_EFFORT is 2, durability TRANSIENT_LOCAL is 1 (the rmw enums), e.g. ``::,10:,:,:,,``."""
        return f"{'' if self.reliable else 2}:{1 if self.transient_local else ''}:,{self.depth}:,:,:,,"


@dataclass(frozen=True)
class Node:
    """A ROS 2 node as the graph sees it: domain, Zenoh session id, node id, name and namespace."""

    domain: int
    session_id: str
    node_id: int
    name: str
    namespace: str = "/"
    enclave: str = "/"

    def _head(self, entity_id: int, kind: str) -> str:
        return (f"{ADMIN_SPACE}/{check_domain(self.domain)}/{self.session_id}/{self.node_id}/{entity_id}/{kind}/"
                f"{mangle(self.enclave)}/{mangle(self.namespace)}/{mangle(self.name)}")

    def token(self) -> str:
        """The node's liveliness token key expression."""
        return self._head(self.node_id, NODE)

    def entity_token(self, entity_id: int, kind: str, topic: str, ros_type: str, type_hash: str, qos: Qos) -> str:
        """The liveliness token of a publisher (``MP``) or subscription (``MS``) of this node."""
        if kind not in (PUBLISHER, SUBSCRIPTION):
            raise WireError(f"entity kind {kind!r}: expected {PUBLISHER} or {SUBSCRIPTION}")
        return (f"{self._head(entity_id, kind)}/{mangle(check_topic(topic))}/{dds_type_name(ros_type)}/"
                f"{type_hash}/{qos.keyexpr()}")


def gid(token: str) -> bytes:
    """The 16-byte GID of the entity whose liveliness token is ``token`` (XXH3-128)."""
    h = xxhash.xxh3_128_intdigest(token.encode())
    return struct.pack("<QQ", h & 0xFFFF_FFFF_FFFF_FFFF, h >> 64)


@dataclass(frozen=True)
class Attachment:
    """What every publication carries beside its CDR payload."""

    sequence: int
    timestamp_ns: int
    gid: bytes

    def encode(self) -> bytes:
        if len(self.gid) != GID_SIZE:
            raise WireError(f"GID of {len(self.gid)} bytes, expected {GID_SIZE}")
        return _ATTACHMENT.pack(self.sequence, self.timestamp_ns, GID_SIZE) + bytes(self.gid)

    @staticmethod
    def decode(data: bytes) -> Attachment:
        """Parse an attachment; :class:`WireError` saying what is wrong for anything else."""
        if len(data) != ATTACHMENT_SIZE:
            raise WireError(f"attachment of {len(data)} bytes, expected {ATTACHMENT_SIZE}")
        seq, ts, n = _ATTACHMENT.unpack_from(data)
        if n != GID_SIZE:
            raise WireError(f"attachment GID length {n}, expected {GID_SIZE}")
        return Attachment(seq, ts, bytes(data[_ATTACHMENT.size:]))
