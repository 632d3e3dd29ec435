"""Resolving a declared graph for one team: :func:`build_plan` turns a
:class:`~cekm_swarm.graph.spec.Graph` and its node programs' port types into the
:class:`~cekm_swarm.graph.plan.RunPlan` of a run (every node instance of every robot, its
bindings, its period), and refuses, naming the node and the field, a graph that cannot run.
The meaning of what it builds, the rule of a tick, is :mod:`cekm_swarm.graph.plan`'s.
Plain data in, plain data out: nothing here imports node code.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

from cekm_swarm.protocol import KeySpace
from cekm_swarm.ticks import TICK_S

from .plan import WORLD_KEYS, WORLD_OWNER, Binding, NodePlan, PortTypes, RunPlan, Source
from .spec import Graph, GraphError, InputDecl, NodeDecl


def timed_by(period: int, triggers: set[int]) -> bool:
    """Whether a node due every ``period`` ticks hears a value of each of its due ticks
    from a same-tick source (one of period p sends at every multiple of p). If not, it
    also listens to the world's clock: a node due every tick that reads only a reading
    sent every other tick would otherwise learn of its odd ticks from no one."""
    return any(period % p == 0 for p in triggers)


def _source_keys(known: Mapping[str, Any], rel: str) -> list[tuple[str, Any]]:
    """The keys of ``known`` (a robot's own outputs, or the world's keys) an input pattern
    matches, in their order: (relative key, label: the instance or sensor number)."""
    if rel.endswith("/*"):
        head = rel[:-1]
        out: list[tuple[str, Any]] = []
        for k in known:
            if k.startswith(head) and "/" not in k[len(head):] and k != head:
                last = k[len(head):]
                out.append((k, int(last) if last.isdigit() else last))
        return out
    return [(rel, None)] if rel in known else []


def unknown_port(direction: str, port: str, declared: Iterable[str]) -> str:
    """What is wrong with a graph binding ``port``, which its program does not declare
    among its ``direction`` (input or output) ports: the program's ports, and the close
    one when the name looks misspelled."""
    names = sorted(declared)
    close = difflib.get_close_matches(port, names, n=1)
    hint = f"; did you mean {close[0]!r}?" if close else ""
    return f"its program has no {direction} port {port!r} (its {direction} ports: {', '.join(names) or 'none'}){hint}"


def _gcd(values: list[int]) -> int:
    g = 0
    for v in values:
        g = math.gcd(g, v)
    return g


Hit = tuple[str, Any, str, int | None, str]
"""One key an input reads: (relative key, label, message kind, world period or None, producer)."""


@dataclass
class _Resolving:
    """What the phases of :func:`build_plan` know of a graph so far: the call's
    arguments, then each phase's result (own outputs, the world's keys, every input's
    sources, the dependency order, the periods)."""

    graph: Graph
    team: tuple[str, ...]
    task: str
    ports: Mapping[str, PortTypes]
    sensors: int
    keys: KeySpace
    counts: dict[str, int] = field(default_factory=dict)  # node -> number of instances
    instanced: dict[str, bool] = field(default_factory=dict)  # node -> declared with instances
    outputs: dict[str, tuple[str, str, int | None, str]] = field(default_factory=dict)  # rel -> node, port, i, kind
    world: dict[str, tuple[str, int, str]] = field(default_factory=dict)  # rel -> kind, period, key pattern
    edges: dict[str, set[str]] = field(default_factory=dict)  # consumer -> producers (delay 0, own)
    resolved: dict[tuple[str, int | None], list[tuple[InputDecl, list[Hit]]]] = field(default_factory=dict)
    read_rel: set[str] = field(default_factory=set)
    order: list[str] = field(default_factory=list)  # nodes, producers before their same-tick consumers
    periods: dict[str, int] = field(default_factory=dict)

    @property
    def src(self) -> str:
        return self.graph.source

    def instances(self, name: str) -> range | list[None]:
        return range(self.counts[name]) if self.instanced[name] else [None]

    def producer_period(self, prod: str, world_period: int | None) -> int:
        if world_period is not None:
            return world_period
        return self.periods[prod.split("-")[0]]  # an instance's name is <node>-<i>; node names have no '-'


def build_plan(graph: Graph, team: tuple[str, ...] | list[str], task: str, ports: Mapping[str, PortTypes],
               sensors: int = 12, keys: KeySpace | None = None, hold: bool = True) -> RunPlan:
    """Resolve ``graph`` for ``team`` on a scenario of ``task`` with robots of ``sensors``
    distance sensors. Raises :class:`GraphError` naming the node and the field for
    anything that cannot run: an unknown key, a port bound wrong, a cycle with no delay, a
    node with no rate, no answer every tick, a task the graph is not for."""
    st = _Resolving(graph, tuple(team), task, ports, sensors, keys or KeySpace())
    _check_task_and_programs(st)
    _own_outputs(st)
    _world_keys(st)
    _resolve_inputs(st)
    _dependency_order(st)
    _periods(st)
    _check_answer(st)
    plan = RunPlan(graph, st.team, task, sensors, st.keys, dict(ports), warnings=_unread_outputs(st), hold=hold)
    for robot in st.team:
        plan.nodes[robot] = [_node_plan(st, robot, name, inst) for name in st.order for inst in st.instances(name)]
    return plan


def _check_task_and_programs(st: _Resolving) -> None:
    """The graph is for this task, and every node's program's ports are known."""
    if st.graph.task not in ("any", st.task):
        raise GraphError(st.src, "[graph].task",
                         f"the graph is for {st.graph.task} scenarios, this one is a {st.task} scenario")
    for n in st.graph.nodes:
        if n.name not in st.ports:
            raise GraphError(st.src, n.where, "its program's ports are unknown (not checked)")
    st.counts = {n.name: st.sensors if n.instances == "sensors" else int(n.instances or 1) for n in st.graph.nodes}
    st.instanced = {n.name: n.instances is not None for n in st.graph.nodes}


def _check_bound(st: _Resolving, n: NodeDecl, direction: str, bound: set[str], declared: Iterable[str]) -> None:
    """Every port a node binds is its program's, and every port of its program is bound."""
    names = set(declared)
    for port in sorted(bound - names):  # first: a misspelled port also leaves the real one unbound
        raise GraphError(st.src, f"{n.where}.{direction}s.{port}", unknown_port(direction, port, names))
    for port in sorted(names - bound):
        raise GraphError(st.src, f"{n.where}.{direction}s",
                         f"{direction} port {port!r} of its program is not given a key")


