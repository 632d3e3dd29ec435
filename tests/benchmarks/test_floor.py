"""The floor benchmark's tracking-motor probe: the messages it sends are the motor's (2.4 a
tick, valid protocol messages) and the lean motor answers each tick once, with a command."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

from cekm_swarm.protocol import KeyKind, WheelCommand
from cekm_swarm.protocol.codec import decode

_PATH = Path(__file__).resolve().parents[2] / "benchmarks" / "floor.py"


@pytest.fixture(scope="module")
def floor():
    spec = importlib.util.spec_from_file_location("floor_bench", _PATH)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


class Collect:
    def __init__(self) -> None:
        self.sent: list[bytes] = []

    def put(self, payload: bytes) -> None:
        self.sent.append(payload)


def test_the_motor_messages_are_the_tracking_motors(floor):
    ticks = [floor.motor_messages(k) for k in range(20)]
    assert sum(len(t) for t in ticks) / len(ticks) == pytest.approx(2.4)
    for k, tick in enumerate(ticks):
        assert tick[0][0] == "sense/unchanged"
        kinds = {kind.value: kind for kind in KeyKind}
        msgs = [decode(kinds[kind], payload) for kind, payload in tick]  # every one valid
        notice = msgs[0]
        fields = [m for m in msgs if m.KIND is KeyKind.FIELD_OBSTACLE]
        # a sensor's field comes exactly when the notice does not hold its reading back
        assert len(notice.keys) + len(fields) == floor.SENSORS
        assert not {f"sense/range/{m.index}" for m in fields} & set(notice.keys)
        assert (msgs[-1].KIND is KeyKind.FIELD_TRACKING) == (k % 2 == 0)


@pytest.mark.parametrize("mode", ["motor-messages", "lean-motor"])
def test_the_probe_answers_each_tick_once(floor, mode):
    reply = Collect()
    work = floor._motor(mode, reply, "r1/motor")
    for k in range(6):
        tick = floor.motor_messages(k)
        for j, (kind, payload) in enumerate(tick):
            work(kind, payload, j == len(tick) - 1)
        assert len(reply.sent) == k + 1
    if mode == "lean-motor":
        cmds = [decode(KeyKind.CMD_WHEELS, p) for p in reply.sent]
        assert all(type(c) is WheelCommand for c in cmds)
        assert [c.seq for c in cmds] == list(range(1, 7))
        assert [c.stamp for c in cmds] == [round((k + 1) * 0.128, 3) for k in range(6)]
