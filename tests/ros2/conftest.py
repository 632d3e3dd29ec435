"""Fixtures of the ROS 2 tests: a ``crossing`` lockstep run (made once), the ``.msg`` files
of the SDK peer, and processes killed at teardown."""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from ros2_helpers import REPO, Lines, cekm, write_msg_files


@pytest.fixture(scope="session")
def msg_dir(tmp_path_factory) -> Path:
    return write_msg_files(tmp_path_factory.mktemp("msg"))


@pytest.fixture(scope="session")
def crossing_run(tmp_path_factory) -> Path:
    """A ``crossing`` lockstep run through the distributed runtime (3 robots), made once."""
    out = tmp_path_factory.mktemp("crossing")
    r = cekm("launch", "crossing", "--mode", "lockstep", "--out", str(out), "--overwrite")
    assert r.returncode == 0, r.stderr[-3000:]
    return out


@pytest.fixture
def processes() -> Iterator[Callable[..., Lines]]:
    """Start processes (``Lines``); every one still running is killed at teardown."""
    started: list[Lines] = []

    def start(argv: list[str], env: dict[str, str] | None = None) -> Lines:
        full = dict(os.environ, PYTHONPATH=f"{REPO}{os.pathsep}{os.environ.get('PYTHONPATH', '')}", **(env or {}))
        p = Lines(argv, full)
        started.append(p)
        return p

    yield start
    for p in started:
        p.stop()
