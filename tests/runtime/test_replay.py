"""Replay republishes exactly the recorded messages, in order, at the recorded timing."""

from __future__ import annotations

import threading
import time

import pytest
from runtime_samples import sample_traffic, write_log

from cekm_swarm.protocol import DEFAULT_KEYS
from cekm_swarm.runtime.bridge import Publishers
from cekm_swarm.runtime.config import free_port
from cekm_swarm.runtime.mcap_log import McapRecorder
from cekm_swarm.runtime.replay import ReplayControl, replay_log

K = DEFAULT_KEYS
T = 20.0


def ready_publishers(session, probe_key: str) -> Publishers:
    """BLOCK publishers whose session already knows the subscriber (no message can be lost
    to a subscription still propagating)."""
    pubs = Publishers(session, block=True)
    assert pubs.wait_matching(probe_key, T)
    return pubs


@pytest.mark.slow
def test_replay_republishes_exactly_the_recorded_messages_in_order(tmp_path, clients, helpers, router):
    path = tmp_path / "run.mcap"
    traffic = sample_traffic(30)
    with McapRecorder(path) as rec:
        for key, data, t in traffic:
            rec.write(key, data, t)
        rec.write_encoded("/view/other", "json", rec._msgpack_schema("x"), b"{}", 0.0)  # not republished
    sub = helpers("sub", router, "cekm/**", str(len(traffic)))
    sub.expect("READY")
    a = clients()
    pubs = ready_publishers(a, traffic[0][0])
    result = replay_log(a, path, rate=None, publishers=pubs)
    lines = sub.lines_until("DONE")
    pubs.close()
    got = [(k, bytes.fromhex(h)) for k, h in (line.split("\t") for line in lines)]
    assert got == [(k, d) for k, d, _ in traffic]
    assert result.published == len(traffic) and result.loops == 1
    assert result.per_key[K.world_clock()] == 30 and "/view/other" not in result.per_key
    assert result.sim_seconds == pytest.approx(29 * 0.128)


def test_replay_follows_recorded_timing_scaled_by_rate(tmp_path, clients):
    path = tmp_path / "run.mcap"
    write_log(path, [(K.world_clock(), b"\x80", t) for t in (0.0, 0.5, 1.0)])
    a, b = clients(), clients()
    arrivals: list[float] = []
    done = threading.Event()

    def on_sample(_):
        arrivals.append(time.monotonic())
        if len(arrivals) == 3:
            done.set()

    sub = b.declare_subscriber(K.world_clock(), on_sample)
    pubs = ready_publishers(a, K.world_clock())
    result = replay_log(a, path, rate=5.0, publishers=pubs)  # 1 s of sim time in 0.2 s
    assert done.wait(T)
    sub.undeclare()
    pubs.close()
    assert 0.19 <= result.wall_seconds < 1.0  # never ahead of the scaled schedule
    assert 0.15 <= arrivals[2] - arrivals[0] < 0.6  # 0.2 s apart, whatever the scheduling noise


def test_replay_loops_and_filters_and_stops(tmp_path, clients):
    path = tmp_path / "run.mcap"
    traffic = sample_traffic(5)
    write_log(path, traffic)
    a, b = clients(), clients()
    got: list[str] = []
    lock = threading.Lock()
    expected = 2 * sum(1 for k, _, _ in traffic if k.startswith("cekm/r1/"))
    enough = threading.Event()

    def on_sample(s):
        with lock:
            got.append(str(s.key_expr))
            if len(got) == expected:
                enough.set()

    sub = b.declare_subscriber("cekm/**", on_sample)
    pubs = ready_publishers(a, K.cmd_wheels("r1"))
    result = replay_log(a, path, rate=None, loop=True, max_loops=2, key_expr="cekm/r1/**", publishers=pubs)
    assert enough.wait(T)
    assert result.loops == 2 and result.published == expected
    assert all(k.startswith("cekm/r1/") for k in got)
    stop = threading.Event()
    stop.set()
    stopped = replay_log(a, path, rate=1.0, loop=True, stop=stop, publishers=pubs)
    assert stopped.stopped and stopped.published == 0
    sub.undeclare()
    pubs.close()


