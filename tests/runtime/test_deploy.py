"""deploy/: the configs load with zenoh.Config.from_file, and the router's access control
lets a robot publish on its own keys only.

Every check sends a forbidden message and then an allowed one from the same session: a
Zenoh session delivers in order, so once the allowed one has arrived, the forbidden one
was dropped by the router (no waiting for something not to happen)."""

from __future__ import annotations

import json
import queue
import time
from pathlib import Path

import pytest
import zenoh

from cekm_swarm.protocol import DEFAULT_KEYS, WheelCommand, encode
from cekm_swarm.runtime.bridge import Publishers, declare_alive
from cekm_swarm.runtime.config import load_config, open_session
from cekm_swarm.runtime.errors import RuntimeTransportError

DEPLOY = Path(__file__).resolve().parents[2] / "deploy"
K = DEFAULT_KEYS
T = 20.0


def get(config: zenoh.Config, path: str):
    return json.loads(config.get_json(path))


def test_every_config_loads_and_says_what_it_should():
    files = sorted(p.name for p in DEPLOY.glob("*.json5"))
    assert files == ["monitor.json5", "operator.json5", "robot-r1.json5", "robot-r2.json5", "robot-r3.json5",
                     "router.json5", "world.json5"]
    router = zenoh.Config.from_file(str(DEPLOY / "router.json5"))
    assert get(router, "mode") == "router" and get(router, "scouting/multicast/enabled") is False
    acl = get(router, "access_control")
    assert acl["enabled"] is True and acl["default_permission"] == "deny"
    rule_ids = {r["id"] for r in acl["rules"]}
    for policy in acl["policies"]:
        assert set(policy["rules"]) <= rule_ids
    users = {u for s in acl["subjects"] for u in s["usernames"]}
    creds = {line.split(":")[0] for line in (DEPLOY / "credentials.example.txt").read_text().split()}
    assert users == creds == {"world", "r1", "r2", "r3", "r4", "monitor", "operator"}
    for name, user in [
        ("world", "world"),
        ("robot-r1", "r1"),
        ("robot-r2", "r2"),
        ("robot-r3", "r3"),
        ("monitor", "monitor"),
        ("operator", "operator"),
    ]:
        c = zenoh.Config.from_file(str(DEPLOY / f"{name}.json5"))
        assert get(c, "mode") == "client" and get(c, "scouting/multicast/enabled") is False
        assert get(c, "transport/auth/usrpwd/user") == user
        assert get(c, "connect/endpoints") == ["tcp/cekm-router.local:7447"]
    assert (DEPLOY / "README.md").read_text().count("--connect") >= 1


@pytest.fixture
def acl_router(acl_endpoint):
    """Clients of deploy/router.json5 (conftest's ``acl_endpoint``), by config name."""
    endpoint = acl_endpoint
    opened: list[zenoh.Session] = []

    def client(name: str, password: str | None = None) -> zenoh.Session:
        overrides: dict[str, object] = {"connect/endpoints": [endpoint]}
        if password is not None:
            overrides["transport/auth/usrpwd/password"] = password
        s = open_session(load_config(DEPLOY / f"{name}.json5", overrides), name)
        opened.append(s)
        return s

    yield client
    for s in opened:
        s.close()


def _kind(sample: zenoh.Sample) -> str:
    return "PUT" if sample.kind == zenoh.SampleKind.PUT else "DELETE"


class Inbox:
    """Keys received by a subscriber, in order."""

    def __init__(self, session: zenoh.Session, key_expr: str, liveliness: bool = False) -> None:
        self.q: queue.SimpleQueue[str] = queue.SimpleQueue()
        cb = (
            (lambda s: self.q.put(f"{_kind(s)}:{s.key_expr}"))
            if liveliness
            else (lambda s: self.q.put(str(s.key_expr)))
        )
        self.sub = (session.liveliness().declare_subscriber(key_expr, cb, history=True) if liveliness
                    else session.declare_subscriber(key_expr, cb))

    def until(self, last: str) -> list[str]:
        got = []
        while (item := self.q.get(timeout=T)) != last:
            got.append(item)
        return got + [last]


def replies_once_served(session: zenoh.Session, key: str) -> list[bytes]:
    """The replies to a query of ``key``, asked again until there is one or ``T`` s pass: a
    queryable just declared in another session is not known to the router at once."""
    deadline = time.monotonic() + T
    got: list[bytes] = []
    while not got and time.monotonic() < deadline:
        got = [r.ok.payload.to_bytes() for r in session.get(key, timeout=1.0) if r.ok is not None]
    return got


def cmd(sender: str) -> bytes:
    return encode(WheelCommand(1.0, sender, 0.1, 0.1, 1))


