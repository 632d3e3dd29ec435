"""Crash-safe logs: ``recover_log`` and ``cekm log recover`` on files cut anywhere (a writer
killed in the middle of a record, or with its chunk still in memory)."""

from __future__ import annotations

import os
import signal

from click.testing import CliRunner
from mcap.reader import make_reader

from cekm_swarm.cli import main as cli
from cekm_swarm.runtime.mcap_log import McapRecorder, is_complete, read_messages, recover_log
from runtime_samples import sample_traffic


def _write(path, traffic, chunk_size=1024):
    with McapRecorder(path, chunk_size=chunk_size, flush_interval=None,
                      metadata={"scenario": "concave", "seed": "1"}) as rec:
        rec.add_metadata("geometry", {"json": "[]"})
        for key, data, t in traffic:
            rec.write(key, data, t)


def _indexed(path):
    """(topic, data, log_time) of every message and the metadata, read with the seeking reader."""
    with open(path, "rb") as f:
        reader = make_reader(f)
        assert reader.get_summary() is not None
        msgs = [(c.topic, m.data, m.log_time) for _, c, m in reader.iter_messages(log_time_order=False)]
        meta = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
    return msgs, meta


def test_a_cut_anywhere_recovers_a_prefix_of_the_messages(tmp_path):
    path = tmp_path / "run.mcap"
    traffic = sample_traffic(12)
    _write(path, traffic)
    data = path.read_bytes()
    full, meta = _indexed(path)
    assert len(full) == len(traffic) and meta["cekm"]["scenario"] == "concave"
    cut, out = tmp_path / "cut.mcap", tmp_path / "out.mcap"
    previous = 0
    # every 199th byte (a prime: cuts land at varied places inside the header, metadata,
    # chunk, message-index and summary records), and one byte short of the end
    for size in list(range(len(b"\x89MCAP0\r\n"), len(data), 199)) + [len(data) - 1]:
        cut.write_bytes(data[:size])
        report = recover_log(cut, out)
        assert not report.input_complete and report.cut_reason, size
        got, got_meta = _indexed(out)
        assert report.messages == len(got) and got == full[:len(got)], size  # a prefix, in order
        assert len(got) >= previous, size  # a longer file never gives fewer messages
        previous = len(got)
        if got:  # the metadata come before the first chunk
            assert got_meta == meta
    assert previous == len(traffic)  # cut in the summary: every message is back
    whole = recover_log(path, out)
    assert whole.input_complete and whole.cut_reason is None and whole.messages == len(traffic)
    assert whole.metadata == 2 and _indexed(out) == (full, meta)


def test_log_recover_command_on_a_killed_writer(tmp_path, helpers):
    path = tmp_path / "killed.mcap"
    writer = helpers("mcap", str(path), "300")
    writer.expect("FLUSHED 300")
    os.kill(writer.proc.pid, signal.SIGKILL)
    writer.proc.wait(timeout=10)
    out = tmp_path / "fixed.mcap"
    res = CliRunner().invoke(cli, ["log", "recover", str(path), str(out)])
    assert res.exit_code == 0, res.output
    assert "recovered 300 messages on 1 channels" in res.output and "ends early" in res.output
    assert is_complete(out) and not is_complete(path)
    assert len(list(read_messages(out))) == 300
    again = CliRunner().invoke(cli, ["log", "recover", str(path), str(out)])
    assert again.exit_code != 0 and "exists; use --force" in again.output
    assert CliRunner().invoke(cli, ["log", "recover", str(path), str(out), "--force"]).exit_code == 0
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(b"not mcap")
    err = CliRunner().invoke(cli, ["log", "recover", str(bad), str(tmp_path / "x.mcap")])
    assert err.exit_code != 0 and "bad.mcap: not an MCAP file" in err.output
