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
:mod:`cekm_swarm.graph.check` or from a run spec).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Mapping

from cekm_swarm.protocol import KeySpace
from cekm_swarm.ticks import TARGET_EVERY, TICK_S

from .spec import Graph, GraphError, InputDecl, NodeDecl

WORLD_OWNER = "world"


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
    def from_dict(cls, doc: Mapping[str, Any]) -> "PortTypes":
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
        for b, d in zip(self.bindings, self.decl.inputs):
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
        """The node instances (of any robot) that read ``key``."""
        return [n for r in self.team for n in self.nodes[r] if any(s.key == key for b in n.bindings for s in b.sources)]

    # ------------------------------------------------------------------ held readings

    def holding_reader(self, node: NodePlan) -> str | None:
        """The one world reading ``node`` is a pure function of, when a tick in which that
        reading is unchanged may leave the node's run out (its previous outputs, restamped,
        stand for the tick's): a pure node reading that one key of its own period at the
        same tick, not the graph's answer. None otherwise."""
        if not node.pure or node.clock_key is not None or len(node.bindings) != 1:
            return None
        b = node.bindings[0]
        if len(b.sources) != 1 or b.delay != 0 or b.team:
            return None
        s = b.sources[0]
        if s.owner != WORLD_OWNER or s.period != node.period or s.key.startswith(f"{self.keys.root}/world/"):
            return None
        if self.answer_key(node.robot) in node.outputs.values():
            return None
        return s.key

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
        by_output = {key: n for r in self.team for n in self.nodes[r] for key in n.outputs.values()}
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


def _source_keys(plan_outputs: dict[str, tuple[str, str, int | None, str]], rel: str) -> list[tuple[str, Any]]:
    """The own keys an input pattern matches, in producer order: (relative key, label)."""
    if rel.endswith("/*"):
        head = rel[:-1]
        out = []
        for k in plan_outputs:
            if k.startswith(head) and "/" not in k[len(head):] and k != head:
                last = k[len(head):]
                out.append((k, int(last) if last.isdigit() else last))
        return out
    return [(rel, None)] if rel in plan_outputs else []


def _gcd(values: list[int]) -> int:
    g = 0
    for v in values:
        g = math.gcd(g, v)
    return g