def test_robot_publishes_on_its_own_keys_only(acl_router):
    world, r1 = acl_router("world"), acl_router("robot-r1")
    inbox = Inbox(world, "cekm/**")
    with Publishers(r1, block=True) as pubs:
        assert pubs.wait_matching(K.cmd_wheels("r1"), T)
        pubs.put(K.cmd_wheels("r2"), cmd("r1"))  # another robot's command: denied
        pubs.put(K.sense_target("r1"), b"\x80")  # a world key, even under its own robot: denied
        pubs.put(K.world_clock(), b"\x80")  # denied
        pubs.put(K.cmd_wheels("r1"), cmd("r1"))  # its own: allowed
        pubs.put(K.field_obstacle("r1", 3), b"\x80")  # its own: allowed
    assert inbox.until(K.field_obstacle("r1", 3)) == [K.cmd_wheels("r1"), K.field_obstacle("r1", 3)]
    inbox.sub.undeclare()


def test_robot_receives_only_its_own_sense_keys(acl_router):
    world, r1 = acl_router("world"), acl_router("robot-r1")
    wide = Inbox(r1, "cekm/**")  # more than r1 may receive: the router refuses this subscription
    own = Inbox(r1, K.sense_target("r1"))  # what its target node subscribes to
    clock = Inbox(r1, K.world_clock())
    with Publishers(world, block=True) as pubs:
        assert pubs.wait_matching(K.sense_target("r1"), T)
        assert pubs.wait_matching(K.world_clock(), T)
        pubs.put(K.sense_target("r2"), b"\x80")
        pubs.put(K.world_state(), b"\x80")
        pubs.put(K.sense_target("r1"), b"\x80")
        pubs.put(K.world_clock(), b"\x80")
    # r1's session hands every sample it gets to all its matching subscriptions, the wide
    # one too, each in order (callbacks of different subscriptions are not ordered with
    # each other). The router never forwarded r2's key or the state: the wide
    # subscription saw only what r1's allowed subscriptions brought in.
    assert wide.until(K.world_clock()) == [K.sense_target("r1"), K.world_clock()]
    assert own.until(K.sense_target("r1")) == [K.sense_target("r1")]
    assert clock.until(K.world_clock()) == [K.world_clock()]
    for inbox in (wide, own, clock):
        inbox.sub.undeclare()


def test_robot_holds_liveliness_tokens_on_its_own_keys_only(acl_router):
    r1, monitor = acl_router("robot-r1"), acl_router("monitor")
    watch = Inbox(monitor, K.alive_all(), liveliness=True)
    bad = declare_alive(r1, K.alive("r2", "motor"))
    good = declare_alive(r1, K.alive("r1", "motor"))
    assert watch.until(f"PUT:{K.alive('r1', 'motor')}") == [f"PUT:{K.alive('r1', 'motor')}"]
    good.undeclare()
    bad.undeclare()
    assert watch.until(f"DELETE:{K.alive('r1', 'motor')}") == [f"DELETE:{K.alive('r1', 'motor')}"]
    watch.sub.undeclare()


def test_other_robot_and_operator(acl_router):
    world, r2, operator = acl_router("world"), acl_router("robot-r2"), acl_router("operator")
    inbox = Inbox(world, "cekm/**")
    with Publishers(r2, block=True) as pubs:
        assert pubs.wait_matching(K.cmd_wheels("r2"), T)
        pubs.put(K.cmd_wheels("r1"), cmd("r2"))
        pubs.put(K.share("r2"), b"\x80")
    assert inbox.until(K.share("r2")) == [K.share("r2")]
    with Publishers(operator, block=True) as pubs:  # replay / launcher: any cekm key
        assert pubs.wait_matching(K.cmd_wheels("r1"), T)
        pubs.put(K.cmd_wheels("r1"), cmd("operator"))
        pubs.put(K.sense_target("r3"), b"\x80")
    assert inbox.until(K.sense_target("r3")) == [K.cmd_wheels("r1"), K.sense_target("r3")]
    inbox.sub.undeclare()


def test_wrong_password_is_refused(acl_router):
    with pytest.raises(RuntimeTransportError, match="cannot open robot-r1"):
        acl_router("robot-r1", password="wrong")


def test_monitor_fetches_the_scene_the_world_serves_and_a_robot_does_not(acl_router):
    """``cekm record`` and monitors ask the world for the static scene (a queryable): the
    monitor identity may query it and get the world's reply; a robot may not."""
    world, monitor, r1 = acl_router("world"), acl_router("monitor"), acl_router("robot-r1")
    key = K.world_geometry()
    queryable = world.declare_queryable(key, lambda q: q.reply(key, b"scene"))
    try:
        assert replies_once_served(monitor, key) == [b"scene"]
        assert [r for r in r1.get(key, timeout=1.0) if r.ok is not None] == []
    finally:
        queryable.undeclare()


