"""A child process of a launcher dies with it, whatever kills the launcher.

The launcher starts each child with ``CEKM_PARENT_PID`` in its environment
(:func:`child_env`); the child calls :func:`die_with_parent` first thing, which asks the
kernel (Linux ``PR_SET_PDEATHSIG``) to send it SIGTERM when that parent dies, SIGKILL
included. A launcher that died while the child was still starting is caught by comparing
the parent's pid. Set in the child rather than between fork and exec, so the launcher
(which runs Zenoh's threads) never runs Python code in a forked copy of itself.
"""

from __future__ import annotations

import ctypes
import os
import signal
import sys

PARENT_ENV = "CEKM_PARENT_PID"
PR_SET_PDEATHSIG = 1


def child_env(base: dict[str, str] | None = None) -> dict[str, str]:
    """The environment for a child that must die with this process."""
    env = dict(os.environ if base is None else base)
    env[PARENT_ENV] = str(os.getpid())
    return env


def die_with_parent(sig: int = signal.SIGTERM) -> bool:
    """If started by a launcher (``CEKM_PARENT_PID`` set), receive ``sig`` when it dies;
    True if so. The variable is removed, so it does not pass on to our own children."""
    text = os.environ.pop(PARENT_ENV, None)
    if not text or not text.isdigit():
        return False
    signal_on_parent_death(int(text), sig)
    return True


def signal_on_parent_death(parent: int, sig: int = signal.SIGTERM) -> None:
    """Receive ``sig`` when ``parent`` (our parent now) dies; at once if it already has."""
    if sys.platform.startswith("linux"):
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, int(sig), 0, 0, 0)
    if os.getppid() != parent:  # the parent is already gone
        os.kill(os.getpid(), sig)