def test_a_looping_replay_is_quiet_between_loops_so_readers_take_the_next_as_a_new_run(tmp_path, clients):
    """A module's stamp window and ``cekm record`` take any stamp after QUIET_S without one:
    the pause lets them take the next loop's early stamps instead of dropping them."""
    from cekm_swarm.protocol.stamps import QUIET_S, StampWindow
    from cekm_swarm.runtime.replay import LOOP_PAUSE_S

    path = tmp_path / "run.mcap"
    stamps = [round(0.128 * k, 3) for k in range(17)]  # 2.048 s: more than a window (8 ticks) behind at the loop
    write_log(path, [(K.world_clock(), bytes([0x80]), t) for t in stamps])
    a = clients()
    sent: list[tuple[float, float]] = []  # (wall time, log time)
    window = StampWindow()  # a reader judging each stamp as it goes out
    taken: list[bool] = []

    def on_publish(m) -> None:
        sent.append((time.monotonic(), m.log_time / 1e9))
        taken.append(window.check(m.log_time / 1e9) is None)

    result = replay_log(a, path, rate=None, loop=True, max_loops=2, on_publish=on_publish)
    assert result.loops == 2 and [t for _, t in sent] == stamps + stamps
    assert sent[17][0] - sent[16][0] >= LOOP_PAUSE_S > QUIET_S
    assert abs(result.sim_seconds - 2 * 2.048) < 1e-9
    assert all(taken), taken


def test_replay_starts_at_an_offset_and_reports_progress(tmp_path, clients):
    path = tmp_path / "run.mcap"
    write_log(path, [(K.world_clock(), bytes([0x80 + 0]), t) for t in (0.0, 0.5, 1.0, 1.5, 2.0)])
    a, b = clients(), clients()
    got: list[float] = []
    done = threading.Event()
    sub = b.declare_subscriber(K.world_clock(), lambda s: (got.append(time.monotonic()), len(got) == 3 and done.set()))
    pubs = ready_publishers(a, K.world_clock())
    reports = []
    result = replay_log(a, path, rate=None, start=0.9, publishers=pubs, on_progress=reports.append)
    assert done.wait(T)
    sub.undeclare()
    pubs.close()
    assert result.published == 3 and result.sim_seconds == pytest.approx(1.0)  # 1.0, 1.5, 2.0
    last = reports[-1]
    assert (last.sim_time, last.start, last.end, last.published, last.fraction) == (2.0, 0.0, 2.0, 3, 1.0)
    assert last.line().startswith("replay    2.00 / 2.00 s  100%  3 msgs  loop 1")


def test_replay_pauses_and_resumes(tmp_path, clients):
    """Paused before the first message, the replay publishes nothing and reports it is
    paused; resumed, it publishes everything, keeping the recorded gaps."""
    path = tmp_path / "run.mcap"
    write_log(path, [(K.world_clock(), b"\x80", t) for t in (0.0, 0.2, 0.4)])
    a = clients()
    pubs = Publishers(a, block=True)
    control = ReplayControl()
    control.pause()
    paused = threading.Event()
    reports = []

    def on_progress(p):
        reports.append(p)
        if p.paused:
            paused.set()

    out: list = []
    t = threading.Thread(target=lambda: out.append(replay_log(a, path, rate=1.0, publishers=pubs, control=control,
                                                               on_progress=on_progress)))
    t.start()
    assert paused.wait(T)
    assert all(p.published == 0 for p in reports) and reports[-1].line().endswith("[paused: space to resume]")
    t_resume = time.perf_counter()
    control.resume()
    t.join(T)
    pubs.close()
    result = out[0]
    assert result.published == 3 and not result.stopped
    assert time.perf_counter() - t_resume >= 0.4  # the gaps after the pause were kept (never ahead of schedule)
    stop = threading.Event()
    control.pause()
    stopper = threading.Thread(target=lambda: paused.wait(T) and stop.set())
    paused.clear()
    stopper.start()
    stopped = replay_log(a, path, rate=1.0, publishers=Publishers(a, block=True), control=control, stop=stop,
                         on_progress=on_progress)
    stopper.join(T)
    assert stopped.stopped and stopped.published == 0  # a stop ends a paused replay


