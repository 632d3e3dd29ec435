"""Why a launch cannot go on."""

from __future__ import annotations

from cekm_swarm.errors import CekmError, RunError


class LaunchError(RunError):
    """A launch cannot go on: the world server or the modules did not come up."""


class NodeCannotStart(CekmError):
    """A node of the graph cannot start (a bad model, a bad parameter): its own line (exit 2)."""


class NodeFailed(RunError):
    """A node's step failed, hung past ``--step-timeout``, or its process kept dying at one
    lockstep tick: the run cannot go on (exit 1), its own line."""
