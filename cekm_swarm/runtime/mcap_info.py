"""The summary of a log (``cekm log info``): channels, counts, rates, duration."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .mcap_read import StreamResult, _open, stream_messages
from .mcap_sets import log_files


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
    files: tuple[str, ...] = ()  # a log set: its files, in order (one file: empty)

    @property
    def duration(self) -> float:
        """end - start, in seconds of sim time."""
        return self.end - self.start


def log_info(path: str | Path) -> LogInfo:
    """Summarise a log (complete or truncated; a file, or a log set as one log: see
    :mod:`.mcap_sets`) by streaming its messages once."""
    files = [_open(p) for p in log_files(path)]
    stats: dict[str, list[Any]] = {}
    complete, cut = True, None
    for src in files:
        result = StreamResult()
        for m in stream_messages(src, result):
            s = stats.get(m.topic)
            if s is None:
                stats[m.topic] = [m.message_encoding, m.schema_name, 1, m.log_time, m.log_time]
            else:
                s[2] += 1
                s[3] = min(s[3], m.log_time)
                s[4] = max(s[4], m.log_time)
        if not result.complete and complete:
            complete, cut = False, result.error if len(files) == 1 else f"{src.name}: {result.error}"
    channels = tuple(ChannelInfo(t, s[0], s[1], s[2], s[3] / 1e9, s[4] / 1e9) for t, s in sorted(stats.items()))
    start = min((c.first for c in channels), default=0.0)
    end = max((c.last for c in channels), default=0.0)
    shown = Path(path) if len(files) > 1 else files[0]
    return LogInfo(shown, sum(p.stat().st_size for p in files), complete, sum(c.count for c in channels), start, end,
                   channels, cut, tuple(str(p) for p in files) if len(files) > 1 else ())


def format_log_info(info: LogInfo) -> str:
    """A human-readable table of :func:`log_info`'s result."""
    lines = [f"{info.path}: {info.size_bytes / 1024:.1f} KiB, "
             f"{'complete' if info.complete else 'INCOMPLETE (writer did not finish: ' + str(info.cut_reason) + ')'}",
             f"messages {info.messages}, channels {len(info.channels)}, sim time {info.start:.3f} .. {info.end:.3f} s "
             f"(duration {info.duration:.3f} s)"]
    if info.files:
        lines.insert(1, f"a log set of {len(info.files)} files: {Path(info.files[0]).name} .. "
                        f"{Path(info.files[-1]).name}")
    if info.channels:
        w = max(len(c.topic) for c in info.channels)
        lines.append(f"  {'topic':<{w}}  {'encoding':<9} {'count':>7} {'rate Hz':>9} {'first s':>9} "
                     f"{'last s':>9}  schema")
        for c in info.channels:
            lines.append(f"  {c.topic:<{w}}  {c.message_encoding:<9} {c.count:>7} {c.rate:>9.2f} {c.first:>9.3f} "
                         f"{c.last:>9.3f}  {c.schema_name or '-'}")
    return "\n".join(lines)
