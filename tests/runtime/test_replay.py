"""Replay republishes exactly the recorded messages, in order, at the recorded timing."""

from __future__ import annotations

import threading
import time

import pytest

from cekm_swarm.protocol import DEFAULT_KEYS
from cekm_swarm.runtime.bridge import Publishers
from cekm_swarm.runtime.mcap_log import McapRecorder
from cekm_swarm.runtime.replay import replay_log

from runtime_samples import sample_traffic, write_log

K = DEFAULT_KEYS
T = 20.0


def ready_publishers(session, probe_key: str) -> Publishers:
    """BLOCK publishers whose session already knows the subscriber (no message can be lost
    to a subscription still propagating)."""
    pubs = Publishers(session, block=True)
    assert pubs.wait_matching(probe_key, T)
    return pubs


def test_replay_republishes_exactly_the_recorded_messages_in_order(tmp_path, clients, helpers, router):
    path = tmp_path / "run.mcap"
    traffic = sample_traffic(30)
    with McapRecorder(path) as rec:
        for key, data, t in traffic:
            rec.write(key, data, t)
        rec.write_encoded("/view/other", "json", rec._msgpack_schema("x"), b"{}", 0.0)  # not republished
    sub = helpers("sub", router, "cekm/**", str(len(traffic)))
    sub.expect("READY")
    a = clients()
    pubs = ready_publishers(a, traffic[0][0])
    result = replay_log(a, path, rate=None, publishers=pubs)
    lines = sub.lines_until("DONE")
    pubs.close()
    got = [(k, bytes.fromhex(h)) for k, h in (line.split("\t") for line in lines)]
    assert got == [(k, d) for k, d, _ in traffic]
    assert result.published == len(traffic) and result.loops == 1
    assert result.per_key[K.world_clock()] == 30 and "/view/other" not in result.per_key
    assert result.sim_seconds == pytest.approx(29 * 0.128)


def test_replay_follows_recorded_timing_scaled_by_rate(tmp_path, clients):
    path = tmp_path / "run.mcap"
    write_log(path, [(K.world_clock(), b"\x80", t) for t in (0.0, 0.5, 1.0)])
    a, b = clients(), clients()
    arrivals: list[float] = []
    done = threading.Event()

    def on_sample(_):
        arrivals.append(time.monotonic())
        if len(arrivals) == 3:
            done.set()

    sub = b.declare_subscriber(K.world_clock(), on_sample)
    pubs = ready_publishers(a, K.world_clock())
    result = replay_log(a, path, rate=5.0, publishers=pubs)  # 1 s of sim time in 0.2 s
    assert done.wait(T)
    sub.undeclare()
    pubs.close()
    assert 0.19 <= result.wall_seconds < 1.0  # never ahead of the scaled schedule
    assert 0.15 <= arrivals[2] - arrivals[0] < 0.6  # 0.2 s apart, whatever the scheduling noise


def test_replay_loops_and_filters_and_stops(tmp_path, clients):
    path = tmp_path / "run.mcap"
    traffic = sample_traffic(5)
    write_log(path, traffic)
    a, b = clients(), clients()
    got: list[str] = []
    lock = threading.Lock()
    expected = 2 * sum(1 for k, _, _ in traffic if k.startswith("cekm/r1/"))
    enough = threading.Event()

    def on_sample(s):
        with lock:
            got.append(str(s.key_expr))
            if len(got) == expected:
                enough.set()

    sub = b.declare_subscriber("cekm/**", on_sample)
    pubs = ready_publishers(a, K.cmd_wheels("r1"))
    result = replay_log(a, path, rate=None, loop=True, max_loops=2, key_expr="cekm/r1/**", publishers=pubs)
    assert enough.wait(T)
    assert result.loops == 2 and result.published == expected
    assert all(k.startswith("cekm/r1/") for k in got)
    stop = threading.Event()
    stop.set()
    stopped = replay_log(a, path, rate=1.0, loop=True, stop=stop, publishers=pubs)
    assert stopped.stopped and stopped.published == 0
    sub.undeclare()
    pubs.close()
