"""What a node sends, checked on its own side as its readers check what they receive.

A message is validated when it is built (its field types and ranges), but some of what a
reader needs is a fact of the run, not of the message: a field (a target, obstacle or
tracking field) holds one value per neuron of the run's model's lattice, and its winners
are neurons of it (:func:`~cekm_swarm.protocol.checks.lattice_misfit`). A reader drops
and counts a field that does not fit (it may come from outside the run); in lockstep it
would then wait for good for a value that never comes. So the producer's step is refused
for it first, as a step that returns a message of the wrong type is: one line naming the
node, the tick, the output and what is wrong, in ``cekm run`` and in a launch alike.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from cekm_swarm.graph.plan import NodePlan
from cekm_swarm.protocol import Nothing
from cekm_swarm.protocol.checks import lattice_misfit, on_lattice

from .api import Context, Node, NodeError


class OutputCheck:
    """The checks of the outputs of one node that are over the run's lattice."""

    __slots__ = ("label", "ctx", "ports", "_n")

    def __init__(self, label: str, ctx: Context, ports: tuple[tuple[int, str], ...]) -> None:
        self.label, self.ctx, self.ports = label, ctx, ports  # ports: (index in the step's outputs, port)
        self._n: int | None = None

    def lattice(self) -> int:
        """Neurons of the run's model's lattice (0: the run has no model, nothing to fit);
        the model is loaded once per process, shared with the nodes that use it."""
        if self._n is None:
            self._n = 0 if self.ctx.model_source is None else int(self.ctx.model().lattice.n)
        return self._n

    def __call__(self, t: float, sent: Sequence[tuple[str, Any]]) -> None:
        """Raise NodeError naming the node, the tick and the output when one of ``sent``
        (the step's ``(key, message)`` per output, in the plan's output order) does not fit."""
        n = self.lattice()
        if not n:
            return
        for i, port in self.ports:
            if type(sent[i][1]) is Nothing:  # nothing sent on it this tick
                continue
            why = lattice_misfit(sent[i][1], n)
            if why is not None:
                raise NodeError(f"{self.label}: its step at t={t:.3f} s failed: output {port!r}: {why}")


def output_check(plan: NodePlan, node: Node) -> OutputCheck | None:
    """The check of what ``node`` sends (None: none of its outputs needs one)."""
    ports = tuple((i, port) for i, port in enumerate(plan.outputs) if on_lattice(node.outputs[port].type))
    ctx = getattr(node, "ctx", None)  # a Node always has one; a test's stand-in may not (nothing to check then)
    return OutputCheck(plan.label, ctx, ports) if ports and ctx is not None else None


__all__ = ["OutputCheck", "output_check"]
