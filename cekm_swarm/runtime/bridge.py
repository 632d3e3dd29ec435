"""Zenoh <-> asyncio: subscriptions as async queues, latest-value caches, publishers, liveliness.

zenoh-python has no asyncio API. Its callbacks run on Zenoh's own threads, so every
callback here does one thing: copy the sample into a plain :class:`Received` record and
hand it to the event loop with ``loop.call_soon_threadsafe``. A callback never blocks and
never calls into a Zenoh session (which could deadlock Zenoh's threads); coroutines
``await`` the queue.

Ordering: samples of one subscription arrive in order. zenoh-python runs each
subscription's callback on its own thread, so samples of *different* subscriptions are
not ordered with each other, even from one publisher session; put keys whose relative
order matters under one subscription (one key expression).
"""

from __future__ import annotations

import asyncio
import contextlib
import ctypes
import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import zenoh

from cekm_swarm.protocol import MSGPACK_ENCODING, Message, encode

log = logging.getLogger("cekm_swarm.runtime.bridge")
MSGPACK = zenoh.Encoding(MSGPACK_ENCODING)
"""The Zenoh encoding label of every payload of the protocol."""


@dataclass(frozen=True, slots=True)
class Received:
    """One sample as plain data: key, payload bytes, ``put``/``delete``, encoding, and the
    ``time.monotonic()`` at which the Zenoh callback ran (for rates, ages, latencies)."""

    key: str
    payload: bytes
    kind: str
    encoding: str
    at: float

    @staticmethod
    def from_sample(sample: zenoh.Sample) -> Received:
        """Copy what matters out of a Zenoh sample (safe to call in a Zenoh callback)."""
        return Received(str(sample.key_expr), sample.payload.to_bytes(),
                        "put" if sample.kind == zenoh.SampleKind.PUT else "delete", str(sample.encoding),
                        time.monotonic())


def _handoff(loop: asyncio.AbstractEventLoop, fn: Callable[[Received], None]) -> Callable[[zenoh.Sample], None]:
    """A Zenoh callback that forwards each sample to ``fn`` on ``loop``'s thread."""

    def callback(sample: zenoh.Sample) -> None:
        keep_thread_state()
        rec = Received.from_sample(sample)
        try:  # noqa: SIM105 -- every sample: a try costs nothing, suppress() a context manager each
            loop.call_soon_threadsafe(fn, rec)
        except RuntimeError:  # loop closed while Zenoh still delivers: nothing left to receive it
            pass

    return callback


class _Subscriber:
    """What every subscription wrapper here shares: ``close()`` undeclares its Zenoh
    subscriber (idempotent), and it is a context manager that closes on exit."""

    _sub: Any = None

    def close(self) -> None:
        """Undeclare the subscriber (idempotent)."""
        if self._sub is not None:
            self._sub.undeclare()
            self._sub = None

    def __enter__(self) -> Any:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class AsyncSubscription(_Subscriber):
    """Samples on ``key_expr`` as an asyncio queue: ``await sub.get()`` or ``async for rec in sub``.

    ``maxsize`` 0 keeps every sample (FIFO, unbounded); a positive ``maxsize`` keeps the
    newest ``maxsize`` and counts the dropped oldest ones in ``dropped``. Must be created
    from inside the event loop (or given it)."""

    def __init__(self, session: zenoh.Session, key_expr: str, *, maxsize: int = 0,
                 loop: asyncio.AbstractEventLoop | None = None) -> None:
        self.key_expr = key_expr
        self.dropped = 0
        self._loop = loop or asyncio.get_running_loop()
        self._queue: asyncio.Queue[Received] = asyncio.Queue(maxsize)
        push = self._queue.put_nowait if maxsize <= 0 else self._push_bounded
        self._sub = session.declare_subscriber(key_expr, _handoff(self._loop, push))

    def _push_bounded(self, rec: Received) -> None:
        if self._queue.full():
            self._queue.get_nowait()
            self.dropped += 1
        self._queue.put_nowait(rec)

    async def get(self, timeout: float | None = None) -> Received:
        """The next sample; raises TimeoutError after ``timeout`` seconds."""
        if timeout is None:
            return await self._queue.get()
        return await asyncio.wait_for(self._queue.get(), timeout)

    def get_nowait(self) -> Received | None:
        """The next sample if one is waiting, else None."""
        try:
            return self._queue.get_nowait()
        except asyncio.QueueEmpty:
            return None

    def pending(self) -> int:
        """Samples waiting in the queue."""
        return self._queue.qsize()

    def __aiter__(self) -> AsyncSubscription:
        return self

    async def __anext__(self) -> Received:
        return await self._queue.get()


_thread_kept = threading.local()


