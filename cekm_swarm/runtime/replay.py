"""Replay: republish a recorded MCAP log onto Zenoh at the recorded timing.

Only the key-space channels (message encoding ``msgpack``) are republished, each on its
recorded key with its recorded bytes, in log-time order. The gap between two messages is
their sim-time gap divided by ``rate``; ``rate=None`` publishes as fast as possible.
Monitors and tools attach to a replay exactly as to a live run. A replay can be paused
and resumed (:class:`ReplayControl`; the recorded gaps are kept across a pause), can
start ``start`` seconds into the log, and reports its progress (:class:`ReplayProgress`).

A gap of more than :data:`MAX_GAP_S` of sim time between two messages it publishes one
after the other is not waited for: the later message goes out at once and the schedule
goes on from it (counted in :attr:`ReplayResult.jumped`; ``cekm replay`` says so in one
line). No run leaves a minute of sim time without a message (the world's clock comes
every tick), so such a gap comes from a stamp no run reaches that a recorder kept (a log
of ``cekm record`` from before it judged stamps: a stamp of 1e300 filed at the largest
time MCAP holds made the replay wait 584 years for it).

A ``--loop`` replay is silent for :data:`LOOP_PAUSE_S` of wall time before it starts
over. Readers that judge a stamp against the newest one they took (a module's stamp
window, ``cekm record``) take any stamp after :data:`~cekm_swarm.protocol.stamps.QUIET_S`
without one, as at the start of a run: so the next loop's first stamps, back at the
log's start, are taken as a new run's, not dropped as out of their window until the
loop came near the old stamps again.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import zenoh
from mcap.reader import make_reader

from ..protocol.stamps import QUIET_S
from .bridge import Publishers
from .mcap_log import MSGPACK, LoggedMessage, is_complete, read_messages
from .mcap_sets import log_files

MAX_GAP_S = 60.0
"""Sim seconds between two consecutive published messages beyond which replay does not
wait (the gap is jumped): far more than any run's (a tick, 0.128 s, for a full or lean
log; a few seconds for a log of a few sparse keys), far less than a bogus stamp's."""

LOOP_PAUSE_S = QUIET_S + 0.25
"""Wall seconds of silence between two loops of a replay (module docstring)."""


class ReplayControl:
    """Pause and resume a running replay from another thread (a key press, a test)."""

    def __init__(self) -> None:
        self._cond = threading.Condition()
        self._paused = False

    @property
    def paused(self) -> bool:
        return self._paused

    def pause(self) -> None:
        with self._cond:
            self._paused = True

    def resume(self) -> None:
        with self._cond:
            self._paused = False
            self._cond.notify_all()

    def toggle(self) -> bool:
        """Pause if running, resume if paused; True when now paused."""
        with self._cond:
            self._paused = not self._paused
            self._cond.notify_all()
            return self._paused

    def wait_running(self, stop: threading.Event | None) -> float:
        """Block while paused (until resumed or ``stop`` is set); the seconds spent paused."""
        t0 = time.perf_counter()
        with self._cond:
            while self._paused and not (stop is not None and stop.is_set()):
                self._cond.wait(0.1)
        return time.perf_counter() - t0


@dataclass(frozen=True, slots=True)
class ReplayProgress:
    """Where a replay is: sim time of the last message published, the log's sim-time span,
    messages published so far, the loop, and whether it is paused."""

    sim_time: float
    start: float
    end: float
    published: int
    loop: int
    paused: bool

    @property
    def fraction(self) -> float:
        span = self.end - self.start
        return 1.0 if span <= 0 else min(1.0, max(0.0, (self.sim_time - self.start) / span))

    def line(self) -> str:
        """``replay  12.3 / 45.6 s  27%  1234 msgs  loop 1  [paused]``"""
        state = "  [paused: space to resume]" if self.paused else ""
        return (f"replay {self.sim_time:7.2f} / {self.end:.2f} s {100 * self.fraction:4.0f}%  "
                f"{self.published} msgs  loop {self.loop + 1}{state}")


def log_span(path: str | Path) -> tuple[float, float] | None:
    """(first, last) log time in seconds from the log's summary statistics (every file of a
    log set); None when a file has none (a truncated log) or the log holds no message."""
    if not is_complete(path):
        return None
    spans = []
    for p in log_files(path):
        try:
            with open(p, "rb") as f:
                summary = make_reader(f).get_summary()
        except Exception:
            return None
        if summary is None or summary.statistics is None:
            return None
        if summary.statistics.message_count:
            spans.append((summary.statistics.message_start_time / 1e9, summary.statistics.message_end_time / 1e9))
    if not spans:
        return None
    return min(a for a, _ in spans), max(b for _, b in spans)


