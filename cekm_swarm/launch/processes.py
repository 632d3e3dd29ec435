"""What the launcher needs to start a process of a run: its command line (from the
parameters each process declares), a run id, and the tie that ends a child with its
launcher.

Run isolation: every process a launcher starts gets ``PR_SET_PDEATHSIG`` (SIGTERM), so
when the launcher dies, whatever kills it (SIGKILL included), the kernel stops its
children: the world server writes its outcome and closes its log, and the modules leave.
A process started on another host belongs to that host's launcher and dies with it.
The run id in every liveliness token (``KeySpace.run``) keeps any process of another
run, alive for whatever reason, from being counted as one of this run's.
"""

from __future__ import annotations

import ctypes
import os
import secrets
import signal
import sys
import time
from collections.abc import Callable
from typing import Any

from cekm_swarm.modules.shell import module_argv

PR_SET_PDEATHSIG = 1

__all__ = ["die_with_parent", "module_argv", "new_run_id", "server_argv"]


def new_run_id() -> str:
    """A fresh run id: the UTC start time and 6 random hex digits (``20261201-134500-a1b2c3``)."""
    return time.strftime("%Y%m%d-%H%M%S", time.gmtime()) + "-" + secrets.token_hex(3)


def server_argv(**values: Any) -> list[str]:
    """The world server's command line (its declared parameters, ``world.server.WORLD_PARAMS``)."""
    from world.server import server_argv as world_argv

    return world_argv(**values)


def die_with_parent(sig: int = signal.SIGTERM) -> Callable[[], None] | None:
    """A ``preexec_fn`` that makes the child receive ``sig`` when this process dies (Linux;
    None elsewhere). The signal fires when the thread that forked the child exits, so
    children must be started from the launcher's main thread (its event loop's). A
    launcher that died between fork and the ``prctl`` is caught by comparing the parent's
    pid after it."""
    if not sys.platform.startswith("linux"):
        return None
    libc = ctypes.CDLL(None, use_errno=True)  # loaded here, in the parent: nothing to load after fork
    prctl = libc.prctl
    parent = os.getpid()

    def preexec() -> None:
        prctl(PR_SET_PDEATHSIG, int(sig), 0, 0, 0)
        if os.getppid() != parent:  # the launcher died before the prctl took effect
            os.kill(os.getpid(), sig)

    return preexec
