"""A node's gate: what decides, from the values that come, when the node runs and with
which inputs (the rule of :mod:`cekm_swarm.graph.plan`). One interface, :class:`Gate`,
four kinds: :class:`~.direct_gate.DirectGate` (a stateless node of one key, on every
value), :class:`~.timing.LockstepGate`, :class:`~.timing.RealtimeGate` and
:class:`~.timer_gate.TimerGate` (real time, on a timer of the node's own);
:func:`make_gate` picks a node's.
"""

from __future__ import annotations

from collections.abc import Collection, Iterable
from typing import Any, Protocol

from .direct_gate import DirectGate
from .runner import Runner
from .timer_gate import TimerGate
from .timing import Drop, GateCounts, LockstepGate, RealtimeGate

Sent = list[tuple[str, Any]]
"""Messages to send now: (key, message)."""


class Gate(Protocol):
    """What a node's process hands its received values and events to; each call returns
    the messages to send now."""

    def put(self, key: str, msg: Any) -> Sent:
        """A value received on ``key`` (checked, its stamp admitted)."""
        ...

    def hold(self, key: str, k: int, since: int) -> Sent:
        """``key``'s value of tick ``since`` stands for tick ``k`` too (a held reading)."""
        ...

    def hold_all(self, holds: Iterable[tuple[str, int, int]]) -> Sent:
        """Every ``(key, k, since)`` of one ``Unchanged`` message."""
        ...

    def teammate(self, robot: str, alive: bool) -> Sent:
        """A teammate's processes are gone, or back."""
        ...

    def resend(self, keys: Collection[str] | None = None) -> Sent:
        """The recent runs' outputs again (on ``keys``, or all), for a reader that (re)appeared."""
        ...

    def counts(self) -> GateCounts:
        """What the gate counted, for the node's report."""
        ...


def make_gate(runner: Runner, mode: str, drop: Drop, clock_key: str | None = None) -> Gate:
    """The gate of ``runner``'s node in ``mode`` (``lockstep`` or ``realtime``): its own timer
    when it declares one in real time (then ``clock_key`` tells it of each tick); every
    value as it comes for a stateless node of one key; else the mode's gate."""
    node = runner.plan
    if TimerGate.fits(node, mode):
        return TimerGate(runner, drop=drop, clock_key=clock_key)
    if DirectGate.fits(node):
        return DirectGate(runner, drop=drop)
    if mode == "lockstep":
        return LockstepGate(runner, drop=drop)
    return RealtimeGate(runner, drop=drop)


__all__ = ["Gate", "Sent", "make_gate"]
