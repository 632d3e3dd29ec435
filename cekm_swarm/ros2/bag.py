"""``cekm log export RUN.mcap --to ros2 --out BAG_DIR``: a run's log as a rosbag2 bag.

The bag is what ``ros2 bag record`` writes with its default storage: a directory with
``metadata.yaml`` (rosbag2 version 9) and one MCAP file with the ``ros2`` profile, one
channel per ROS topic with its ``ros2msg`` schema, CDR messages, zstd-compressed chunks.
The layout and the CDR come from the ``rosbags`` package (:class:`rosbags.rosbag2.Writer`,
its type stores), the messages from the key-to-ROS mapping (:mod:`.mapping`).

Every msgpack key channel of the log is read in log-time order and decoded with the
protocol's validating decoder (a malformed message is dropped and counted, as everywhere);
the Foxglove view channels are not exported (their content is in the mapping's topics).
A message's bag time is its sim-time stamp. A log whose writer was killed is exported up
to its cut. Scenario, seed and mode go into the bag's ``custom_data``.
"""

from __future__ import annotations

import itertools
import json
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mcap.reader import SeekingReader
from mcap.records import Metadata
from mcap.stream_reader import StreamReader

from cekm_swarm.errors import CekmError
from cekm_swarm.protocol import DEFAULT_KEYS, DropCounter, KeySpace
from cekm_swarm.runtime.mcap_log import MSGPACK, ResendFilter, is_complete, read_messages

from .interfaces import DEFAULT_DISTRO, interfaces
from .mapping import RosMapper
from .wire import Qos

PROGRESS_EVERY = 2000
"""Log messages between two progress calls."""


class ExportError(CekmError):
    """The export cannot be done (unwritable output); the message names the path."""


@dataclass
class ExportReport:
    """What an export did: messages read and dropped, messages written per topic."""

    source: Path
    bag: Path
    distro: str
    read: int = 0
    dropped: int = 0
    complete: bool = True
    topics: Counter[str] = field(default_factory=Counter)

    @property
    def written(self) -> int:
        return sum(self.topics.values())


def log_metadata(path: Path, complete: bool = True) -> dict[str, dict[str, str]]:
    """The log's metadata records {name: {key: value}} (scenario, seed, mode; the geometry):
    from the summary's index of a complete log (a recording may add the geometry late), from
    the start of an incomplete one (the world server writes them before its first message)."""
    out: dict[str, dict[str, str]] = {}
    with open(path, "rb") as f:
        try:
            if complete:
                for m in SeekingReader(f).iter_metadata():
                    out[m.name] = dict(m.metadata)
                return out
            for record in StreamReader(f, skip_magic=False).records:
                if isinstance(record, Metadata):
                    out[record.name] = dict(record.metadata)
                elif type(record).__name__ in ("Chunk", "Message"):
                    break
        except Exception:  # an unreadable summary or a cut before the first chunk: what was read is what there is
            pass
    return out


def geometry_of(metadata: dict[str, dict[str, str]]) -> dict[str, Any] | None:
    """The run's static scene from its ``geometry`` metadata record, None if absent or unreadable."""
    try:
        doc = json.loads(metadata["geometry"]["json"])
    except (KeyError, ValueError, TypeError):
        return None
    return doc if isinstance(doc, dict) else None


def msgpack_message_count(path: Path) -> int | None:
    """How many key-channel messages a complete log holds (from its summary), else None."""
    try:
        with open(path, "rb") as f:
            summary = SeekingReader(f).get_summary()
    except Exception:
        return None
    if summary is None or summary.statistics is None:
        return None
    ids = {cid for cid, ch in summary.channels.items() if ch.message_encoding == MSGPACK}
    return sum(n for cid, n in summary.statistics.channel_message_counts.items() if cid in ids)


def _rosbags_qos(q: Qos) -> Any:
    from rosbags.interfaces import Qos as RQos
    from rosbags.interfaces import QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime

    default = QosTime(0, 0)  # rmw's "default" duration: no deadline, no lifespan
    return RQos(QosHistory.KEEP_LAST, q.depth, QosReliability.RELIABLE if q.reliable else QosReliability.BEST_EFFORT,
                QosDurability.TRANSIENT_LOCAL if q.transient_local else QosDurability.VOLATILE, default, default,
                QosLiveliness.AUTOMATIC, default, False)


