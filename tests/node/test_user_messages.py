"""A user's own message type (cekm_swarm.protocol.UserMessage) between two user nodes
(docs/examples/free_direction.py): decoded against its declaration, refused on a key of
another type, compared by `cekm graph check` between the nodes that send and read it,
filled in by the runner (stamp, sender, seq), recorded with its type in run.mcap and
decoded by `cekm log cat` and `cekm topic echo`; a run in one process, in lockstep and in
real time."""

from __future__ import annotations

import json
import shutil
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from cekm_swarm.experiments.graph_run import run_graph
from cekm_swarm.graph.spec import GraphError
from cekm_swarm.node.api import StepFailed
from cekm_swarm.node.graph_check import check_graph
from cekm_swarm.protocol import (
    MessageKindError,
    Nothing,
    UntypedData,
    UserMessage,
    WheelCommand,
    decode,
    encode,
    summary,
    to_plain,
)
from cekm_swarm.protocol.user import USER_TYPES
from world import load_scenario

EXAMPLES = Path(__file__).resolve().parents[2] / "docs" / "examples"


@pytest.fixture
def example(tmp_path, monkeypatch):
    """The example where a user keeps it: the graph file and its module side by side."""
    for name in ("free.toml", "free_direction.py"):
        shutil.copy(EXAMPLES / name, tmp_path / name)
    monkeypatch.syspath_prepend(str(tmp_path))
    # lone_obstacle with the robot nearer the disc: nothing in sight for its first ticks (FreeSpace sends
    # nothing), then the disc (it sends the free direction)
    lone = (Path(__file__).resolve().parents[2] / "world" / "scenarios" / "lone_obstacle.toml").read_text()
    (tmp_path / "near.toml").write_text(lone.replace("start = [0.5, 1.0, 0.0]", "start = [0.7, 1.0, 0.0]"))
    return tmp_path / "free.toml"


def test_a_user_message_is_encoded_decoded_and_refused_by_its_declaration():
    class Heading(UserMessage):
        TYPE = "qa.Heading"
        alpha: float
        gains: np.ndarray | None = None

    m = Heading(0.128, "r1/h", 0.5, np.arange(3.0))
    key = "cekm/r1/mine/heading"
    assert decode(key, encode(m)) == m  # the payload names its type: decoded as declared
    assert to_plain(m) == {"kind": "data", "type": "qa.Heading", "stamp": 0.128, "sender": "r1/h", "alpha": 0.5,
                           "gains": [0.0, 1.0, 2.0]}
    assert summary(m).startswith("qa.Heading t=0.128 from=r1/h alpha=0.5")

    class Other(UserMessage):
        TYPE = "qa.Other"
        alpha: float

    with pytest.raises(MessageKindError, match="message type 'qa.Heading', the key carries qa.Other"):
        decode(key, encode(m), expect=Other)  # a reader drops it (and counts it)
    with pytest.raises(MessageKindError, match="message type 'qa.Heading', the key carries data"):
        decode(key, encode(m), expect=__import__("cekm_swarm.protocol", fromlist=["KeyKind"]).KeyKind.DATA)
    # a process without the declaration (the world's recorder) checks the envelope, reads the fields
    del USER_TYPES["qa.Heading"]
    u = decode(key, encode(m))
    assert type(u) is UntypedData and u.type == "qa.Heading" and u.values == {"alpha": 0.5, "gains": [0.0, 1.0, 2.0]}
    assert to_plain(u) == to_plain(m)
    with pytest.raises(TypeError, match="field 'type' is a name of the envelope"):
        class Clash(UserMessage):
            type: str


