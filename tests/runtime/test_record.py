"""``cekm record`` keeps only stamps it can believe (as the world's own log does), and
stops on SIGTERM as on Ctrl-C: a complete file and its summary."""

from __future__ import annotations

import os
import shlex
import signal
import subprocess
import sys
import threading

import click
import msgpack
import pytest
from click.testing import CliRunner

from cekm_swarm.protocol import DEFAULT_KEYS as K
from cekm_swarm.protocol import Clock, WheelCommand, encode
from cekm_swarm.protocol import stamps as stamps_mod
from cekm_swarm.protocol.stamps import StampWindow
from cekm_swarm.runtime.bridge import Publishers
from cekm_swarm.runtime.commands import COMMANDS
from cekm_swarm.runtime.lines import LineReader
from cekm_swarm.runtime.mcap_log import McapRecorder, log_info, read_messages
from cekm_swarm.runtime.record import Recording, record_problem

T = 20.0


def tick(k: int) -> float:
    return round(k * 0.128, 9)


def wheels(stamp: object, seq: int = 1) -> bytes:
    """A well-formed wheel command but for its stamp (what a raw client can send)."""
    return msgpack.packb({"v": 1, "kind": "cmd/wheels", "stamp": stamp, "sender": "fuzz", "v_l": 0.1, "v_r": 0.1,
                          "seq": seq})


class FakeWall:
    """Stands in for ``time`` in the stamps module: a wall clock the test moves."""

    def __init__(self) -> None:
        self.now = 100.0

    def monotonic(self) -> float:
        return self.now


# --------------------------------------------------------------------------- the filter, no Zenoh


def test_record_problem_refuses_stamps_it_cannot_believe(monkeypatch):
    """Out of bounds, off the tick grid, or more than 8 ticks from the newest stamp taken:
    refused with the reason; an unreadable stamp is no reason (recorded at the latest time)."""
    wall = FakeWall()
    monkeypatch.setattr(stamps_mod, "time", wall)
    w = StampWindow()
    assert "outside [0, 1e+07]" in record_problem(1e300, w)  # before any stamp: the bounds still hold
    assert "outside [0, 1e+07]" in record_problem(-1.0, w)
    assert "outside [0, 1e+07]" in record_problem(1e18, w)
    assert record_problem(None, w) is None
    assert record_problem(tick(80), w) is None and w.newest == tick(80)  # the first in bounds: now
    assert "not a tick's sim time" in record_problem(tick(80) + 0.05, w)
    assert "outside [0, 1e+07]" in record_problem(1e300, w)
    assert "outside the window" in record_problem(tick(70), w)  # 10 ticks back
    assert "outside the window" in record_problem(tick(90), w)  # 10 ticks ahead
    assert record_problem(tick(73), w) is None and w.newest == tick(80)  # 7 ticks back: late, believed
    assert record_problem(tick(81), w) is None and w.newest == tick(81)
    wall.now += 0.5
    assert "outside the window" in record_problem(tick(5), w)
    wall.now += 1.0  # a second of wall time with no stamp taken (a new run, a replay looping back)
    assert record_problem(tick(5), w) is None and w.newest == tick(5)


def test_recording_drops_and_counts_unbelievable_stamps_so_the_logs_times_stay_sane(tmp_path):
    """What a raw client sent during a real-time run: stamps of 1e300, -1, 1e18 and between
    ticks on the run's keys. `cekm record` kept them (1e300 at the largest time MCAP holds,
    its summary said `sim time -1.000 .. 1e300 s`); now they are dropped and counted, an
    unreadable message is still recorded at the latest time taken."""
    out = tmp_path / "rec.mcap"
    with McapRecorder(out) as recorder:
        rec = Recording(recorder, views=False)
        for k in range(40, 45):
            rec.add(K.world_clock(), encode(Clock(tick(k), "world", k)))
            rec.add(K.cmd_wheels("r1"), encode(WheelCommand(tick(k), "r1/motor", 0.1, 0.1, k)))
            rec.add(K.cmd_wheels("r1"), wheels(1e300))
            rec.add(K.cmd_wheels("r1"), wheels(-1))
            rec.add(K.world_clock(), msgpack.packb({"v": 1, "kind": "world/clock", "stamp": 1e18, "sender": "fuzz",
                                                     "tick": -1}))
            rec.add(K.cmd_wheels("r1"), wheels(tick(k) + 0.05))
        rec.add(K.cmd_wheels("r2"), b"\x00\xff garbage")  # no stamp to read: recorded at the latest
    r = rec.result
    assert r.messages == 11 and r.dropped == 20
    assert (r.first_stamp, r.last_stamp) == (tick(40), tick(44))
    assert rec.stamp_drops.by_source() == {K.cmd_wheels("r1"): 15, K.world_clock(): 5}
    info = log_info(out)
    assert info.complete and info.messages == 11
    times = [m.log_time for m in read_messages(out)]
    assert min(times) == 5_120_000_000 and max(times) == 5_632_000_000  # ticks 40 .. 44


