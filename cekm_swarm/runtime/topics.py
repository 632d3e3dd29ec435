"""Topic tools in the manner of ``ros2 topic``: list keys, echo messages, measure rates.

Pure functions compute the statistics; thin synchronous shells attach a Zenoh
subscriber whose callback only records the arrival (thread-safe), so tools never block
Zenoh's threads.
"""

from __future__ import annotations

import itertools
import json
import math
import queue
import threading
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import msgspec
import zenoh

from cekm_swarm.protocol import DEFAULT_KEYS, KeyKind, KeySpace, KeySpaceError, MessageError, decode, summary, to_plain
from cekm_swarm.protocol.messages import MESSAGE_TYPES, encode

from .bridge import Publishers, Received, wait_matching
from .config import MAX_MESSAGE_BYTES
from .jsonout import json_line


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
    periods = [b - a for a, b in itertools.pairwise(times)]
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
        if s.count < 2:  # one message in the window (a held reading, sent only when it changes): no period
            why = "held (sent when it changes)" if "/sense/" in s.key else "fewer than 2 messages in the window"
            lines.append(f"{s.key:<{w}}  {s.count:>6} {'-':>9} {'-':>10} {'-':>8} {'-':>8} {'-':>8} "
                         f"{s.age:>7.2f}  {why}")
            continue
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
        self._sub: zenoh.Subscriber[None] | None = session.declare_subscriber(key_expr, self._on_sample)

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

    def __enter__(self) -> ArrivalLog:
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
         timeout: float | None = None, keys: KeySpace = DEFAULT_KEYS, full: bool = False, as_json: bool = False,
         stop: threading.Event | None = None, waiting: Callable[[str], None] | None = None,
         waiting_after: float = 0.5) -> int:
    """Decode and print each message on ``key_expr`` via ``out`` (malformed ones are printed
    as errors, not raised), until ``count`` messages, ``timeout`` seconds of silence, or
    ``stop``. ``as_json``: one JSON object per message (:func:`echo_record`). If nothing
    arrives within ``waiting_after`` s, ``waiting("waiting for messages on KEYEXPR ...")``
    is called once. Returns how many messages arrived."""
    q: queue.SimpleQueue[Received] = queue.SimpleQueue()
    sub = session.declare_subscriber(key_expr, lambda s: q.put(Received.from_sample(s)))
    n = 0
    t0 = time.monotonic()
    said = waiting is None
    try:
        while count is None or n < count:
            if stop is not None and stop.is_set():
                break
            step = 0.1 if not said else (timeout if timeout is not None else 0.2)
            try:
                rec = q.get(timeout=step)
            except queue.Empty:
                silent = time.monotonic() - t0
                if not said and silent >= waiting_after:
                    waiting(f"waiting for messages on {key_expr} ...")  # type: ignore[misc]
                    said = True
                if timeout is not None and silent >= timeout:
                    break
                continue
            said = True
            n += 1
            t0 = time.monotonic()
            if as_json:
                out(json_line(echo_record(rec.key, rec.kind, rec.payload, keys)))
                continue
            if rec.kind != "put":
                out(f"{rec.key}: DELETE")
                continue
            try:
                msg = decode(rec.key, rec.payload, keys=keys)
            except MessageError as exc:
                out(f"{rec.key}: MALFORMED ({len(rec.payload)} bytes): {exc}")
                continue
            out(f"{rec.key}: {json_line(to_plain(msg)) if full else summary(msg)}")
    finally:
        sub.undeclare()
    return n


# --------------------------------------------------------------------------- echo as JSON


def echo_record(key: str, kind: str, payload: bytes, keys: KeySpace = DEFAULT_KEYS) -> dict[str, Any]:
    """One received sample as plain data: the key and the decoded message, or ``error``
    (a malformed message), or ``kind: delete``."""
    if kind != "put":
        return {"key": key, "kind": "delete"}
    try:
        return {"key": key, "message": to_plain(decode(key, payload, keys=keys))}
    except MessageError as exc:
        return {"key": key, "error": str(exc), "bytes": len(payload)}


# --------------------------------------------------------------------------- topic info


@dataclass
class Endpoints:
    """Who publishes and who subscribes on a key expression, from the router's admin space:
    {declared key expression: [names]}; a name is the module holding a liveliness token in
    that session (``r1/motor``), or the session's Zenoh id."""

    publishers: dict[str, list[str]]
    subscribers: dict[str, list[str]]


