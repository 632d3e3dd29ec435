"""deploy/tls/: mutual TLS between the Zenoh router and every client, with the access
control of deploy/router.json5 keyed by the certificates' common names.

Certificates come from deploy/make-certs.sh in a temporary directory. The shipped configs
name them by relative paths (``certs/ca.pem``, ...), so each test runs from that
directory, as an operator runs from the folder holding ``certs/``. As in test_deploy.py,
a forbidden message is followed by an allowed one from the same session: once the
allowed one has arrived, the router dropped the forbidden one (no waiting for nothing)."""

from __future__ import annotations

import json
import os
import queue
import subprocess
import threading
from pathlib import Path

import pytest
import zenoh

from cekm_swarm.experiments.default_model import default_model, default_model_path
from cekm_swarm.experiments.navigation_run import run_scenario
from cekm_swarm.protocol import DEFAULT_KEYS, ObstacleField, WheelCommand, decode, encode
from cekm_swarm.runtime.bridge import Publishers
from cekm_swarm.runtime.config import free_port, load_config, open_session
from cekm_swarm.runtime.errors import RuntimeTransportError
from cekm_swarm.runtime.mcap_log import read_messages
from helpers.launch import LaunchProcess
from world import load_scenario

pytestmark = pytest.mark.slow  # starts real processes (tests/process_guard.py)

DEPLOY = Path(__file__).resolve().parents[2] / "deploy"
TLS = DEPLOY / "tls"
K = DEFAULT_KEYS
T = 20.0
SEED = 2
CLIENTS = {"world": "world", "robot-r1": "r1", "robot-r2": "r2", "robot-r3": "r3", "monitor": "monitor",
           "operator": "operator"}


def make_certs(where: Path, *routers: str, hosts: str | None = None) -> subprocess.CompletedProcess:
    env = dict(os.environ)
    if hosts is not None:
        env["HOSTS"] = hosts
    return subprocess.run([str(DEPLOY / "make-certs.sh"), str(where), *routers], capture_output=True, text=True,
                          env=env, timeout=60)


@pytest.fixture(scope="module")
def certs(tmp_path_factory) -> Path:
    """A run folder holding certs/ (the run's CA) and other-ca/ (a second, unrelated CA)."""
    root = tmp_path_factory.mktemp("tls-run")
    for sub in ("certs", "other-ca"):
        done = make_certs(root / sub, hosts=None if sub == "certs" else "r1")
        assert done.returncode == 0, done.stderr
    return root


@pytest.fixture
def tls_router(certs, monkeypatch):
    """deploy/tls/router.json5 on a free loopback port, run from the folder holding certs/;
    yields a function opening a client with one of deploy/tls/'s client configs."""
    monkeypatch.chdir(certs)
    port = free_port()
    endpoint = f"tls/127.0.0.1:{port}"
    router = open_session(load_config(TLS / "router.json5", {"listen/endpoints": [endpoint]}), "TLS router")
    opened: list[zenoh.Session] = []

    def client(name: str, **tls: object) -> zenoh.Session:
        overrides: dict[str, object] = {"connect/endpoints": [endpoint]}
        overrides.update({f"transport/link/tls/{k}": v for k, v in tls.items()})
        s = open_session(load_config(TLS / f"{name}.json5", overrides), name)
        opened.append(s)
        return s

    client.endpoint = endpoint  # type: ignore[attr-defined]
    yield client
    for s in opened:
        s.close()
    router.close()


def get(config: zenoh.Config, path: str):
    return json.loads(config.get_json(path))


def test_tls_configs_load_and_keep_the_access_rules_of_router_json5():
    plain = get(zenoh.Config.from_file(str(DEPLOY / "router.json5")), "access_control")
    router = zenoh.Config.from_file(str(TLS / "router.json5"))
    acl = get(router, "access_control")
    assert get(router, "mode") == "router" and get(router, "listen/endpoints") == ["tls/0.0.0.0:7447"]
    assert get(router, "transport/link/tls/enable_mtls") is True
    assert get(router, "transport/link/tls/root_ca_certificate") == "certs/ca.pem"
    assert get(router, "transport/auth/usrpwd/dictionary_file") is None
    assert acl["rules"] == plain["rules"] and acl["policies"] == plain["policies"]
    assert acl["default_permission"] == "deny" and acl["enabled"] is True
    assert [(s["id"], s["cert_common_names"]) for s in acl["subjects"]] == \
        [(s["id"], s["usernames"]) for s in plain["subjects"]]
    assert sorted(p.name for p in TLS.glob("*.json5")) == sorted([f"{n}.json5" for n in CLIENTS] + ["router.json5"])
    for name, cn in CLIENTS.items():
        c = zenoh.Config.from_file(str(TLS / f"{name}.json5"))
        assert get(c, "mode") == "client" and get(c, "scouting/multicast/enabled") is False
        assert get(c, "connect/endpoints") == ["tls/cekm-router.local:7447"]
        assert get(c, "transport/link/tls/connect_certificate") == f"certs/{cn}.pem"
        assert get(c, "transport/link/tls/connect_private_key") == f"certs/{cn}.key"
        assert get(c, "transport/auth/usrpwd/user") is None


