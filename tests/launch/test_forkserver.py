"""The fork server: a node forked warm is a process like an exec'd one (its own pid,
session, log, environment, command line, exit code and signals), dies with the fork
server, and a launch started cold equals one started warm."""

from __future__ import annotations

import asyncio
import json
import os
import signal
import sys
import textwrap
import time
from pathlib import Path

import pytest

from cekm_swarm.launch.spawn import ForkServer

pytestmark = pytest.mark.slow  # starts real processes (tests/process_guard.py)

CHILD = textwrap.dedent("""
    import json, os, signal, sys, time
    what = sys.argv[1]
    print(json.dumps({"pid": os.getpid(), "ppid": os.getppid(), "sid": os.getsid(0), "argv": sys.argv,
                      "env": os.environ.get("FORKED_FLAVOUR"), "stdin": os.readlink("/proc/self/fd/0"),
                      "cmdline": open("/proc/self/cmdline", "rb").read().rstrip(b"\\0").decode(),
                      "name": __name__}), flush=True)
    if what == "exit":
        sys.exit(int(sys.argv[2]))
    if what == "raise":
        raise RuntimeError("boom")
    if what == "sleep":
        time.sleep(60)
""")


@pytest.fixture
def child_module(tmp_path, monkeypatch):
    (tmp_path / "pkg").mkdir()
    (tmp_path / "pkg" / "forkchild.py").write_text(CHILD)
    monkeypatch.setenv("PYTHONPATH", str(tmp_path / "pkg") + os.pathsep + os.environ.get("PYTHONPATH", ""))
    return "forkchild"


def started(log: Path) -> bool:
    """The child has written its first line (its log exists once the child opened it)."""
    return log.is_file() and bool(log.read_text())


def alive(pid: int) -> bool:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


async def start(tmp_path: Path) -> ForkServer:
    return await ForkServer.start([], tmp_path / "fork-server.log")


def test_a_forked_child_is_its_own_process_with_its_log_env_and_exit_code(tmp_path, child_module):
    async def go():
        server = await start(tmp_path)
        try:
            env = dict(os.environ, FORKED_FLAVOUR="warm")
            argv = [sys.executable, "-m", child_module, "exit", "3"]
            proc = await server.spawn(argv, tmp_path / "a.log", env)
            assert await proc.wait() == 3 and proc.returncode == 3
            crash = await server.spawn([sys.executable, "-m", child_module, "raise"], tmp_path / "b.log", env)
            assert await crash.wait() == 1
            return server.pid, proc.pid
        finally:
            await server.close()

    server_pid, pid = asyncio.run(go())
    doc = json.loads((tmp_path / "a.log").read_text().splitlines()[0])
    assert doc["pid"] == pid and doc["ppid"] == server_pid and doc["sid"] == pid  # its own session leader
    assert doc["env"] == "warm" and doc["stdin"] == "/dev/null" and doc["name"] == "__main__"
    assert doc["argv"][1:] == ["exit", "3"]
    assert doc["cmdline"] == f"{sys.executable} -m {child_module} exit 3"  # what ps shows
    assert "RuntimeError: boom" in (tmp_path / "b.log").read_text()


def test_signals_reach_the_child_and_its_end_is_reported_like_subprocess(tmp_path, child_module):
    async def go():
        server = await start(tmp_path)
        try:
            proc = await server.spawn(
                [sys.executable, "-m", child_module, "sleep"], tmp_path / "c.log", dict(os.environ)
            )
            while not started(tmp_path / "c.log"):
                await asyncio.sleep(0.01)
            proc.send_signal(signal.SIGTERM)
            assert await proc.wait() == -signal.SIGTERM
            with pytest.raises(ProcessLookupError):
                proc.kill()  # gone: as asyncio's Process after its end
        finally:
            await server.close()

    asyncio.run(go())


def test_a_command_line_the_fork_server_cannot_run_is_refused(tmp_path):
    async def go():
        server = await start(tmp_path)
        try:
            with pytest.raises(OSError, match="not a 'python -m module' command line"):
                await server.spawn(["/bin/true"], tmp_path / "d.log", dict(os.environ))
        finally:
            await server.close()

    asyncio.run(go())


def test_children_die_with_the_fork_server(tmp_path, child_module):
    async def go():
        server = await start(tmp_path)
        procs = [await server.spawn([sys.executable, "-m", child_module, "sleep"], tmp_path / f"e{i}.log",
                                    dict(os.environ)) for i in range(3)]
        while not all(started(tmp_path / f"e{i}.log") for i in range(3)):
            await asyncio.sleep(0.01)
        os.kill(server.pid, signal.SIGKILL)  # the fork server killed outright
        codes = await asyncio.wait_for(asyncio.gather(*(p.wait() for p in procs)), 10)
        return [p.pid for p in procs], codes

    pids, codes = asyncio.run(go())
    assert codes == [-signal.SIGTERM] * 3
    deadline = time.monotonic() + 5
    while any(alive(p) for p in pids) and time.monotonic() < deadline:
        time.sleep(0.02)
    assert not any(alive(p) for p in pids)


def test_a_gone_fork_server_is_said_once_and_nodes_start_afresh(tmp_path):
    """The fork server killed mid-run takes its forked nodes with it (signal 15): the
    launcher says so once, and starts every node afresh from then on."""
    from types import SimpleNamespace

    from cekm_swarm.launch.launcher import LaunchConfig, Launcher
    from cekm_swarm.launch.supervision import Child

    said: list[str] = []
    launcher = Launcher(LaunchConfig("lone_obstacle", tmp_path), echo=said.append)
    closed = []

    async def close() -> None:
        closed.append(True)

    launcher.fork_server = SimpleNamespace(alive=False, pid=4242, close=close)

    async def scenario() -> list[int]:
        codes = []
        for i in range(2):
            child = Child("r1", f"n{i}", [sys.executable, "-c", "pass"], tmp_path / f"n{i}.log")
            await launcher._spawn(child)
            codes.append(await child.proc.wait())
        return codes

    assert asyncio.run(scenario()) == [0, 0]  # both started afresh
    gone = [s for s in said if "fork server (pid 4242) is gone" in s]
    assert len(gone) == 1 and "starts afresh" in gone[0] and closed == [True]
    assert launcher.fork_server is None
