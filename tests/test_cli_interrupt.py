"""The ``cekm`` entry stops on SIGINT even when started with SIGINT ignored, as every
background job of a shell script is (a supervisor's or a test's ``kill -INT`` would
otherwise be lost and the command run on until killed)."""

from __future__ import annotations

import signal
import subprocess
import sys

import pytest

from cekm_swarm.runtime.config import free_port
from cekm_swarm.runtime.lines import LineReader

pytestmark = pytest.mark.slow  # starts a cekm process (tests/process_guard.py)


def _ignore_sigint() -> None:  # in the child, before exec: as `cekm view ... &` in a script
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def test_a_command_started_ignoring_sigint_is_still_interrupted_by_it():
    view = subprocess.Popen([sys.executable, "-m", "cekm_swarm", "view", "crossing", "--http", "0",
                             "--connect", f"tcp/127.0.0.1:{free_port()}"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            start_new_session=True, preexec_fn=_ignore_sigint)
    try:
        LineReader(view.stderr).wait_line("waiting for the router", 60)  # up, and waiting
        view.send_signal(signal.SIGINT)
        assert view.wait(timeout=30) == 130  # interrupted, not run on until killed
    finally:
        if view.poll() is None:
            view.kill()
            view.wait(10)