def keep_thread_state() -> None:
    """Keep this (Zenoh-owned) thread's Python thread state alive between callbacks.

    A callback from a thread Python did not start takes the GIL with
    ``PyGILState_Ensure``, which creates a thread state (its frame stack is an mmap of its
    own) and destroys it when the callback returns: an mmap, madvise, munmap and gettid
    per message (strace); keeping it cut a module's CPU per tick by about a sixth. One
    extra ``PyGILState_Ensure`` that is never released keeps the state for the thread's
    life. Call it with the GIL held, from the callback."""
    if not getattr(_thread_kept, "on", False):
        ctypes.pythonapi.PyGILState_Ensure()
        _thread_kept.on = True


class InlineSubscription(_Subscriber):
    """Samples on ``key_expr`` handed to ``fn(rec)`` on Zenoh's receiving thread itself
    (``zenoh.handlers.Callback(..., indirect=False)``): no extra thread and no event-loop
    wake-up. ``fn`` must be quick and must never block or wait on the session (a module's
    compute-and-publish qualifies: publishing does not wait for an answer). Samples of the
    one subscription arrive in order. An exception in ``fn`` is counted in ``errors`` and
    logged once; the subscription keeps going. ``raw=True`` hands ``fn`` the
    ``zenoh.Sample`` itself (no copy into a :class:`Received`: the module hot path)."""

    def __init__(self, session: zenoh.Session, key_expr: str, fn: Callable[[Any], None], *,
                 raw: bool = False) -> None:
        self.key_expr = key_expr
        self.errors = 0
        handle = fn if raw else (lambda sample: fn(Received.from_sample(sample)))

        def callback(sample: zenoh.Sample) -> None:
            keep_thread_state()
            try:
                handle(sample)
            except Exception as exc:  # noqa: BLE001 - never let an error reach Zenoh's thread
                self.errors += 1
                if self.errors == 1:
                    log.error("subscription %s: handler failed: %s: %s", key_expr, type(exc).__name__, exc)

        self._sub = session.declare_subscriber(key_expr, zenoh.handlers.Callback(callback, indirect=False))


class LatestValues(_Subscriber):
    """The newest sample of each key matching ``key_expr`` (what motor integration needs:
    the latest vector of each source), plus the set of keys updated since last asked.

    ``await latest.wait_updates()`` returns the keys that changed since the previous call
    (waiting for at least one); ``latest.get(key)`` / ``latest.snapshot()`` read values.
    """

    def __init__(self, session: zenoh.Session, key_expr: str, *,
                 loop: asyncio.AbstractEventLoop | None = None) -> None:
        self.key_expr = key_expr
        self.updates = 0
        self._loop = loop or asyncio.get_running_loop()
        self._latest: dict[str, Received] = {}
        self._dirty: set[str] = set()
        self._event = asyncio.Event()
        self._sub = session.declare_subscriber(key_expr, _handoff(self._loop, self._store))

    def _store(self, rec: Received) -> None:
        self._latest[rec.key] = rec
        self._dirty.add(rec.key)
        self.updates += 1
        self._event.set()

    def get(self, key: str) -> Received | None:
        """The newest sample on ``key``, None if none arrived yet."""
        return self._latest.get(key)

    def snapshot(self) -> dict[str, Received]:
        """A copy of {key: newest sample}."""
        return dict(self._latest)

    def forget(self, key: str) -> None:
        """Drop the stored value of ``key`` (e.g. a source gone stale)."""
        self._latest.pop(key, None)
        self._dirty.discard(key)

    async def wait_updates(self, timeout: float | None = None) -> set[str]:
        """Keys updated since the last call, waiting until there is at least one."""
        if not self._dirty:
            self._event.clear()
            if timeout is None:
                await self._event.wait()
            else:
                await asyncio.wait_for(self._event.wait(), timeout)
        dirty, self._dirty = self._dirty, set()
        self._event.clear()
        return dirty


def ring_subscriber(session: zenoh.Session, key_expr: str, capacity: int = 1) -> zenoh.Subscriber[Any]:
    """A Zenoh subscriber that keeps only the newest ``capacity`` samples (RingChannel);
    poll it with ``try_recv()`` (None when empty). For synchronous loops."""
    return session.declare_subscriber(key_expr, zenoh.handlers.RingChannel(capacity))


# --------------------------------------------------------------------------- publishing


def wait_matching(publisher: zenoh.Publisher, timeout: float) -> bool:
    """Wait until ``publisher`` has at least one matching subscriber; False on timeout.

    Blocks the calling thread (use :func:`wait_matching_async` in a coroutine)."""
    if publisher.matching_status.matching:  # type: ignore[attr-defined]  # zenoh's stub says bool: a MatchingStatus
        return True
    ready = threading.Event()
    listener = publisher.declare_matching_listener(lambda status: ready.set() if status.matching else None)
    try:
        return publisher.matching_status.matching or ready.wait(timeout)  # type: ignore[attr-defined]  # as above
    finally:
        listener.undeclare()


async def wait_matching_async(publisher: zenoh.Publisher, timeout: float) -> bool:
    """:func:`wait_matching` for coroutines (the wait runs in a worker thread)."""
    return await asyncio.to_thread(wait_matching, publisher, timeout)


