"""A node's wire gives exactly what the protocol's decode and encode give, on random
sequences of readings and fields, valid and malformed: it drops what decode refuses, and
counts it."""

from __future__ import annotations

import numpy as np

from cekm_swarm.node.wire import Decoder, Encoder
from cekm_swarm.protocol import DEFAULT_KEYS as K
from cekm_swarm.protocol import (
    DropCounter,
    KeyKind,
    ObstacleField,
    SenseRange,
    SenseTarget,
    TargetField,
    decode,
    encode,
)
from cekm_swarm.ticks import tick_time

RNG = np.random.default_rng(7)
TABLE = RNG.random((5, 9))
TABLE.flags.writeable = False
ROWS = tuple(TABLE[s] for s in range(5))


def samples(n: int):
    for _ in range(n):
        t = tick_time(int(RNG.integers(0, 500)))
        j = int(RNG.integers(0, 12))
        s = int(RNG.integers(0, 5))
        yield (
            K.sense_range("r1", j),
            KeyKind.SENSE_RANGE,
            encode(SenseRange(t, "world", j, 0.5, None if s == 0 else 0.1 * s)),
        )
        yield K.field_obstacle("r1", j), KeyKind.FIELD_OBSTACLE, encode(
            ObstacleField(t, f"r1/obstacle-{j}", j, None if s == 0 else s, None if s == 0 else ROWS[s]))
        yield K.field_target("r1"), KeyKind.FIELD_TARGET, encode(TargetField(t, "r1/target", s, ROWS[s], -0.3, 0.2))
        yield K.sense_target("r1"), KeyKind.SENSE_TARGET, encode(SenseTarget(t, "world", 0.1, 0.2, bool(s % 2)))
        yield "cekm/r1/avoid/x", KeyKind.FIELD_OBSTACLE, encode(ObstacleField(t, "r1/x", 0, s, ROWS[s]))


def test_the_decoder_gives_what_decode_gives_and_drops_what_it_drops():
    drops = DropCounter("t")
    dec = Decoder(K, drops)
    for key, kind, payload in samples(200):
        got = dec.decode(key, kind, payload)
        assert type(got) is type(decode(key, payload, expect=kind)) and got == decode(key, payload, expect=kind)
        for bad in (payload[:-1], payload.replace(b"world", b"wrld!"), b"\x00"):
            try:
                want = decode(key, bad, expect=kind)
            except Exception:
                want = None
            before = drops.total
            got = dec.decode(key, kind, bad)
            assert (got is None and drops.total == before + 1) if want is None else got == want
    # a sensor index that is not the key's is refused as decode refuses it
    wrong = encode(SenseRange(0.0, "world", 4, 0.5, 0.1))
    assert dec.decode(K.sense_range("r1", 3), KeyKind.SENSE_RANGE, wrong) is None


def test_the_encoder_gives_what_encode_gives_for_every_sequence():
    enc = Encoder()
    for k in range(2000):
        t = tick_time(k)
        s = int(RNG.integers(0, 5))
        j = int(RNG.integers(0, 3))
        for msg in (ObstacleField(t, f"r1/obstacle-{j}", j, s, ROWS[s]), ObstacleField(t, "r1/o", j, None, None),
                    TargetField(t, "r1/target", s, ROWS[s], 0.1 * j, 0.2),
                    ObstacleField(t, "r1/w", j, s, RNG.random(9))):  # a fresh writeable array: never spliced
            assert enc(msg) == encode(msg)
