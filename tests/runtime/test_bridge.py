"""The asyncio bridge, publishers and liveliness against a real in-process router."""

from __future__ import annotations

import asyncio

import numpy as np
import pytest

from cekm_swarm.protocol import DEFAULT_KEYS, DropCounter, TargetField, WheelCommand, decode, encode
from cekm_swarm.runtime.bridge import (
    AsyncSubscription,
    InlineSubscription,
    LatestValues,
    LivelinessWatcher,
    Publishers,
    declare_alive,
    ring_subscriber,
    wait_matching_async,
)

K = DEFAULT_KEYS
T = 10.0  # generous timeout for every wait


def cmd(i: int) -> WheelCommand:
    return WheelCommand(0.1 * i, "r1/motor", 0.001 * i, -0.001 * i, i)


def test_async_subscription_delivers_in_order_with_msgpack_label(clients):
    a, b = clients(), clients()
    key = K.cmd_wheels("r1")

    async def run():
        with AsyncSubscription(b, "cekm/**") as sub, Publishers(a, block=True) as pubs:
            assert await wait_matching_async(pubs.publisher(key), T)
            for i in range(50):
                pubs.send(key, cmd(i))
            got = [await sub.get(T) for _ in range(50)]
        assert [decode(r.key, r.payload) for r in got] == [cmd(i) for i in range(50)]
        assert {r.key for r in got} == {key} and {r.kind for r in got} == {"put"}
        assert {r.encoding for r in got} == {"application/msgpack"}
        assert all(x.at <= y.at for x, y in zip(got, got[1:], strict=False))

    asyncio.run(run())


def test_async_iteration_and_bounded_queue_keeps_newest(clients):
    a, b = clients(), clients()
    key = K.cmd_wheels("r1")

    async def run():
        loop = asyncio.get_running_loop()
        with AsyncSubscription(b, key, maxsize=3) as sub, Publishers(a, block=True) as pubs:
            assert await wait_matching_async(pubs.publisher(key), T)
            for i in range(10):
                pubs.send(key, cmd(i))
            pubs.send(key, cmd(99))
            deadline = loop.time() + T
            while sub.dropped + sub.pending() < 11:  # every sample handed over to the loop
                assert loop.time() < deadline
                await asyncio.sleep(0.001)
            seqs = []
            async for rec in sub:
                seqs.append(decode(rec.key, rec.payload).seq)
                if len(seqs) == 3:
                    break
        assert seqs == [8, 9, 99] and sub.dropped == 8 and sub.get_nowait() is None

    asyncio.run(run())


def test_latest_values_keep_newest_per_key(clients):
    a, b = clients(), clients()
    keys = [K.field_obstacle("r1", j) for j in range(3)]

    async def run():
        with LatestValues(b, "cekm/r1/field/obstacle/*") as latest, Publishers(a, block=True) as pubs:
            assert await wait_matching_async(pubs.publisher(keys[0]), T)
            for rnd in range(5):
                for j, key in enumerate(keys):
                    from cekm_swarm.protocol import ObstacleField

                    pubs.send(key, ObstacleField(rnd * 0.128, f"r1/obstacle-{j}", j, rnd, np.full(225, float(rnd))))
            dirty: set[str] = set()
            while latest.updates < 15:
                dirty |= await latest.wait_updates(T)
            assert dirty == set(keys)
            snap = latest.snapshot()
            assert set(snap) == set(keys)
            for key in keys:
                assert decode(key, snap[key].payload).winner == 4
            latest.forget(keys[0])
            assert latest.get(keys[0]) is None
            with pytest.raises(TimeoutError):
                await latest.wait_updates(0.05)  # nothing new

    asyncio.run(run())


