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
    replay = _Replay(session, path, rate=rate, key_expr=key_expr, stop=stop, publishers=publishers,
                     on_publish=on_publish, start=start, control=control, on_progress=on_progress,
                     progress_every=progress_every)
    return replay.run(loop, max_loops)


class _Stopped(Exception):
    """The replay's ``stop`` was set: unwinds a replay to :meth:`_Replay.run`."""


@dataclass
class _Schedule:
    """One loop's schedule: the wall time its first message went out at (``t0``, moved on
    by a pause), the log times of its first and latest messages, and the sim time of the
    gaps jumped (left out of the schedule)."""

    t0: float
    first_ns: int | None = None
    last_ns: int = 0
    jumped_ns: int = 0

    def due(self, log_time: int, rate: float) -> float:
        """The wall time a message of ``log_time`` goes out at."""
        assert self.first_ns is not None
        return self.t0 + (log_time - self.first_ns - self.jumped_ns) / 1e9 / rate

    def sim_seconds(self) -> float:
        """The sim time the loop has replayed so far (0 before its first message)."""
        return 0.0 if self.first_ns is None else (self.last_ns - self.first_ns - self.jumped_ns) / 1e9


class _Replay:
    """One :func:`replay_log`: its settings, its counts and the current loop's schedule."""

    def __init__(self, session: zenoh.Session, path: str | Path, *, rate: float | None, key_expr: str | None,
                 stop: threading.Event | None, publishers: Publishers | None,
                 on_publish: Callable[[LoggedMessage], None] | None, start: float, control: ReplayControl | None,
                 on_progress: Callable[[ReplayProgress], None] | None, progress_every: float) -> None:
        self.path, self.start, self.stop, self.control = path, start, stop, control
        self.rate = None if rate is None or rate <= 0 else rate  # None: as fast as possible
        self.wanted = _selector(key_expr)
        self.own = publishers is None
        self.pubs = publishers or Publishers(session, block=True)
        self.on_publish, self.on_progress, self.progress_every = on_publish, on_progress, progress_every
        self.result = ReplayResult()
        span = log_span(path) if on_progress is not None else None
        self.log_start_ns: int | None = None if span is None else int(round(span[0] * 1e9))
        self.end_s = math.nan if span is None else span[1]
        self.last_report = -math.inf
        self.sched = _Schedule(time.perf_counter())

    def run(self, loop: bool, max_loops: int | None) -> ReplayResult:
        """Every loop, until the log is done (``loop`` False, or ``max_loops``) or ``stop``."""
        result = self.result
        t_start = time.perf_counter()
        try:
            while True:
                published_before = result.published
                self.one_loop()
                if not loop or result.published == published_before:
                    return result
                if max_loops is not None and result.loops >= max_loops:
                    return result
                self.sleep(LOOP_PAUSE_S)  # quiet long enough that readers take the next loop as a new run
        except _Stopped:
            result.stopped = True
            return result
        finally:
            if result.stopped:  # the part of the interrupted loop
                result.sim_seconds += self.sched.sim_seconds()
            result.wall_seconds = time.perf_counter() - t_start
            if self.own:
                self.pubs.close()

    def one_loop(self) -> None:
        """The log once, from ``start`` s in, each message when its schedule says."""
        self.sched = _Schedule(time.perf_counter())
        skip_before = None if self.log_start_ns is None else self.log_start_ns + int(round(self.start * 1e9))
        for m in read_messages(self.path, encodings=(MSGPACK,)):
            if self.log_start_ns is None:
                self.log_start_ns = m.log_time
            if skip_before is None:
                skip_before = self.log_start_ns + int(round(self.start * 1e9))
            if m.log_time < skip_before or not self.wanted(m.topic):
                continue
            self.check_stop()
            self.hold_while_paused()
            self.schedule(m)
            if self.rate is not None:
                self.wait_due(m, self.rate)
            self.publish(m)
        self.report(self.sched.last_ns, force=True)
        self.result.loops += 1
        self.result.sim_seconds += self.sched.sim_seconds()
        self.sched.first_ns = None  # counted: a stop in the pause after it adds nothing more

    def schedule(self, m: LoggedMessage) -> None:
        """The schedule starts at the loop's first message; a gap no run reaches is jumped."""
        sched = self.sched
        if sched.first_ns is None:
            sched.t0 = time.perf_counter()
            sched.first_ns = m.log_time
        elif m.log_time - sched.last_ns > int(MAX_GAP_S * 1e9):  # a time no run reaches: do not wait for it
            sched.jumped_ns += m.log_time - sched.last_ns
            self.result.jumped += 1
        sched.last_ns = m.log_time

    def wait_due(self, m: LoggedMessage, rate: float) -> None:
        """Until ``m`` is due, reporting progress and holding while paused meanwhile."""
        delay = self.sched.due(m.log_time, rate) - time.perf_counter()
        while delay > 0:
            self.report(self.sched.last_ns)
            watched = self.on_progress is not None or self.control is not None
            self.sleep(min(delay, self.progress_every) if watched else delay)
            self.hold_while_paused()
            delay = self.sched.due(m.log_time, rate) - time.perf_counter()

    def publish(self, m: LoggedMessage) -> None:
        self.pubs.put(m.topic, m.data)
        result = self.result
        result.published += 1
        result.per_key[m.topic] = result.per_key.get(m.topic, 0) + 1
        if self.on_publish is not None:
            self.on_publish(m)
        self.report(m.log_time)

    def check_stop(self) -> None:
        if self.stop is not None and self.stop.is_set():
            raise _Stopped

    def sleep(self, seconds: float) -> None:
        """``seconds`` of wall time, or until ``stop``."""
        if self.stop is None:
            time.sleep(seconds)
        elif self.stop.wait(seconds):
            raise _Stopped

    def hold_while_paused(self) -> None:
        """While ``control`` is paused; the recorded gaps are kept across a pause."""
        if self.control is not None and self.control.paused:
            self.report(self.sched.last_ns, force=True)
            self.sched.t0 += self.control.wait_running(self.stop)
            self.check_stop()

    def report(self, sim_ns: int, force: bool = False) -> None:
        """``on_progress``, at most every ``progress_every`` s unless ``force``."""
        now = time.perf_counter()
        if self.on_progress is None or (not force and now - self.last_report < self.progress_every):
            return
        self.last_report = now
        first = 0.0 if self.log_start_ns is None else self.log_start_ns / 1e9
        end = self.end_s if math.isfinite(self.end_s) else sim_ns / 1e9
        paused = self.control is not None and self.control.paused
        self.on_progress(ReplayProgress(sim_ns / 1e9, first, end, self.result.published, self.result.loops, paused))
