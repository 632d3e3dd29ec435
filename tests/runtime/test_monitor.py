"""cekm monitor: the pure view model, and the real command attached to a live router."""

from __future__ import annotations

import subprocess
import sys


from cekm_swarm.protocol import DEFAULT_KEYS as K
from cekm_swarm.protocol import SenseRange, WheelCommand, WorldState, encode
from cekm_swarm.runtime.bridge import declare_alive
from cekm_swarm.runtime.monitor import MonitorState, render_text


def world_state(t, x):
    return WorldState(t, "world", {"r1": {"x": x, "y": 0.5, "theta": 0.1, "in_contact": False, "goal": [2.0, 0.5]}},
                      {}, {})


def test_view_model_poses_latency_rates_and_drops():
    st = MonitorState()
    st.observe(K.world_state(), encode(world_state(1.0, 0.3)), at=10.0)
    for j in range(12):
        st.observe(K.sense_range("r1", j), encode(SenseRange(1.024, "world", j, 0.0, None)), at=10.000 + j * 1e-4)
    st.observe(K.cmd_wheels("r1"), encode(WheelCommand(1.024, "r1/motor", 0.1, 0.12, 1)), at=10.003)
    st.observe(K.cmd_wheels("r1"), b"\x00garbage", at=10.004)
    v = st.robots["r1"]
    assert v.pose == (0.3, 0.5, 0.1) and v.goal == (2.0, 0.5) and v.status == "moving"
    assert abs(v.latency_ms(0.5) - 3.0) < 1e-6  # first sense of the tick to the command of the same stamp
    assert st.drops.total == 1  # the malformed command was dropped and counted
    st.set_alive({"cekm/r1/alive/motor", "cekm/r1/alive/target"})
    n, missing = st.modules_alive("r1")
    assert n == 2 and "obstacle-0" in missing
    text = render_text(st, now=10.01)
    assert "r1" in text and "moving" in text and "2/14" in text and "dropped: 1" in text
    st.observe(K.cmd_wheels("r1"), encode(WheelCommand(2.0, "r1/motor", 0.0, 0.0, 2)), at=11.0)
    assert st.robots["r1"].status == "stopped"


def test_monitor_command_attaches_to_a_live_run(router, clients):
    """`cekm monitor --once` in another process sees the robot, its module and the keys."""
    pub = clients()
    token = declare_alive(pub, "cekm/r1/alive/motor")
    proc = subprocess.Popen([sys.executable, "-m", "cekm_swarm", "monitor", "--connect", router, "--once", "2"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    t = 0.0
    while proc.poll() is None:  # publish a steady run until the monitor has taken its snapshot
        t += 0.128
        pub.put(K.world_state(), encode(world_state(t, 0.1 + t / 100)))
        pub.put(K.cmd_wheels("r1"), encode(WheelCommand(t, "r1/motor", 0.05, 0.06, int(t / 0.128))))
        try:
            proc.wait(timeout=0.02)
        except subprocess.TimeoutExpired:
            pass
    out, err = proc.communicate(timeout=10)
    assert proc.returncode == 0, err
    assert "r1" in out and "moving" in out and "1/14" in out
    assert "cekm/r1/cmd/wheels" in out and "cekm/world/state" in out
    del token
