"""MCAP logs of the key space: record, read, recover after a crash, summarise. One name
for the parts, each its own module:

- :mod:`.mcap_record`: :class:`McapRecorder` (one file: channels per key, sim-time
  stamps, chunked and indexed by :mod:`.mcap_writer`, flushed every half second, closed
  cleanly when its disk fills) and :func:`record_zenoh`;
- :mod:`.mcap_read`: :func:`read_messages` (time order), :func:`stream_messages` (file
  order, up to a cut), :func:`is_complete`, :func:`log_root`, :func:`without_resends` and
  :class:`ResendFilter` (one sample a tick);
- :mod:`.mcap_recover`: :func:`recover_log`;
- :mod:`.mcap_info`: :func:`log_info`, :func:`format_log_info`.
"""

from __future__ import annotations

from .mcap_info import ChannelInfo, LogInfo, format_log_info, log_info
from .mcap_read import (
    LoggedMessage,
    ResendFilter,
    StreamResult,
    is_complete,
    log_root,
    read_messages,
    stream_messages,
    without_resends,
)
from .mcap_record import (
    DEFAULT_CHUNK_SIZE,
    DEFAULT_FLUSH_INTERVAL,
    LIBRARY,
    MAX_CHANNELS,
    MAX_NS,
    MSGPACK,
    PROFILE,
    McapRecorder,
    SchemaSpec,
    record_zenoh,
    sim_ns,
)
from .mcap_recover import RecoveryReport, recover_log

__all__ = ["ChannelInfo", "LogInfo", "format_log_info", "log_info", "LoggedMessage", "StreamResult", "is_complete",
           "log_root", "read_messages", "stream_messages", "without_resends", "ResendFilter", "DEFAULT_CHUNK_SIZE",
           "DEFAULT_FLUSH_INTERVAL", "LIBRARY",
           "MAX_CHANNELS", "MAX_NS", "MSGPACK", "PROFILE", "McapRecorder", "SchemaSpec", "record_zenoh", "sim_ns",
           "RecoveryReport", "recover_log"]
