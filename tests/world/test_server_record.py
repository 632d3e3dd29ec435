"""What the world's recorder takes from other sessions (world.recorder.RecordFilter)."""

import numpy as np

from cekm_swarm.protocol import DEFAULT_KEYS as K
from cekm_swarm.protocol import DropCounter, ObstacleField, WheelCommand, encode
from cekm_swarm.ticks import tick_time
from world.recorder import RecordFilter


def test_only_this_runs_keys_with_decodable_messages_and_believable_stamps_are_recorded():
    drops = DropCounter("test")
    f = RecordFilter(K, ["r1"], drops)
    now = tick_time(100)
    cmd = encode(WheelCommand(tick_time(99), "r1/motor", 0.1, 0.1, 3))
    assert f.check(K.cmd_wheels("r1"), cmd, now) == tick_time(99)
    field = encode(ObstacleField(now, "r1/obstacle-2", 2, 1, np.ones(4)))
    assert f.check(K.field_obstacle("r1", 2), field, now) == now
    refused = [
        (K.cmd_wheels("r2"), cmd),  # a robot this run does not have
        ("cekm/fuzz/1", cmd),  # not a key of the key space
        (K.cmd_wheels("r1"), b"\xc1"),  # not msgpack
        (K.cmd_wheels("r1"), encode(WheelCommand(1e18, "x", 0.0, 0.0, 0))),  # far future
        (K.cmd_wheels("r1"), encode(WheelCommand(tick_time(101), "x", 0.0, 0.0, 0))),  # ahead of the world's clock
        (K.cmd_wheels("r1"), encode(WheelCommand(tick_time(50), "x", 0.0, 0.0, 0))),  # an old tick
        (K.cmd_wheels("r1"), encode(WheelCommand(now - 0.05, "x", 0.0, 0.0, 0))),  # not a tick's time
    ]
    for key, payload in refused:
        assert f.check(key, payload, now) is None, key
    assert drops.total == len(refused)
    assert drops.count(K.cmd_wheels("r1")) == 5