def test_the_shipped_router_configs_are_the_generators_output_for_every_shipped_graph():
    """deploy/router.json5 and deploy/tls/router.json5 come from `cekm graph acl` (the
    graphs' own keys, robots r1-r4): regenerate them with that command, never by hand."""
    from cekm_swarm.node.graph_commands import shipped_router_config as shipped

    assert (DEPLOY / "router.json5").read_text() == shipped()
    assert (DEPLOY / "tls" / "router.json5").read_text() == shipped(tls=True)
    head = (DEPLOY / "router.json5").read_text().splitlines()[1]
    assert (
        "cekm graph acl acmommt-tracking cekm-learning-navigation cekm-learning-team-navigation cekm-navigation "
        "cekm-tracking cekm-tuned-navigation fusion-navigation kmeans-global-tracking kmeans-tracking stay "
        "--robots r1,r2,r3,r4"
        in head
    )


def test_a_graphs_own_keys_are_its_robots_only(acl_router):
    """Keys a graph gives its nodes (command fusion's proposals) are r1's to send under r1
    only: r1 publishing r2's is dropped by the router, the monitor publishes nothing."""
    from cekm_swarm.runtime.record import serve_json

    world, r1, monitor = acl_router("world"), acl_router("robot-r1"), acl_router("monitor")
    inbox = Inbox(world, "cekm/**")
    scene = serve_json(world, K.world_geometry(), {"walls": []})
    assert replies_once_served(monitor, K.world_geometry())  # the router knows the world's queryable
    with Publishers(monitor, block=True) as mon:
        mon.put(K.cmd_wheels("r1"), b"\x80")  # the monitor: denied
        mon.put(K.world_state(), b"\x80")  # denied
    # the monitor's query reaches the world after its puts would have (one session, in
    # order; the world's callbacks run in order too): once the reply is back, they were dropped
    assert [r for r in monitor.get(K.world_geometry(), timeout=T) if r.ok is not None]
    with Publishers(r1, block=True) as pubs:
        assert pubs.wait_matching("cekm/r1/fusion/avoid", T)
        pubs.put("cekm/r2/fusion/avoid", b"\x80")  # another robot's: denied
        pubs.put("cekm/r1/fusion/avoid", b"\x80")  # its own: allowed
    assert inbox.until("cekm/r1/fusion/avoid") == ["cekm/r1/fusion/avoid"]
    scene.undeclare()
    inbox.sub.undeclare()


def test_the_documented_split_launch_starts_every_robot_of_its_scenario():
    """Following deploy/README.md's example with launch-hosts.sh's default SCENARIO starts
    a host for every robot, each with its client config (and its TLS one)."""
    import re

    from world import load_scenario

    script = (DEPLOY / "launch-hosts.sh").read_text()
    scenario = re.search(r"SCENARIO=\$\{SCENARIO:-([\w-]+)\}", script).group(1)
    robots = [r.id for r in load_scenario(scenario).robots]
    readme = (DEPLOY / "README.md").read_text()
    started = set(re.findall(r"^deploy/launch-hosts\.sh (r\d+) ", readme, re.M))
    assert started == set(robots), (scenario, robots, started)
    for r in robots:
        assert (DEPLOY / f"robot-{r}.json5").is_file() and (DEPLOY / "tls" / f"robot-{r}.json5").is_file(), r


def test_cekm_param_under_access_control_reaches_a_robots_own_nodes_only(acl_router):
    """``cekm param``: the operator asks a node's parameter queryable and gets its answer; a
    robot serves only its own nodes' parameter keys (r2 serving r1's is dropped: r2's own,
    declared after it from the same session, answers first); the monitor may not ask (a
    change is a write); the node publishes its ParamChange on its key and the world gets it."""
    world, r1, r2 = acl_router("world"), acl_router("robot-r1"), acl_router("robot-r2")
    operator, monitor = acl_router("operator"), acl_router("monitor")
    key = K.param("r1", "motor")
    served = [r2.declare_queryable(key, lambda q: q.reply(key, b"r2")),  # another robot's node: denied
              r2.declare_queryable(K.param("r2", "motor"), lambda q: q.reply(K.param("r2", "motor"), b"mine")),
              r1.declare_queryable(key, lambda q: q.reply(key, b"r1"))]
    inbox = Inbox(world, "cekm/*/param/*")
    try:
        assert replies_once_served(operator, K.param("r2", "motor")) == [b"mine"]  # r2's denied one came before
        assert replies_once_served(operator, key) == [b"r1"]
        assert [r for r in monitor.get(key, timeout=1.0) if r.ok is not None] == []
        with Publishers(r1, block=True) as pubs:
            assert pubs.wait_matching(key, T)
            pubs.put(K.param("r2", "motor"), b"\x80")  # another robot's parameter key: denied
            pubs.put(key, b"\x80")
        assert inbox.until(key) == [key]
    finally:
        for q in served:
            q.undeclare()
        inbox.sub.undeclare()