def _is_world_key(rel: str) -> bool:
    return rel.startswith("world/") or rel.split("/")[0] == "sense"


def _own_outputs(st: _Resolving) -> None:
    """Every output key of one robot: relative key -> (node, port, instance, kind)."""
    for n in st.graph.nodes:
        pt = st.ports[n.name]
        _check_bound(st, n, "output", {o.port for o in n.outputs}, pt.outputs)
        for o in n.outputs:
            for i in st.instances(n.name):
                rel = o.key if i is None else o.key.replace("{i}", str(i))
                if _is_world_key(rel):
                    raise GraphError(st.src, f"{n.where}.outputs.{o.port}", f"{rel!r} is the world's key")
                if rel in st.outputs:
                    raise GraphError(st.src, f"{n.where}.outputs.{o.port}",
                                     f"key {rel!r} is already sent by node '{st.outputs[rel][0]}'")
                st.outputs[rel] = (n.name, o.port, i, pt.outputs[o.port])
            if st.counts[n.name] > 1 and "{i}" not in o.key:
                raise GraphError(st.src, f"{n.where}.outputs.{o.port}",
                                 f"{o.key!r}: every instance would send on this one key (use {{i}})")


def _world_keys(st: _Resolving) -> None:
    """The world's keys, relative to a robot (or the world): one per sensor for ``{j}``."""
    for rel, wk in WORLD_KEYS.items():
        if "{j}" in rel:
            for j in range(st.sensors):
                st.world[rel.replace("{j}", str(j))] = (wk.kind, wk.period, rel)
        else:
            st.world[rel] = (wk.kind, wk.period, rel)