def _zids(doc: dict[str, Any], *fields: str) -> list[str]:
    """The session ids listed under ``fields`` of an admin-space entry (anything else ignored)."""
    out: list[str] = []
    for f in fields:
        value = doc.get(f)
        if isinstance(value, list):
            out.extend(v for v in value if isinstance(v, str))
    return out


def _admin(session: zenoh.Session, selector: str, timeout: float) -> list[tuple[str, dict[str, Any]]]:
    out = []
    for reply in session.get(selector, timeout=timeout):
        if reply.ok is None:
            continue
        try:
            doc = json.loads(reply.ok.payload.to_bytes())
        except ValueError:
            continue
        if isinstance(doc, dict):
            out.append((str(reply.ok.key_expr), doc))
    return out


def router_endpoints(session: zenoh.Session, key_expr: str, keys: KeySpace = DEFAULT_KEYS,
                     timeout: float = 2.0) -> Endpoints | None:
    """Publishers and subscribers whose declared key expression intersects ``key_expr``,
    read from the router's admin space (``@/<router>/router/{publisher,subscriber,token}/**``);
    None when the router does not answer (its admin space is off, as in ``deploy/``'s router).

    A session is named by the liveliness tokens it holds (a module process holds one);
    this tool's own session is left out. A publisher in the router's own process (the world
    server, which hosts the embedded router) is named ``router``."""
    target = zenoh.KeyExpr(key_expr)
    me = str(session.info.zid())
    entries = _admin(session, "@/*/router/**", timeout)
    if not any("/router/" in k for k, _ in entries):
        return None
    names = _session_names(entries, keys)

    def who(doc: dict[str, Any], routers: bool) -> list[str]:
        out = []
        for zid in _zids(doc, "clients", "peers"):
            if zid != me:
                out.append(", ".join(sorted(names[zid])) if zid in names else f"zid {zid}")
        if routers and _zids(doc, "routers"):
            out.append("router")
        return sorted(out)

    pubs: dict[str, list[str]] = {}
    subs: dict[str, list[str]] = {}
    for k, doc in entries:
        for marker, table, routers in (("/router/publisher/", pubs, True), ("/router/subscriber/", subs, False)):
            _, _, declared = k.partition(marker)
            if declared and _intersects(declared, target):
                named = who(doc, routers)
                if named:
                    table.setdefault(declared, []).extend(named)
    return Endpoints(pubs, subs)


def _session_names(entries: list[tuple[str, Any]], keys: KeySpace) -> dict[str, list[str]]:
    """{session zid: its names}: ``router`` for the router's own session, ``robot/module``
    for each liveliness token a session holds (the token's key when it is not the key space's)."""
    names: dict[str, list[str]] = {}
    for k, _ in entries:
        parts = k.split("/")
        if len(parts) == 3 and parts[2] == "router":  # @/<zid>/router: the router's own session
            names.setdefault(parts[1], []).append("router")
    for k, doc in entries:
        _, _, rest = k.partition("/router/token/")
        if not rest:
            continue
        try:
            parsed = keys.parse(rest)
            label = f"{parsed.robot}/{parsed.module}"
        except Exception:
            label = rest
        for zid in _zids(doc, "clients", "peers"):
            names.setdefault(zid, []).append(label)
    return names


def _intersects(declared: str, target: zenoh.KeyExpr) -> bool:
    """Whether a declared key expression meets ``target`` (False for one Zenoh refuses)."""
    try:
        return bool(zenoh.KeyExpr(declared).intersects(target))
    except Exception:
        return False


def format_endpoints(ep: Endpoints | None, stats: Sequence[HzStats]) -> str:
    """``topic info``'s text: publishers, subscribers, then the measured rates."""
    lines = []
    if ep is None:
        lines.append("publishers/subscribers: unknown (the router's admin space is off)")
    else:
        for title, table in (("publishers", ep.publishers), ("subscribers", ep.subscribers)):
            n = sum(len(v) for v in table.values())
            lines.append(f"{title} ({n}):")
            for declared in sorted(table):
                lines.append(f"  {declared}: {'; '.join(table[declared])}")
    lines.append(format_hz(stats))
    return "\n".join(lines)


# --------------------------------------------------------------------------- topic pub


