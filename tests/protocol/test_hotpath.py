"""The hot path agrees with the general decoder and encoder: a map it accepts is one
``decode`` accepts with the same values, every well-formed message is accepted, and
re-stamped bytes equal ``encode``."""

import math

import msgpack
import numpy as np
import pytest

from cekm_swarm.protocol import DEFAULT_KEYS as K
from cekm_swarm.protocol import (MessageError, ObstacleField, SenseRange, SenseTarget, TargetField, WheelCommand,
                                 decode, encode)
from cekm_swarm.protocol.hotpath import (Splice, VectorCache, obstacle_field_values, sense_range_values,
                                        sense_target_values, target_field_values, unpack)

ODD_VALUES = [0, 1, 3, -1, True, False, None, 0.0, -0.0, -1e-300, 1.5, -4.0, 4.0, math.pi, -math.pi, 3.1415927,
              math.nan, math.inf, -math.inf, 1e308, "", "x", "sense/range", "sense/target", "w" * 129, b"\x00",
              [1.0], {"a": 1}, 2**64 - 1]


def mutations(wire: dict):
    """The map itself, then every field replaced by each odd value, removed, and an extra field."""
    yield dict(wire)
    for name in wire:
        for value in ODD_VALUES:
            m = dict(wire)
            m[name] = value
            yield m
        m = dict(wire)
        del m[name]
        yield m
    yield {**wire, "extra": 1}


def general(key, m):
    """decode's verdict on the map: the message, or None when it refuses it."""
    try:
        return decode(key, msgpack.packb(m, use_bin_type=True))
    except MessageError:
        return None


RANGE_MSGS = [SenseRange(0.0, "world", 3, 0.5, 0.3), SenseRange(12.8, "world", 3, -math.pi, None),
              SenseRange(1.024, "w", 3, math.pi, 0.0)]


@pytest.mark.parametrize("msg", RANGE_MSGS)
def test_sense_range_fast_accepts_only_what_decode_accepts_with_the_same_values(msg):
    key = K.sense_range("r1", 3)
    wire = msgpack.unpackb(encode(msg))
    accepted = 0
    for m in mutations(wire):
        fast = sense_range_values(m, 3)
        if fast is None:
            continue
        accepted += 1
        ref = general(key, m)
        assert ref is not None, f"fast path took a map decode refuses: {m}"
        assert fast == (ref.stamp, ref.alpha, ref.d)
        assert all(type(a) is type(b) for a, b in zip(fast, (ref.stamp, ref.alpha, ref.d)))
    assert sense_range_values(wire, 3) == (msg.stamp, msg.alpha, msg.d)
    assert accepted > 1  # the mutations include accepted values, not only refusals


def test_sense_range_fast_path_checks_the_sensor_index():
    wire = msgpack.unpackb(encode(RANGE_MSGS[0]))
    assert sense_range_values(wire, 3) is not None
    assert sense_range_values(wire, 4) is None


TARGET_MSGS = [SenseTarget(0.256, "world", 0.25, 1.5, True), SenseTarget(0.0, "world", 0.0, 0.0, False)]


@pytest.mark.parametrize("msg", TARGET_MSGS)
def test_sense_target_fast_accepts_only_what_decode_accepts_with_the_same_values(msg):
    key = K.sense_target("r1")
    wire = msgpack.unpackb(encode(msg))
    for m in mutations(wire):
        fast = sense_target_values(m)
        if fast is None:
            continue
        ref = general(key, m)
        assert ref is not None, f"fast path took a map decode refuses: {m}"
        assert fast == (ref.stamp, ref.alpha, ref.d, ref.visible)
    assert sense_target_values(wire) == (msg.stamp, msg.alpha, msg.d, msg.visible)


def array_mutations(wire: dict, name: str):
    """Mutations of the array map in field ``name``: each of its entries replaced or removed."""
    arr = wire[name]
    for k in arr:
        for value in ODD_VALUES + [[225.0], [224], [1], "<f4", ">f8", b"<f8", arr["data"][:-8],
                                   np.full(225, np.nan).tobytes(), np.full(225, 1e200).tobytes()]:
            yield {**wire, name: {**arr, k: value}}
        yield {**wire, name: {kk: vv for kk, vv in arr.items() if kk != k}}


FIELD_MSGS = [ObstacleField(0.128, "r1/obstacle-3", 3, 17, np.linspace(0, 1, 225)),
              ObstacleField(0.256, "r1/obstacle-3", 3, None, None)]


