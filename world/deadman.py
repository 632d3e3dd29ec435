"""The world server's dead-man (real time): a robot whose commands have stopped is
stopped (wheels 0) before ``DEADMAN_S`` s of silence would pass."""

from __future__ import annotations

DEADMAN_S = 0.5
DEADMAN_MARGIN_S = 0.025
"""How late a tick boundary may come on a loaded machine (measured: up to a few ms with a
second run of 56 processes beside it); the dead-man stops a robot this much early rather
than late."""


class Deadman:
    """Per robot: when did its last command arrive (monotonic s), and is it stopped."""

    def __init__(self, robots: list[str], limit: float, now: float, margin: float = DEADMAN_MARGIN_S) -> None:
        self.limit = limit
        self.margin = margin
        self.last = {r: now for r in robots}
        self.stopped = {r: False for r in robots}

    def restart(self, now: float) -> None:
        """Every robot heard ``now`` and none stopped (the run's clock starts)."""
        self.last = {r: now for r in self.last}
        self.stopped = {r: False for r in self.stopped}

    def heard(self, robot: str, at: float) -> None:
        self.last[robot] = at

    def check(self, robot: str, now: float, horizon: float) -> tuple[bool, bool]:
        """(stop now?, newly stopped?): stop when the coming ``horizon`` s (plus the margin
        for a late boundary) would run past ``limit`` s of silence."""
        silent = now + horizon + self.margin - self.last[robot] > self.limit
        newly = silent and not self.stopped[robot]
        self.stopped[robot] = silent
        return silent, newly
