"""The summary of a log (``cekm log info``): channels, counts, rates, duration."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .mcap_read import StreamResult, _open, stream_messages


@dataclass(frozen=True, slots=True)
class ChannelInfo:
    """One channel of a log: count, first/last sim time (s), mean rate (Hz)."""

    topic: str
    message_encoding: str
    schema_name: str | None
    count: int
    first: float
    last: float

    @property
    def rate(self) -> float:
        """Mean rate over the channel's own span (0 for fewer than 2 messages)."""
        span = self.last - self.first
        return (self.count - 1) / span if self.count > 1 and span > 0 else 0.0


@dataclass(frozen=True, slots=True)
class LogInfo:
    """Summary of a log: channels, counts, rates, start/end sim time and duration."""

    path: Path
    size_bytes: int
    complete: bool
    messages: int
    start: float
    end: float
    channels: tuple[ChannelInfo, ...] = field(default=())
    cut_reason: str | None = None

    @property
    def duration(self) -> float:
        """end - start, in seconds of sim time."""
        return self.end - self.start


def log_info(path: str | Path) -> LogInfo:
    """Summarise a log (complete or truncated) by streaming its messages once."""
    src = _open(path)
    result = StreamResult()
    stats: dict[str, list[Any]] = {}
    for m in stream_messages(src, result):
        s = stats.get(m.topic)
        if s is None:
            stats[m.topic] = [m.message_encoding, m.schema_name, 1, m.log_time, m.log_time]
        else:
            s[2] += 1
            s[3] = min(s[3], m.log_time)
            s[4] = max(s[4], m.log_time)
    channels = tuple(ChannelInfo(t, s[0], s[1], s[2], s[3] / 1e9, s[4] / 1e9) for t, s in sorted(stats.items()))
    start = min((c.first for c in channels), default=0.0)
    end = max((c.last for c in channels), default=0.0)
    return LogInfo(src, src.stat().st_size, result.complete, sum(c.count for c in channels), start, end, channels,
                   result.error)


def format_log_info(info: LogInfo) -> str:
    """A human-readable table of :func:`log_info`'s result."""
    lines = [f"{info.path}: {info.size_bytes / 1024:.1f} KiB, "
             f"{'complete' if info.complete else 'INCOMPLETE (writer did not finish: ' + str(info.cut_reason) + ')'}",
             f"messages {info.messages}, channels {len(info.channels)}, sim time {info.start:.3f} .. {info.end:.3f} s "
             f"(duration {info.duration:.3f} s)"]
    if info.channels:
        w = max(len(c.topic) for c in info.channels)
        lines.append(f"  {'topic':<{w}}  {'encoding':<9} {'count':>7} {'rate Hz':>9} {'first s':>9} {'last s':>9}  schema")
        for c in info.channels:
            lines.append(f"  {c.topic:<{w}}  {c.message_encoding:<9} {c.count:>7} {c.rate:>9.2f} {c.first:>9.3f} "
                         f"{c.last:>9.3f}  {c.schema_name or '-'}")
    return "\n".join(lines)
