"""Endpoint resolution (--connect > CEKM_CONNECT > default) and waiting for the router."""

from __future__ import annotations

import os
import subprocess
import sys
import threading

import pytest

from cekm_swarm.protocol import DEFAULT_KEYS as K
from cekm_swarm.protocol import WheelCommand
from cekm_swarm.runtime.bridge import Publishers
from cekm_swarm.runtime.config import DEFAULT_ENDPOINT, client_config, free_port, open_embedded_router
from cekm_swarm.runtime.errors import RuntimeTransportError
from cekm_swarm.runtime.wait import ENV_CONNECT, open_client_when_ready, open_when_ready, resolve_endpoint

T = 20.0


def test_connect_option_beats_the_environment_which_beats_the_default():
    env = {ENV_CONNECT: "tcp/10.0.0.2:7448"}
    assert resolve_endpoint("tcp/127.0.0.1:9", env).endpoint == "tcp/127.0.0.1:9"
    assert resolve_endpoint("tcp/127.0.0.1:9", env).source == "--connect"
    got = resolve_endpoint(None, env)
    assert (got.endpoint, got.source, got.explicit) == ("tcp/10.0.0.2:7448", ENV_CONNECT, True)
    got = resolve_endpoint(None, {ENV_CONNECT: "  "})
    assert (got.endpoint, got.source, got.explicit) == (DEFAULT_ENDPOINT, "default", False)
    with pytest.raises(RuntimeTransportError, match=f"^{ENV_CONNECT}: endpoint '10.0.0.2:7448'"):
        resolve_endpoint(None, {ENV_CONNECT: "10.0.0.2:7448"})
    with pytest.raises(RuntimeTransportError, match="^--connect: endpoint 'nope'"):
        resolve_endpoint("nope", env)


@pytest.mark.parametrize("port", ["0", "65536", "99999"])
def test_a_port_that_cannot_exist_is_refused_at_once(port):
    """It was accepted and waited for as 'no router' (--wait 60: a minute for a typo)."""
    endpoint = f"tcp/127.0.0.1:{port}"
    with pytest.raises(
        RuntimeTransportError, match=f"^--connect: endpoint '{endpoint}': port {port} is not in 1..65535"
    ):
        resolve_endpoint(endpoint, {})
    with pytest.raises(RuntimeTransportError, match=f"^{ENV_CONNECT}: endpoint '{endpoint}': port {port} is not in"):
        resolve_endpoint(None, {ENV_CONNECT: endpoint})
    assert resolve_endpoint("tcp/127.0.0.1:65535", {}).endpoint == "tcp/127.0.0.1:65535"


def test_waits_for_a_router_that_comes_up_later():
    port = free_port()
    endpoint = f"tcp/127.0.0.1:{port}"
    said: list[str] = []
    waiting = threading.Event()

    def say(text: str) -> None:
        said.append(text)
        waiting.set()

    routers = []

    def bring_up() -> None:  # once the client says it waits, start the router
        if waiting.wait(T):
            routers.append(open_embedded_router(port))

    t = threading.Thread(target=bring_up)
    t.start()
    session = open_when_ready(lambda: client_config(endpoint), endpoint, timeout=T, say=say)
    t.join(T)
    session.close()
    routers[0].close()
    assert said == [f"waiting for the router at {endpoint} ..."]


def test_gives_up_after_the_timeout_naming_the_endpoint():
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    with pytest.raises(RuntimeTransportError, match=f"no router at {endpoint} after waiting"):
        open_client_when_ready(endpoint, timeout=0.3)
    with pytest.raises(RuntimeTransportError, match=f"no router at {endpoint} \\(start a run"):
        open_client_when_ready(endpoint, timeout=0)