class Publishers:
    """One declared Zenoh publisher per key, created on first use, all labelled
    ``application/msgpack``.

    ``block=True`` uses congestion control BLOCK (nothing dropped under load: replay and
    tests); the default DROP never stalls a real-time module on a slow subscriber.
    ``express=True`` sends each message at once instead of batching (lower latency)."""

    def __init__(self, session: zenoh.Session, *, block: bool = False, express: bool = False) -> None:
        self._session = session
        self._options: dict[str, Any] = {
            "encoding": MSGPACK,
            "congestion_control": zenoh.CongestionControl.BLOCK if block else zenoh.CongestionControl.DROP,
            "express": express,
        }
        self._pubs: dict[str, zenoh.Publisher] = {}

    def publisher(self, key: str) -> zenoh.Publisher:
        """The publisher of ``key``, declared now if it is new."""
        pub = self._pubs.get(key)
        if pub is None:
            pub = self._pubs[key] = self._session.declare_publisher(key, **self._options)
        return pub

    def put(self, key: str, payload: bytes) -> None:
        """Publish raw msgpack bytes on ``key``."""
        self.publisher(key).put(payload)

    def send(self, key: str, msg: Message) -> None:
        """Encode ``msg`` and publish it on ``key``."""
        self.publisher(key).put(encode(msg))

    def wait_matching(self, key: str, timeout: float) -> bool:
        """Wait until someone subscribes to ``key`` (see :func:`wait_matching`)."""
        return wait_matching(self.publisher(key), timeout)

    def keys(self) -> list[str]:
        """Keys with a declared publisher."""
        return list(self._pubs)

    def close(self) -> None:
        """Undeclare every publisher."""
        for pub in self._pubs.values():
            pub.undeclare()
        self._pubs.clear()

    def __enter__(self) -> Publishers:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


# --------------------------------------------------------------------------- liveliness


def declare_alive(session: zenoh.Session, key: str) -> zenoh.LivelinessToken:
    """Hold a liveliness token on ``key`` (``<root>/<robot>/alive/<module>``) until undeclared
    or the process dies; watchers see it vanish.

    Keep the returned token referenced for as long as the module lives: a token that is
    garbage-collected is undeclared."""
    return session.liveliness().declare_token(key)


@dataclass(frozen=True, slots=True)
class LivelinessEvent:
    """A token appeared (``alive`` True) or disappeared, seen at ``at`` (time.monotonic())."""

    key: str
    alive: bool
    at: float


class LivelinessWatcher(_Subscriber):
    """Tokens matching ``key_expr``: the set alive now and the stream of appear/disappear
    events. Uses a liveliness subscriber with history, so tokens that existed before the
    watcher started are reported as appearing."""

    def __init__(self, session: zenoh.Session, key_expr: str, *,
                 loop: asyncio.AbstractEventLoop | None = None) -> None:
        self.key_expr = key_expr
        self._loop = loop or asyncio.get_running_loop()
        self._alive: set[str] = set()
        self._events: asyncio.Queue[LivelinessEvent] = asyncio.Queue()
        self._change: asyncio.Future[None] = self._loop.create_future()
        self._sub = session.liveliness().declare_subscriber(key_expr, _handoff(self._loop, self._store), history=True)

    def _store(self, rec: Received) -> None:
        alive = rec.kind == "put"
        if alive:
            self._alive.add(rec.key)
        else:
            self._alive.discard(rec.key)
        self._events.put_nowait(LivelinessEvent(rec.key, alive, rec.at))
        done, self._change = self._change, self._loop.create_future()
        done.set_result(None)

    @property
    def alive(self) -> frozenset[str]:
        """Keys whose token is alive now."""
        return frozenset(self._alive)

    async def next_event(self, timeout: float | None = None) -> LivelinessEvent:
        """The next appear/disappear event; TimeoutError after ``timeout`` seconds."""
        if timeout is None:
            return await self._events.get()
        return await asyncio.wait_for(self._events.get(), timeout)

    async def _until(self, done: Callable[[], bool], timeout: float | None) -> None:
        """Wait until ``done()`` holds, checked at every token change; TimeoutError after ``timeout``."""

        async def until() -> None:
            while not done():
                await asyncio.shield(self._change)

        await asyncio.wait_for(until(), timeout)

    async def wait_all(self, keys: set[str] | frozenset[str], timeout: float) -> frozenset[str]:
        """Wait until every token of ``keys`` is alive, at most ``timeout`` seconds; the
        keys still missing then (empty when all came)."""
        with contextlib.suppress(TimeoutError):
            await self._until(lambda: keys <= self._alive, timeout)
        return frozenset(keys) - self._alive

    async def wait_for(self, key: str, alive: bool = True, timeout: float | None = None) -> None:
        """Wait until ``key``'s token is alive (or gone, ``alive=False``); TimeoutError after ``timeout``."""
        await self._until(lambda: (key in self._alive) == alive, timeout)

    def __aiter__(self) -> LivelinessWatcher:
        return self

    async def __anext__(self) -> LivelinessEvent:
        return await self._events.get()

