"""The click commands (topic list/echo/hz, log info, replay) against a real router."""

from __future__ import annotations

import threading
from collections.abc import Iterator
from contextlib import contextmanager

import click
import pytest
from click.testing import CliRunner
from runtime_samples import sample_traffic, write_log

from cekm_swarm.protocol import DEFAULT_KEYS, WheelCommand
from cekm_swarm.runtime.bridge import Publishers, declare_alive
from cekm_swarm.runtime.commands import COMMANDS
from cekm_swarm.runtime.config import free_port

K = DEFAULT_KEYS
T = 20.0


@click.group()
def cli() -> None:
    """Stand-in for the main CLI."""


for _c in COMMANDS:
    cli.add_command(_c)


def run(*args: str):
    return CliRunner().invoke(cli, list(args), catch_exceptions=False)


@contextmanager
def steady_publisher(session, key: str, period: float = 0.01) -> Iterator[None]:
    """Publish a WheelCommand on ``key`` every ``period`` s from a thread, once someone listens."""
    stop = threading.Event()
    pubs = Publishers(session, block=True)

    def loop() -> None:
        if not pubs.wait_matching(key, T):
            return
        i = 0
        while not stop.is_set():
            pubs.send(key, WheelCommand(i * period, "r1/motor", 0.1, 0.1, i))
            if i == 3:
                pubs.put(K.cmd_wheels("r7"), b"\xc1")  # one malformed message
            i += 1
            stop.wait(period)

    t = threading.Thread(target=loop, daemon=True)
    t.start()
    try:
        yield
    finally:
        stop.set()
        t.join(T)
        pubs.close()


def test_commands_are_exported():
    assert [c.name for c in COMMANDS] == ["topic", "log", "replay", "monitor", "node", "record"]
    assert set(COMMANDS[0].commands) == {"list", "echo", "hz", "info", "pub"}
    assert set(COMMANDS[1].commands) == {"info", "cat", "recover"} and set(COMMANDS[4].commands) == {"list"}


def test_topic_echo_decodes_and_reports_malformed(router, clients):
    a = clients()
    with steady_publisher(a, K.cmd_wheels("r1")):
        result = run("topic", "echo", "cekm/*/cmd/wheels", "--connect", router, "--count", "6", "--timeout", "10")
    assert result.exit_code == 0, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 6
    assert lines[0].startswith("cekm/r1/cmd/wheels: cmd/wheels t=") and "seq=" in lines[0]
    assert any("cekm/r7/cmd/wheels: MALFORMED" in line for line in lines)


@pytest.mark.slow
def test_topic_list_and_hz(router, clients):
    a = clients()
    token = declare_alive(a, K.alive("r1", "motor"))
    with steady_publisher(a, K.cmd_wheels("r1")):
        listed = run("topic", "list", "--connect", router, "--window", "0.5")
        hz = run("topic", "hz", "cekm/r1/**", "--connect", router, "--duration", "0.6", "--interval", "0.3")
    token.undeclare()
    assert listed.exit_code == 0, listed.output
    assert "cekm/r1/cmd/wheels" in listed.output and "Hz" in listed.output
    assert "cekm/r1/alive/motor" in listed.output
    assert hz.exit_code == 0, hz.output
    table = [line for line in hz.output.splitlines() if line.startswith("cekm/r1/cmd/wheels")]
    assert len(table) >= 1
    rate = float(table[-1].split()[2])
    assert 20 < rate < 200  # published every 10 ms


def test_log_info_and_recover(tmp_path):
    path = tmp_path / "run.mcap"
    write_log(path, sample_traffic(20), chunk_size=2048)
    ok = run("log", "info", str(path))
    assert ok.exit_code == 0 and "complete" in ok.output and "cekm/world/clock" in ok.output
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    fixed = tmp_path / "fixed.mcap"
    res = run("log", "info", str(cut), "--recover", str(fixed))
    assert res.exit_code == 0 and "INCOMPLETE" in res.output and f"into {fixed}" in res.output
    assert "complete" in run("log", "info", str(fixed)).output
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(b"nope")
    err = CliRunner().invoke(cli, ["log", "info", str(bad)])
    assert err.exit_code != 0 and "not an MCAP file" in err.output


def test_replay_command(router, clients, tmp_path):
    path = tmp_path / "run.mcap"
    traffic = sample_traffic(10)
    write_log(path, traffic)
    b = clients()
    got: list[bytes] = []
    done = threading.Event()

    def on_sample(s):
        got.append(s.payload.to_bytes())
        if len(got) == len(traffic):
            done.set()

    sub = b.declare_subscriber("cekm/**", on_sample)
    # make sure the router has the subscription before the replay's new session publishes
    probe = Publishers(clients(), block=True)
    assert probe.wait_matching(K.world_clock(), T)
    probe.close()
    result = run("replay", str(path), "--connect", router, "--rate", "50")
    assert result.exit_code == 0, result.output
    assert f"published {len(traffic)} messages" in result.output
    assert done.wait(T) and got == [d for _, d, _ in traffic]
    sub.undeclare()


def test_unreachable_endpoint_is_a_clean_error():
    port = free_port()
    res = CliRunner().invoke(cli, ["topic", "list", "--connect", f"tcp/127.0.0.1:{port}", "--window", "0.1",
                                   "--wait", "0"])
    assert res.exit_code == 1 and f"no router at tcp/127.0.0.1:{port}" in res.output
    res = CliRunner().invoke(cli, ["topic", "list", "--connect", "127.0.0.1:7447"])
    assert res.exit_code != 0 and "expected e.g. 'tcp/127.0.0.1:7447'" in res.output


def test_topic_hz_says_why_a_key_has_no_rate_instead_of_nan():
    from cekm_swarm.runtime.topics import format_hz, hz_stats

    table = format_hz(
        [
            hz_stats("cekm/r1/sense/range/3", [1.0], 2.5),
            hz_stats("cekm/r1/cmd/wheels", [1.0, 1.128, 1.256], 2.5),
            hz_stats("cekm/r1/mine/x", [2.0], 2.5),
        ]
    ).splitlines()
    assert "nan" not in "\n".join(table)
    assert table[1].split()[:3] == ["cekm/r1/sense/range/3", "1", "-"] and table[1].endswith("held (sent when it "
                                                                                             "changes)")
    assert table[2].split()[2] == "7.81"
    assert table[3].endswith("fewer than 2 messages in the window")
