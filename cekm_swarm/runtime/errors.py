"""Errors of the Zenoh runtime plumbing."""

from __future__ import annotations

from cekm_swarm.errors import EXIT_FAILED, CekmError


class RuntimeTransportError(CekmError):
    """A Zenoh session cannot be opened or configured (endpoint, config file, credentials).
    At the command line a run failure (exit 1); a bad config file is refused as usage first."""

    exit_code = EXIT_FAILED


class McapLogError(CekmError):
    """An MCAP log cannot be written, read or recovered; names the file and the problem."""

    def __init__(self, path: str, problem: str) -> None:
        self.path = str(path)
        self.problem = problem
        super().__init__(f"{self.path}: {problem}")