def test_make_certs_names_the_router_and_each_host(tmp_path):
    done = make_certs(tmp_path / "c", "router.example", "10.1.2.3", hosts="world r1")
    assert done.returncode == 0, done.stderr
    c = tmp_path / "c"
    assert sorted(p.name for p in c.iterdir() if p.suffix in (".pem", ".key")) == [
        "ca.key", "ca.pem", "r1.key", "r1.pem", "router.key", "router.pem", "world.key", "world.pem"]
    for key in c.glob("*.key"):
        assert key.stat().st_mode & 0o077 == 0, key
    text = subprocess.run(["openssl", "x509", "-in", str(c / "router.pem"), "-noout", "-text"], capture_output=True,
                          text=True, check=True).stdout
    assert "DNS:router.example, IP Address:10.1.2.3" in text
    subject = subprocess.run(["openssl", "x509", "-in", str(c / "r1.pem"), "-noout", "-subject"], capture_output=True,
                             text=True, check=True).stdout
    assert subject.strip().replace(" ", "") == "subject=CN=r1"
    verify = subprocess.run(
        ["openssl", "verify", "-CAfile", str(c / "ca.pem"), str(c / "r1.pem"), str(c / "router.pem")],
        capture_output=True,
        text=True,
    )
    assert verify.returncode == 0, verify.stdout + verify.stderr
    # A second run keeps what exists (no silent re-keying) and adds what is missing.
    before = (c / "r1.pem").read_bytes()
    again = make_certs(c, hosts="r1 r2")
    assert again.returncode == 0 and "r1.pem exists; kept" in again.stderr
    assert (c / "r1.pem").read_bytes() == before and (c / "r2.pem").is_file()
    bad = make_certs(tmp_path / "d", "bad name")
    assert bad.returncode != 0 and "'bad name' is not a valid name" in bad.stderr


def test_a_client_without_a_certificate_is_refused(tls_router):
    tls_router("robot-r1")  # the same config with its certificate joins
    with pytest.raises(RuntimeTransportError, match="cannot open robot-r1"):
        tls_router("robot-r1", enable_mtls=False, connect_certificate=None, connect_private_key=None)


def test_a_certificate_from_another_ca_is_refused(tls_router, certs):
    other = certs / "other-ca"
    # It trusts the right CA (so it would accept the router) but shows a foreign certificate.
    with pytest.raises(RuntimeTransportError, match="cannot open robot-r1"):
        tls_router("robot-r1", connect_certificate=str(other / "r1.pem"), connect_private_key=str(other / "r1.key"))
    # And a client trusting only another CA does not accept the router.
    with pytest.raises(RuntimeTransportError, match="cannot open robot-r1"):
        tls_router("robot-r1", root_ca_certificate=str(other / "ca.pem"))


def test_plain_tcp_to_the_tls_router_is_refused(tls_router):
    endpoint = tls_router.endpoint.replace("tls/", "tcp/")
    with pytest.raises(RuntimeTransportError, match="cannot open"):
        open_session(load_config(DEPLOY / "robot-r1.json5", {"connect/endpoints": [endpoint]}), "tcp client")


class Inbox:
    """Keys received by a subscriber, in order."""

    def __init__(self, session: zenoh.Session, key_expr: str) -> None:
        self.q: queue.SimpleQueue[str] = queue.SimpleQueue()
        self.sub = session.declare_subscriber(key_expr, lambda s: self.q.put(str(s.key_expr)))

    def until(self, last: str) -> list[str]:
        got = []
        while (item := self.q.get(timeout=T)) != last:
            got.append(item)
        return got + [last]


def cmd(sender: str) -> bytes:
    return encode(WheelCommand(1.0, sender, 0.3, -0.3, 1))


def test_r2_cannot_command_r1_and_the_monitor_cannot_publish(tls_router):
    world, r1, r2, monitor = (tls_router(n) for n in ("world", "robot-r1", "robot-r2", "monitor"))
    inbox = Inbox(world, "cekm/**")
    with Publishers(r2, block=True) as pubs:
        assert pubs.wait_matching(K.cmd_wheels("r1"), T)
        pubs.put(K.cmd_wheels("r1"), cmd("r2"))  # r2's certificate on r1's command: dropped
        pubs.put(K.share("r2"), b"\x80")  # its own: delivered
    assert inbox.until(K.share("r2")) == [K.share("r2")]
    with Publishers(monitor, block=True) as pubs:
        assert pubs.wait_matching(K.cmd_wheels("r1"), T)
        for key in (K.cmd_wheels("r1"), K.world_clock(), K.sense_target("r1"), K.share("r1")):
            pubs.put(key, b"\x80")
    # The monitor may publish nothing, so no allowed message of its own can follow. Its
    # liveliness query (allowed) is answered by the router after it has routed (or dropped)
    # the puts before it on the same link; r1's message, sent after the answer, reaches
    # the world after anything the router forwarded before. (Its key is one the monitor did
    # not try.)
    list(monitor.liveliness().get(K.alive_all(), timeout=T))
    with Publishers(r1, block=True) as pubs:
        assert pubs.wait_matching(K.field_obstacle("r1", 3), T)
        pubs.put(K.field_obstacle("r1", 3), b"\x80")
    assert inbox.until(K.field_obstacle("r1", 3)) == [K.field_obstacle("r1", 3)]
    inbox.sub.undeclare()