def test_inline_callbacks_keep_their_thread_state(clients):
    """Zenoh's thread keeps one Python thread state across callbacks (``keep_thread_state``):
    a thread-local value set in one callback is still there in the next one on that thread
    (a state made and destroyed per callback would lose it, and cost an mmap per message)."""
    import threading
    import time

    a, b = clients(), clients()
    key = K.cmd_wheels("r1")
    local = threading.local()
    seen: list[tuple[int, int | None]] = []
    done = threading.Event()

    def on(sample) -> None:
        seen.append((threading.get_native_id(), getattr(local, "n", None)))
        local.n = len(seen)
        if len(seen) == 20:
            done.set()

    sub = InlineSubscription(b, key, on, raw=True)
    with Publishers(a, block=True) as pubs:
        assert pubs.wait_matching(key, T)
        for i in range(20):
            pubs.send(key, cmd(i))
            time.sleep(0.002)  # one callback at a time, as a module receives them
        assert done.wait(T)
    sub.close()
    first_on_thread: set[int] = set()
    for tid, before in seen:
        if tid in first_on_thread:
            assert before is not None, "a callback's thread state was made afresh"
        first_on_thread.add(tid)
    assert len(first_on_thread) < len(seen)


def test_ring_subscriber_keeps_only_newest(clients):
    a, b = clients(), clients()
    key = K.field_target("r1")
    sub = ring_subscriber(b, key, capacity=1)
    with Publishers(a, block=True) as pubs:
        assert pubs.wait_matching(key, T)
        for i in range(5):
            pubs.send(key, TargetField(float(i), "r1/target", i, np.ones(5)))
        pubs.send(key, TargetField(9.0, "r1/target", 0, np.zeros(4)))
        import time

        deadline = time.monotonic() + T
        newest = None
        while time.monotonic() < deadline:
            s = sub.try_recv()
            if s is not None:
                newest = decode(key, s.payload.to_bytes())
                if newest.stamp == 9.0:
                    break
            else:
                time.sleep(0.001)
        assert newest is not None and newest.stamp == 9.0
        assert sub.try_recv() is None
    sub.undeclare()


def test_malformed_messages_are_dropped_and_counted_receiver_keeps_running(clients):
    a, b = clients(), clients()
    key = K.cmd_wheels("r1")
    drops = DropCounter("world")

    async def run():
        with AsyncSubscription(b, key) as sub, Publishers(a, block=True) as pubs:
            assert await wait_matching_async(pubs.publisher(key), T)
            pubs.put(key, b"\x93garbage")
            pubs.put(key, encode(cmd(1))[:-2])
            wrong = bytearray(encode(cmd(2)))
            wrong[wrong.index(b"\xa1v") + 2] = 7  # schema version 1 -> 7 (positive fixint)
            pubs.put(key, bytes(wrong))
            pubs.send(key, cmd(3))
            good = []
            for _ in range(4):
                rec = await sub.get(T)
                msg = drops.decode(rec.key, rec.payload)
                if msg is not None:
                    good.append(msg)
        assert good == [cmd(3)] and drops.count(key) == 3 and drops.total == 3

    asyncio.run(run())


def test_liveliness_watcher_sees_appear_and_disappear(clients):
    a, b = clients(), clients()
    key = K.alive("r1", "obstacle-3")

    async def run():
        early = declare_alive(a, K.alive("r1", "motor"))
        with LivelinessWatcher(b, K.alive_all()) as watch:
            await watch.wait_for(K.alive("r1", "motor"), True, T)  # existed before: history
            token = declare_alive(a, key)
            await watch.wait_for(key, True, T)
            assert watch.alive == {key, K.alive("r1", "motor")}
            token.undeclare()
            await watch.wait_for(key, False, T)
            events = []
            while True:
                try:
                    events.append(await watch.next_event(0.01))
                except TimeoutError:
                    break
            assert [(e.key, e.alive) for e in events][-2:] == [(key, True), (key, False)]
            with pytest.raises(TimeoutError):
                await watch.wait_for(key, True, 0.05)
        early.undeclare()

    asyncio.run(run())
