"""Sample traffic for the runtime tests (imported by test modules; not a test module)."""

from __future__ import annotations

import numpy as np

from cekm_swarm.protocol import DEFAULT_KEYS, Clock, SenseTarget, TargetField, WheelCommand, encode
from cekm_swarm.runtime.mcap_log import McapRecorder

K = DEFAULT_KEYS


def sample_traffic(n: int = 40) -> list[tuple[str, bytes, float]]:
    """(key, payload, sim time) of a small mixed run, in time order."""
    out = []
    rng = np.random.default_rng(1)
    for i in range(n):
        t = i * 0.128
        out.append((K.world_clock(), encode(Clock(t, "world", i)), t))
        out.append((K.sense_target("r1"), encode(SenseTarget(t, "world", 0.1, 0.5, True)), t))
        if i % 2 == 0:
            out.append((K.field_target("r1"), encode(TargetField(t, "r1/target", 3, rng.random(225))), t))
        out.append((K.cmd_wheels("r1"), encode(WheelCommand(t, "r1/motor", 0.1, 0.05, i)), t))
    return out


def write_log(path, traffic, **kw) -> None:
    with McapRecorder(path, **kw) as rec:
        for key, data, t in traffic:
            rec.write(key, data, t)