def test_two_user_nodes_run_in_one_process_through_the_codec_and_the_runner_fills_the_envelope(example):
    sc = load_scenario(str(example.parent / "near.toml"))
    start = run_graph(sc, graph=str(example), max_time=8.0, stop_at=0, codec=True)
    assert type(start.executor.output("cekm/r1/avoid/free", 0)) is Nothing  # nothing in sight: nothing sent
    assert start.executor.output("cekm/r1/cmd/wheels", 0).v_l > 0  # and its reader drove on (it saw None)
    run = run_graph(sc, graph=str(example), max_time=8.0, stop_at=40, codec=True)
    free = run.executor.output("cekm/r1/avoid/free", 40)
    assert type(free).__name__ == "FreeDirection" and isinstance(free, UserMessage)
    assert free.stamp == pytest.approx(40 * 0.128) and free.sender == "r1/free"
    cmd = run.executor.output("cekm/r1/cmd/wheels", 40)
    assert type(cmd) is WheelCommand and cmd.seq == 40 and cmd.sender == "r1/motor"  # seq: the tick
    plain = run_graph(sc, graph=str(example), max_time=8.0, stop_at=40)
    assert plain.executor.output("cekm/r1/cmd/wheels", 40) == cmd  # through the codec or not: the same


def test_a_step_that_leaves_out_a_field_fails_naming_the_output_and_the_field(example):
    text = (example.parent / "free_direction.py").read_text()
    (example.parent / "free_typo.py").write_text(text.replace('"clearance": reach if best.d is None else best.d',
                                                              '"clearence": 1.0'))
    example.write_text(example.read_text().replace("free_direction:", "free_typo:"))
    with pytest.raises(StepFailed, match=r"^r1/free: its step at t=\d\.\d{3} s failed: output 'free': FreeDirection: "
                                         r".*clearence"):
        run_graph(load_scenario(str(example.parent / "near.toml")), graph=str(example), max_time=8.0)


def test_graph_check_refuses_two_user_nodes_that_disagree_on_the_type_naming_both(example):
    (example.parent / "other_mod.py").write_text(textwrap.dedent('''
        from cekm_swarm.node import In, Node, Out
        from cekm_swarm.protocol import UserMessage, WheelCommand


        class Gap(UserMessage):
            width: float


        class GapMotor(Node):
            inputs = {"free": In(Gap)}
            outputs = {"command": Out(WheelCommand)}

            def step(self, t, inputs):
                return {"command": {"v_l": 0.0, "v_r": 0.0}}
        '''))
    text = example.read_text().replace('program = "free_direction:Blend"', 'program = "other_mod:GapMotor"')
    bad = example.parent / "bad.toml"
    bad.write_text(text.replace('inputs = { target = "sense/target", free = "avoid/free" }',
                                'inputs = { free = "avoid/free" }'))
    with pytest.raises(GraphError) as info:
        check_graph(str(bad)).plan(("r1",), "navigation")  # what `cekm graph check` runs
    line = str(info.value)
    assert "node 'motor'.inputs.free" in line and "(node 'free' sends them)" in line, line
    assert "'avoid/free' carries data:FreeDirection messages" in line and "takes data:Gap" in line, line


def cekm(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "cekm_swarm", *args], cwd=cwd, capture_output=True, text=True,
                          timeout=300)