class Intruder(threading.Thread):
    """r2's credentials publishing wheel commands for r1 during a run, each followed by
    an allowed marker on r2's own obstacle-field key (which nobody but the recorder reads)."""

    def __init__(self, session: zenoh.Session) -> None:
        super().__init__(daemon=True)
        self.session = session
        self.stop = threading.Event()
        self.sent = 0
        self.error: BaseException | None = None

    def run(self) -> None:
        try:
            with Publishers(self.session, block=True) as pubs:
                if not pubs.wait_matching(K.cmd_wheels("r1"), 120):
                    raise AssertionError("no subscriber on r1's wheel command in 120 s")
                while not self.stop.is_set():
                    self.sent += 1
                    pubs.put(K.cmd_wheels("r1"), encode(WheelCommand(0.0, "r2/intruder", 0.5, -0.5, self.sent)))
                    pubs.put(K.field_obstacle("r2", 0), encode(ObstacleField(0.0, "r2/intruder", 0, None, None)))
                    self.stop.wait(0.02)
        except BaseException as exc:  # reported by the test
            self.error = exc


def test_split_launch_over_mutual_tls_and_an_intruder_changes_nothing(tls_router, certs, tmp_path):
    """World host and r1's host launched with deploy/tls/world.json5 and robot-r1.json5
    (cekm launch --config), while r2's identity tries to drive r1: the run equals the
    one-process run bit for bit and r1's recorded wheel commands all come from r1's motor."""
    default_model(progress=False)
    endpoint = tls_router.endpoint
    intruder = Intruder(tls_router("robot-r2"))
    intruder.start()
    common = ("--mode", "lockstep", "--seed", str(SEED), "--max-time", "40", "--connect", endpoint)
    world = LaunchProcess("lone_obstacle", tmp_path / "world-host", "--robots", "none", "--no-plot",
                          "--model", str(default_model_path()), "--config", str(TLS / "world.json5"), *common)
    robots = None
    try:
        world.wait_line("serving the model", timeout=60)
        robots = LaunchProcess("lone_obstacle", tmp_path / "robot-host", "--robots", "r1", "--no-world",
                               "--model-from-zenoh", "--config", str(TLS / "robot-r1.json5"), *common)
        assert world.finish(timeout=120) == 0, "\n".join(world.lines)
        assert robots.finish(timeout=60) == 0, "\n".join(robots.lines)
    finally:
        intruder.stop.set()
        intruder.join(10)
        world.kill()
        if robots is not None:
            robots.kill()
    assert intruder.error is None, intruder.error
    outcome = world.outcome()
    assert outcome["robots"]["r1"]["reached"]
    # no command of the intruder's reached the world (the router's ACL refused them); its
    # allowed markers did, and the world's recorder refused them (r2 is not a robot of this
    # run, and their stamp is no tick of it): counted, so the intruder ran during the run
    assert outcome["drops"]["commands"] == {}
    markers = outcome["drops"]["recorder"].pop(K.field_obstacle("r2", 0), 0)
    assert outcome["drops"]["recorder"] == {}
    assert markers > 10, f"the intruder's allowed markers reached the world {markers} times: it ran during the run"
    ref = run_scenario(load_scenario("lone_obstacle"), "cekm", default_model(progress=False), SEED, max_time=40)
    traj = json.loads((world.out / "trajectory.json").read_text())["r1"]
    assert traj["x"] == ref.logs["r1"].x and traj["v_l"] == ref.logs["r1"].v_l
    log = world.out / "run.mcap"
    senders = {decode(K.cmd_wheels("r1"), m.data).sender for m in read_messages(log, topics=[K.cmd_wheels("r1")])}
    assert senders == {"r1/motor"}, senders


def test_a_missing_certificate_file_is_named(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # no certs/ here
    with pytest.raises(RuntimeTransportError, match=r"robot-r1.json5: transport/link/tls/root_ca_certificate: "
                                                    r"no such file 'certs/ca.pem' \(relative to the working directory"):
        load_config(TLS / "robot-r1.json5")
    (tmp_path / "certs").mkdir()
    (tmp_path / "certs" / "ca.pem").write_text("")
    with pytest.raises(RuntimeTransportError, match="connect_certificate: no such file 'certs/r1.pem'"):
        load_config(TLS / "robot-r1.json5")
