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
...         return {"nearest": Data(t, self.ctx.sender, {"d": min(seen) if seen else None})}
"""

from .api import Context, In, Inputs, Node, NodeError, NoParams, NotReady, Out, make_params, need, param_fields

__all__ = ["Context", "In", "Inputs", "Node", "NodeError", "NoParams", "NotReady", "Out", "make_params", "need",
           "param_fields"]