@pytest.mark.slow
def test_topic_echo_started_before_the_router_waits_for_it_and_for_messages():
    """`cekm topic echo` with CEKM_CONNECT only: it says it waits for the router, then for
    messages, then prints the first one as JSON."""
    port = free_port()
    env = dict(os.environ, **{ENV_CONNECT: f"tcp/127.0.0.1:{port}"})
    proc = subprocess.Popen([sys.executable, "-m", "cekm_swarm", "topic", "echo", K.cmd_wheels("r1"), "-n", "1",
                             "--json"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        assert proc.stderr.readline().strip() == f"waiting for the router at tcp/127.0.0.1:{port} ..."
        router = open_embedded_router(port)
        try:
            assert proc.stderr.readline().strip() == f"waiting for messages on {K.cmd_wheels('r1')} ..."
            with Publishers(router, block=True) as pubs:
                assert pubs.wait_matching(K.cmd_wheels("r1"), T)
                pubs.send(K.cmd_wheels("r1"), WheelCommand(1.5, "r1/motor", 0.1, 0.2, 7))
                out, err = proc.communicate(timeout=T)
        finally:
            router.close()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 0, err
    assert out.strip() == ('{"key":"cekm/r1/cmd/wheels","message":{"kind":"cmd/wheels","stamp":1.5,'
                           '"sender":"r1/motor","v_l":0.1,"v_r":0.2,"seq":7}}')


def test_a_refused_session_is_not_waited_for(tmp_path):
    """A wrong password fails like an absent router in Zenoh ("Unable to connect");
    open_session tells them apart by the listening port, and the wait fails at once."""
    import shutil
    import time
    from pathlib import Path

    from cekm_swarm.runtime.config import load_config, open_session

    deploy = Path(__file__).resolve().parents[2] / "deploy"
    shutil.copy(deploy / "credentials.example.txt", tmp_path / "credentials.txt")
    port = free_port()
    endpoint = f"tcp/127.0.0.1:{port}"
    router = open_session(load_config(deploy / "router.json5", {
        "listen/endpoints": [endpoint], "transport/auth/usrpwd/dictionary_file": str(tmp_path / "credentials.txt")}))
    bad = tmp_path / "bad.json5"
    bad.write_text((deploy / "robot-r1.json5").read_text().replace("change-me-r1", "wrong"))
    t0 = time.monotonic()
    try:
        with pytest.raises(RuntimeTransportError, match="authentication failed for user 'r1'"):
            open_client_when_ready(endpoint, bad, timeout=T)
    finally:
        router.close()
    assert time.monotonic() - t0 < T / 2  # not the whole wait


def test_launch_takes_its_endpoint_from_cekm_connect_and_refuses_a_bad_one(tmp_path):
    """`cekm launch` resolves its endpoint by the same rule: a bad CEKM_CONNECT is a usage
    error naming the variable, before any process starts."""
    from click.testing import CliRunner

    from cekm_swarm.cli import main

    res = CliRunner().invoke(main, ["launch", "lone_obstacle", "--out", str(tmp_path / "out")],
                             env={ENV_CONNECT: "localhost:7447"})
    assert res.exit_code == 2 and f"{ENV_CONNECT}: endpoint 'localhost:7447'" in res.output
    assert not (tmp_path / "out").exists()


def test_a_router_that_came_up_during_the_probe_is_asked_once_more_and_a_refusing_one_is_named(monkeypatch):
    """Zenoh fails while the router starts, the TCP probe that explains it then finds the port
    open: that reads as a refused session. Waiting, the tool asks once more; a router that
    refuses again is named at once (no wait for the timeout)."""
    import cekm_swarm.runtime.wait as wait

    refused = RuntimeTransportError("cannot open client session (client, endpoints ['tcp/127.0.0.1:1']): "
                                    "tcp/127.0.0.1:1 accepts connections but refused a Zenoh session: ...")
    answers = [refused, "session"]

    def fake_open(config, what):
        got = answers.pop(0)
        if isinstance(got, BaseException):
            raise got
        return got

    monkeypatch.setattr(wait, "open_session", fake_open)
    assert open_when_ready(lambda: None, "tcp/127.0.0.1:1", timeout=30) == "session"
    answers[:] = [refused, refused, "never reached"]
    with pytest.raises(RuntimeTransportError, match="refused a Zenoh session"):
        open_when_ready(lambda: None, "tcp/127.0.0.1:1", timeout=30)
    assert answers == ["never reached"]
    answers[:] = [refused, "never reached"]  # not waiting (timeout 0): one attempt, said as it is
    with pytest.raises(RuntimeTransportError, match="refused a Zenoh session"):
        open_when_ready(lambda: None, "tcp/127.0.0.1:1", timeout=0)
