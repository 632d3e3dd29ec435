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
        c = int(rng.integers(15))
        if c == 0:  # not msgpack at all
            payload = [b"", b"\xc1", bytes(rng.integers(0, 256, int(rng.integers(1, 300)), dtype=np.uint8)),
                       _pack(m)[:-3], _pack(m) + b"\x00"][int(rng.integers(5))]
            out.append(Fuzz(key, payload, "not msgpack"))
        elif c == 1:  # msgpack, but not a map
            out.append(Fuzz(key, _pack([1, 2, 3] if i % 3 == 0 else ("x" if i % 3 == 1 else None)), "not a map"))
        elif c == 2:  # wrong, missing or mistyped schema version
            m["v"] = [99, "1", None, 1.0, -1][int(rng.integers(5))]
            if i % 6 == 0:
                del m["v"]
            out.append(Fuzz(key, _pack(m), "schema version"))
        elif c == 3:  # a field missing
            victim = [f for f in m if f not in ("v",)][int(rng.integers(len(m) - 1))]
            del m[victim]
            out.append(Fuzz(key, _pack(m), "missing field"))
        elif c == 4:  # an extra field
            m["extra" if i % 2 else "stamp2"] = 1.0
            out.append(Fuzz(key, _pack(m), "extra field"))
        elif c == 5:  # a field of the wrong type
            f = [f for f in m if f not in ("v",)][int(rng.integers(len(m) - 1))]
            wrong = [x for x in ("text", [1.0], {"a": 1}, b"\x00") if type(x) is not type(m[f])]
            m[f] = wrong[int(rng.integers(len(wrong)))] if f != "kind" else 7
            out.append(Fuzz(key, _pack(m), "wrong type"))
        elif c == 6:  # NaN or inf in a float field (or a vector)
            floats = [f for f, x in m.items() if type(x) is float and f != "stamp"]
            if floats:
                m[floats[int(rng.integers(len(floats)))]] = [math.nan, math.inf, -math.inf][i % 3]
            elif "a" in m or "b" in m:
                name = "a" if "a" in m else "b"
                v = np.full(neurons, 0.1)
                v[int(rng.integers(neurons))] = math.nan
                m[name] = {"dtype": "<f8", "shape": [neurons], "data": v.astype("<f8").tobytes()}
            else:
                m["stamp"] = math.nan
            out.append(Fuzz(key, _pack(m), "non-finite"))
        elif c in (7, 8, 9):  # a well-formed message with a stamp no tick of the run has
            m["stamp"] = bogus_stamps[int(rng.integers(len(bogus_stamps)))]
            out.append(Fuzz(key, _pack(m), "bogus stamp"))
        elif c == 10:  # the kind of another key
            other = keys[int(rng.integers(len(keys)))]
            w = _wire(other, now, sender, neurons, j)
            if w["kind"] == m["kind"]:
                w["kind"] = "sense/nothing"
            out.append(Fuzz(key, _pack(w), "wrong kind"))
        elif c == 11:  # a vector of the wrong length (or shape, or dtype)
            if "a" in m or "b" in m:
                name = "a" if "a" in m else "b"
                length = [10, neurons - 1, neurons + 1, 1000][i % 4]
                v = np.full(length, 0.1).astype("<f8").tobytes()
                bad = i % 3
                if bad == 0:  # a believable vector of the wrong length: only the model's owner can tell
                    m[name] = {"dtype": "<f8", "shape": [length], "data": v}
                    m["stamp"] = now
                    out.append(Fuzz(key, _pack(m), "wrong length", decodes=True))
                    continue
                m[name] = ({"dtype": "<f8", "shape": [length + 1], "data": v} if bad == 1
                           else {"dtype": "<f4", "shape": [length], "data": v})
            else:
                m["index" if "index" in m else "stamp"] = [13, -1, 2 ** 63][i % 3]
            out.append(Fuzz(key, _pack(m), "wrong length"))
        elif c == 12 and i % 2:  # beyond a limit of the decoder: a sender name over 128 characters,
            # a declared vector of more than 2^20 floats, 900 bytes of zeros, a payload of
            # exactly the transport's limit
            if i % 8 == 1 and ("a" in m or "b" in m):
                m["a" if "a" in m else "b"] = {"dtype": "<f8", "shape": [(1 << 20) + 1], "data": bytes(800)}
                out.append(Fuzz(key, _pack(m), "oversized"))
            elif i % 8 in (1, 3):
                out.append(Fuzz(key, bytes(900), "oversized"))
            elif i % 8 == 5:
                m["sender"] = "s" * (129 + i % 600)
                out.append(Fuzz(key, _pack(m), "oversized"))
            else:  # exactly the transport's limit (the message and zeros after it): delivered, and
                # refused by the decoder (trailing bytes)
                payload = _pack(m)
                out.append(Fuzz(key, payload + bytes(MAX_MESSAGE_BYTES - len(payload)), "at the limit"))
        elif c == 12:  # over the transport's limit, on the run's keys and invented ones: the router
            # drops them as they come in, before any process sees them
            size = OVER_LIMIT_SIZES[(i // 2) % len(OVER_LIMIT_SIZES)]
            where = key if i % 3 else f"cekm/fuzz/big{i}"
            payload = _pack(m)
            out.append(Fuzz(where, payload + bytes(size - len(payload)), "over the limit"))
        elif c == 13:  # nested deeply
            x: object = 1
            for _ in range(40):
                x = [x]
            m["deep"] = x
            out.append(Fuzz(key, _pack(m), "nested"))
        else:  # a key invented under the root
            r = robots[int(rng.integers(len(robots)))]
            inv = [f"cekm/fuzz/{i}", f"cekm/{r}/bogus/{i}", f"cekm/{r}/field/nothing{i % 7}",
                   f"cekm/rx{i}/sense/target", f"cekm/{r}/sense/range/{12 + i % 5}", "cekm/world/nothing",
                   f"cekm/{r}/alive/fake", f"cekm/{r}/cmd/wheels/extra"][int(rng.integers(8))]
            out.append(Fuzz(inv, _pack(m), "invented key"))
    return out
