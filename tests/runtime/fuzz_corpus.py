"""Malformed messages for the fuzz tests (tests/runtime/test_fuzz.py): every class of the
hostile-input issue, on every key of a running robot and of the world, plus invented keys
under the root. Seeded, so a run's corpus is reproducible.

Each message is ``Fuzz(key, payload, cls, decodes)``: ``decodes`` is True only for the one
class a receiver without the model cannot refuse on its own (a field vector of the wrong
length with a believable stamp): the world may record it, the motor (which knows the
lattice) must drop it. Every other message is refused by every receiver: by the decoder,
or by the stamp check (a stamp far from any tick the run is at, or not on the tick grid).
None is a well-formed message for a tick the run is at: that one an in-key-space peer can
always send (docs/robustness.md says what that leaves to access control).

Messages of the class "over the limit" (payload over the transport's MAX_MESSAGE_BYTES:
just over it, 48 KB, 100 KB, 1 MB) never reach a receiver: the router drops them as they
come in (:attr:`Fuzz.over_limit`). One exactly at the limit reaches every subscriber and
is refused by its decoder like any other.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import msgpack
import numpy as np

from cekm_swarm.protocol import (
    DEFAULT_KEYS,
    Clock,
    ObstacleField,
    SenseRange,
    SenseTarget,
    TargetField,
    WheelCommand,
    WorldState,
)
from cekm_swarm.protocol.messages import to_wire
from cekm_swarm.runtime.config import MAX_MESSAGE_BYTES
from cekm_swarm.ticks import TICK_S, tick_time

K = DEFAULT_KEYS


@dataclass(frozen=True)
class Fuzz:
    key: str
    payload: bytes
    cls: str
    decodes: bool = False

    @property
    def over_limit(self) -> bool:
        """Over the transport's limit: dropped by the router, reaching no process."""
        return len(self.payload) > MAX_MESSAGE_BYTES


OVER_LIMIT_SIZES = (MAX_MESSAGE_BYTES + 1, MAX_MESSAGE_BYTES + 1000, 48 * 1024, 100 * 1024, 1 << 20)
"""Payload sizes of the class "over the limit": just over it, under Zenoh's 64 KB batch
(one piece), over it (in fragments: 2 and 17 of them)."""


def _pack(m) -> bytes:
    return msgpack.packb(m, use_bin_type=True)


def _wire(key: str, stamp: float, sender: str, n: int, j: int = 0) -> dict:
    """The wire map of a well-formed message for ``key`` at ``stamp``."""
    v = np.full(n, 0.1)
    if "/sense/target" in key:
        m = SenseTarget(stamp, sender, 0.3, 0.5, True)
    elif "/sense/range/" in key:
        m = SenseRange(stamp, sender, j, 0.5, 0.1)
    elif "/field/target" in key:
        m = TargetField(stamp, sender, 3, v, 0.3, 0.5)
    elif "/field/obstacle/" in key:
        m = ObstacleField(stamp, sender, j, 3, v)
    elif "/cmd/wheels" in key:
        m = WheelCommand(stamp, sender, 0.01, 0.02, 7)
    elif key.endswith("/world/clock"):
        m = Clock(stamp, sender, int(round(stamp / TICK_S)))
    else:
        m = WorldState(stamp, sender, {"r1": {"x": 0.5, "y": 0.5, "theta": 0.0}}, {}, {})
    return to_wire(m)


def robot_keys(robot: str, sensors: int = 12) -> list[str]:
    """Every key a robot's processes listen on (sense, field, command)."""
    keys = [K.sense_target(robot), K.field_target(robot), K.cmd_wheels(robot)]
    keys += [K.sense_range(robot, j) for j in range(sensors)] + [K.field_obstacle(robot, j) for j in range(sensors)]
    return keys


@dataclass
class _Draw:
    """One message to spoil: its index, key, well-formed wire map and what the spoilers share."""

    rng: np.random.Generator
    i: int
    key: str
    m: dict
    keys: list[str]
    robots: list[str]
    neurons: int
    now: float
    sender: str
    j: int
    bogus_stamps: list[float]