@pytest.mark.slow
def test_two_user_nodes_with_a_typed_message_in_lockstep_equal_cekm_run_and_are_decoded_in_the_log(example, tmp_path):
    from helpers.launch import LaunchProcess

    ref = cekm("run", "near.toml", "--graph", str(example), "--max-time", "8", "--out", str(tmp_path / "run"),
               cwd=example.parent)
    assert ref.returncode == 0, ref.stderr
    launch = LaunchProcess("near.toml", tmp_path / "ls", "--graph", str(example), "--mode", "lockstep",
                           "--max-time", "8", "--no-plot", cwd=example.parent)
    try:
        assert launch.finish(timeout=180) == 0, "\n".join(launch.lines[-30:])
    finally:
        launch.kill()
    a = json.loads((tmp_path / "run" / "outcome.json").read_text())
    assert a["robots"] == launch.outcome()["robots"]  # bit for bit
    log = str(tmp_path / "ls" / "run.mcap")
    cat = cekm("log", "cat", log, "--json", "--topics", "cekm/r1/avoid/free", cwd=tmp_path)
    docs = [json.loads(line)["message"] for line in cat.stdout.splitlines()]
    assert [d["stamp"] for d in docs] == [round(k * 0.128, 9) for k in range(64)]  # every tick of 8 s
    typed = [d for d in docs if d["kind"] == "data"]
    nothing = [d for d in docs if d["kind"] == "none"]  # nothing in sight: nothing sent, and the run went on
    assert typed and nothing and len(typed) + len(nothing) == 64, cat.stdout[:500]
    assert all(d["type"] == "FreeDirection" and set(d) == {"kind", "type", "stamp", "sender", "alpha", "clearance"}
               for d in typed), cat.stdout[:500]
    from mcap.reader import make_reader

    with open(log, "rb") as fh:  # the channel's schema: the type's JSON Schema, from its declaration
        schema = next(s for s in make_reader(fh).get_summary().schemas.values() if s.name == "cekm.data:FreeDirection")
    doc = json.loads(schema.data)
    assert schema.encoding == "jsonschema" and doc["title"] == "FreeDirection" and "robot frame" in doc["description"]
    assert doc["properties"]["alpha"]["maximum"] > 3.14 and doc["properties"]["clearance"]["minimum"] == 0.0
    info = cekm("log", "info", log, cwd=tmp_path)
    assert any("cekm/r1/avoid/free" in line and "cekm.data:FreeDirection" in line for line in info.stdout.splitlines())


BEAT = """
import time

from cekm_swarm.node import In, Node, Out
from cekm_swarm.protocol import Data, SenseTarget


class Beat(Node):
    \"\"\"Says when (wall clock) each of its runs was.\"\"\"

    inputs = {"target": In(SenseTarget)}
    outputs = {"beat": Out(Data)}

    def step(self, t, inputs):
        return {"beat": Data(t, self.ctx.sender, {"wall": time.monotonic()})}
"""
TIMER_S = 0.3


def add_beat(example: Path) -> None:
    """A third node for the example's graph, on a timer of its own (``timer = 0.3``)."""
    (example.parent / "beat.py").write_text(BEAT)
    example.write_text(example.read_text() + f"""
[[node]]
name = "beat"
program = "beat:Beat"
timer = {TIMER_S}
inputs = {{ target = "sense/target" }}
outputs = {{ beat = "beat" }}
""")


def foxglove_channel(port: int, topic: str) -> dict:
    """The channel ``topic`` as the Foxglove server on ``port`` advertises it."""
    import time

    from helpers.foxglove import WsClient

    ws, deadline = WsClient(port), time.monotonic() + 60
    while time.monotonic() < deadline:
        op, data = ws.frame()
        for c in json.loads(data).get("channels", []) if op == 1 else []:
            if c["topic"] == topic:
                return c
    raise AssertionError(f"no channel {topic} advertised")


