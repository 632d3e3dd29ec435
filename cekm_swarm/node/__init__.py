"""The public module API: write a node of a robot's controller as a small class, declare it
in a graph file, and run it with ``cekm launch --graph FILE`` (each node its own process)
or ``cekm run --graph FILE`` (the whole graph in one process). docs/modules.md walks
through an example.

>>> from dataclasses import dataclass
>>> from cekm_swarm.node import In, Node, Out
>>> from cekm_swarm.protocol import Data, SenseRange
>>> class Nearest(Node):
...     '''The nearest obstacle any distance sensor sees.'''
...     inputs = {"ranges": In(SenseRange, many=True)}
...     outputs = {"nearest": Out(Data)}
...     def step(self, t, inputs):
...         seen = [r.d for r in inputs["ranges"].values() if r.d is not None]
...         return {"nearest": {"values": {"d": min(seen) if seen else None}}}

**A node's life.** The framework builds the node, ``cls(ctx, params)``, which calls
:meth:`Node.setup` once (a launch first builds one of each kind in its own process, with
``ctx.mode == "check"``, to refuse a bad parameter or model before anything starts);
then calls :meth:`Node.step` ``(t, inputs)`` at each of its due ticks (``t`` is the
tick's sim time, ``k * 0.128`` s, :func:`cekm_swarm.ticks.tick_time`), with the inputs the
rule of a tick names (docs/modules.md section 3); :meth:`Node.check_input` for each
received message it may refuse; :meth:`Node.teammate_left` when a teammate's processes
are gone; and :meth:`Node.close` once at the end. A step returns, per output port, the
message or a dict of its own fields (the runner fills in ``stamp``, ``sender`` and a
``seq`` left out).

**Failures and exit codes** (``cekm run``, ``cekm launch``): a node that cannot start
(:func:`~.api.cannot_start`: its type, file and line; the traceback in its log) ends the
command with ``cekm: error: ...``, exit code 2 (bad input: :data:`cekm_swarm.errors.EXIT_USAGE`);
a step that fails (:class:`StepFailed`) or runs past ``--step-timeout`` in lockstep or
one process ends the run with ``cekm: failed: ...``, exit code 1
(:data:`cekm_swarm.errors.EXIT_FAILED`); in real time a failed step is counted, grouped
by where it was raised, and the run goes on. Ctrl-C: exit code 130. A node's own process
exits 78 when it cannot start and 79 when its lockstep step failed
(:mod:`cekm_swarm.node.process`).
"""

from .api import (
    Context,
    In,
    Inputs,
    Node,
    NodeError,
    NoParams,
    NotReady,
    Out,
    StepFailed,
    make_params,
    need,
    param_fields,
)

__all__ = ["Context", "In", "Inputs", "Node", "NodeError", "NoParams", "NotReady", "Out", "StepFailed", "make_params",
           "need", "param_fields"]