def _world_sources(st: _Resolving, rel: str, where: str) -> list[Hit]:
    """The world's keys an input pattern matches, refused when this task's world does not
    publish them."""
    hits = _source_keys(st.world, rel)
    out: list[Hit] = []
    for k, label in hits:
        kind, period, pattern = st.world[k]
        if st.task not in WORLD_KEYS[pattern].tasks:
            raise GraphError(st.src, where, f"reads {k!r}, which the world publishes only in "
                                            f"{' and '.join(WORLD_KEYS[pattern].tasks)} scenarios, "
                                            f"not this {st.task} one")
        out.append((k, label, kind, period, WORLD_OWNER))
    return out


def _input_hits(st: _Resolving, n: NodeDecl, d: InputDecl, rel: str, where: str) -> list[Hit]:
    """The keys one input of one node instance reads (the world's or the graph's); a
    same-tick read of the robot's own node is a dependency edge."""
    if d.scope == "world" and not _is_world_key(rel):
        raise GraphError(st.src, where, f"{rel!r} is not a world key (world keys: {', '.join(WORLD_KEYS)})")
    if _is_world_key(rel):
        if d.scope == "teammates":
            raise GraphError(st.src, where, f"{rel!r} is the world's key, not a teammate's")
        return _world_sources(st, rel, where)
    hits: list[Hit] = []
    for k, lab in _source_keys(st.outputs, rel):
        pn, _, pi, kind = st.outputs[k]
        hits.append((k, lab, kind, None, pn if pi is None else f"{pn}-{pi}"))
        if d.scope == "own" and d.delay == 0:
            st.edges[n.name].add(pn)
    return hits


def _check_hits(st: _Resolving, n: NodeDecl, d: InputDecl, rel: str, where: str, hits: list[Hit]) -> None:
    """An input reads at least one key, of its port's message kind, and several keys only
    through a port that takes many."""
    want_kind, many = st.ports[n.name].inputs[d.port]
    if not hits:
        raise GraphError(st.src, where, f"unknown key {rel!r}: no node of the graph sends it and the world "
                                        f"does not publish it")
    for _, _, kind, _, prod in hits:
        if kind != want_kind:
            by = "" if prod == WORLD_OWNER else f" (node {prod!r} sends them)"
            raise GraphError(st.src, where, f"{rel!r} carries {kind} messages{by}, the port of node "
                                            f"{n.name!r} takes {want_kind}")
    if not many and (len(hits) > 1 or d.scope == "teammates" or rel.endswith("/*")):
        raise GraphError(st.src, where, f"port {d.port!r} takes one key, {rel!r} "
                                        f"{'is every teammate' if d.scope == 'teammates' else 'matches several'}")


def _resolve_inputs(st: _Resolving) -> None:
    """Every input of every node instance resolved to the keys it reads (without periods
    yet), checked, and the same-tick dependency edges between the robot's own nodes."""
    st.edges = {n.name: set() for n in st.graph.nodes}
    for n in st.graph.nodes:
        _check_bound(st, n, "input", {i.port for i in n.inputs}, st.ports[n.name].inputs)
        for inst in st.instances(n.name):
            per_input = []
            for d in n.inputs:
                where = f"{n.where}.inputs.{d.port}"
                rel = d.key if inst is None else d.key.replace("{i}", str(inst))
                hits = _input_hits(st, n, d, rel, where)
                _check_hits(st, n, d, rel, where, hits)
                st.read_rel.update(k for k, *_ in hits)
                per_input.append((d, hits))
            st.resolved[(n.name, inst)] = per_input


def _dependency_order(st: _Resolving) -> None:
    """The nodes in dependency order over their same-tick inputs; a cycle through such
    inputs alone is refused, naming its nodes."""
    state: dict[str, int] = {}  # 1: being visited, 2: done

    def visit(name: str, path: list[str]) -> None:
        st_ = state.get(name, 0)
        if st_ == 1:
            cyc = path[path.index(name):] + [name]
            raise GraphError(st.src, f"node '{name}'", "nodes " + " -> ".join(reversed(cyc)) + " form a cycle in "
                             "which every input is of the same tick, so none of them can start: give one of those "
                             "inputs `delay = 1` (the previous run's value)")
        if st_ == 2:
            return
        state[name] = 1
        for p in sorted(st.edges[name]):
            visit(p, path + [name])
        state[name] = 2
        st.order.append(name)

    for n in st.graph.nodes:
        visit(n.name, [])