def test_record_summary_names_the_dropped_messages(router, clients, tmp_path):
    @click.group()
    def cli() -> None:
        """Stand-in for the main CLI."""

    for c in COMMANDS:
        cli.add_command(c)
    out = tmp_path / "rec.mcap"
    result: list = []
    t = threading.Thread(target=lambda: result.append(CliRunner().invoke(
        cli, ["record", "--out", str(out), "--connect", router, "--count", "3", "--no-views"],
        catch_exceptions=False)))
    a = clients()
    t.start()
    with Publishers(a, block=True) as pubs:
        assert pubs.wait_matching(K.cmd_wheels("r1"), T)  # the recorder's subscription is in place
        pubs.put(K.cmd_wheels("r1"), wheels(tick(10)))
        pubs.put(K.cmd_wheels("r1"), wheels(1e300))
        pubs.put(K.cmd_wheels("r1"), wheels(-1))
        pubs.put(K.cmd_wheels("r1"), wheels(tick(11)))
        pubs.put(K.cmd_wheels("r1"), wheels(tick(12)))
        t.join(T)
    assert not t.is_alive()
    res = result[0]
    assert res.exit_code == 0, res.output
    assert (f"recorded 3 messages on 1 keys, sim time 1.280 .. 1.536 s, 2 dropped (stamp not believable) "
            f"into {out}") in res.output
    assert log_info(out).complete


@pytest.mark.slow  # a router
def test_record_force_over_a_set_leaves_only_the_new_recording(router, clients, tmp_path):
    """--force replaces an existing log set as a whole: an old file past the new set's end
    would be read back as part of it."""

    @click.group()
    def cli() -> None:
        """Stand-in for the main CLI."""

    for c in COMMANDS:
        cli.add_command(c)
    for k in range(4):
        (tmp_path / f"run_{k}.mcap").write_bytes(b"an older recording")
    out = tmp_path / "run.mcap"
    result: list = []
    t = threading.Thread(target=lambda: result.append(CliRunner().invoke(
        cli, ["record", "--out", str(out), "--connect", router, "--count", "3", "--no-views", "--max-log-size", "1G",
              "--force"], catch_exceptions=False)))
    a = clients()
    t.start()
    with Publishers(a, block=True) as pubs:
        assert pubs.wait_matching(K.cmd_wheels("r1"), T)  # the recorder's subscription is in place
        for k in range(3):
            pubs.put(K.cmd_wheels("r1"), wheels(tick(10 + k)))
        t.join(T)
    assert not t.is_alive()
    assert result[0].exit_code == 0, result[0].output
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run_0.mcap"]
    assert log_info(tmp_path).complete and log_info(tmp_path).messages == 3


# --------------------------------------------------------------------------- SIGTERM


class Lines(LineReader):
    """A stream's lines, read by a thread, so every wait has a timeout (``T`` unless told)."""

    def expect(self, prefix: str, timeout: float = T, where=None) -> str:
        return super().expect(prefix, timeout, where)

    def rest(self, timeout: float = T) -> list[str]:
        return super().rest(timeout)


def start_record(*args: str) -> subprocess.Popen:
    """`cekm record ARGS` as `cekm record ... &` in a shell script starts it: SIGINT ignored."""
    cmd = " ".join(shlex.quote(a) for a in (sys.executable, "-m", "cekm_swarm", "record", *args))
    return subprocess.Popen(["sh", "-c", f"trap '' INT; exec {cmd}"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env={**os.environ, "PYTHONUNBUFFERED": "1"})


@pytest.mark.slow
def test_sigterm_ends_a_recording_like_ctrl_c(router, clients, tmp_path):
    """`cekm record` killed by SIGTERM left an MCAP file without its summary (`cekm log
    info` said INCOMPLETE) and printed nothing; now SIGTERM stops it as Ctrl-C does: the
    file closed with its summary, the summary line printed, exit 130."""
    out = tmp_path / "rec.mcap"
    proc = start_record("--out", str(out), "--connect", router, "--no-views")
    try:
        err = Lines(proc.stderr)
        err.expect("waiting for messages on ")
        a = clients()
        with Publishers(a, block=True) as pubs:
            assert pubs.wait_matching(K.world_clock(), T)  # the recorder's subscription is in place
            for k in range(5):
                pubs.send(K.world_clock(), Clock(tick(k), "world", k))
            err.expect("recording ")
        proc.send_signal(signal.SIGTERM)
        stdout = proc.stdout.read()
        rc = proc.wait(T)
        rest = err.rest()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert rc == 130, (rc, err.seen, stdout)
    assert stdout.startswith("recorded ") and f"into {out}" in stdout, (stdout, rest)
    info = log_info(out)
    assert info.complete, "the recording was not closed with its summary"
    assert info.messages == int(stdout.split()[1]) >= 1
    res = subprocess.run([sys.executable, "-m", "cekm_swarm", "log", "info", str(out)], capture_output=True,
                         text=True, timeout=60)
    assert res.returncode == 0 and ", complete" in res.stdout.splitlines()[0], res.stdout


@pytest.mark.slow
def test_sigterm_ends_a_recorder_still_waiting_for_its_router(tmp_path):
    """Before any file is opened, SIGTERM ends the wait for the router as Ctrl-C does
    (exit 130), whether or not SIGINT is ignored."""
    from cekm_swarm.runtime.config import free_port

    out = tmp_path / "rec.mcap"
    proc = start_record("--out", str(out), "--connect", f"tcp/127.0.0.1:{free_port()}", "--wait", "60")
    try:
        err = Lines(proc.stderr)
        err.expect("waiting for the router at ")
        proc.send_signal(signal.SIGTERM)
        rc = proc.wait(T)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert rc == 130 and err.rest() == ["cekm: interrupted"] and not out.exists()
