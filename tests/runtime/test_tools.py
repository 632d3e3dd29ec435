"""The operator tools against a real router: topic pub (and its refusal under access
control), topic info, node list, log cat, record."""

from __future__ import annotations

import json
import threading
import time
from pathlib import Path

import click
import msgpack
import pytest
import zenoh
from click.testing import CliRunner
from runtime_samples import sample_traffic, write_log

from cekm_swarm.protocol import DEFAULT_KEYS as K
from cekm_swarm.protocol import WheelCommand, WorldState, decode, encode
from cekm_swarm.runtime.bridge import Publishers, declare_alive
from cekm_swarm.runtime.commands import COMMANDS
from cekm_swarm.runtime.config import load_config, open_session
from cekm_swarm.runtime.mcap_log import log_info, read_messages
from cekm_swarm.runtime.mcap_read import read_geometry
from cekm_swarm.runtime.record import serve_geometry
from cekm_swarm.runtime.rungraph import default_nodes

DEPLOY = Path(__file__).resolve().parents[2] / "deploy"
T = 20.0


@click.group()
def cli() -> None:
    """Stand-in for the main CLI."""


for _c in COMMANDS:
    cli.add_command(_c)


def run(*args: str):
    return CliRunner().invoke(cli, list(args), catch_exceptions=False)


class Inbox:
    def __init__(self, session, key_expr: str) -> None:
        self.got: list[tuple[str, bytes]] = []
        self.event = threading.Event()
        self.want = 1
        self.sub = session.declare_subscriber(key_expr, self._on)

    def _on(self, s) -> None:
        self.got.append((str(s.key_expr), s.payload.to_bytes()))
        if len(self.got) >= self.want:
            self.event.set()


# --------------------------------------------------------------------------- topic pub


def test_topic_pub_publishes_a_validated_message(router, clients):
    inbox = Inbox(clients(), K.cmd_wheels("r1"))
    inbox.want = 3
    res = run("topic", "pub", K.cmd_wheels("r1"), '{"v_l": 0.05, "v_r": -0.02, "seq": 4}', "--count", "3",
              "--rate", "50", "--connect", router, "--stamp", "2.5")
    assert res.exit_code == 0, res.output
    assert "published 3 message(s) on cekm/r1/cmd/wheels" in res.output and "no subscriber" not in res.output
    assert inbox.event.wait(T)
    msg = decode(*inbox.got[0])
    assert (msg.stamp, msg.sender, msg.v_l, msg.v_r, msg.seq) == (2.5, "operator", 0.05, -0.02, 4)


@pytest.mark.parametrize("key,body,problem", [
    ("cekm/r1/cmd/wheels", '{"v_l": 0.05}', "missing field(s) v_r, seq"),
    ("cekm/r1/cmd/wheels", '{"v_l": 0.05, "v_r": 0, "seq": 1, "speed": 2}', "unknown field(s) speed"),
    ("cekm/r1/cmd/wheels", '{"v_l": "fast", "v_r": 0, "seq": 1}', "v_l"),
    ("cekm/r1/cmd/wheels", "[1, 2]", "must be a JSON map"),
    ("cekm/r1/alive/motor", "{}", "carries no message"),
    ("cekm/r1/nothing", "{}", "a graph's own key"),
    ("cekm/r1/sense/nothing", "{}", "not a key of the cekm key space"),
])
def test_topic_pub_refuses_a_bad_message_naming_the_field(key, body, problem):
    res = CliRunner().invoke(cli, ["topic", "pub", key, body, "--wait", "0"])
    assert res.exit_code == 2 and problem in res.output, res.output


def test_topic_pub_is_refused_where_access_control_denies_it(acl_endpoint):
    """The monitor account may listen to everything but publish nothing: the router drops
    its put silently, and the command says so (exit 1); the operator account may publish."""
    world = open_session(load_config(DEPLOY / "world.json5", {"connect/endpoints": [acl_endpoint]}), "world")
    inbox = Inbox(world, K.cmd_wheels_all())
    body = '{"v_l": 0.0, "v_r": 0.0, "seq": 1}'
    denied = CliRunner().invoke(cli, ["topic", "pub", K.cmd_wheels("r1"), body, "--connect", acl_endpoint,
                                      "--config", str(DEPLOY / "monitor.json5"), "--confirm-timeout", "1"])
    assert denied.exit_code == 1, denied.output
    assert "the router passed on 0 of 1 message(s): its access control forbids this client" in denied.output
    allowed = CliRunner().invoke(cli, ["topic", "pub", K.cmd_wheels("r1"), body, "--connect", acl_endpoint,
                                       "--config", str(DEPLOY / "operator.json5")])
    assert allowed.exit_code == 0, allowed.output
    assert allowed.output.splitlines()[-1] == "published 1 message(s) on cekm/r1/cmd/wheels"
    assert inbox.event.wait(T) and [k for k, _ in inbox.got] == [K.cmd_wheels("r1")]  # the operator's only
    world.close()


