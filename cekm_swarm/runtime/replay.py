"""Replay: republish a recorded MCAP log onto Zenoh at the recorded timing.

Only the key-space channels (message encoding ``msgpack``) are republished, each on its
recorded key with its recorded bytes, in log-time order. The gap between two messages is
their sim-time gap divided by ``rate``; ``rate=None`` publishes as fast as possible.
Monitors and tools attach to a replay exactly as to a live run.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import zenoh

from .bridge import Publishers
from .mcap_log import MSGPACK, LoggedMessage, read_messages


@dataclass
class ReplayResult:
    """Counts of a replay: messages published (in all loops), loops completed, per key."""

    published: int = 0
    loops: int = 0
    per_key: dict[str, int] = field(default_factory=dict)
    wall_seconds: float = 0.0
    sim_seconds: float = 0.0
    stopped: bool = False


def _selector(key_expr: str | None) -> Callable[[str], bool]:
    if key_expr is None:
        return lambda key: True
    ke = zenoh.KeyExpr(key_expr)
    cache: dict[str, bool] = {}

    def wanted(key: str) -> bool:
        hit = cache.get(key)
        if hit is None:
            hit = cache[key] = ke.intersects(zenoh.KeyExpr(key))
        return hit

    return wanted


def replay_log(session: zenoh.Session, path: str | Path, *, rate: float | None = 1.0, loop: bool = False,
               max_loops: int | None = None, key_expr: str | None = None, stop: threading.Event | None = None,
               publishers: Publishers | None = None,
               on_publish: Callable[[LoggedMessage], None] | None = None) -> ReplayResult:
    """Republish the msgpack channels of the log at ``path`` onto ``session``.

    ``rate`` scales time (2.0 = twice as fast; None or <= 0 = as fast as possible);
    ``loop`` starts over at the end until ``stop`` is set or ``max_loops`` loops are done;
    ``key_expr`` keeps only matching keys. Publishing uses congestion control BLOCK, so a
    slow subscriber slows the replay instead of losing messages. Returns the counts."""
    fast = rate is None or rate <= 0
    wanted = _selector(key_expr)
    own = publishers is None
    pubs = publishers or Publishers(session, block=True)
    result = ReplayResult()
    t_start = time.perf_counter()
    try:
        while True:
            first_ns: int | None = None
            last_ns = 0
            loop_t0 = time.perf_counter()
            published_before = result.published
            for m in read_messages(path, encodings=(MSGPACK,)):
                if not wanted(m.topic):
                    continue
                if stop is not None and stop.is_set():
                    result.stopped = True
                    return result
                if first_ns is None:
                    first_ns = m.log_time
                last_ns = m.log_time
                if not fast:
                    due = loop_t0 + (m.log_time - first_ns) / 1e9 / rate  # type: ignore[operator]
                    delay = due - time.perf_counter()
                    if delay > 0:
                        if stop is not None:
                            if stop.wait(delay):
                                result.stopped = True
                                return result
                        else:
                            time.sleep(delay)
                pubs.put(m.topic, m.data)
                result.published += 1
                result.per_key[m.topic] = result.per_key.get(m.topic, 0) + 1
                if on_publish is not None:
                    on_publish(m)
            result.loops += 1
            if first_ns is not None:
                result.sim_seconds += (last_ns - first_ns) / 1e9
            if not loop or result.published == published_before:
                return result
            if max_loops is not None and result.loops >= max_loops:
                return result
    finally:
        result.wall_seconds = time.perf_counter() - t_start
        if own:
            pubs.close()