@pytest.mark.slow
def test_two_user_nodes_with_a_typed_message_in_real_time_are_decoded_by_topic_echo(example, tmp_path):
    """And a third node on a timer of its own (``timer = 0.3``): it runs at its timer's
    rate, at most once a tick, whatever rate its input comes at; and `cekm view --foxglove`
    serves the typed messages under their JSON Schema, taken from the run spec."""
    from cekm_swarm.protocol import decode
    from cekm_swarm.runtime.config import free_port
    from cekm_swarm.runtime.mcap_log import read_messages
    from helpers.launch import LaunchProcess, interrupt

    add_beat(example)
    port = free_port()  # a view with its Foxglove server attached from the start (the type's schema)
    view = subprocess.Popen([sys.executable, "-m", "cekm_swarm", "view", "--http", "0", "--foxglove", "0",
                             "--connect", f"tcp/127.0.0.1:{port}"], stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)
    run = LaunchProcess("near.toml", tmp_path / "rt", "--graph", str(example), "--mode", "realtime",
                        "--max-time", "6", "--no-plot", cwd=example.parent, port=port)
    try:
        run.wait_line("world started ticking", timeout=120)
        echo = cekm("topic", "echo", "cekm/r1/avoid/free", "--count", "40", "--timeout", "10",
                    "--connect", f"tcp/127.0.0.1:{port}", cwd=tmp_path)
        code = run.finish(timeout=120)
        said = ""
        while "foxglove WebSocket server on ws://" not in said:
            said = view.stderr.readline()
            assert said, "the view ended without serving Foxglove"
        free = foxglove_channel(int(said.split(":")[-1]), "cekm/r1/avoid/free")
    finally:
        run.kill()
        interrupt(view)
    assert code == 0, "\n".join(run.lines[-30:])
    assert free["encoding"] == "json" and free["schemaName"] == "cekm.data:FreeDirection"
    assert json.loads(free["schema"])["properties"]["clearance"]["minimum"] == 0.0  # from the run spec
    lines = [line.removeprefix("cekm/r1/avoid/free: ") for line in echo.stdout.splitlines()]
    typed = [line for line in lines if line.startswith("FreeDirection t=")]
    assert len(lines) == 40 and typed and all("from=r1/free alpha=" in line and "clearance=" in line for line in typed)
    assert all(line.startswith("none (nothing sent) t=") for line in lines if line not in typed), echo.stdout
    beats = [decode(m.topic, m.data) for m in read_messages(tmp_path / "rt" / "run.mcap", topics=["cekm/r1/beat"])]
    ticks = [round(b.stamp / 0.128) for b in beats]
    walls = [b.values["wall"] for b in beats]
    span = walls[-1] - walls[0]
    assert len(beats) >= 3 and ticks == sorted(set(ticks)), ticks  # at most once a tick
    # at its timer's rate: never faster (its first run may be late by up to a period), nor three times slower
    assert (len(beats) - 1) * TIMER_S <= span + TIMER_S and (len(beats) - 1) * 3 * TIMER_S >= span, (len(beats), span)


