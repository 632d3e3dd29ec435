"""The wire format is unchanged: every kind of message encodes to the bytes the protocol
wrote before the messages were declared with msgspec, and those bytes (as logs written
before hold them) decode to the same message.

``wire_v1.msgpack`` holds (key, payload) pairs of :func:`samples`, written by the code
before the change (commit f3c6712):
``PYTHONPATH=<that checkout> python3 tests/protocol/test_wire_format.py --write``.
The samples use only the constructors both versions share.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import msgpack
import numpy as np

from cekm_swarm.protocol import DEFAULT_KEYS as K
from cekm_swarm.protocol import (
    Clock,
    Data,
    ObstacleField,
    SensePose,
    SenseRange,
    SenseTarget,
    SenseTargets,
    Share,
    TargetField,
    TrackingField,
    WheelCommand,
    WorldState,
    decode,
    encode,
)

FIXTURE = Path(__file__).with_name("wire_v1.msgpack")


def samples() -> list[tuple[str, object]]:
    """Messages of every kind, with the values a run sends and the edges of each field."""
    rng = np.random.default_rng(22)
    a = rng.random(225)
    out: list[tuple[str, object]] = []
    for t in (0.0, 0.128, 12.8, 1234.56, 9999999.0):
        out.append((K.sense_target("r1"), SenseTarget(t, "world", float(rng.uniform(-math.pi, math.pi)), 0.5, True)))
        out.append((K.sense_target("r1"), SenseTarget(t, "world", 0.0, 0.0, False)))
        for j in (0, 5, 11):
            out.append(
                (K.sense_range("r1", j), SenseRange(t, "world", j, -math.pi + j * 0.5, None if j == 5 else 0.0851))
            )
        out.append((K.field_target("r2"), TargetField(t, "r2/target", 112, a, 0.3, 1.2)))
        out.append((K.field_target("r2"), TargetField(t, "r2/target", 0, a[:9])))
        out.append((K.field_target("r2"), TargetField(t, "r2/target", None, None, -1.0, 0.0, at_goal=True)))
        out.append((K.field_target("r2"), TargetField(t, "r2/target", None, None)))
        out.append((K.field_obstacle("r1", 3), ObstacleField(t, "r1/obstacle-3", 3, 224, -a)))
        out.append((K.field_obstacle("r1", 3), ObstacleField(t, "r1/obstacle-3", 3, None, None)))
        for seq in (0, 1, 127, 128, 65536, 2**32, 2**63 - 1):
            out.append((K.cmd_wheels("r1"), WheelCommand(t, "r1/motor", 0.15625, -0.0, seq)))
        out.append((K.share("r3"), Share(t, "r3/share", (0.1, -0.2, 3.0), {"t1": (1.0, 2.0), "t2": (0.0, -1.5)})))
        out.append((K.share("r3"), Share(t, "r3/share", (0.0, 0.0, 0.0), {})))
        out.append((K.sense_pose("r3"), SensePose(t, "world", (1.0, 2.0, -0.5))))
        out.append((K.sense_targets("r3"), SenseTargets(t, "world", {"t1": (0.3, 0.2), "t9": (-3.0, 0.0)})))
        out.append((K.field_tracking("r3"), TrackingField(t, "r3/target", a, a[::-1].copy(),
                                                          ((3, 0.1, 0.5, 1.0), (200, -2.0, 0.0, 0.25)),
                                                          {"t1": 1.0, "t2": 0.25}, False)))
        robots = {f"r{i}": {"x": float(rng.uniform(0, 2)), "y": float(rng.uniform(0, 2)),
                            "theta": float(rng.uniform(-math.pi, math.pi)), "v_l": 0.15625, "v_r": -0.1,
                            "v_l_exec": 0.1503, "v_r_exec": -0.1002, "in_contact": i == 2,
                            "goal": [1.8, 0.5] if i != 3 else None} for i in (1, 2, 3)}
        out.append((K.world_state(), WorldState(t, "world", robots, {"t1": {"x": 1.0, "y": 2.0}},
                                                {"box": {"x": 0.5, "y": 0.25, "theta": 7.5}})))
        out.append((K.world_clock(), Clock(t, "world", round(t / 0.128))))
        out.append(("cekm/r1/fusion/avoid", Data(t, "r1/fusion", {"v": [0.1, -0.2], "ok": True, "none": None,
                                                                  "n": -3, "big": 2**64 - 1, "s": "x" * 40})))
    return out


def test_every_message_encodes_to_the_bytes_written_before():
    pairs = msgpack.unpackb(FIXTURE.read_bytes(), raw=False)
    now = samples()
    assert len(pairs) == len(now)
    for (key, payload), (k, msg) in zip(pairs, now, strict=True):
        assert key == k
        assert encode(msg) == payload, (key, msg)


def test_bytes_written_before_decode_to_the_same_message_and_back():
    for key, payload in msgpack.unpackb(FIXTURE.read_bytes(), raw=False):
        msg = decode(key, payload)
        assert encode(msg) == payload


def test_encode_is_msgpack_of_the_documented_wire_map():
    """Independently of the fixture: the bytes are ``msgpack.packb`` of the map the module
    docstring documents (envelope, then the fields in order, arrays as dtype/shape/data)."""
    for key, msg in samples():
        wire = {"v": 1, "kind": msg.KIND.value}
        for name in msg.__struct_fields__:
            v = getattr(msg, name)
            if isinstance(v, np.ndarray):
                v = {"dtype": "<f8", "shape": [v.shape[0]], "data": v.tobytes()}
            elif isinstance(v, dict):
                v = {k: (dict(e.items()) if hasattr(e, "items") else e) for k, e in v.items()}
            wire[name] = v
        assert encode(msg) == msgpack.packb(wire, use_bin_type=True), key


if __name__ == "__main__" and sys.argv[1:] == ["--write"]:
    FIXTURE.write_bytes(msgpack.packb([(k, encode(m)) for k, m in samples()], use_bin_type=True))
    print(f"wrote {FIXTURE} ({len(samples())} messages)")
