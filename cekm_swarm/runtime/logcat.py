"""``cekm log cat``: a log's messages as text or JSON lines (like ``mcap cat``, ``ros2 bag echo``).

Key-space channels (msgpack) are decoded and validated like live messages: a malformed
one is printed as an error line and counted, never raised. View channels (Foxglove
protobuf) are listed by size only with ``views=True``.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import zenoh

from cekm_swarm.protocol import DEFAULT_KEYS, KeySpace, MessageError, decode, summary, to_plain

from .errors import McapLogError
from .jsonout import json_line
from .mcap_log import MSGPACK, LoggedMessage, read_messages


def key_filter(patterns: tuple[str, ...] | list[str] | None) -> Callable[[str], bool]:
    """A predicate: does a topic match any of ``patterns`` (Zenoh key expressions, e.g.
    ``cekm/r1/**``; a view topic like ``/view/scene`` matches only itself)? None: all."""
    if not patterns:
        return lambda topic: True
    exprs, exact = [], set()
    for p in patterns:
        if p.startswith("/"):
            exact.add(p)
            continue
        try:
            exprs.append(zenoh.KeyExpr(p))
        except Exception as exc:
            raise McapLogError("--topics", f"{p!r} is not a key expression: {str(exc).split(' at /')[0]}") from None
    cache: dict[str, bool] = {}

    def match(topic: str) -> bool:
        hit = cache.get(topic)
        if hit is None:
            if topic in exact:
                hit = True
            elif topic.startswith("/"):
                hit = False
            else:
                try:
                    ke = zenoh.KeyExpr(topic)
                    hit = any(e.intersects(ke) for e in exprs)
                except Exception:
                    hit = False
            cache[topic] = hit
        return hit

    return match


@dataclass
class CatCounts:
    """What :func:`cat_lines` printed: messages, malformed ones, and view messages skipped."""

    messages: int = 0
    malformed: int = 0
    views_skipped: int = 0
    per_topic: dict[str, int] = field(default_factory=dict)


def message_record(m: LoggedMessage, keys: KeySpace = DEFAULT_KEYS) -> dict[str, Any]:
    """One logged message as plain data: topic, times (s), sequence, and the decoded
    message, or ``error`` for a malformed one, or the size of a non-msgpack one."""
    doc: dict[str, Any] = {"topic": m.topic, "log_time": m.log_time / 1e9, "publish_time": m.publish_time / 1e9,
                           "sequence": m.sequence}
    if m.message_encoding != MSGPACK:
        doc.update(encoding=m.message_encoding, schema=m.schema_name, bytes=len(m.data))
        return doc
    try:
        doc["message"] = to_plain(decode(m.topic, m.data, keys=keys))
    except MessageError as exc:
        doc.update(error=str(exc), bytes=len(m.data))
    return doc


def cat_lines(path: str | Path, *, topics: tuple[str, ...] | None = None, as_json: bool = False,
              views: bool = False, start: float | None = None, end: float | None = None,
              keys: KeySpace = DEFAULT_KEYS, counts: CatCounts | None = None) -> Iterator[str]:
    """The lines ``cekm log cat`` prints, one per message in log-time order (a truncated
    log: file order up to the cut). ``start``/``end`` bound the log time in seconds."""
    counts = counts if counts is not None else CatCounts()
    wanted = key_filter(topics)
    for m in read_messages(path):
        if not wanted(m.topic):
            continue
        t = m.log_time / 1e9
        if (start is not None and t < start) or (end is not None and t > end):
            continue
        if m.message_encoding != MSGPACK and not views:
            counts.views_skipped += 1
            continue
        doc = message_record(m, keys)
        counts.messages += 1
        counts.per_topic[m.topic] = counts.per_topic.get(m.topic, 0) + 1
        if "error" in doc:
            counts.malformed += 1
        if as_json:
            yield json_line(doc)
        elif "message" in doc:
            yield f"{t:10.3f} {m.topic}: {summary(decode(m.topic, m.data, keys=keys))}"
        elif "error" in doc:
            yield f"{t:10.3f} {m.topic}: MALFORMED ({doc['bytes']} bytes): {doc['error']}"
        else:
            yield f"{t:10.3f} {m.topic}: {doc['encoding']} {doc['schema']} ({doc['bytes']} bytes)"
