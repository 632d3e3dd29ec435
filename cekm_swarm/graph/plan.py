"""What a declared graph means for one run: every node instance of every robot, the keys
it reads and sends, when it runs, and everything derived from that and nowhere else: the
processes, the world's lockstep wait set and what it publishes, what "robot r answered
tick t" means, the nodes a monitor expects, the keys the world records.

Time is in ticks of 0.128 s (tick k at sim time t_k = k * 0.128 s). Each node has a
period P (its ``every``, or the greatest common divisor of the periods of what it reads
this tick) and runs at the ticks k with k % P == 0. **The rule** of what a node running
at tick k sees, in ``cekm run`` and in lockstep alike (docs/runtime.md):

* an input with ``delay = 0`` is its producer's output of the producer's latest run at
  or before k: tick ``k - k % P_producer``;
* an input with ``delay = 1`` (every teammate's key) is the producer's output of its
  latest run strictly before k: tick ``(k-1) - (k-1) % P_producer`` (none before tick 0);
* in lockstep a node runs once it holds every such value from every producer that is
  alive, whatever order they came in, however many robots; ``cekm run`` computes the
  same values in the same order in one process, so the two agree bit for bit.

Cycles are allowed only through a delayed input. Plain data in, plain data out: nothing
here imports node code (the node classes' port types come in as ``ports``, from
:mod:`cekm_swarm.node.graph_check` or from a run spec). :func:`cekm_swarm.graph.resolve.build_plan`
builds a :class:`RunPlan` from a graph and refuses one that cannot run.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from cekm_swarm.protocol import KeySpace
from cekm_swarm.ticks import ODOMETRY_EVERY, TARGET_EVERY

from .spec import Graph, NodeDecl

WORLD_OWNER = "world"
MAP_KIND = "map"  # a learner's map version (protocol KeyKind.MAP_VERSION)


@dataclass(frozen=True)
class WorldKey:
    """A key the world publishes: its message kind, its period in ticks, and the tasks
    whose scenarios have it."""

    kind: str
    period: int
    tasks: tuple[str, ...]
    per_robot: bool = True


WORLD_KEYS: dict[str, WorldKey] = {
    "sense/target": WorldKey("sense/target", TARGET_EVERY, ("navigation",)),
    "sense/range/{j}": WorldKey("sense/range", 1, ("navigation", "tracking")),
    "sense/pose": WorldKey("sense/pose", TARGET_EVERY, ("tracking",)),
    "sense/targets": WorldKey("sense/targets", TARGET_EVERY, ("tracking",)),
    "sense/odometry": WorldKey("sense/odometry", ODOMETRY_EVERY, ("navigation",)),
    "world/clock": WorldKey("world/clock", 1, ("navigation", "tracking"), per_robot=False),
    "world/state": WorldKey("world/state", 1, ("navigation", "tracking"), per_robot=False),
}
"""What the world publishes each tick (docs/design.md section 6); ``{j}``: one per sensor."""


@dataclass(frozen=True)
class PortTypes:
    """A node class's ports as plain data: input port -> (message kind, many), output port
    -> message kind; and whether it keeps state across ticks / reads the model."""

    inputs: Mapping[str, tuple[str, bool]]
    outputs: Mapping[str, str]
    stateful: bool = False
    uses_model: bool = False
    pure: bool = False

    def to_dict(self) -> dict[str, Any]:
        return {"inputs": {p: list(v) for p, v in self.inputs.items()}, "outputs": dict(self.outputs),
                "stateful": self.stateful, "uses_model": self.uses_model, "pure": self.pure}

    @classmethod
    def from_dict(cls, doc: Mapping[str, Any]) -> PortTypes:
        return cls({p: (v[0], bool(v[1])) for p, v in doc["inputs"].items()}, dict(doc["outputs"]),
                   bool(doc["stateful"]), bool(doc["uses_model"]), bool(doc.get("pure", False)))


@dataclass(frozen=True)
class Source:
    """One key a binding reads: the full key, its label in the step's dict (instance
    number, robot id or None), its owner robot (or ``world``), the producing node
    instance's name, and the producer's period (ticks)."""

    key: str
    label: Any
    owner: str
    producer: str
    period: int


@dataclass(frozen=True)
class Binding:
    """An input port of one node instance, resolved."""

    port: str
    kind: str
    many: bool
    delay: int
    team: bool
    stale_s: float
    sources: tuple[Source, ...]

    def needed(self, source: Source, k: int) -> int | None:
        """The producer tick whose value a run at tick ``k`` reads from ``source`` (the rule)."""
        return needed_tick(k, source.period, self.delay)


def needed_tick(k: int, period: int, delay: int) -> int | None:
    """The producer's tick read at tick ``k``: its latest run at or before k (delay 0),
    or strictly before k (delay 1; None before its first run)."""
    if delay == 0:
        return k - k % period
    k1 = k - 1
    if k1 < 0:
        return None
    return k1 - k1 % period


@dataclass(frozen=True)
class NodePlan:
    """One node instance of one robot: what runs as one process."""

    robot: str
    decl: NodeDecl
    instance: int | None
    period: int
    bindings: tuple[Binding, ...]
    outputs: Mapping[str, str]  # port -> full key
    output_kinds: Mapping[str, str]  # port -> message kind
    clock_key: str | None  # the world's clock, when no input of the tick triggers the node
    stateful: bool
    uses_model: bool
    pure: bool = False  # its outputs are a function of its inputs' values alone (t only stamps them)

    @property
    def name(self) -> str:
        return self.decl.name if self.instance is None else f"{self.decl.name}-{self.instance}"

    @property
    def label(self) -> str:
        return f"{self.robot}/{self.name}"

    def due(self, k: int) -> bool:
        return k % self.period == 0

    def subscriptions(self, root: str) -> list[str]:
        """The key expressions the node's process subscribes to: each input's keys, an
        input of many keys as one expression (``<root>/r1/field/obstacle/*``, every
        teammate's ``<root>/*/share``), the world's clock when it triggers the node."""
        exprs: list[str] = []
        for b, d in zip(self.bindings, self.decl.inputs, strict=True):  # a binding per input
            if d.scope == "teammates":
                exprs.append(f"{root}/*/{d.key}")
            elif d.key.endswith("/*"):
                exprs.append(f"{root}/{d.key}" if d.key.startswith("world/") else f"{root}/{self.robot}/{d.key}")
            else:
                exprs += [s.key for s in b.sources]
        if self.clock_key is not None:
            exprs.append(self.clock_key)
        return list(dict.fromkeys(exprs))


