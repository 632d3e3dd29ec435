"""Topic tools in the manner of ``ros2 topic``: list keys, echo messages, measure rates.

Pure functions compute the statistics; thin synchronous shells attach a Zenoh
subscriber whose callback only records the arrival (thread-safe), so tools never block
Zenoh's threads.
"""

from __future__ import annotations

import math
import queue
import threading
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import zenoh

from cekm_swarm.protocol import DEFAULT_KEYS, KeySpace, MessageError, decode, summary

from .bridge import Received


@dataclass(frozen=True, slots=True)
class HzStats:
    """Rate statistics of one key over a window of arrival times (seconds, monotonic)."""

    key: str
    count: int
    rate: float
    mean_period: float
    min_period: float
    max_period: float
    std_period: float
    age: float


def hz_stats(key: str, times: Sequence[float], now: float) -> HzStats:
    """Rate (Hz), period statistics (s) and age of the newest arrival (s) from arrival times."""
    n = len(times)
    age = now - times[-1] if n else math.inf
    if n < 2:
        return HzStats(key, n, 0.0, math.nan, math.nan, math.nan, math.nan, age)
    periods = [b - a for a, b in zip(times, times[1:])]
    mean = (times[-1] - times[0]) / (n - 1)
    var = sum((p - mean) ** 2 for p in periods) / len(periods)
    return HzStats(key, n, 1.0 / mean if mean > 0 else math.inf, mean, min(periods), max(periods), math.sqrt(var), age)


def format_hz(stats: Sequence[HzStats]) -> str:
    """A table of rate statistics, one key per line."""
    if not stats:
        return "no messages"
    w = max(len(s.key) for s in stats)
    lines = [f"{'key':<{w}}  {'count':>6} {'rate Hz':>9} {'period ms':>10} {'min ms':>8} {'max ms':>8} "
             f"{'std ms':>8} {'age s':>7}"]
    for s in stats:
        lines.append(f"{s.key:<{w}}  {s.count:>6} {s.rate:>9.2f} {s.mean_period * 1e3:>10.2f} "
                     f"{s.min_period * 1e3:>8.2f} {s.max_period * 1e3:>8.2f} {s.std_period * 1e3:>8.2f} {s.age:>7.2f}")
    return "\n".join(lines)


class ArrivalLog:
    """Arrival times (and bytes) per key on ``key_expr``, the newest ``window`` seconds kept.

    The Zenoh callback appends under a lock and returns; readers take snapshots."""

    def __init__(self, session: zenoh.Session, key_expr: str, window: float = 10.0) -> None:
        self.key_expr = key_expr
        self.window = window
        self._lock = threading.Lock()
        self._times: dict[str, deque[float]] = {}
        self._counts: dict[str, int] = {}
        self._bytes: dict[str, int] = {}
        self._sub = session.declare_subscriber(key_expr, self._on_sample)

    def _on_sample(self, sample: zenoh.Sample) -> None:
        now = time.monotonic()
        key = str(sample.key_expr)
        size = len(sample.payload)
        with self._lock:
            q = self._times.get(key)
            if q is None:
                q = self._times[key] = deque()
                self._counts[key] = 0
                self._bytes[key] = 0
            q.append(now)
            self._counts[key] += 1
            self._bytes[key] += size
            while q and now - q[0] > self.window:
                q.popleft()

    def totals(self) -> dict[str, tuple[int, int]]:
        """{key: (messages, bytes)} since the log started."""
        with self._lock:
            return {k: (self._counts[k], self._bytes[k]) for k in sorted(self._counts)}

    def stats(self, now: float | None = None) -> list[HzStats]:
        """Rate statistics of every key seen, over the window, sorted by key."""
        now = time.monotonic() if now is None else now
        with self._lock:
            snap = {k: [t for t in q if now - t <= self.window] for k, q in self._times.items()}
            last = {k: q[-1] for k, q in self._times.items() if q}
        out = []
        for k in sorted(snap):
            s = hz_stats(k, snap[k], now)
            if not snap[k] and k in last:
                s = HzStats(k, 0, 0.0, math.nan, math.nan, math.nan, math.nan, now - last[k])
            out.append(s)
        return out

    def close(self) -> None:
        """Undeclare the subscriber (idempotent)."""
        if self._sub is not None:
            self._sub.undeclare()
            self._sub = None

    def __enter__(self) -> "ArrivalLog":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def topic_list(session: zenoh.Session, key_expr: str, window: float,
               stop: threading.Event | None = None) -> dict[str, tuple[int, int]]:
    """Keys seen on ``key_expr`` during ``window`` seconds: {key: (messages, bytes)}."""
    with ArrivalLog(session, key_expr, window=max(window, 1.0)) as log:
        (stop or threading.Event()).wait(window)
        return log.totals()


def alive_tokens(session: zenoh.Session, key_expr: str, timeout: float = 1.0) -> list[str]:
    """Liveliness tokens alive now on ``key_expr`` (a liveliness query)."""
    replies = session.liveliness().get(key_expr, timeout=timeout)
    keys = set()
    for reply in replies:
        if reply.ok is not None:
            keys.add(str(reply.ok.key_expr))
    return sorted(keys)


def echo(session: zenoh.Session, key_expr: str, out: Callable[[str], None], *, count: int | None = None,
         timeout: float | None = None, keys: KeySpace = DEFAULT_KEYS, full: bool = False,
         stop: threading.Event | None = None) -> int:
    """Decode and print each message on ``key_expr`` via ``out`` (malformed ones are printed
    as errors, not raised), until ``count`` messages, ``timeout`` seconds of silence, or
    ``stop``. Returns how many messages arrived."""
    q: queue.SimpleQueue[Received] = queue.SimpleQueue()
    sub = session.declare_subscriber(key_expr, lambda s: q.put(Received.from_sample(s)))
    n = 0
    try:
        while count is None or n < count:
            if stop is not None and stop.is_set():
                break
            try:
                rec = q.get(timeout=timeout if timeout is not None else 0.2)
            except queue.Empty:
                if timeout is not None:
                    break
                continue
            n += 1
            if rec.kind != "put":
                out(f"{rec.key}: DELETE")
                continue
            try:
                msg = decode(rec.key, rec.payload, keys=keys)
            except MessageError as exc:
                out(f"{rec.key}: MALFORMED ({len(rec.payload)} bytes): {exc}")
                continue
            if full:
                from cekm_swarm.protocol import to_plain

                out(f"{rec.key}: {to_plain(msg)}")
            else:
                out(f"{rec.key}: {summary(msg)}")
    finally:
        sub.undeclare()
    return n