def _not_msgpack(d: _Draw) -> Fuzz:
    rng, m = d.rng, d.m
    payload = [b"", b"\xc1", bytes(rng.integers(0, 256, int(rng.integers(1, 300)), dtype=np.uint8)),
               _pack(m)[:-3], _pack(m) + b"\x00"][int(rng.integers(5))]
    return Fuzz(d.key, payload, "not msgpack")


def _not_a_map(d: _Draw) -> Fuzz:
    i = d.i
    return Fuzz(d.key, _pack([1, 2, 3] if i % 3 == 0 else ("x" if i % 3 == 1 else None)), "not a map")


def _schema_version(d: _Draw) -> Fuzz:
    """Wrong, missing or mistyped."""
    d.m["v"] = [99, "1", None, 1.0, -1][int(d.rng.integers(5))]
    if d.i % 6 == 0:
        del d.m["v"]
    return Fuzz(d.key, _pack(d.m), "schema version")


def _missing_field(d: _Draw) -> Fuzz:
    m = d.m
    victim = [f for f in m if f not in ("v",)][int(d.rng.integers(len(m) - 1))]
    del m[victim]
    return Fuzz(d.key, _pack(m), "missing field")


def _extra_field(d: _Draw) -> Fuzz:
    d.m["extra" if d.i % 2 else "stamp2"] = 1.0
    return Fuzz(d.key, _pack(d.m), "extra field")


def _wrong_type(d: _Draw) -> Fuzz:
    m, rng = d.m, d.rng
    f = [f for f in m if f not in ("v",)][int(rng.integers(len(m) - 1))]
    wrong = [x for x in ("text", [1.0], {"a": 1}, b"\x00") if type(x) is not type(m[f])]
    m[f] = wrong[int(rng.integers(len(wrong)))] if f != "kind" else 7
    return Fuzz(d.key, _pack(m), "wrong type")


def _non_finite(d: _Draw) -> Fuzz:
    """NaN or inf in a float field (or a vector)."""
    m, rng, neurons = d.m, d.rng, d.neurons
    floats = [f for f, x in m.items() if type(x) is float and f != "stamp"]
    if floats:
        m[floats[int(rng.integers(len(floats)))]] = [math.nan, math.inf, -math.inf][d.i % 3]
    elif "a" in m or "b" in m:
        name = "a" if "a" in m else "b"
        v = np.full(neurons, 0.1)
        v[int(rng.integers(neurons))] = math.nan
        m[name] = {"dtype": "<f8", "shape": [neurons], "data": v.astype("<f8").tobytes()}
    else:
        m["stamp"] = math.nan
    return Fuzz(d.key, _pack(m), "non-finite")


def _bogus_stamp(d: _Draw) -> Fuzz:
    """A well-formed message with a stamp no tick of the run has."""
    d.m["stamp"] = d.bogus_stamps[int(d.rng.integers(len(d.bogus_stamps)))]
    return Fuzz(d.key, _pack(d.m), "bogus stamp")


def _wrong_kind(d: _Draw) -> Fuzz:
    """The kind of another key."""
    other = d.keys[int(d.rng.integers(len(d.keys)))]
    w = _wire(other, d.now, d.sender, d.neurons, d.j)
    if w["kind"] == d.m["kind"]:
        w["kind"] = "sense/nothing"
    return Fuzz(d.key, _pack(w), "wrong kind")


def _wrong_length(d: _Draw) -> Fuzz:
    """A vector of the wrong length (or shape, or dtype)."""
    m, i, neurons = d.m, d.i, d.neurons
    if "a" in m or "b" in m:
        name = "a" if "a" in m else "b"
        length = [10, neurons - 1, neurons + 1, 1000][i % 4]
        v = np.full(length, 0.1).astype("<f8").tobytes()
        bad = i % 3
        if bad == 0:  # a believable vector of the wrong length: only the model's owner can tell
            m[name] = {"dtype": "<f8", "shape": [length], "data": v}
            m["stamp"] = d.now
            return Fuzz(d.key, _pack(m), "wrong length", decodes=True)
        m[name] = ({"dtype": "<f8", "shape": [length + 1], "data": v} if bad == 1
                   else {"dtype": "<f4", "shape": [length], "data": v})
    else:
        m["index" if "index" in m else "stamp"] = [13, -1, 2 ** 63][i % 3]
    return Fuzz(d.key, _pack(m), "wrong length")