# --------------------------------------------------------------------------- topic info, node list


@pytest.mark.slow
def test_topic_info_names_publishers_and_subscribers_and_measures_the_rate(router, clients):
    motor, world = clients(), clients()
    tokens = [declare_alive(motor, K.alive("r1", "motor")), declare_alive(world, K.alive("world", "server"))]
    _subscriber = Inbox(world, K.cmd_wheels_all())  # the world's subscriber, which topic info names
    stop = threading.Event()
    pubs = Publishers(motor, block=True)
    assert pubs.wait_matching(K.cmd_wheels("r1"), T)

    def steady() -> None:
        i = 0
        while not stop.wait(0.02):
            pubs.send(K.cmd_wheels("r1"), WheelCommand(i * 0.02, "r1/motor", 0.1, 0.1, i))
            i += 1

    t = threading.Thread(target=steady)
    t.start()
    try:
        res = run("topic", "info", K.cmd_wheels("r1"), "--connect", router, "--window", "1")
        js = run("topic", "info", "cekm/r1/**", "--connect", router, "--window", "0.5", "--json")
    finally:
        stop.set()
        t.join(T)
        pubs.close()
    assert res.exit_code == 0, res.output
    lines = res.output.splitlines()
    assert lines[0] == "publishers (1):" and lines[1] == "  cekm/r1/cmd/wheels: r1/motor"
    assert lines[2] == "subscribers (1):" and lines[3] == "  cekm/*/cmd/wheels: world/server"
    rate = float(next(line for line in lines if line.startswith("cekm/r1/cmd/wheels ")).split()[2])
    assert 10 < rate < 80  # one every 20 ms
    doc = json.loads(js.output)
    assert doc["publishers"] == {"cekm/r1/cmd/wheels": ["r1/motor"]}
    assert [k["key"] for k in doc["keys"]] == ["cekm/r1/cmd/wheels"]
    del tokens


def test_node_list_groups_live_modules_and_names_the_missing(router, clients):
    """The nodes each robot should have come from the graph the world serves (as a world server does)."""
    from cekm_swarm.launch.prepare import run_spec
    from cekm_swarm.node.graph_check import check_graph
    from cekm_swarm.robot import RobotBody
    from cekm_swarm.runtime.record import serve_json

    a = clients()
    spec = run_spec(check_graph("cekm-navigation"), ("r1", "r2"), "navigation", RobotBody())
    served = serve_json(a, K.world_graph(), spec.to_dict())
    asking, deadline = clients(), time.monotonic() + T
    while not [r for r in asking.get(K.world_graph(), timeout=1.0) if r.ok is not None]:  # the router knows it
        assert time.monotonic() < deadline, "the graph was never served"
    tokens = [declare_alive(a, K.alive("r1", m)) for m in default_nodes()]
    tokens += [declare_alive(a, K.alive("r2", "motor")), declare_alive(a, K.alive("r2", "target")),
               declare_alive(a, K.alive("world", "server"))]
    res = run("node", "list", "--connect", router)
    assert res.exit_code == 0, res.output
    lines = res.output.splitlines()
    assert lines[0] == "graph cekm-navigation (controller cekm): 14 nodes per robot"
    assert lines[1] == "world    server"
    assert lines[2] == "r1       14/14 nodes alive: target, obstacle-0..11, motor"  # their names, too
    assert lines[3].startswith("r2        2/14 nodes alive: target, motor; missing: obstacle-0, obstacle-1")
    listed = run("node", "list", "--connect", router, "--json")
    js = [json.loads(line) for line in listed.output.splitlines()]
    assert len(js) == 3, listed.output
    assert js[2] == {"owner": "r2", "alive": ["target", "motor"], "missing": [f"obstacle-{j}" for j in range(12)],
                     "runs": []}
    gone, there = threading.Semaphore(0), threading.Semaphore(0)
    watch = clients().liveliness().declare_subscriber(
        K.alive_all(), lambda smp: (gone if smp.kind == zenoh.SampleKind.DELETE else there).release(), history=True)
    for _ in tokens:  # the watcher knows every token
        assert there.acquire(timeout=T)
    for t in tokens:
        t.undeclare()
    for _ in tokens:  # the router has taken every token away
        assert gone.acquire(timeout=T)
    watch.undeclare()
    served.undeclare()
    empty = run("node", "list", "--connect", router, "--timeout", "0.2")
    assert empty.output.splitlines()[-1] == "no live modules"


# --------------------------------------------------------------------------- log cat


