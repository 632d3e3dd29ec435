"""Zenoh plumbing of the distributed runtime: sessions and configs, the asyncio bridge,
publishers and liveliness, MCAP logging, replay and topic tools.

Submodules: :mod:`.config`, :mod:`.bridge`, :mod:`.mcap_log`, :mod:`.foxglove_view`
(needs ``foxglove-sdk``), :mod:`.replay`, :mod:`.topics`, :mod:`.commands` (click).
"""

from .bridge import (
                     MSGPACK,
                     AsyncSubscription,
                     LatestValues,
                     LivelinessEvent,
                     LivelinessWatcher,
                     Publishers,
                     Received,
                     declare_alive,
                     ring_subscriber,
                     wait_matching,
                     wait_matching_async,
)
from .config import (
                     DEFAULT_ENDPOINT,
                     DEFAULT_HOST,
                     DEFAULT_PORT,
                     client_config,
                     embedded_router_config,
                     free_port,
                     load_config,
                     open_client,
                     open_embedded_router,
                     open_session,
)
from .errors import McapLogError, RuntimeTransportError
from .mcap_log import (
                     ChannelInfo,
                     LoggedMessage,
                     LogInfo,
                     McapRecorder,
                     RecoveryReport,
                     format_log_info,
                     is_complete,
                     log_info,
                     read_messages,
                     record_zenoh,
                     recover_log,
                     stream_messages,
)
from .replay import ReplayResult, replay_log

__all__ = [
    "MSGPACK", "AsyncSubscription", "LatestValues", "LivelinessEvent", "LivelinessWatcher", "Publishers", "Received",
    "declare_alive", "ring_subscriber", "wait_matching", "wait_matching_async",
    "DEFAULT_ENDPOINT", "DEFAULT_HOST", "DEFAULT_PORT", "client_config", "embedded_router_config", "free_port",
    "load_config", "open_client", "open_embedded_router", "open_session",
    "McapLogError", "RuntimeTransportError",
    "ChannelInfo", "LoggedMessage", "LogInfo", "McapRecorder", "RecoveryReport", "format_log_info", "is_complete",
    "log_info", "read_messages", "record_zenoh", "recover_log", "stream_messages",
    "ReplayResult", "replay_log",
]
