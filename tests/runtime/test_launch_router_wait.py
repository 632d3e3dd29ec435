"""A launch whose router is not up yet waits for it (README: networked commands wait for
the router instead of failing), saying so; Ctrl-C ends the wait at once (exit 130, no
traceback)."""

from __future__ import annotations

import signal

import pytest

from cekm_swarm.runtime.config import free_port
from helpers.launch import LaunchProcess


@pytest.mark.slow
def test_ctrl_c_ends_a_robot_hosts_wait_for_the_router_at_once(tmp_path):
    nobody = f"tcp/127.0.0.1:{free_port()}"  # nothing listens there
    launch = LaunchProcess("crossing", tmp_path / "out", "--mode", "lockstep", "--max-time", "2", "--robots", "r1",
                           "--no-world", "--connect", nobody)
    try:
        launch.wait_line(f"waiting for the router at {nobody}", 30)
        launch.proc.send_signal(signal.SIGINT)
        code = launch.finish(10)  # the wait is 60 s: ending within 10 s is Ctrl-C's doing
    finally:
        launch.kill()
    assert code == 130, "\n".join(launch.lines)
    assert not any("Traceback" in line or "Exception in callback" in line for line in launch.lines), launch.lines


@pytest.mark.slow
def test_a_world_host_joining_a_router_not_up_yet_waits_for_it_and_ctrl_c_ends_the_wait(tmp_path):
    nobody = f"tcp/127.0.0.1:{free_port()}"
    launch = LaunchProcess("crossing", tmp_path / "out", "--mode", "lockstep", "--connect", nobody)
    try:
        launch.wait_line(f"world: waiting for the router at {nobody}", 30)  # not "the world server ended"
        launch.proc.send_signal(signal.SIGINT)
        code = launch.finish(15)
    finally:
        launch.kill()
    assert code == 130, "\n".join(launch.lines)
    assert not any("Traceback" in line or "world server ended" in line for line in launch.lines), launch.lines