def build_plan(graph: Graph, team: tuple[str, ...] | list[str], task: str, ports: Mapping[str, PortTypes],
               sensors: int = 12, keys: KeySpace | None = None, hold: bool = True) -> RunPlan:
    """Resolve ``graph`` for ``team`` on a scenario of ``task`` with robots of ``sensors``
    distance sensors. Raises :class:`GraphError` naming the node and the field for
    anything that cannot run: an unknown key, a port bound wrong, a cycle with no delay, a
    node with no rate, no answer every tick, a task the graph is not for."""
    keys = keys or KeySpace()
    src = graph.source
    team = tuple(team)
    if graph.task not in ("any", task):
        raise GraphError(src, "[graph].task", f"the graph is for {graph.task} scenarios, this one is a {task} scenario")
    for n in graph.nodes:
        if n.name not in ports:
            raise GraphError(src, n.where, "its program's ports are unknown (not checked)")
    counts = {n.name: (sensors if n.instances == "sensors" else (n.instances or 1)) for n in graph.nodes}
    instanced = {n.name: n.instances is not None for n in graph.nodes}

    # every output key of one robot: relative key -> (node, port, instance, kind)
    outputs: dict[str, tuple[str, str, int | None, str]] = {}
    for n in graph.nodes:
        pt = ports[n.name]
        declared = set(pt.outputs)
        bound = {o.port for o in n.outputs}
        for port in sorted(declared - bound):
            raise GraphError(src, f"{n.where}.outputs", f"output port {port!r} of its program is not given a key")
        for port in sorted(bound - declared):
            raise GraphError(src, f"{n.where}.outputs.{port}", f"its program has no output port {port!r} "
                                                                f"(ports: {', '.join(sorted(declared)) or 'none'})")
        for o in n.outputs:
            for i in (range(counts[n.name]) if instanced[n.name] else [None]):
                rel = o.key if i is None else o.key.replace("{i}", str(i))
                if rel.split("/")[0] == "sense" or rel.startswith("world/"):
                    raise GraphError(src, f"{n.where}.outputs.{o.port}", f"{rel!r} is the world's key")
                if rel in outputs:
                    raise GraphError(src, f"{n.where}.outputs.{o.port}",
                                     f"key {rel!r} is already sent by node '{outputs[rel][0]}'")
                outputs[rel] = (n.name, o.port, i, pt.outputs[o.port])
            if counts[n.name] > 1 and "{i}" not in o.key:
                raise GraphError(src, f"{n.where}.outputs.{o.port}",
                                 f"{o.key!r}: every instance would send on this one key (use {{i}})")

    # the world's keys, relative to a robot (or the world)
    world: dict[str, tuple[str, int, str]] = {}  # rel -> (kind, period, key pattern)
    for rel, wk in WORLD_KEYS.items():
        if "{j}" in rel:
            for j in range(sensors):
                world[rel.replace("{j}", str(j))] = (wk.kind, wk.period, rel)
        else:
            world[rel] = (wk.kind, wk.period, rel)

    def world_sources(decl: InputDecl, rel: str, where: str) -> list[tuple[str, Any, str, int]]:
        if rel.endswith("/*"):
            head = rel[:-1]
            hits = [(k, int(k[len(head):]) if k[len(head):].isdigit() else k[len(head):]) for k in world
                    if k.startswith(head) and "/" not in k[len(head):] and k != head]
        else:
            hits = [(rel, None)] if rel in world else []
        out = []
        for k, label in hits:
            kind, period, pattern = world[k]
            if task not in WORLD_KEYS[pattern].tasks:
                raise GraphError(src, where, f"reads {k!r}, which the world publishes only in "
                                             f"{' and '.join(WORLD_KEYS[pattern].tasks)} scenarios, not this {task} one")
            out.append((k, label, kind, period))
        return out

    # port bindings by node (without periods yet): (decl, input, [(rel, label, kind, world?)])
    periods: dict[str, int] = {}
    edges: dict[str, set[str]] = {n.name: set() for n in graph.nodes}  # consumer -> producers (delay 0, own)
    resolved: dict[tuple[str, int | None], list[tuple[InputDecl, list[tuple[str, Any, str, int | None, str]]]]] = {}
    read_rel: set[str] = set()
    for n in graph.nodes:
        pt = ports[n.name]
        declared = dict(pt.inputs)
        bound = {i.port for i in n.inputs}
        for port in sorted(set(declared) - bound):
            raise GraphError(src, f"{n.where}.inputs", f"input port {port!r} of its program is not given a key")
        for port in sorted(bound - set(declared)):
            raise GraphError(src, f"{n.where}.inputs.{port}", f"its program has no input port {port!r} "
                                                               f"(ports: {', '.join(sorted(declared)) or 'none'})")
        for inst in (range(counts[n.name]) if instanced[n.name] else [None]):
            per_input = []
            for d in n.inputs:
                where = f"{n.where}.inputs.{d.port}"
                rel = d.key if inst is None else d.key.replace("{i}", str(inst))
                want_kind, many = declared[d.port]
                hits: list[tuple[str, Any, str, int | None, str]] = []  # rel, label, kind, period|None, producer
                if d.scope == "world":
                    if not rel.startswith("world/") and rel.split("/")[0] != "sense":
                        raise GraphError(src, where, f"{rel!r} is not a world key (world keys: "
                                                     f"{', '.join(WORLD_KEYS)})")
                if rel.startswith("world/") or rel.split("/")[0] == "sense":
                    if d.scope == "teammates":
                        raise GraphError(src, where, f"{rel!r} is the world's key, not a teammate's")
                    hits = [(k, lab, kind, per, WORLD_OWNER) for k, lab, kind, per in world_sources(d, rel, where)]
                else:
                    for k, lab in _source_keys(outputs, rel):
                        pn, _, pi, kind = outputs[k]
                        hits.append((k, lab, kind, None, pn if pi is None else f"{pn}-{pi}"))
                        if d.scope == "own" and d.delay == 0:
                            edges[n.name].add(pn)
                if not hits:
                    raise GraphError(src, where, f"unknown key {rel!r}: no node of the graph sends it and the world "
                                                 f"does not publish it")
                for k, lab, kind, _, _ in hits:
                    if kind != want_kind:
                        raise GraphError(src, where, f"{rel!r} carries {kind} messages, the port takes {want_kind}")
                if not many and (len(hits) > 1 or d.scope == "teammates" or rel.endswith("/*")):
                    raise GraphError(src, where, f"port {d.port!r} takes one key, {rel!r} "
                                                 f"{'is every teammate' if d.scope == 'teammates' else 'matches several'}")
                read_rel.update(k for k, *_ in hits)
                per_input.append((d, hits))
            resolved[(n.name, inst)] = per_input

    # cycles through delay-0 inputs (own robot)
    state: dict[str, int] = {}
    order: list[str] = []

    def visit(name: str, path: list[str]) -> None:
        st = state.get(name, 0)
        if st == 1:
            cyc = path[path.index(name):] + [name]
            raise GraphError(src, f"node '{name}'", "nodes " + " -> ".join(reversed(cyc)) + " form a cycle in which "
                             "every input is of the same tick, so none of them can start: give one of those inputs "
                             "`delay = 1` (the previous run's value)")
        if st == 2:
            return
        state[name] = 1
        for p in sorted(edges[name]):
            visit(p, path + [name])
        state[name] = 2
        order.append(name)

    for n in graph.nodes:
        visit(n.name, [])

    # periods, in dependency order
    for name in order:
        n = graph.node(name)
        if n.every is not None:
            periods[name] = n.every
            continue
        same_tick = []
        for inst in (range(counts[name]) if instanced[name] else [None]):
            for d, hits in resolved[(name, inst)]:
                if d.delay == 0:
                    for k, _, _, per, prod in hits:
                        same_tick.append(per if per is not None else periods[prod.split("-")[0]])
        if not same_tick:
            raise GraphError(src, f"{n.where}.every", "the node has no rate: give `every = N` (ticks), or an input of "
                                                      "the same tick that triggers it")
        periods[name] = _gcd(same_tick)

    def producer_period(prod: str, world_period: int | None) -> int:
        if world_period is not None:
            return world_period
        return periods[prod.split("-")[0]]  # an instance's name is <node>-<i>; node names have no '-'

    # the answer
    if graph.answer not in outputs:
        raise GraphError(src, "[graph].answer", f"no node sends {graph.answer!r}")
    an, ap, _, akind = outputs[graph.answer]
    if akind != "cmd/wheels":
        raise GraphError(src, "[graph].answer", f"{graph.answer!r} carries {akind} messages, the world needs cmd/wheels")
    if periods[an] != 1:
        raise GraphError(src, "[graph].answer", f"node '{an}' runs every {periods[an]} ticks: the world needs an answer "
                                                f"every tick")

    # outputs nobody reads (teammates' reads count)
    team_reads = {d.key for n in graph.nodes for d in n.inputs if d.scope == "teammates"}
    warnings = [f"{src}: node '{pn}'.outputs.{port}: {rel!r} is read by no node (it is only recorded)"
                for rel, (pn, port, _, _) in outputs.items()
                if rel != graph.answer and rel not in read_rel and rel not in team_reads]

    plan = RunPlan(graph, team, task, sensors, keys, dict(ports), warnings=warnings, hold=hold)
    for robot in team:
        nodes = []
        for name in order:
            n = graph.node(name)
            pt = ports[name]
            for inst in (range(counts[name]) if instanced[name] else [None]):
                bindings = []
                trigger = False
                for d, hits in resolved[(name, inst)]:
                    srcs = []
                    if d.scope == "teammates":
                        for mate in team:
                            if mate == robot:
                                continue
                            for k, lab, kind, per, prod in hits:
                                srcs.append(Source(f"{keys.root}/{mate}/{k}", mate, mate, prod,
                                                   producer_period(prod, per)))
                    else:
                        for k, lab, kind, per, prod in hits:
                            owner = WORLD_OWNER if prod == WORLD_OWNER else robot
                            full = f"{keys.root}/{k}" if k.startswith("world/") else f"{keys.root}/{robot}/{k}"
                            srcs.append(Source(full, lab, owner, prod, producer_period(prod, per)))
                    period_of = max((s.period for s in srcs), default=1)
                    stale = d.stale if d.stale is not None else (2 if d.delay == 0 else 4) * period_of * TICK_S
                    trigger = trigger or d.delay == 0
                    bindings.append(Binding(d.port, pt.inputs[d.port][0], pt.inputs[d.port][1], d.delay,
                                            d.scope == "teammates", stale, tuple(srcs)))
                outs = {o.port: f"{keys.root}/{robot}/{o.key if inst is None else o.key.replace('{i}', str(inst))}"
                        for o in n.outputs}
                nodes.append(NodePlan(robot, n, inst, periods[name], tuple(bindings), outs,
                                      {o.port: pt.outputs[o.port] for o in n.outputs},
                                      None if trigger else keys.world_clock(), pt.stateful, pt.uses_model,
                                      pt.pure and not pt.stateful))
        plan.nodes[robot] = nodes
    return plan

