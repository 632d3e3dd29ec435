"""A node's parameters changed while it runs (``cekm param set``): validated against the
node's ``Params`` as a graph's values are (:func:`~.api.make_params`), then applied
before the node's first run at or after the sim time the change names, so a lockstep run
given the same changes at the same times computes the same; every change is logged (the
node's log, and a :class:`~cekm_swarm.protocol.ParamChange` on the node's parameter key,
which the world records in ``run.mcap``) and reported (``outcome.json``:
``launcher.nodes[...].param_changes``).

The rule of the tick: a change for sim time ``at`` applies from tick ``ceil(at / 0.128)``;
one whose tick the node has already run is refused ("too late"); without ``at`` it
applies from the node's second due tick after its last run (in real time, about two
periods from now; in lockstep give ``at`` for a reproducible run)."""

from __future__ import annotations

import dataclasses
import logging
import math
from typing import Any

from cekm_swarm.protocol import ParamChange
from cekm_swarm.ticks import TICK_S, tick_time

from .api import make_params, param_fields

log = logging.getLogger("cekm_swarm.node")


class LiveParams:
    """The parameters of the node ``runner`` runs, and the changes waiting for their tick."""

    def __init__(self, runner: Any) -> None:
        self.runner = runner
        self.pending: list[tuple[int, str, Any, Any]] = []  # (tick, name, value, the Params it makes)
        self.changes: list[dict[str, Any]] = []  # applied: {"name", "value", "t"}
        self.on_change: Any = None  # called with the ParamChange of each change applied (the node's process sends it)

    def describe(self) -> dict[str, Any]:
        """The node's parameters now: name -> {value, type}; and the changes waiting."""
        node = self.runner.node
        cls = type(node)
        hints = {f.name: f.type for f in dataclasses.fields(cls.Params)}
        return {"node": self.runner.plan.label, "t": tick_time(self.runner.done) if self.runner.done >= 0 else None,
                "params": {n: {"value": getattr(node.params, n), "type": str(hints.get(n, ""))}
                           for n in param_fields(cls)},
                "pending": [{"name": n, "value": v, "t": tick_time(k)} for k, n, v, _ in self.pending]}

    def set(self, name: str, value: Any, at: float | None) -> dict[str, Any]:
        """Schedule ``name = value`` from sim time ``at``; ValueError naming what is wrong."""
        runner = self.runner
        cls = type(runner.node)
        label = runner.plan.label
        current = {f: getattr(runner.node.params, f) for f in param_fields(cls)}
        params = make_params(cls, {**current, name: value}, f"{label}.params")  # refuses an unknown name or type
        period = runner.plan.period
        k = math.ceil(round(at / TICK_S, 9)) if at is not None else runner.done + 2 * period
        if k <= runner.done:
            raise ValueError(f"{label}: too late for t={tick_time(k):.3f} s: "
                             f"the node has run t={tick_time(runner.done):.3f} s")
        self.pending.append((k, name, getattr(params, name), params))
        self.pending.sort(key=lambda p: p[0])
        return {"node": label, "name": name, "value": getattr(params, name), "t": tick_time(k)}

    def apply_due(self, k: int) -> None:
        """Before the run of tick ``k``: apply every change whose tick has come."""
        while self.pending and self.pending[0][0] <= k:
            _, name, value, _ = self.pending.pop(0)
            node = self.runner.node
            old = getattr(node.params, name)
            node.params = dataclasses.replace(node.params, **{name: value})
            self.changes.append({"name": name, "value": value, "t": tick_time(k)})
            log.info("%s: parameter %s = %r from t=%.3f s (was %r)", self.runner.plan.label, name, value, tick_time(k),
                     old)
            if self.on_change is not None:
                plan = self.runner.plan
                self.on_change(ParamChange(tick_time(k), plan.label, plan.name, name, _plain(value), _plain(old)))


def _plain(value: Any) -> Any:
    """A parameter's value as plain data (a tuple as a list) for its :class:`ParamChange`."""
    return [_plain(v) for v in value] if isinstance(value, (tuple, list)) else value