@pytest.mark.slow
def test_replay_command_hosts_the_router_when_told_no_endpoint(tmp_path):
    """`cekm replay LOG --port P` with no --connect and no CEKM_CONNECT hosts the router:
    a client joins it (waiting until it is up), receives the replay, and Ctrl-C ends it
    with exit code 130. A taken port is a clear error."""
    import os
    import signal
    import subprocess
    import sys

    from cekm_swarm.runtime.wait import ENV_CONNECT, open_client_when_ready

    path = tmp_path / "run.mcap"
    write_log(path, sample_traffic(10))
    port = free_port()
    env = {k: v for k, v in os.environ.items() if k != ENV_CONNECT}
    proc = subprocess.Popen([sys.executable, "-m", "cekm_swarm", "replay", str(path), "--port", str(port), "--loop",
                             "--rate", "10"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        session = open_client_when_ready(f"tcp/127.0.0.1:{port}", timeout=T)
        got = threading.Event()
        sub = session.declare_subscriber(K.cmd_wheels("r1"), lambda s: got.set())
        assert got.wait(T)
        sub.undeclare()
        taken = subprocess.run([sys.executable, "-m", "cekm_swarm", "replay", str(path), "--port", str(port)],
                               capture_output=True, text=True, env=env, timeout=60)
        session.close()
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=T)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 130, err
    assert f"replay: hosting the router on tcp/127.0.0.1:{port}" in err and out.startswith("published ")
    assert taken.returncode == 1 and f"holds port {port}?" in taken.stderr


def gap_log(path) -> int:
    """A log as `cekm record` wrote it before it judged stamps: a -1 stamp filed at 0, a run
    joined at 500 s of sim time, and 1e300 stamps filed at the largest time MCAP holds.
    Returns the number of messages."""
    traffic = [(K.cmd_wheels("r1"), b"\x80", -1.0)]
    traffic += [(K.world_clock(), bytes([0x80 + k]), round(500.0 + k * 0.128, 9)) for k in range(5)]
    traffic += [(K.cmd_wheels("r1"), b"\x81", 1e300)] * 2
    write_log(path, traffic)
    return len(traffic)


def test_replay_does_not_wait_across_a_gap_no_run_has(tmp_path, clients):
    """Replaying such a log at the recorded timing published the first message, then waited
    500 s for the run, then 584 years for the last ones; now a gap of more than MAX_GAP_S
    between two messages is not waited for, counted, and left out of the sim time."""
    path = tmp_path / "rec.mcap"
    n = gap_log(path)
    a = clients()
    pubs = Publishers(a, block=True)
    out: list = []
    stop = threading.Event()
    t = threading.Thread(target=lambda: out.append(replay_log(a, path, rate=1.0, publishers=pubs, stop=stop)))
    t.start()
    t.join(T)
    stop.set()  # a replay still waiting ends (and the test fails below)
    t.join(T)
    pubs.close()
    result = out[0]
    assert not result.stopped, f"still waiting after {T} s: published {result.published} of {n}"
    from cekm_swarm.runtime.replay import MAX_GAP_S

    assert result.published == n and result.jumped == 2 and MAX_GAP_S < 500
    assert result.sim_seconds == pytest.approx(4 * 0.128)
    assert 4 * 0.128 <= result.wall_seconds < 4 * 0.128 + 2.0  # the run's own gaps still kept
    fast = replay_log(a, path, rate=None)
    assert fast.published == n and fast.jumped == 2 and fast.sim_seconds == pytest.approx(4 * 0.128)


def test_replay_command_says_how_many_gaps_it_did_not_wait_for(tmp_path, router):
    import click
    from click.testing import CliRunner

    from cekm_swarm.runtime.commands import COMMANDS

    @click.group()
    def cli() -> None:
        """Stand-in for the main CLI."""

    for c in COMMANDS:
        cli.add_command(c)
    path = tmp_path / "rec.mcap"
    n = gap_log(path)
    out: list = []
    t = threading.Thread(target=lambda: out.append(CliRunner().invoke(
        cli, ["replay", str(path), "--connect", router, "--rate", "100"], catch_exceptions=False)), daemon=True)
    t.start()
    t.join(T)
    assert not t.is_alive(), "the replay is still waiting"
    res = out[0]
    assert res.exit_code == 0, res.output
    assert res.stdout.startswith(f"published {n} messages on 2 keys in 1 loop(s), 0.512 s of sim time")
    warning = [line for line in res.stderr.splitlines() if "did not wait" in line]
    assert warning == ["replay: did not wait across 2 gap(s) of more than 60 s of sim time between two messages "
                       "(log times no run reaches: stamps its recorder should not have kept)"]