@dataclass
class ReplayResult:
    """Counts of a replay: messages published (in all loops), loops completed, per key,
    gaps of more than :data:`MAX_GAP_S` not waited for (``jumped``, their sim time left
    out of ``sim_seconds``)."""

    published: int = 0
    loops: int = 0
    per_key: dict[str, int] = field(default_factory=dict)
    wall_seconds: float = 0.0
    sim_seconds: float = 0.0
    stopped: bool = False
    jumped: int = 0


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
               on_publish: Callable[[LoggedMessage], None] | None = None, start: float = 0.0,
               control: ReplayControl | None = None,
               on_progress: Callable[[ReplayProgress], None] | None = None,
               progress_every: float = 0.25) -> ReplayResult:
    """Republish the msgpack channels of the log at ``path`` onto ``session``.

    ``rate`` scales time (2.0 = twice as fast; None or <= 0 = as fast as possible);
    ``loop`` starts over at the end, after :data:`LOOP_PAUSE_S` s of silence, until ``stop``
    is set or ``max_loops`` loops are done;
    ``key_expr`` keeps only matching keys. Publishing uses congestion control BLOCK, so a
    slow subscriber slows the replay instead of losing messages. ``start`` skips the first
    ``start`` seconds of the log (in every loop); ``control`` pauses and resumes;
    ``on_progress`` is called at most every ``progress_every`` s and once at the end of
    each loop. A gap of more than :data:`MAX_GAP_S` of sim time between two messages is
    not waited for (module docstring). Returns the counts."""
    fast = rate is None or rate <= 0
    wanted = _selector(key_expr)
    own = publishers is None
    pubs = publishers or Publishers(session, block=True)
    result = ReplayResult()
    t_start = time.perf_counter()
    span = log_span(path) if on_progress is not None else None
    log_start_ns: int | None = None if span is None else int(round(span[0] * 1e9))
    end_s = math.nan if span is None else span[1]
    last_report = -math.inf

    def report(sim_ns: int, force: bool = False) -> None:
        nonlocal last_report
        now = time.perf_counter()
        if on_progress is None or (not force and now - last_report < progress_every):
            return
        last_report = now
        first = 0.0 if log_start_ns is None else log_start_ns / 1e9
        on_progress(ReplayProgress(sim_ns / 1e9, first, end_s if math.isfinite(end_s) else sim_ns / 1e9,
                                   result.published, result.loops, control is not None and control.paused))

    first_ns: int | None = None
    last_ns = 0
    jumped_ns = 0  # sim time of the gaps jumped in this loop: left out of the schedule
    max_gap_ns = int(MAX_GAP_S * 1e9)
    try:
        while True:
            first_ns = None
            last_ns = 0
            jumped_ns = 0
            skip_before: int | None = None if log_start_ns is None else log_start_ns + int(round(start * 1e9))
            loop_t0 = time.perf_counter()
            published_before = result.published
            for m in read_messages(path, encodings=(MSGPACK,)):
                if log_start_ns is None:
                    log_start_ns = m.log_time
                if skip_before is None:
                    skip_before = log_start_ns + int(round(start * 1e9))
                if m.log_time < skip_before or not wanted(m.topic):
                    continue
                if stop is not None and stop.is_set():
                    result.stopped = True
                    return result
                if control is not None and control.paused:
                    report(last_ns, force=True)
                    loop_t0 += control.wait_running(stop)  # the recorded gaps are kept across a pause
                    if stop is not None and stop.is_set():
                        result.stopped = True
                        return result
                if first_ns is None:
                    loop_t0 = time.perf_counter()  # the schedule starts at the first message
                    first_ns = m.log_time
                elif m.log_time - last_ns > max_gap_ns:  # a time no run reaches: do not wait for it
                    jumped_ns += m.log_time - last_ns
                    result.jumped += 1
                last_ns = m.log_time
                if not fast:
                    due = loop_t0 + (m.log_time - first_ns - jumped_ns) / 1e9 / rate  # type: ignore[operator]
                    delay = due - time.perf_counter()
                    while delay > 0:
                        report(last_ns)
                        pause = min(delay, progress_every) if on_progress is not None or control is not None \
                            else delay
                        if stop is not None:
                            if stop.wait(pause):
                                result.stopped = True
                                return result
                        else:
                            time.sleep(pause)
                        if control is not None and control.paused:
                            report(last_ns, force=True)
                            loop_t0 += control.wait_running(stop)
                            if stop is not None and stop.is_set():
                                result.stopped = True
                                return result
                        delay = (loop_t0 + (m.log_time - first_ns - jumped_ns) / 1e9 / rate  # type: ignore[operator]
                                 - time.perf_counter())
                pubs.put(m.topic, m.data)
                result.published += 1
                result.per_key[m.topic] = result.per_key.get(m.topic, 0) + 1
                if on_publish is not None:
                    on_publish(m)
                report(m.log_time)
            report(last_ns, force=True)
            result.loops += 1
            if first_ns is not None:
                result.sim_seconds += (last_ns - first_ns - jumped_ns) / 1e9
                first_ns = None  # counted: a stop in the pause below adds nothing more
            if not loop or result.published == published_before:
                return result
            if max_loops is not None and result.loops >= max_loops:
                return result
            if stop is not None:  # quiet long enough that readers take the next loop as a new run
                if stop.wait(LOOP_PAUSE_S):
                    result.stopped = True
                    return result
            else:
                time.sleep(LOOP_PAUSE_S)
    finally:
        if result.stopped and first_ns is not None:  # the part of the interrupted loop
            result.sim_seconds += (last_ns - first_ns - jumped_ns) / 1e9
        result.wall_seconds = time.perf_counter() - t_start
        if own:
            pubs.close()
