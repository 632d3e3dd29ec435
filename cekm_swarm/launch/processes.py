"""What the launcher needs to start a process of a run: its command line (from the
parameters each process declares), its environment, and a run id.

Run isolation: every process a launcher starts dies with it, whatever kills the
launcher (SIGKILL included): its environment names the launcher
(:func:`cekm_swarm.runtime.lifetime.child_env`) and the process asks the kernel for
SIGTERM when that parent dies (``PR_SET_PDEATHSIG``): the world server writes its
outcome and closes its log, the modules leave. A process started on another host
belongs to that host's launcher and dies with it. The run id in every liveliness token
(``KeySpace.run``) keeps any process of another run, alive for whatever reason, from
being counted as one of this run's.
"""

from __future__ import annotations

import secrets
import time
from typing import Any

from cekm_swarm.node.process import node_argv
from cekm_swarm.runtime.lifetime import child_env
from world.server import server_argv as world_argv

__all__ = ["child_env", "new_run_id", "node_argv", "server_argv"]


def new_run_id() -> str:
    """A fresh run id: the UTC start time and 6 random hex digits (``20261201-134500-a1b2c3``)."""
    return time.strftime("%Y%m%d-%H%M%S", time.gmtime()) + "-" + secrets.token_hex(3)


def server_argv(**values: Any) -> list[str]:
    """The world server's command line (its declared parameters, ``world.server.WORLD_PARAMS``)."""
    return world_argv(**values)
