"""The fast MCAP writer writes exactly the bytes of ``mcap.writer.Writer`` (same calls,
same options), and its files read back with the independent ``mcap`` reader."""

from __future__ import annotations

import io
import random

import pytest
from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer

from cekm_swarm.runtime.mcap_writer import ChunkedWriter

COMPRESSION = {"zstd": CompressionType.ZSTD, "none": CompressionType.NONE}


def _calls(seed: int, n: int) -> list[tuple]:
    """A random sequence of writer calls: schemas and channels registered along the way,
    messages with times that go back and forth, metadata, attachments and flushes between."""
    rng = random.Random(seed)
    calls: list[tuple] = [("schema", "cekm.sense/range", "", b""), ("channel", "cekm/r1/sense/range/0", "msgpack", 1)]
    schemas, channels = 1, 1
    t = 0
    for _ in range(n):
        r = rng.random()
        if r < 0.03:
            schemas += 1
            calls.append(("schema", f"s{schemas}", rng.choice(["", "protobuf"]), rng.randbytes(rng.randrange(0, 40))))
        elif r < 0.08:
            channels += 1
            calls.append(("channel", f"topic/{channels}", rng.choice(["msgpack", "protobuf"]), rng.randint(0, schemas)))
        elif r < 0.09:
            calls.append(("metadata", f"m{len(calls)}", {"k": str(rng.random())}))
        elif r < 0.095:
            calls.append(("attachment", rng.randrange(0, 1 << 40), t, f"a{len(calls)}", "text/plain",
                          rng.randbytes(rng.randrange(0, 300))))
        elif r < 0.11:
            calls.append(("flush",))
        else:
            t = max(0, t + rng.randint(-2_000_000, 130_000_000))
            size = rng.choice([0, 1, 40, 300, 1000, 5000])
            calls.append(("message", rng.randint(1, channels), t, rng.randbytes(size), t + rng.randint(0, 9),
                          rng.randrange(0, 1 << 32)))
    return calls


def _play(writer, calls: list[tuple]) -> None:
    writer.start(profile="", library="cekm-swarm test")
    for c in calls:
        kind, args = c[0], c[1:]
        if kind == "schema":
            writer.register_schema(*args)
        elif kind == "channel":
            writer.register_channel(*args)
        elif kind == "metadata":
            writer.add_metadata(*args)
        elif kind == "attachment":
            create, log, name, media, data = args
            writer.add_attachment(create_time=create, log_time=log, name=name, media_type=media, data=data)
        elif kind == "flush":
            writer.flush()
        else:
            cid, log, data, publish, seq = args
            writer.add_message(cid, log_time=log, data=data, publish_time=publish, sequence=seq)
    writer.finish()


@pytest.mark.parametrize("compression", ["zstd", "none"])
@pytest.mark.parametrize("seed", [1, 2, 3])
@pytest.mark.parametrize("chunk_size", [512, 8 * 1024, 64 * 1024])
def test_same_bytes_as_the_mcap_writer(seed, compression, chunk_size):
    calls = _calls(seed, 1500)
    theirs, ours = io.BytesIO(), io.BytesIO()
    _play(Writer(theirs, chunk_size=chunk_size, compression=COMPRESSION[compression]), calls)
    _play(ChunkedWriter(ours, chunk_size=chunk_size, compression=compression), calls)
    assert len(ours.getvalue()) > 1000
    assert ours.getvalue() == theirs.getvalue()


def test_an_empty_file_and_one_without_messages_match_too():
    for calls in ([], [("schema", "s", "", b""), ("channel", "t", "msgpack", 1), ("metadata", "m", {"a": "b"})]):
        theirs, ours = io.BytesIO(), io.BytesIO()
        _play(Writer(theirs, chunk_size=1024), calls)
        _play(ChunkedWriter(ours, chunk_size=1024), calls)
        assert ours.getvalue() == theirs.getvalue()


def test_the_mcap_reader_reads_every_message_back():
    calls = _calls(7, 800)
    out = io.BytesIO()
    _play(ChunkedWriter(out, chunk_size=4096), calls)
    sent = [(c[1], c[2], c[3]) for c in calls if c[0] == "message"]
    reader = make_reader(io.BytesIO(out.getvalue()))
    got = [(ch.id, m.log_time, m.data) for _, ch, m in reader.iter_messages(log_time_order=False)]
    assert got == sent
    stats = reader.get_summary().statistics
    assert stats.message_count == len(sent)


def test_an_unknown_compression_is_refused():
    with pytest.raises(ValueError, match="compression 'brotli'"):
        ChunkedWriter(io.BytesIO(), compression="brotli")


def test_memory_stays_flat_over_many_chunks(tmp_path):
    """The chunk indexes spill to a temporary file: writing ten times more chunks (each
    with a hundred channels) keeps the writer's memory within the spool's bound, and the
    file still reads back whole through its index."""
    import tracemalloc

    from cekm_swarm.runtime.mcap_writer import INDEX_SPOOL

    path = tmp_path / "long.mcap"
    with open(path, "wb") as f:
        w = ChunkedWriter(f, chunk_size=4096, compression="none")
        w.start()
        sid = w.register_schema("s", "", b"")
        channels = [w.register_channel(f"t/{i}", "msgpack", sid) for i in range(100)]
        payload = bytes(30)
        t = 0

        def chunks(n: int) -> None:
            nonlocal t
            for _ in range(n):
                for cid in channels:
                    t += 1000
                    w.add_message(cid, t, payload, t)
                w.flush()

        chunks(200)
        tracemalloc.start()
        before = tracemalloc.get_traced_memory()[0]
        chunks(2000)
        grown = tracemalloc.get_traced_memory()[0] - before
        tracemalloc.stop()
        w.finish()
    assert grown < INDEX_SPOOL + 64 * 1024, grown  # before: ~2 KB per chunk, 4 MB here
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary.statistics.message_count == 2200 * 100
        assert len(summary.chunk_indexes) == summary.statistics.chunk_count > 2200
        assert sum(1 for _ in reader.iter_messages()) == 2200 * 100