@pytest.mark.slow
def test_a_parameter_changed_while_a_lockstep_run_goes_is_applied_at_its_tick_and_logged(example, tmp_path):
    """r1's FreeSpace is held (SIGSTOP: the lockstep world waits for it), so the motor's
    last run is known while `cekm param` asks; the change names its sim time, and the
    motor's commands show it from exactly that tick (Blend's wheel speeds average `speed`)."""
    import math
    import os

    from cekm_swarm.runtime.mcap_log import read_messages
    from helpers.launch import LaunchProcess

    # up to 60 s of sim time (r1 reaches its goal at about 50 s, some 3 s of wall time in
    # lockstep): the hold below, once "world started ticking" is read, lands long before the end
    run = LaunchProcess("near.toml", tmp_path / "ls", "--graph", str(example), "--mode", "lockstep",
                        "--max-time", "60", "--no-plot", cwd=example.parent)
    connect = ("--connect", f"tcp/127.0.0.1:{run.port}")
    try:
        run.wait_line("world started ticking", timeout=120)
        free = run.pids()["r1/free"]
        os.kill(free, signal.SIGSTOP)
        try:
            listed = cekm("param", "list", "r1/motor", *connect, cwd=tmp_path)
            assert listed.returncode == 0, listed.stderr
            head, *rows = listed.stdout.splitlines()
            assert rows == ["speed = 0.05  (float)", "near = 0.2  (float)", "gain = 0.08  (float)"], listed.stdout
            last = float(head.split("t=")[1].split()[0]) if "t=" in head else 0.0  # the motor's last run
            got = cekm("param", "get", "r1/motor", "speed", *connect, cwd=tmp_path)
            assert got.stdout == "0.05\n"
            bad = cekm("param", "set", "r1/motor", "speed", "fast", *connect, cwd=tmp_path)
            assert bad.returncode == 2 and "r1/motor.params.speed: expected a number, got 'fast'" in bad.stderr
            at = last + 1.0
            ok = cekm("param", "set", "r1/motor", "speed", "0.08", "--at", str(at), *connect, cwd=tmp_path)
            assert ok.returncode == 0, ok.stderr
        finally:
            os.kill(free, signal.SIGCONT)
        assert run.finish(timeout=120) == 0, "\n".join(run.lines[-20:])
    finally:
        run.kill()
    t_at = round(math.ceil(round(at / 0.128, 9)) * 0.128, 9)
    assert ok.stdout == f"r1/motor: speed = 0.08 from t={t_at:.3f} s\n"
    assert run.outcome()["launcher"]["nodes"]["r1/motor"]["param_changes"] == [
        {"name": "speed", "value": 0.08, "t": t_at}]  # logged with the run
    assert f"parameter speed = 0.08 from t={t_at:.3f} s" in (tmp_path / "ls" / "logs" / "r1-motor.log").read_text()
    from cekm_swarm.protocol import decode

    cmds = [decode(m.topic, m.data) for m in read_messages(tmp_path / "ls" / "run.mcap", topics=["cekm/r1/cmd/wheels"])]
    moving = [(c.stamp, round((c.v_l + c.v_r) / 2, 9)) for c in cmds if (c.v_l, c.v_r) != (0.0, 0.0)]
    assert {v for t, v in moving if t < t_at} == {0.05} and {v for t, v in moving if t >= t_at} == {0.08}, moving
    # and in the run's log, on a channel of its own, decoded by `cekm log cat` and listed by `cekm log info`
    log = str(tmp_path / "ls" / "run.mcap")
    cat = cekm("log", "cat", log, "--json", "--topics", "cekm/*/param/*", cwd=tmp_path)
    records = [json.loads(line) for line in cat.stdout.splitlines()]
    assert [(r["topic"], r["message"]) for r in records] == [
        (
            "cekm/r1/param/motor",
            {
                "kind": "data",
                "type": "cekm.ParamChange",
                "stamp": t_at,
                "sender": "r1/motor",
                "node": "motor",
                "name": "speed",
                "value": 0.08,
                "was": 0.05,
            },
        )
    ], cat.stdout + cat.stderr
    info = cekm("log", "info", log, cwd=tmp_path)
    assert any("cekm/r1/param/motor" in line and "cekm.data:cekm.ParamChange" in line
               for line in info.stdout.splitlines()), info.stdout


def test_a_change_for_a_tick_the_node_has_run_is_refused_and_one_to_come_waits_for_its_tick():
    from types import SimpleNamespace

    from cekm_swarm.node.live_params import LiveParams

    class Node_:
        from dataclasses import dataclass

        @dataclass(frozen=True)
        class Params:
            speed: float = 0.05

        def __init__(self):
            self.params = self.Params()

    runner = SimpleNamespace(node=Node_(), plan=SimpleNamespace(label="r1/motor", period=1), done=10)
    live = LiveParams(runner)
    with pytest.raises(ValueError, match="too late for t=1.280 s: the node has run t=1.280 s"):
        live.set("speed", 0.1, 1.28)
    with pytest.raises(ValueError, match="expected a number"):
        live.set("speed", "fast", None)
    assert live.set("speed", 0.1, None) == {
        "node": "r1/motor",
        "name": "speed",
        "value": 0.1,
        "t": 1.536,
    }  # 2 periods on
    live.apply_due(11)
    assert runner.node.params.speed == 0.05 and live.changes == []
    live.apply_due(12)
    assert runner.node.params.speed == 0.1 and live.changes == [{"name": "speed", "value": 0.1, "t": 1.536}]


def test_a_node_on_a_timer_runs_at_its_graph_rate_in_one_process(example):
    """In ``cekm run`` (and lockstep) a node's timer is not used: it runs at its inputs'
    rate (sense/target: every other tick), so the run stays reproducible."""
    add_beat(example)
    run = run_graph(load_scenario(str(example.parent / "near.toml")), graph=str(example), max_time=8.0, stop_at=10)
    assert [k for k in range(11) if run.executor.output("cekm/r1/beat", k) is not None] == [0, 2, 4, 6, 8, 10]
