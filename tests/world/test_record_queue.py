"""The world's recording queue (a Zenoh ring channel of RECORD_QUEUE samples, drained once
a tick): a drain that finds it full says so, once, in the world's log."""

from __future__ import annotations

import logging
from types import SimpleNamespace

import zenoh

from world.publisher import TickPublisher
from world.recorder import RECORD_QUEUE


class Ring:
    """Stands in for the record subscription: ``n`` deletes waiting (nothing to write)."""

    def __init__(self, n: int) -> None:
        self.n = n

    def try_recv(self):
        if self.n == 0:
            return None
        self.n -= 1
        return SimpleNamespace(kind=zenoh.SampleKind.DELETE)


def drain(pub: TickPublisher, n: int) -> None:
    pub.record_sub = Ring(n)
    pub.drain(1.0)


def test_a_full_recording_queue_is_reported_once(caplog):
    pub = TickPublisher.__new__(TickPublisher)
    pub.record_filter = SimpleNamespace(check=None)
    pub.record_full = 0
    with caplog.at_level(logging.WARNING, logger="world.publisher"):
        drain(pub, RECORD_QUEUE - 1)
        assert pub.record_full == 0 and not caplog.records
        drain(pub, RECORD_QUEUE)
        drain(pub, RECORD_QUEUE)
    assert pub.record_full == 2
    assert len(caplog.records) == 1 and "recording queue was full" in caplog.records[0].getMessage()
