"""A launcher's child dies with it (``cekm_swarm.runtime.lifetime``): real processes, a
middle one killed with SIGKILL."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from cekm_swarm.runtime.lifetime import PARENT_ENV, child_env, die_with_parent

CHILD = ("from cekm_swarm.runtime.lifetime import die_with_parent; import os, time; "
         "print(die_with_parent(), os.environ.get('CEKM_PARENT_PID'), flush=True); time.sleep(60)")
PARENT = ("import subprocess, sys; from cekm_swarm.runtime.lifetime import child_env; "
          f"p = subprocess.Popen([sys.executable, '-c', {CHILD!r}], env=child_env()); "
          "print(p.pid, flush=True); p.wait()")


def gone(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] == "Z"
    except OSError:
        return True


@pytest.mark.slow
def test_the_child_gets_sigterm_when_its_launcher_is_killed():
    parent = subprocess.Popen([sys.executable, "-c", PARENT], stdout=subprocess.PIPE, text=True)
    try:
        child = int(parent.stdout.readline())
        assert parent.stdout.readline().split() == ["True", "None"]  # tied, and the variable not passed on
        parent.kill()
        parent.wait(10)
        deadline = time.monotonic() + 2.0
        while not gone(child) and time.monotonic() < deadline:
            time.sleep(0.02)
        assert gone(child), "the child outlived its launcher by 2 s"
    finally:
        parent.kill()


@pytest.mark.slow
def test_a_child_whose_launcher_is_already_gone_stops_at_once():
    env = dict(os.environ, **{PARENT_ENV: "1"})  # not our parent: as if the launcher died while we started
    r = subprocess.run([sys.executable, "-c", CHILD], env=env, timeout=60, capture_output=True)
    assert r.returncode == -signal.SIGTERM


def test_a_process_not_started_by_a_launcher_is_left_alone(monkeypatch):
    monkeypatch.delenv(PARENT_ENV, raising=False)
    assert die_with_parent() is False
    assert child_env({})[PARENT_ENV] == str(os.getpid())