def _periods(st: _Resolving) -> None:
    """Each node's period, in dependency order: its ``every``, or the greatest common
    divisor of the periods of what it reads this tick."""
    for name in st.order:
        n = st.graph.node(name)
        if n.every is not None:
            st.periods[name] = n.every
            continue
        same_tick = [st.producer_period(prod, per)
                     for inst in st.instances(name) for d, hits in st.resolved[(name, inst)] if d.delay == 0
                     for _, _, _, per, prod in hits]
        if not same_tick:
            raise GraphError(st.src, f"{n.where}.every", "the node has no rate: give `every = N` (ticks), or an input "
                                                         "of the same tick that triggers it")
        st.periods[name] = _gcd(same_tick)


def _check_answer(st: _Resolving) -> None:
    """The graph's answer is a node's cmd/wheels output, sent every tick."""
    answer = st.graph.answer
    if answer not in st.outputs:
        raise GraphError(st.src, "[graph].answer", f"no node sends {answer!r}")
    an, _, _, akind = st.outputs[answer]
    if akind != "cmd/wheels":
        raise GraphError(st.src, "[graph].answer", f"{answer!r} carries {akind} messages, the world needs cmd/wheels")
    if st.periods[an] != 1:
        raise GraphError(st.src, "[graph].answer", f"node '{an}' runs every {st.periods[an]} ticks: the world needs "
                                                   f"an answer every tick")


def _unread_outputs(st: _Resolving) -> list[str]:
    """A warning for each output nobody reads (teammates' reads count)."""
    team_reads = {d.key for n in st.graph.nodes for d in n.inputs if d.scope == "teammates"}
    return [f"{st.src}: node '{pn}'.outputs.{port}: {rel!r} is read by no node (it is only recorded)"
            for rel, (pn, port, _, _) in st.outputs.items()
            if rel != st.graph.answer and rel not in st.read_rel and rel not in team_reads]


def _sources(st: _Resolving, robot: str, d: InputDecl, hits: list[Hit]) -> list[Source]:
    """The full keys one input of ``robot``'s node reads: every teammate's, or the robot's
    own and the world's."""
    root = st.keys.root
    if d.scope == "teammates":
        return [Source(f"{root}/{mate}/{k}", mate, mate, prod, st.producer_period(prod, per))
                for mate in st.team if mate != robot for k, _, _, per, prod in hits]
    srcs = []
    for k, lab, _, per, prod in hits:
        owner = WORLD_OWNER if prod == WORLD_OWNER else robot
        full = f"{root}/{k}" if k.startswith("world/") else f"{root}/{robot}/{k}"
        srcs.append(Source(full, lab, owner, prod, st.producer_period(prod, per)))
    return srcs


def _node_plan(st: _Resolving, robot: str, name: str, inst: int | None) -> NodePlan:
    """One node instance of ``robot``: its bindings, outputs, period and clock."""
    n = st.graph.node(name)
    pt = st.ports[name]
    bindings = []
    triggers: set[int] = set()  # periods of the same-tick sources
    for d, hits in st.resolved[(name, inst)]:
        srcs = _sources(st, robot, d, hits)
        period_of = max((s.period for s in srcs), default=1)
        stale = d.stale if d.stale is not None else (2 if d.delay == 0 else 4) * period_of * TICK_S
        if d.delay == 0:
            triggers.update(s.period for s in srcs)
        kind, many = pt.inputs[d.port]
        bindings.append(Binding(d.port, kind, many, d.delay, d.scope == "teammates", stale, tuple(srcs)))
    outs = {o.port: f"{st.keys.root}/{robot}/{o.key if inst is None else o.key.replace('{i}', str(inst))}"
            for o in n.outputs}
    clock = None if timed_by(st.periods[name], triggers) else st.keys.world_clock()
    return NodePlan(robot, n, inst, st.periods[name], tuple(bindings), outs,
                    {o.port: pt.outputs[o.port] for o in n.outputs}, clock,
                    pt.stateful, pt.uses_model, pt.pure and not pt.stateful)
