"""The ROS 2 commands' own checks: one line, the documented exit code, nothing started."""

import pytest

from cekm_swarm.cli import main
from cekm_swarm.cli_support import run_cli
from cekm_swarm.runtime.config import free_port


def one_line(capsys, argv: list[str], code: int, kind: str) -> str:
    assert run_cli(main, argv) == code
    err = capsys.readouterr().err
    assert "Traceback" not in err and len(err.splitlines()) == 1, err
    assert err.startswith(f"cekm: {kind}: ")
    return err


@pytest.mark.parametrize("option,value,needle", [
    ("--robots", "r1,bad id", "robot id 'bad id'"),
    ("--teleop", ",", "give robot ids"),
    ("--teleop", "world", "'world' is reserved"),
])
def test_bad_robot_lists_are_refused_by_name(capsys, option, value, needle):
    line = one_line(capsys, ["ros2", "bridge", option, value, "--wait", "0"], 2, "error")
    assert option in line and needle in line


def test_no_router_is_a_failure_naming_the_endpoint(capsys):
    ep = f"tcp/127.0.0.1:{free_port()}"
    line = one_line(capsys, ["ros2", "bridge", "--connect", ep, "--wait", "0"], 1, "failed")
    assert f"no router at {ep}" in line


def test_export_needs_an_mcap_log(capsys, tmp_path):
    (tmp_path / "x.mcap").write_bytes(b"\x89MCAP0\r\n")  # the magic, then nothing: a log cut before its first message
    line = one_line(capsys, ["log", "export", str(tmp_path / "x.mcap"), "--to", "ros2", "--out", str(tmp_path / "b")],
                    2, "error")
    assert f"{tmp_path / 'x.mcap'}: no message of the key space to export" in line
    assert not (tmp_path / "b").exists()