@dataclass
class RunPlan:
    """A graph for one team: every robot's node instances and what follows from them."""

    graph: Graph
    team: tuple[str, ...]
    task: str
    sensors: int
    keys: KeySpace
    ports: Mapping[str, PortTypes]
    nodes: dict[str, list[NodePlan]] = field(default_factory=dict)  # robot -> nodes in topological order
    warnings: list[str] = field(default_factory=list)
    hold: bool = True  # the world may leave unchanged readings out (held_readings); False: it sends every one
    _held: dict[str, list[str]] = field(default_factory=dict, repr=False, compare=False)
    _index: dict[str, Any] = field(default_factory=dict, repr=False, compare=False)  # readers, producers by key

    # ------------------------------------------------------------------ derived

    def robot_nodes(self, robot: str) -> list[NodePlan]:
        return self.nodes[robot]

    def node(self, robot: str, name: str) -> NodePlan:
        for n in self.nodes[robot]:
            if n.name == name:
                return n
        raise KeyError(f"{robot}/{name}")

    def node_names(self) -> list[str]:
        """The node instances of one robot, in launch order (what ``cekm node list`` expects)."""
        return [n.name for n in self.nodes[self.team[0]]] if self.team else []

    def tokens(self, robots: list[str] | tuple[str, ...] | None = None) -> set[str]:
        """The liveliness tokens of every node of ``robots`` (all: the world's wait set before tick 0)."""
        return {self.keys.alive(r, n.name) for r in (robots or self.team) for n in self.nodes[r]}

    def answer_key(self, robot: str) -> str:
        """The key whose message stamped t means: robot ``robot`` answered tick t."""
        return f"{self.keys.root}/{robot}/{self.graph.answer}"

    def world_keys(self, robot: str) -> list[str]:
        """The sense keys the world publishes for ``robot``: those the graph reads."""
        read = {s.key for n in self.nodes[robot] for b in n.bindings for s in b.sources if s.owner == WORLD_OWNER}
        keys = []
        for rel, wk in WORLD_KEYS.items():
            if not wk.per_robot:
                continue
            expand = [rel.replace("{j}", str(j)) for j in range(self.sensors)] if "{j}" in rel else [rel]
            keys += [f"{self.keys.root}/{robot}/{k}" for k in expand if f"{self.keys.root}/{robot}/{k}" in read]
        return keys

    def sent_keys(self, robot: str) -> dict[str, str]:
        """Every key a robot's nodes send on -> its message kind (what the world records)."""
        return {n.outputs[p]: n.output_kinds[p] for n in self.nodes[robot] for p in n.outputs}

    def readers(self, robot: str, key: str) -> list[NodePlan]:
        """The node instances (of any robot) that read ``key``, in team and node order (from
        an index of the whole team built once: a scan per key made the world's start
        quadratic in the team, 35 s for 256 robots)."""
        by_key = self._index.get("readers")
        if by_key is None:
            by_key = {}
            for r in self.team:
                for n in self.nodes[r]:
                    for k in dict.fromkeys(s.key for b in n.bindings for s in b.sources):
                        by_key.setdefault(k, []).append(n)
            self._index["readers"] = by_key
        return list(by_key.get(key, ()))

    def producers(self) -> dict[str, NodePlan]:
        """Every output key of the team -> the node instance that sends on it (built once)."""
        by_output = self._index.get("producers")
        if by_output is None:
            by_output = self._index["producers"] = {key: n for r in self.team for n in self.nodes[r]
                                                    for key in n.outputs.values()}
        return by_output

    # ------------------------------------------------------------------ held readings

    def holding_reader(self, node: NodePlan) -> str | None:
        """The one world reading ``node`` is a pure function of, when a tick in which that
        reading is unchanged may leave the node's run out (its previous outputs, restamped,
        stand for the tick's): a pure node reading that one key of its own period at the
        same tick, not the graph's answer. None otherwise. A delayed map version input (a
        learning robot's, docs/learning.md) does not count: the world sends every reading
        that sees something again at the first tick of each version (:meth:`map_period`;
        a sensor that sees nothing has no field, whatever the map)."""
        bindings = [b for b in node.bindings if not (b.kind == MAP_KIND and b.delay)]
        if not node.pure or node.clock_key is not None or len(bindings) != 1:
            return None
        b = bindings[0]
        if len(b.sources) != 1 or b.delay != 0 or b.team:
            return None
        if node.decl.timer is not None:  # on a timer of its own in real time: its runs are not the reading's
            return None
        s = b.sources[0]
        if s.owner != WORLD_OWNER or s.period != node.period or s.key.startswith(f"{self.keys.root}/world/"):
            return None
        if self.answer_key(node.robot) in node.outputs.values():
            return None
        return s.key

    def map_period(self, robot: str) -> int | None:
        """The period of ``robot``'s map versions (its learner's, docs/learning.md), None
        without one: a version made at tick k is used from k + 1, so the world sends every
        reading that sees something at the ticks k with k % period == 1 % period."""
        return next((n.period for n in self.nodes[robot] if MAP_KIND in n.output_kinds.values()), None)

    def held_readings(self, robot: str) -> list[str]:
        """The readings of ``robot`` the world may leave out in a tick where they equal the
        last ones it sent (the paper: the localization EKMs "remain activated until they
        are updated at the next sensing cycle"): those whose every reader has them as its
        :meth:`holding_reader`. The world then sends the robot's ``sense/unchanged`` instead."""
        cached = self._held.get(robot)
        if cached is None:
            cached = [k for k in self.world_keys(robot)
                      if (rs := self.readers(robot, k)) and all(self.holding_reader(n) == k for n in rs)
                      ] if self.hold else []
            self._held[robot] = cached
        return cached

    def listens(self, node: NodePlan) -> list[str]:
        """The key expressions ``node``'s process subscribes to: its inputs'
        (:meth:`NodePlan.subscriptions`) and the ``sense/unchanged`` keys of :meth:`holds`."""
        return node.subscriptions(self.keys.root) + sorted(self.holds(node))

    def holds(self, node: NodePlan) -> dict[str, dict[str, tuple[str, ...]]]:
        """What ``node`` learns from the world's ``sense/unchanged`` messages: per such key
        (one per robot whose held readings it reads through), each held reading -> the keys
        of ``node``'s sources that reading's reader sends (their values stand for the tick)."""
        out: dict[str, dict[str, list[str]]] = {}
        by_output = self.producers()
        for b in node.bindings:
            for s in b.sources:
                producer = by_output.get(s.key)
                if producer is None:
                    continue
                reading = self.holding_reader(producer)
                if reading is None or reading not in self.held_readings(producer.robot):
                    continue
                mk = self.keys.sense_unchanged(producer.robot)
                out.setdefault(mk, {}).setdefault(reading, []).append(s.key)
        return {mk: {r: tuple(v) for r, v in m.items()} for mk, m in out.items()}

    def to_dict(self) -> dict[str, Any]:
        return {"graph": self.graph.to_dict(), "team": list(self.team), "task": self.task, "sensors": self.sensors,
                "root": self.keys.root, "ports": {k: v.to_dict() for k, v in self.ports.items()}}
