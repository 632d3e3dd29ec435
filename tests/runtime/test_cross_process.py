"""End to end across OS processes: a real in-process router on loopback, peers in helper
processes (tests/runtime/zenoh_helper.py)."""

from __future__ import annotations

import asyncio
import os
import signal
import time

import numpy as np
import pytest

from cekm_swarm.protocol import DEFAULT_KEYS, ObstacleField, SenseRange, WheelCommand, decode, encode
from cekm_swarm.runtime.bridge import AsyncSubscription, LivelinessWatcher, Publishers

pytestmark = pytest.mark.slow  # starts real processes (tests/process_guard.py)

K = DEFAULT_KEYS
T = 20.0
LIVELINESS_BOUND = 2.0  # seconds from SIGKILL to the token's disappearance (measured: a few ms)


def test_publish_to_a_subscriber_in_another_process(clients, helpers, router):
    a = clients()
    sent = []
    for j in range(12):
        sent.append((K.sense_range("r1", j), encode(SenseRange(0.128, "world", j, 0.5, None if j % 2 else 0.1))))
        sent.append((K.field_obstacle("r1", j), encode(ObstacleField(0.128, f"r1/obstacle-{j}", j, j,
                                                                     np.linspace(0, 1, 225)))))
    sub = helpers("sub", router, "cekm/r1/**", str(len(sent)))
    sub.expect("READY")
    with Publishers(a, block=True) as pubs:
        assert pubs.wait_matching(sent[0][0], T)
        for key, data in sent:
            pubs.put(key, data)
        lines = sub.lines_until("DONE")
    got = [(k, bytes.fromhex(h)) for k, h in (line.split("\t") for line in lines)]
    assert got == sent
    assert all(decode(k, d) is not None for k, d in got)


def test_asyncio_subscriber_receives_from_another_process(clients, helpers, router):
    b = clients()
    key = K.cmd_wheels("r2")

    async def run():
        with AsyncSubscription(b, key) as sub:
            pub = helpers("pub", router, key, "30")
            pub.expect("READY")
            got = [decode(r.key, r.payload) for r in [await sub.get(T) for _ in range(30)]]
            pub.expect("DONE")
        assert [m.seq for m in got] == list(range(30))
        assert all(isinstance(m, WheelCommand) and m.sender == "helper" for m in got)

    asyncio.run(run())


def test_liveliness_token_vanishes_soon_after_sigkill(clients, helpers, router):
    b = clients()
    key = K.alive("r1", "obstacle-3")

    async def run():
        with LivelinessWatcher(b, K.alive_all()) as watch:
            holder = helpers("token", router, key)
            holder.expect("READY")
            await watch.wait_for(key, True, T)
            t_kill = time.monotonic()
            os.kill(holder.proc.pid, signal.SIGKILL)
            await watch.wait_for(key, False, LIVELINESS_BOUND)
            gone_after = time.monotonic() - t_kill
        assert key not in watch.alive
        return gone_after

    gone_after = asyncio.run(run())
    assert gone_after < LIVELINESS_BOUND