def test_node_list_names_the_run():
    from cekm_swarm.protocol import KeySpace
    from cekm_swarm.runtime.nodes import format_nodes, group_tokens

    run = KeySpace(run="abc-1")
    nodes = default_nodes()
    groups, other = group_tokens({run.alive("world", "server"), run.alive("r1", "motor"), "cekm/r1/nothing"}, K, nodes)
    assert format_nodes(groups, other).splitlines() == [
        "world    server (run abc-1)", "r1        1/14 nodes alive (run abc-1): motor; missing: " +
        ", ".join(["target"] + [f"obstacle-{j}" for j in range(12)]), "other token: cekm/r1/nothing"]
    groups, other = group_tokens({run.alive("r1", "motor")}, K)  # no graph known: what is alive, nothing missing
    assert format_nodes(groups, other) == "r1        1 nodes alive (run abc-1): motor"
    # a robot of the run's team with no live node (its host not started) is named, all missing
    groups, _ = group_tokens({run.alive("r1", n) for n in nodes}, K, nodes, ("r1", "r2"))
    lines = format_nodes(groups, []).splitlines()
    assert lines[0] == "r1       14/14 nodes alive (run abc-1): target, obstacle-0..11, motor"
    assert lines[1].startswith("r2        0/14 nodes alive; missing: target, obstacle-0")


def test_log_cat_prints_decoded_messages_text_and_json(tmp_path):
    path = tmp_path / "run.mcap"
    traffic = sample_traffic(5)
    traffic.insert(3, (K.cmd_wheels("r7"), b"\xc1", 0.0))  # malformed on the wire, recorded as it was
    write_log(path, traffic)
    text = run("log", "cat", str(path), "--topics", "cekm/*/cmd/wheels")
    assert text.exit_code == 0, text.output
    lines = [line for line in text.output.splitlines() if "cekm/r1/" in line]
    assert len(lines) == 5 and lines[0].split() == ["0.000", "cekm/r1/cmd/wheels:", "cmd/wheels", "t=0.000",
                                                    "from=r1/motor", "v_l=0.1", "v_r=0.05", "seq=0"]
    assert "cekm/r7/cmd/wheels: MALFORMED (1 bytes)" in text.output
    assert "1 malformed message(s) in the log" in text.output  # on stderr
    js = run("log", "cat", str(path), "--json", "--topics", "cekm/world/clock,cekm/r7/**")
    docs = [json.loads(line) for line in js.output.splitlines() if line.startswith("{")]
    assert sorted(d["topic"] for d in docs) == ["cekm/r7/cmd/wheels"] + ["cekm/world/clock"] * 5
    clock = next(d for d in docs if d["topic"] == "cekm/world/clock")
    assert clock["message"] == {"kind": "world/clock", "stamp": 0.0, "sender": "world", "tick": 0}
    bad = next(d for d in docs if d["topic"] == "cekm/r7/cmd/wheels")
    assert bad["error"] and bad["bytes"] == 1 and "message" not in bad
    window = run("log", "cat", str(path), "--json", "--start", "0.2", "--end", "0.3")
    assert {json.loads(line)["log_time"] for line in window.output.splitlines()} == {0.256}
    wrong = CliRunner().invoke(cli, ["log", "cat", str(path), "--topics", "cekm//x"])
    assert wrong.exit_code == 2 and "--topics" in wrong.output