def build_message(key: str, fields_json: str, keys: KeySpace = DEFAULT_KEYS, *, stamp: float | None = None,
                  sender: str = "operator") -> bytes:
    """The msgpack bytes of the message for ``key`` from a JSON map of its fields (e.g.
    ``{"v_l": 0.05, "v_r": 0.05, "seq": 0}`` for ``cekm/r1/cmd/wheels``), validated like a
    received message. ``stamp`` and ``sender`` may also be given in the map."""
    try:
        parsed = keys.parse(key)
    except KeySpaceError as exc:
        raise MessageError(str(exc)) from None
    try:
        doc = json.loads(fields_json)
    except ValueError as exc:
        raise MessageError(f"{key}: the message is not JSON ({exc})") from None
    if not isinstance(doc, dict):
        raise MessageError(f"{key}: the message must be a JSON map of fields, got {type(doc).__name__}")
    kind = parsed.kind
    if kind is KeyKind.NODE:  # a graph's own key: the message says its kind
        named = doc.pop("kind", None)
        kinds = sorted(k.value for k in MESSAGE_TYPES)
        if named not in kinds:
            raise MessageError(f"{key}: a graph's own key; say the message's kind in the JSON map, \"kind\": one of "
                               f"{', '.join(kinds)}")
        kind = KeyKind(named)
    cls = MESSAGE_TYPES.get(kind)
    if cls is None:
        raise MessageError(f"{key}: a {kind.value} key carries no message")
    if stamp is not None:
        doc["stamp"] = stamp
    doc.setdefault("stamp", 0.0)
    doc.setdefault("sender", sender)
    if parsed.index is not None:
        doc.setdefault("index", parsed.index)
    names = list(cls.__struct_fields__)
    unknown = sorted(set(doc) - set(names))
    if unknown:
        raise MessageError(f"{key}: unknown field(s) {', '.join(unknown)}; a {kind.value} message has "
                           f"{', '.join(names)}")
    try:
        msg = cls(**doc)
    except TypeError:
        missing = [f.name for f in msgspec.structs.fields(cls) if f.name not in doc and f.required]
        raise MessageError(f"{key}: missing field(s) {', '.join(missing)}") from None
    data = encode(msg)
    decode(key, data, keys=keys, expect=kind)  # the checks a receiver makes (index matches the key, ...)
    if len(data) > MAX_MESSAGE_BYTES:  # every router and client drops it: refused here, not sent for nothing
        raise MessageError(f"{key}: the message is {len(data):,} bytes, over the {MAX_MESSAGE_BYTES // 1024} KB "
                           f"limit every router and client enforce ({MAX_MESSAGE_BYTES:,} bytes)")
    return data


@dataclass
class PubResult:
    """What :func:`publish` did: messages put, subscribers matched, and how many of the
    messages a probe subscriber saw come back through the router (None: not checked)."""

    sent: int = 0
    matched: bool = False
    confirmed: int | None = None


def publish(session: zenoh.Session, key: str, payload: bytes, *, count: int = 1, rate: float | None = None,
            probe: zenoh.Session | None = None, confirm_timeout: float = 3.0,
            stop: threading.Event | None = None, wait_subscriber: float = 0.0,
            waiting: Callable[[str], None] | None = None, keys: KeySpace = DEFAULT_KEYS) -> PubResult:
    """Put ``payload`` on ``key`` ``count`` times (``rate`` Hz apart). With ``probe`` (a second
    session on the same router, with the same credentials) subscribed to ``key``, count how
    many come back through the router: a router whose access control denies the put drops
    it silently, so a shortfall is the one sign of that. ``wait_subscriber``: first wait up
    to that many seconds for a subscriber (saying so through ``waiting``), as ``ros2 topic
    pub`` does; published anyway after it, with ``matched`` False."""
    stop = stop or threading.Event()
    result = PubResult()
    got = threading.Semaphore(0)
    probe_sub = None
    with Publishers(session, block=True) as pubs:
        pub = pubs.publisher(key)
        result.matched = pub.matching_status.matching  # type: ignore[attr-defined]  # zenoh's stub says bool
        if not result.matched and wait_subscriber > 0:
            if waiting is not None:
                waiting(f"waiting for a subscriber on {key} ...")
            result.matched = wait_matching(pub, wait_subscriber)
        if probe is not None:
            probe_sub = probe.declare_subscriber(key, lambda s: got.release())
            # A barrier: the router answers the probe's liveliness query after it has taken
            # the probe's subscription (one link, in order), so the first put finds it there.
            for _ in probe.liveliness().get(keys.alive_all(), timeout=confirm_timeout):
                pass
        try:
            for i in range(count):
                if stop.is_set():
                    break
                if i and rate and stop.wait(1.0 / rate):
                    break
                pub.put(payload)
                result.sent += 1
            if probe_sub is not None:
                n = 0
                deadline = time.monotonic() + confirm_timeout
                while n < result.sent and got.acquire(timeout=max(0.0, deadline - time.monotonic())):
                    n += 1
                result.confirmed = n
        finally:
            if probe_sub is not None:
                probe_sub.undeclare()
    return result
