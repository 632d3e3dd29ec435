"""Recovery of a log whose writer was killed: :func:`recover_log` rewrites every complete
record of it into a complete, indexed file."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from mcap.exceptions import McapError
from mcap.records import Attachment, Channel, Footer, Message, Metadata, Schema
from mcap.stream_reader import StreamReader

from .errors import McapLogError
from .mcap_read import _cut_reason, _open
from .mcap_record import DEFAULT_CHUNK_SIZE, McapRecorder, SchemaSpec


@dataclass(frozen=True, slots=True)
class RecoveryReport:
    """What :func:`recover_log` did: messages, channels, metadata and attachment records
    copied, and how the input ended (``cut_reason`` None when it was complete)."""

    source: Path
    output: Path
    messages: int
    channels: int
    input_complete: bool
    cut_reason: str | None
    metadata: int = 0
    attachments: int = 0


def recover_log(path: str | Path, output: str | Path | None = None, *,
                chunk_size: int = DEFAULT_CHUNK_SIZE,
                extra: Callable[[McapRecorder], object] | None = None) -> RecoveryReport:
    """Rewrite a (possibly truncated) log as a complete, indexed file.

    Reads the input's records in file order with the mcap library's stream reader (no
    index or footer needed) and writes every complete message, with its channel, schema,
    times and sequence, and every metadata and attachment record into ``output``
    (default ``<name>.recovered.mcap``). A record cut in the middle (the writer was
    killed while writing it, or its chunk was still in memory) ends the copy: what came
    before is kept. ``extra``, when given, then writes more into the output (channels of
    views made from the log: :func:`~cekm_swarm.runtime.lattice_view.add_lattice_channel`).
    The input is left untouched."""
    src = _open(path)
    out = Path(output) if output is not None else src.with_name(src.stem + ".recovered.mcap")
    if out.resolve() == src.resolve():
        raise McapLogError(str(src), "recovery output must differ from the input")
    schemas: dict[int, SchemaSpec] = {}
    channels: dict[int, int] = {}  # input channel id -> output channel id
    footer, cut = False, None
    n = n_meta = n_att = 0
    with McapRecorder(out, chunk_size=chunk_size, flush_interval=None) as rec, open(src, "rb") as f:
        try:
            for record in StreamReader(f, validate_crcs=True).records:
                if isinstance(record, Message):
                    cid = channels.get(record.channel_id)
                    if cid is None:
                        raise McapError(f"message on channel {record.channel_id}, which has no channel record")
                    rec.add_raw(cid, record.data, record.log_time, record.publish_time, record.sequence)
                    n += 1
                elif isinstance(record, Schema):
                    schemas[record.id] = SchemaSpec(record.name, record.encoding, bytes(record.data))
                elif isinstance(record, Channel):
                    spec = schemas.get(record.schema_id, SchemaSpec("")) if record.schema_id else SchemaSpec("")
                    channels[record.id] = rec.channel(record.topic, record.message_encoding, spec)
                elif isinstance(record, Metadata):
                    rec.add_metadata(record.name, dict(record.metadata))
                    n_meta += 1
                elif isinstance(record, Attachment):
                    rec.add_attachment(record.name, record.media_type, bytes(record.data), record.log_time,
                                       record.create_time)
                    n_att += 1
                elif isinstance(record, Footer):
                    footer = True
        except Exception as exc:  # the cut: EndOfFile, McapError (bad CRC), struct.error, zstd errors ...
            cut = _cut_reason(exc)
        if extra is not None:
            extra(rec)
        n_channels = len(rec.topics)
    if cut is None and not footer:
        cut = "no footer"
    return RecoveryReport(src, out, n, n_channels, cut is None, cut, n_meta, n_att)