def _beyond_a_decoder_limit(d: _Draw) -> Fuzz:
    """A sender name over 128 characters, a declared vector of more than 2^20 floats, 900
    bytes of zeros, a payload of exactly the transport's limit."""
    m, i, key = d.m, d.i, d.key
    if i % 8 == 1 and ("a" in m or "b" in m):
        m["a" if "a" in m else "b"] = {"dtype": "<f8", "shape": [(1 << 20) + 1], "data": bytes(800)}
        return Fuzz(key, _pack(m), "oversized")
    if i % 8 in (1, 3):
        return Fuzz(key, bytes(900), "oversized")
    if i % 8 == 5:
        m["sender"] = "s" * (129 + i % 600)
        return Fuzz(key, _pack(m), "oversized")
    # exactly the transport's limit (the message and zeros after it): delivered, and refused
    # by the decoder (trailing bytes)
    payload = _pack(m)
    return Fuzz(key, payload + bytes(MAX_MESSAGE_BYTES - len(payload)), "at the limit")


def _over_the_transport_limit(d: _Draw) -> Fuzz:
    """On the run's keys and invented ones: the router drops them as they come in, before any
    process sees them."""
    i = d.i
    size = OVER_LIMIT_SIZES[(i // 2) % len(OVER_LIMIT_SIZES)]
    where = d.key if i % 3 else f"cekm/fuzz/big{i}"
    payload = _pack(d.m)
    return Fuzz(where, payload + bytes(size - len(payload)), "over the limit")


def _too_large(d: _Draw) -> Fuzz:
    return _beyond_a_decoder_limit(d) if d.i % 2 else _over_the_transport_limit(d)


def _nested(d: _Draw) -> Fuzz:
    x: object = 1
    for _ in range(40):
        x = [x]
    d.m["deep"] = x
    return Fuzz(d.key, _pack(d.m), "nested")


def _invented_key(d: _Draw) -> Fuzz:
    """A key invented under the root."""
    i, rng = d.i, d.rng
    r = d.robots[int(rng.integers(len(d.robots)))]
    inv = [f"cekm/fuzz/{i}", f"cekm/{r}/bogus/{i}", f"cekm/{r}/field/nothing{i % 7}",
           f"cekm/rx{i}/sense/target", f"cekm/{r}/sense/range/{12 + i % 5}", "cekm/world/nothing",
           f"cekm/{r}/alive/fake", f"cekm/{r}/cmd/wheels/extra"][int(rng.integers(8))]
    return Fuzz(inv, _pack(d.m), "invented key")


SPOILERS = (_not_msgpack, _not_a_map, _schema_version, _missing_field, _extra_field, _wrong_type, _non_finite,
            _bogus_stamp, _bogus_stamp, _bogus_stamp, _wrong_kind, _wrong_length, _too_large, _nested,
            _invented_key)
"""Each way a message is spoiled, drawn uniformly (the bogus stamp three times as often)."""


def make_corpus(rng: np.random.Generator, n: int, tick: int, robots: list[str], neurons: int,
                start: int = 0) -> list[Fuzz]:
    """``n`` malformed messages for a run at tick ``tick`` (>= 20: then a stamp of the run's
    first ticks is outside every receiver's window)."""
    assert tick >= 20
    keys = [k for r in robots for k in robot_keys(r)] + [K.world_state(), K.world_clock()]
    now = tick_time(tick)
    bogus_stamps = [1e18, 1e300, 1e9, 1e7 + 1.0, -1.0, -TICK_S, -1e-9, math.nan, math.inf, -math.inf,
                    0.0, tick_time(max(0, tick - 20)), tick_time(tick + 1000), now + 0.05, now - 0.001]
    out: list[Fuzz] = []
    for i in range(start, start + n):
        key = keys[int(rng.integers(len(keys)))]
        j = int(key.rsplit("/", 1)[1]) if key.rsplit("/", 1)[1].isdigit() else 0
        sender = f"fuzz-{i}"
        m = _wire(key, now, sender, neurons, j)
        spoil = SPOILERS[int(rng.integers(len(SPOILERS)))]
        out.append(spoil(_Draw(rng, i, key, m, keys, robots, neurons, now, sender, j, bogus_stamps)))
    return out
