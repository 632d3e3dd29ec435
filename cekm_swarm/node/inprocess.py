"""A whole graph in one process (``cekm run``): every node instance of every robot, run at
each tick in the graph's order with the inputs the rule names (:func:`.timing.gather`),
the same values a lockstep run's processes wait for. So ``cekm launch --mode lockstep``
equals ``cekm run`` bit for bit, by construction rather than by a second copy of the
controller's schedule.

Messages pass between nodes as objects. They are validated and normalized when built
(floats, read-only float64 arrays), which is what decoding gives, so a process reading
them off the wire computes the same; ``codec=True`` sends every message through
``encode``/``decode`` anyway, to check exactly that (tests do).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from cekm_swarm.graph.plan import NodePlan, RunPlan
from cekm_swarm.node.graph_check import CheckedGraph
from cekm_swarm.protocol import Nothing, decode, encode, expect_of
from cekm_swarm.ticks import STEP_TIMEOUT, TICK_S, tick_time

from .api import Context, Node, NodeError, StepFailed, start_node
from .runner import Runner
from .timing import gather
from .watchdog import Watchdog

KEEP_TICKS = 16
"""Ticks of values kept per key (more than any shipped node's period and delay need)."""


class GraphExecutor:
    """Run ``plan``'s nodes tick by tick: :meth:`put` the world's messages of tick k, then
    :meth:`tick` (k) returns each robot's answer (its wheel command of tick k)."""

    def __init__(self, plan: RunPlan, checked: CheckedGraph, context: Callable[[NodePlan], Context],
                 codec: bool = False, step_timeout: float | None = STEP_TIMEOUT) -> None:
        self.plan = plan
        self.codec = codec
        self.runners: list[Runner] = []
        for robot in plan.team:
            for node in plan.nodes[robot]:
                cls = checked.classes[node.decl.name]
                self.runners.append(Runner(node, start_node(cls, context(node), checked.make_params(node.decl.name)),
                                           plan.answer_key(robot)))
        # what a reader checks of what it receives, its producer's step is refused for
        # (in a launch the reader would drop it and wait for good): the run's checks of
        # each node's outputs (.checks, in Runner.run), and the readers' own (Node.check_input)
        self.refusers: dict[str, list[tuple[Runner, str]]] = {}  # key -> (reader, port) with a check_input
        for r in self.runners:
            if type(r.node).check_input is not Node.check_input:
                for b in r.plan.bindings:
                    for s in b.sources:
                        self.refusers.setdefault(s.key, []).append((r, b.port))
        self.values: dict[str, dict[int, Any]] = {}
        self.answer_keys = {r: plan.answer_key(r) for r in plan.team}
        keep = max([n.period for r in plan.team for n in plan.nodes[r]] + [1])
        self.keep = max(KEEP_TICKS, 4 * keep)
        self.kinds = {k: expect_of(v) for r in plan.team for k, v in plan.sent_keys(r).items()}
        self.watchdog = None if step_timeout is None else Watchdog(step_timeout)  # a step that never returns

    def _lookup(self, key: str, tick: int) -> Any:
        held = self.values.get(key)
        return None if held is None else held.get(tick)

    def _store(self, key: str, tick: int, msg: Any) -> None:
        if self.codec:
            msg = decode(key, encode(msg), keys=self.plan.keys, expect=self.kinds.get(key))
        self.values.setdefault(key, {})[tick] = msg

    def put(self, key: str, tick: int, msg: Any) -> None:
        """A world message of tick ``tick`` on ``key``."""
        self._store(key, tick, msg)

    def tick(self, k: int) -> dict[str, Any]:
        """Run every node due at tick ``k``; each robot's answer."""
        for runner in self.runners:
            node = runner.plan
            if k % node.period:
                continue
            inputs, missing = gather(node, k, self._lookup)
            if missing:
                raise NodeError(f"{node.label}: at t={round(k * TICK_S, 9)} nothing has sent {missing[0]} (in lockstep "
                                f"this node would wait for it forever)")
            sent = self._run(runner, k, inputs)
            for key, msg in sent:
                for reader, port in self.refusers.get(key, ()) if type(msg) is not Nothing else ():
                    why = reader.node.check_input(port, msg)
                    if why is not None:
                        self._refused(runner, k, key, reader, why)
                self._store(key, k, msg)
        answers = {r: self._lookup(key, k) for r, key in self.answer_keys.items()}
        if k % self.keep == 0:
            old = k - self.keep
            for held in self.values.values():
                for t in [t for t in held if t < old]:
                    del held[t]
        return answers

    def _run(self, runner: Runner, k: int, inputs: Any) -> list[tuple[str, Any]]:
        """``runner.run``, watched: a step past ``step_timeout`` ends the run (:mod:`.watchdog`)."""
        dog = self.watchdog
        if dog is None:
            return runner.run(k, inputs)
        dog.runner = runner
        try:
            return runner.run(k, inputs)
        except KeyboardInterrupt:
            timeout = dog.timed_out()
            if timeout is None:
                raise
            raise timeout from None
        finally:
            dog.runner = None

    @staticmethod
    def _refused(runner: Runner, k: int, key: str, reader: Runner, why: str) -> None:
        port = next(p for p, kk in runner.plan.outputs.items() if kk == key)
        raise StepFailed(f"{runner.plan.label}: its step at t={tick_time(k):.3f} s failed: output {port!r}: "
                        f"{reader.plan.label} cannot use it: {why}")

    def output(self, key: str, tick: int) -> Any:
        """What was sent on ``key`` at ``tick`` (while it is kept), e.g. a robot's fields for Fig. 4."""
        return self._lookup(key, tick)

    def node(self, robot: str, name: str) -> Node:
        """The node object of ``robot``'s node instance ``name``."""
        for r in self.runners:
            if r.plan.robot == robot and r.plan.name == name:
                return r.node
        raise KeyError(f"{robot}/{name}")

    def close(self) -> None:
        if self.watchdog is not None:
            self.watchdog.close()
        for r in self.runners:
            r.node.close()