def export_ros2(log: str | Path, bag: str | Path, *, distro: str = DEFAULT_DISTRO, keys: KeySpace = DEFAULT_KEYS,
                progress: Callable[[int, int | None], None] | None = None) -> ExportReport:
    """Write the rosbag2 directory ``bag`` (absent or empty) from the run log ``log``.

    ``progress(done, total)`` is called every :data:`PROGRESS_EVERY` log messages and at
    the end (total None when the log is incomplete). Raises :class:`McapLogError` for a
    missing or non-MCAP ``log``, :class:`ExportError` for a log without a message and for an
    unusable ``bag``, both before anything is written."""
    from rosbags.rosbag2 import Writer
    from rosbags.rosbag2.enums import CompressionFormat, CompressionMode, StoragePlugin

    log, bag = Path(log), Path(bag)
    complete = is_complete(log)  # McapLogError: no such file, not an MCAP file
    messages = read_messages(log, encodings=[MSGPACK])
    first = next(messages, None)
    if first is None:
        raise ExportError(f"{log}: no message of the key space to export"
                          + ("" if complete else " (the log ends before its first message)"))
    if bag.exists():
        if not bag.is_dir() or any(bag.iterdir()):
            raise ExportError(f"{bag}: exists and is not an empty directory")
        bag.rmdir()  # the rosbag2 writer makes the directory itself
    ifc = interfaces(distro)
    metadata = log_metadata(log, complete)
    drops = DropCounter("ros2 export", keys=keys)
    mapper = RosMapper(ifc, geometry=geometry_of(metadata), keys=keys, drops=drops)
    total = msgpack_message_count(log) if complete else None
    report = ExportReport(log, bag, distro, complete=complete)
    writer = Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP)
    writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
    for k, v in sorted(metadata.get("cekm", {}).items()):
        writer.set_custom_data(f"cekm.{k}", str(v))
    writer.set_custom_data("cekm.source", log.name)
    writer.set_custom_data("cekm.ros_distro", distro)
    try:
        writer.open()
    except OSError as exc:
        raise ExportError(f"{bag}: cannot write: {exc.strerror or exc}") from None
    connections: dict[str, Any] = {}
    resends = ResendFilter()  # one message a tick per key: a stalled tick's re-sends are left out
    try:
        for m in itertools.chain([first], messages):
            report.read += 1
            msg = None if resends.is_resend(m) else drops.decode(m.topic, m.data)
            if msg is not None:
                for out in mapper.feed(m.topic, msg):
                    conn = connections.get(out.topic)
                    if conn is None:
                        conn = connections[out.topic] = writer.add_connection(
                            out.topic, out.ros_type, msgdef=ifc.definition(out.ros_type), rihs01=ifc.hash(out.ros_type),
                            offered_qos_profiles=[_rosbags_qos(out.qos)])
                    writer.write(conn, out.stamp_ns, ifc.cdr(out.msg, out.ros_type))
                    report.topics[out.topic] += 1
            if progress is not None and report.read % PROGRESS_EVERY == 0:
                progress(report.read, total)
    finally:
        writer.close()
    report.dropped = drops.total
    if progress is not None:
        progress(report.read, total if total is not None else report.read)
    return report


def format_report(r: ExportReport) -> str:
    """One line about an export, for the command's output."""
    cut = "" if r.complete else " (the log is incomplete: exported up to its cut)"
    drop = f", {r.dropped} malformed dropped" if r.dropped else ""
    rate = "" if not r.topics else f" on {len(r.topics)} topics"
    return (f"wrote {r.bag} (rosbag2, MCAP storage, ROS 2 {r.distro}): {r.written} messages{rate} from "
            f"{r.read} log messages{drop}{cut}")


__all__ = ["ExportError", "ExportReport", "export_ros2", "format_report", "geometry_of", "log_metadata",
           "msgpack_message_count"]
