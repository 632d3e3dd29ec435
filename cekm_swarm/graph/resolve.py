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
from typing import Any, Mapping

from cekm_swarm.protocol import KeySpace
from cekm_swarm.ticks import TICK_S

from .plan import WORLD_KEYS, WORLD_OWNER, Binding, NodePlan, PortTypes, RunPlan, Source
from .spec import Graph, GraphError, InputDecl


def timed_by(period: int, triggers: set[int]) -> bool:
    """Whether a node due every ``period`` ticks hears a value of each of its due ticks
    from a same-tick source (one of period p sends at every multiple of p). If not, it
    also listens to the world's clock: a node due every tick that reads only a reading
    sent every other tick would otherwise learn of its odd ticks from no one."""
    return any(period % p == 0 for p in triggers)

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


def unknown_port(direction: str, port: str, declared) -> str:
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
        for port in sorted(bound - declared):  # first: a misspelled port also leaves the real one unbound
            raise GraphError(src, f"{n.where}.outputs.{port}", unknown_port("output", port, declared))
        for port in sorted(declared - bound):
            raise GraphError(src, f"{n.where}.outputs", f"output port {port!r} of its program is not given a key")
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
        for port in sorted(bound - set(declared)):  # first: a misspelled port also leaves the real one unbound
            raise GraphError(src, f"{n.where}.inputs.{port}", unknown_port("input", port, declared))
        for port in sorted(set(declared) - bound):
            raise GraphError(src, f"{n.where}.inputs", f"input port {port!r} of its program is not given a key")
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
                for k, lab, kind, _, prod in hits:
                    if kind != want_kind:
                        by = "" if prod == WORLD_OWNER else f" (node {prod!r} sends them)"
                        raise GraphError(src, where, f"{rel!r} carries {kind} messages{by}, the port of node "
                                                     f"{n.name!r} takes {want_kind}")
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
                triggers: set[int] = set()  # periods of the same-tick sources
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
                    if d.delay == 0:
                        triggers.update(s.period for s in srcs)
                    bindings.append(Binding(d.port, pt.inputs[d.port][0], pt.inputs[d.port][1], d.delay,
                                            d.scope == "teammates", stale, tuple(srcs)))
                outs = {o.port: f"{keys.root}/{robot}/{o.key if inst is None else o.key.replace('{i}', str(inst))}"
                        for o in n.outputs}
                nodes.append(NodePlan(robot, n, inst, periods[name], tuple(bindings), outs,
                                      {o.port: pt.outputs[o.port] for o in n.outputs},
                                      None if timed_by(periods[name], triggers) else keys.world_clock(),
                                      pt.stateful, pt.uses_model,
                                      pt.pure and not pt.stateful))
        plan.nodes[robot] = nodes
    return plan
