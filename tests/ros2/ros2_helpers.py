"""Helpers of the ROS 2 tests: ``cekm`` in a subprocess, the ``.msg`` files the independent
``zenoh-ros2-sdk`` peer reads, and processes whose stdout lines are read on a thread so
that every wait has a timeout."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

from cekm_swarm.ros2.interfaces import MESSAGE_TYPES, interfaces
from helpers.processes import Process

REPO = Path(__file__).resolve().parents[2]
PEER = Path(__file__).with_name("ros2_peer.py")
SEPARATOR = "=" * 80


def write_msg_files(directory: Path, types: tuple[str, ...] = MESSAGE_TYPES) -> Path:
    """``<pkg>/msg/<Name>.msg`` for ``types`` and everything they use, from rosbags' Jazzy
    definitions (what the SDK would otherwise clone from the ROS 2 repositories)."""
    ifc = interfaces("jazzy")
    for ros_type in types:
        sections = ifc.definition(ros_type).split(SEPARATOR + "\n")
        pkg, _, name = ros_type.split("/")
        named = [(f"{pkg}/{name}", sections[0])]
        for sec in sections[1:]:
            head, _, body = sec.partition("\n")
            named.append((head.removeprefix("MSG: ").strip(), body))
        for full, body in named:
            p, n = full.split("/")
            path = directory / p / "msg" / f"{n}.msg"
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(body.strip() + "\n")
    return directory


def cekm(*args: str, timeout: float = 600) -> subprocess.CompletedProcess:
    """Run ``cekm ARGS`` in a subprocess (this worktree's package first on the path)."""
    env = dict(os.environ, PYTHONPATH=f"{REPO}{os.pathsep}{os.environ.get('PYTHONPATH', '')}")
    return subprocess.run([sys.executable, "-m", "cekm_swarm", *args], capture_output=True, text=True,
                          timeout=timeout, env=env, cwd=REPO)


class Lines(Process):
    """A process started in the repository (stdin open): :meth:`expect` waits for a line
    with a timeout, :meth:`send` writes a line to its stdin."""

    def __init__(self, argv: list[str], env: dict[str, str] | None = None) -> None:
        super().__init__(argv, env=env, cwd=REPO, stdin=True)


def peer_argv(endpoint: str, msg_dir: Path, domain: int = 0) -> list[str]:
    """The command line of the SDK peer (tests/ros2/ros2_peer.py) joining ``endpoint``."""
    return [sys.executable, str(PEER), endpoint.removeprefix("tcp/"), str(msg_dir), str(domain)]


def bridge_argv(endpoint: str, *args: str) -> list[str]:
    return [sys.executable, "-m", "cekm_swarm", "ros2", "bridge", "--connect", endpoint, "--json", *args]


def acl_router(tmp_path: Path, port: int, rules: list[tuple[str, str, list[str], list[str]]],
               policies: dict[str, list[str]]) -> Any:
    """A router on loopback with access control (deny by default): ``rules`` (id, flow, messages,
    key expressions) allowed, each identity of ``policies`` (user name -> its rules) logging in
    with the password ``pw-<user>``."""
    from cekm_swarm.runtime.config import load_config, open_session

    creds = tmp_path / "credentials.txt"
    creds.write_text("".join(f"{u}:pw-{u}\n" for u in policies))
    doc = {"mode": "router", "listen": {"endpoints": [f"tcp/127.0.0.1:{port}"]},
           "scouting": {"multicast": {"enabled": False}, "delay": 0},
           "transport": {"auth": {"usrpwd": {"dictionary_file": str(creds)}}},
           "access_control": {
               "enabled": True, "default_permission": "deny",
               "rules": [{"id": i, "permission": "allow", "flows": [f], "messages": m, "key_exprs": k}
                         for i, f, m, k in rules],
               "subjects": [{"id": u, "usernames": [u]} for u in policies],
               "policies": [{"id": u, "subjects": [u], "rules": r} for u, r in policies.items()]}}
    path = tmp_path / "router.json5"
    path.write_text(json.dumps(doc))
    return open_session(load_config(path), "ACL router")