def test_log_cat_refuses_an_end_before_the_start(tmp_path, capsys):
    """--start 10 --end 5 printed nothing and exited 0: a usage error naming both options."""
    from cekm_swarm.cli import main
    from cekm_swarm.cli_support import run_cli

    path = tmp_path / "run.mcap"
    write_log(path, sample_traffic(5))
    assert run_cli(main, ["log", "cat", str(path), "--start", "10", "--end", "5"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith("cekm: error: --end 5 is before --start 10"), err
    same = run("log", "cat", str(path), "--json", "--start", "0.256", "--end", "0.256")  # one instant: allowed
    assert {json.loads(line)["log_time"] for line in same.output.splitlines()} == {0.256}


# --------------------------------------------------------------------------- record


def tick(i: int) -> float:
    """Sim time of tick 8 + i (1.024 s, 1.152 s, ...): a recorder takes only a tick's stamp."""
    return round((8 + i) * 0.128, 9)


def world_state(t: float, x: float) -> WorldState:
    return WorldState(t, "world", {"r1": {"x": x, "y": 0.5, "theta": 0.1, "in_contact": False, "goal": [2.0, 0.5]}},
                      {"t1": {"x": 1.0, "y": 1.0}}, {})


GEOMETRY = {"walls": [{"a": [0.0, 0.0], "b": [2.0, 0.0], "thickness": 0.01}], "polygons": [], "discs": [],
            "moving_obstacles": [], "body_radius": 0.03}


def test_record_writes_the_channels_and_views_of_the_worlds_log(router, clients, tmp_path):
    out = tmp_path / "rec.mcap"
    a = clients()
    result: list = []
    t = threading.Thread(target=lambda: result.append(run("record", "cekm/**", "--out", str(out), "--connect",
                                                          router, "--count", "7")))
    pubs = Publishers(a, block=True)
    scene = serve_geometry(a, K.world_geometry(), GEOMETRY)
    t.start()
    try:
        assert pubs.wait_matching(K.world_state(), T)  # the recorder's subscription is in place
        for i in range(3):
            pubs.send(K.world_state(), world_state(tick(i), 0.1 * i))
            pubs.send(K.cmd_wheels("r1"), WheelCommand(tick(i), "r1/motor", 0.1, 0.1, i))
        pubs.put(K.cmd_wheels("r7"), b"\xc1")  # malformed: recorded at the latest sim time seen
    finally:
        t.join(T)
        pubs.close()
    scene.undeclare()
    res = result[0]
    assert res.exit_code == 0, res.output
    assert "no static scene" not in res.output
    assert read_geometry(out) == GEOMETRY  # what `cekm plot` draws the arena from
    from mcap.reader import make_reader

    from cekm_swarm.runtime.mcap_log import log_root

    with open(out, "rb") as f:  # the root its readers decode the keys under (cekm log cat, cekm plot)
        assert [dict(m.metadata)["root"] for m in make_reader(f).iter_metadata() if m.name == "cekm"] == ["cekm"]
    assert log_root(out) == "cekm"
    assert f"recorded 7 messages on 3 keys, sim time 1.024 .. 1.280 s into {out}" in res.output
    info = log_info(out)
    assert info.complete
    topics = {c.topic: (c.message_encoding, c.count) for c in info.channels}
    assert topics[K.world_state()] == ("msgpack", 3) and topics[K.cmd_wheels("r1")] == ("msgpack", 3)
    assert topics["/view/scene"] == ("protobuf", 4) and topics["/view/tf"] == ("protobuf", 3)  # + the static scene
    assert topics["/view/path/r1"][0] == "protobuf"
    bad = [m for m in read_messages(out) if m.topic == K.cmd_wheels("r7")]
    assert len(bad) == 1 and bad[0].log_time == 1_280_000_000 and bad[0].data == b"\xc1"
    assert [m.data for m in read_messages(out, topics=[K.world_state()])] == [
        encode(world_state(tick(i), 0.1 * i)) for i in range(3)]


def test_recording_draws_what_it_can_and_counts_what_it_cannot(tmp_path):
    """A world state without a drawable pose (it does not decode: its entries are typed) is
    recorded as it came, drawn in no view, and counted; so is one that is not a message."""
    from cekm_swarm.runtime.mcap_log import McapRecorder
    from cekm_swarm.runtime.record import Recording

    out = tmp_path / "r.mcap"
    with McapRecorder(out) as recorder:
        rec = Recording(recorder)
        rec.add(K.world_state(), encode(world_state(tick(0), 0.1)))
        no_x = msgpack.unpackb(encode(world_state(tick(1), 0.1)))
        del no_x["robots"]["r1"]["x"]
        rec.add(K.world_state(), msgpack.packb(no_x))  # no x: the typed world state does not decode
        rec.add(K.world_state(), b"\x93\x01")  # not a message
    assert rec.result.messages == 3 and rec.result.malformed == 2
    topics = [m.topic for m in read_messages(out)]
    assert topics.count(K.world_state()) == 3 and topics.count("/view/scene") == 1


def test_echo_full_prints_the_message_as_json(router, clients):
    from cekm_swarm.runtime.topics import echo

    a, b = clients(), clients()
    lines: list[str] = []
    done = threading.Event()
    pubs = Publishers(a, block=True)

    def send() -> None:
        if pubs.wait_matching(K.cmd_wheels("r1"), T):
            pubs.send(K.cmd_wheels("r1"), WheelCommand(0.5, "r1/motor", 0.1, 0.2, 3))
            pubs.put(K.cmd_wheels("r1"), b"\xc1")

    t = threading.Thread(target=send)
    t.start()
    n = echo(b, K.cmd_wheels("r1"), lines.append, count=2, full=True, stop=done)
    t.join(T)
    pubs.close()
    assert n == 2
    key, _, body = lines[0].partition(": ")
    assert key == K.cmd_wheels("r1") and json.loads(body) == {"kind": "cmd/wheels", "stamp": 0.5,
                                                             "sender": "r1/motor", "v_l": 0.1, "v_r": 0.2, "seq": 3}
    assert lines[1].startswith("cekm/r1/cmd/wheels: MALFORMED (1 bytes)")
