"""A launch whose output directory's disk fills while the world logs: the run ends with one
clear line (exit 1), no traceback, and ``run.mcap`` as far as it got is complete and read
whole by ``cekm log info`` and ``cekm log cat``. The disk is a 160 KB tmpfs (the run's log
is about 150 KB), so the test needs root to mount it; it is skipped otherwise
(``test_log_full.py`` covers the recorder with a file-size limit, unprivileged)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from cekm_swarm.experiments.default_model import default_model, default_model_path
from helpers.launch import LaunchProcess

pytestmark = pytest.mark.slow  # launches and child processes


@pytest.fixture
def small_disk(tmp_path) -> Path:
    if os.geteuid() != 0:
        pytest.skip("mounting a small tmpfs needs root")
    mnt = tmp_path / "disk"
    mnt.mkdir()
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=160k", "tmpfs", str(mnt)], capture_output=True,
                          text=True)
    if done.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {done.stderr.strip()}")
    try:
        yield mnt
    finally:
        subprocess.run(["umount", "-l", str(mnt)], check=False)


def _cekm(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "cekm_swarm", *args], capture_output=True, text=True, timeout=120)


def test_a_full_disk_ends_the_launch_in_one_line_with_a_readable_log(small_disk):
    default_model(progress=False)
    out = small_disk / "run"
    run = LaunchProcess("lone_obstacle", out, "--mode", "lockstep", "--model", str(default_model_path()))
    try:
        code = run.finish(timeout=180)
    finally:
        run.kill()
    text = "\n".join(run.lines)
    assert code == 1, text
    failed = [line for line in run.lines if line.startswith("cekm: failed")]
    assert failed == [run.lines[-1]], text  # one line, the last
    assert failed[0].startswith(f"cekm: failed: the log's disk is full: {out / 'run.mcap'}: No space left on device")
    assert "the log stops here, closed with" in failed[0] and "the run stopped at t=" in failed[0]
    assert "Traceback" not in text
    info = _cekm("log", "info", str(out / "run.mcap"), "--json")
    assert info.returncode == 0, info.stderr
    doc = json.loads(info.stdout)
    assert doc["complete"] and doc["messages"] > 100
    assert f"with {doc['messages']} messages" in failed[0]
    cat = _cekm("log", "cat", str(out / "run.mcap"), "--views")
    assert cat.returncode == 0, cat.stderr
    assert len(cat.stdout.splitlines()) == doc["messages"]
    assert not (out / "outcome.json.tmp").exists()
