"""One declaration, two checks that must agree: the wire decoder (msgspec, from the
declared types) and the construction check (compiled from the same types) accept the
same values and give the same message, over maps mutated field by field (and inside
vectors and world-state entries); neither ever raises anything but a MessageError."""

from __future__ import annotations

import contextlib
import math
import warnings

import msgpack
import numpy as np
import pytest
from test_wire_format import samples  # tests/protocol is on the path (pytest prepends it)

from cekm_swarm.protocol import DEFAULT_KEYS as K
from cekm_swarm.protocol import (
    MESSAGE_TYPES,
    KeyKind,
    MessageError,
    ObstacleField,
    RobotState,
    SenseRange,
    TargetField,
    WorldState,
    decode,
    encode,
    to_wire,
)
from cekm_swarm.protocol.checks import wire_vector

ODD = [0, 1, 3, -1, True, False, None, 0.0, -0.0, 1.5, -4.0, 4.0, math.pi, -math.pi, 3.1415927, math.nan, math.inf,
       -math.inf, 1e308, "", "x", "w" * 129, b"\x00", [1.0], [1.0, 2.0], [1.0, 2.0, 3.0], [[1, 0.1, 0.2, 0.3]],
       {"a": 1}, {"t1": [0.1, 0.2]}, 2**63 - 1, 2**63, 2**64 - 1, -2**63, 224, 225, 11, 12]


def mutations(wire: dict):
    """Every field of the body replaced by each odd value; inside a vector map and a
    world-state entry, each of their entries too."""
    body = [k for k in wire if k not in ("v", "kind")]
    for name in body:
        for value in ODD:
            yield {**wire, name: value}
        inner = wire[name]
        if isinstance(inner, dict):
            for k, v in inner.items():
                if isinstance(v, dict):  # a world-state entry, a vector map
                    for kk in v:
                        for value in ODD[:24]:
                            yield {**wire, name: {**inner, k: {**v, kk: value}}}
                else:
                    for value in ODD[:24]:
                        yield {**wire, name: {**inner, k: value}}


def built(key: str, kind: KeyKind, wire: dict):
    """The construction check's verdict on a wire map: the message, or None."""
    cls = MESSAGE_TYPES[kind]
    body = {k: v for k, v in wire.items() if k not in ("v", "kind")}
    try:
        for name in cls.__struct_fields__:
            if name in ("a", "b") and body[name] is not None:
                body[name] = wire_vector(body[name], name)  # a vector travels as its map
        msg = cls(**body)
    except MessageError:
        return None
    index = getattr(msg, "index", None)
    if index is not None and (
        index >= K.range_sensors or (kind is not KeyKind.DATA and key.rsplit("/", 1)[-1] != str(index))
    ):
        return None  # the decoder also holds a sensor index to the key's
    return msg


CASES = [(k, m) for k, m in samples()[::4]]


@pytest.mark.parametrize("key, msg", CASES, ids=[f"{type(m).__name__}-{i}" for i, (_, m) in enumerate(CASES)])
def test_the_decoder_and_the_construction_check_agree(key, msg):
    accepted = refused = 0
    for m in mutations(to_wire(msg)):
        try:
            got = decode(key, msgpack.packb(m, use_bin_type=True))
        except MessageError:
            got = None
        want = built(key, msg.KIND, m)
        assert (got is None) == (want is None), (m, got, want)
        if got is not None:
            assert got == want and encode(got) == encode(want)
            accepted += 1
        else:
            refused += 1
    assert accepted and refused  # the mutations hold values of both verdicts


def test_decoded_values_are_normalized_as_built_ones():
    """Ints become floats where a float is declared, arrays are read-only float64, tuples
    the declared tuples: what a node computes on is the same in `cekm run` and a launch."""
    row = np.arange(9.0)
    built = TargetField(np.float64(0.128), "r1/target", np.int64(3), row, 1, 0)
    wire = decode(K.field_target("r1"), encode(built))
    for m in (built, wire):
        assert type(m.stamp) is float and type(m.alpha) is float and type(m.d) is float and type(m.winner) is int
        assert m.a.dtype == np.float64 and not m.a.flags.writeable
    assert built == wire
    assert row.flags.writeable  # the sender's own array is left as it was
    s = WorldState(0.0, "world", {"r1": {"x": 0, "y": 1, "theta": 0, "goal": [1, 2]}}, {}, {})
    r = decode(K.world_state(), encode(s)).robots["r1"]
    assert isinstance(r, RobotState) and r == s.robots["r1"] and r.goal == (1.0, 2.0) and type(r.x) is float


def test_hostile_bytes_raise_only_message_errors():
    rng = np.random.default_rng(3)
    good = [encode(SenseRange(0.128, "world", 3, 0.5, 0.1)), encode(ObstacleField(0.128, "o", 3, 2, np.ones(9)))]
    deep = b"\x81\xa1v" + b"\x91" * 100_000 + b"\x01"  # nested far deeper than any recursion limit
    payloads = [deep, b"", b"\xc1", bytes(900)] + [bytes(rng.integers(0, 256, int(rng.integers(1, 64)), dtype=np.uint8))
                                                   for _ in range(300)]
    for g in good:
        payloads += [g[:i] for i in range(len(g))] + [g[:i] + bytes([b]) + g[i + 1:] for i in range(0, len(g), 7)
                                                      for b in (0x00, 0xc1, 0xff, 0x91, 0xdf)]
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # even with warnings as errors (a huge vector's overflow)
        for key in (K.sense_range("r1", 3), K.field_obstacle("r1", 3), K.world_state(), "cekm/r1/my/own"):
            for p in payloads:
                with contextlib.suppress(MessageError):
                    decode(key, p)


def test_a_patterned_string_check_remembers_what_passed_and_stays_bounded():
    """The strings that passed a patterned check are remembered (a node sees the same keys
    every tick), at most PASSED_MAX of them; a string that failed never is."""
    import msgspec.inspect as mi

    from cekm_swarm.protocol import checks
    from cekm_swarm.protocol.errors import MessageFieldError

    check = checks._str_check(mi.StrType(pattern="^k[0-9]+$"), "a key")
    passed = next(c.cell_contents for c in check.__closure__ if isinstance(c.cell_contents, set))
    for i in range(checks.PASSED_MAX + 5):
        assert check(f"k{i}", "keys[0]") == f"k{i}"
        assert len(passed) <= checks.PASSED_MAX
    assert check("k1", "keys[0]") == "k1" and "k1" in passed
    for _ in range(2):  # refused again: a failure is not remembered
        with pytest.raises(MessageFieldError, match=r"'x1' is not a key"):
            check("x1", "keys[3]")
    assert "x1" not in passed
