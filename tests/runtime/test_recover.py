"""Crash-safe logs: ``recover_log`` and ``cekm log recover`` on files cut anywhere (a writer
killed in the middle of a record, or with its chunk still in memory)."""

from __future__ import annotations

import os
import signal

import pytest
from click.testing import CliRunner
from mcap.reader import make_reader
from runtime_samples import sample_traffic

from cekm_swarm.cli import main as cli
from cekm_swarm.runtime.mcap_log import McapRecorder, is_complete, read_messages, recover_log


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


@pytest.mark.slow
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


@pytest.mark.slow
def test_sigkilled_world_server_loses_at_most_one_second(tmp_path, clients, router):
    """The world server alone in real time (its readings go out whether or not a robot
    answers), joined to a router, a subscriber beside it: SIGKILL the world mid-run, recover
    its log, and find in it every message the subscriber saw, up to 1 s (of sim time, which
    is wall time in real time) before the last one."""
    import subprocess
    import sys
    import threading

    from cekm_swarm.protocol import DEFAULT_KEYS as K
    from cekm_swarm.protocol import peek

    seen: list[tuple[str, float, bytes]] = []
    enough = threading.Event()

    def on_sample(sample):
        payload = sample.payload.to_bytes()
        _, stamp = peek(payload)
        seen.append((str(sample.key_expr), stamp, payload))
        if stamp is not None and stamp >= 3.0:
            enough.set()

    session = clients()
    sub = session.declare_subscriber(K.everything(), on_sample)  # before tick 0: the world waits for it
    out = tmp_path / "world"
    world = subprocess.Popen([sys.executable, "-m", "world.server", "lone_obstacle", "--connect", router,
                              "--out", str(out), "--mode", "realtime", "--max-time", "60", "--match-timeout", "30"],
                             stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        assert enough.wait(60), f"the world did not reach 3 s of sim time ({len(seen)} messages seen)"
        world.send_signal(signal.SIGKILL)
        world.wait(timeout=10)
    finally:
        if world.poll() is None:
            world.kill()
    sub.undeclare()
    log = out / "run.mcap"
    assert not is_complete(log)
    report = recover_log(log, tmp_path / "recovered.mcap")
    assert not report.input_complete and is_complete(report.output)
    last = max(s for _, s, _ in seen if s is not None)
    logged = [(m.topic, m.log_time, m.data) for m in read_messages(report.output) if m.message_encoding == "msgpack"]
    cutoff = last - 1.0
    saw = sorted((k, round(s * 1e9), p) for k, s, p in seen if s is not None and s <= cutoff)
    kept = sorted(m for m in logged if m[1] <= round(cutoff * 1e9))
    assert saw and kept == saw  # every message up to 1 s before the kill, and nothing else
    assert max(t for _, t, _ in logged) >= round(cutoff * 1e9)