@pytest.mark.parametrize("msg", FIELD_MSGS)
def test_obstacle_field_fast_accepts_only_what_decode_accepts_with_the_same_values(msg):
    key = K.field_obstacle("r1", 3)
    wire = msgpack.unpackb(encode(msg))
    vectors = VectorCache()
    maps = list(mutations(wire)) + (list(array_mutations(wire, "b")) if msg.b is not None else [])
    for m in maps + maps:  # twice: with the vector cache cold and warm
        fast = obstacle_field_values(m, 3, vectors)
        if fast is None:
            continue
        ref = general(key, m)
        assert ref is not None, f"fast path took a map decode refuses: {m}"
        assert fast[:3] == (ref.stamp, ref.sender, ref.winner)
        assert (fast[3] is None and ref.b is None) or np.array_equal(fast[3], ref.b)
    assert obstacle_field_values(wire, 3, vectors) is not None
    assert obstacle_field_values(wire, 2, vectors) is None


def test_target_field_fast_accepts_only_what_decode_accepts_with_the_same_values():
    msg = TargetField(0.256, "r1/target", 4, np.linspace(1, 0, 225), 0.25, 1.5)
    key = K.field_target("r1")
    wire = msgpack.unpackb(encode(msg))
    vectors = VectorCache()
    maps = list(mutations(wire)) + list(array_mutations(wire, "a"))
    for m in maps + maps:
        fast = target_field_values(m, vectors)
        if fast is None:
            continue
        ref = general(key, m)
        assert ref is not None, f"fast path took a map decode refuses: {m}"
        assert fast[:3] + fast[4:] == (ref.stamp, ref.sender, ref.winner, ref.alpha, ref.d)
        assert np.array_equal(fast[3], ref.a)
    assert target_field_values(wire, vectors) is not None


def test_vector_cache_stays_bounded():
    vectors = VectorCache(limit=8)
    for k in range(20):
        assert vectors.vector({"dtype": "<f8", "shape": [3], "data": np.full(3, float(k)).tobytes()}) is not None
    assert len(vectors._arrays) <= 8


def test_unpack_gives_none_for_bytes_that_do_not_read():
    assert unpack(b"\xc1") is None
    assert unpack(msgpack.packb({"a": 1}) + b"\x00") is None  # trailing bytes, as decode refuses them
    assert unpack(msgpack.packb({1: 2})) is None  # a non-string map key
    assert unpack(msgpack.packb({"a": 1})) == {"a": 1}


rng = np.random.default_rng(7)
TEMPLATES = [
    ObstacleField(0.0, "r1/obstacle-3", 3, 17, rng.random(225)),
    ObstacleField(5.5, "r1/obstacle-11", 11, None, None),
    TargetField(0.0, "r1/target", 4, rng.random(225), 0.25, 1.5),
    TargetField(0.0, "r1/target", None, None),
    WheelCommand(0.0, "r1/motor", 0.1, -0.2, 7),
    SenseRange(0.0, "world", 0, 0.5, None),
]
STAMPS = [0.0, 1e-9, 0.128, 0.384, 123.456, 1e6, 2.0**60]


@pytest.mark.parametrize("template", TEMPLATES, ids=lambda m: type(m).__name__)
def test_restamped_bytes_equal_encode(template):
    restamp = Splice(template)
    for stamp in STAMPS:
        template.stamp = stamp
        assert restamp(stamp) == encode(template)


def test_spliced_target_field_equals_encode():
    """The target module's case: stamp and the sensed input (alpha, d) change per message."""
    template = TargetField(0.0, "r1/target", 4, rng.random(225), 0.0, 0.0)
    splice = Splice(template, ("d", "stamp", "alpha"))  # any order given: the wire order is used
    assert splice.fields == ("stamp", "alpha", "d")
    for stamp in STAMPS:
        for alpha, d in ((0.0, 0.0), (-math.pi, 1e-9), (0.123456789, 2.5), (math.pi, 1e3)):
            msg = TargetField(stamp, "r1/target", 4, template.a, alpha, d)
            assert splice(stamp, alpha, d) == encode(msg)


def test_splice_refuses_a_field_the_message_has_not():
    with pytest.raises(ValueError, match="no field 'alpha'"):
        Splice(WheelCommand(0.0, "r1/motor", 0.1, -0.2, 7), ("stamp", "alpha"))


def test_vector_cache_stays_bounded_whatever_it_is_sent():
    """4096 distinct vectors of up to 2^20 floats would be gigabytes: the cache holds at
    most max_bytes, and only vectors of the lattice's length when told it."""
    from cekm_swarm.protocol.hotpath import VectorCache

    def wire(x):
        return {"dtype": "<f8", "shape": [len(x)], "data": np.asarray(x, "<f8").tobytes()}

    cache = VectorCache(max_bytes=1 << 20)
    for i in range(200):
        v = cache.vector(wire(np.full(1 << 13, float(i))))  # 64 KB each
        assert v is not None and v[0] == i
        assert cache.bytes <= cache.max_bytes
    assert cache.vector(wire(np.zeros((1 << 17) + 1))) is not None and cache.bytes <= cache.max_bytes
    sized = VectorCache(length=225)
    assert sized.vector(wire(np.zeros(225))) is not None
    assert sized.vector(wire(np.zeros(224))) is None  # the general decoder then decides
