"""``cekm graph``: list the shipped controllers' graphs, show one, check a graph file, and
write the router's access-control rules a deployment of graphs needs. Its home is beside
the checks it runs (:mod:`.graph_check`, which import the node programs):
:mod:`cekm_swarm.graph` is plain data and imports no node code."""

from __future__ import annotations

import json
from dataclasses import asdict
from pathlib import Path

import click

from cekm_swarm.cli_support import FileRefused, RobotIds, prepare_out_file
from cekm_swarm.graph.acl import router_config
from cekm_swarm.graph.plan import RunPlan
from cekm_swarm.graph.spec import GraphError, load_graph, shipped_graphs
from cekm_swarm.ticks import TICK_S

from .graph_check import CheckedGraph, check_graph, params_doc

TEAM = ("r1", "r2")


@click.group("graph")
def graph_group() -> None:
    """Controllers as process graphs: list, show, check, access control."""


@graph_group.command("list")
def list_cmd() -> None:
    """The shipped graphs: name, controller, task, description."""
    graphs = [(name, load_graph(path)) for name, path in sorted(shipped_graphs().items())]
    wn = max(len(name) for name, _ in graphs)
    wc = max(len(g.controller) for _, g in graphs)
    wt = max(len(g.task) for _, g in graphs)
    for name, g in graphs:
        click.echo(f"{name:<{wn}}  --controller {g.controller:<{wc}}  {g.task:<{wt}}  {g.description}")


def _checked(graph: str) -> CheckedGraph:
    try:
        return check_graph(graph)
    except GraphError as exc:
        raise FileRefused(str(exc)) from None


def _task(checked: CheckedGraph, task: str | None) -> str:
    g = checked.graph
    if task is None:
        return g.task if g.task != "any" else "navigation"
    if g.task not in ("any", task):
        raise click.UsageError(f"{g.source}: the graph is for {g.task} scenarios, not {task}")
    return task


def describe(checked: CheckedGraph, plan: RunPlan) -> list[str]:
    """The graph as text: per node its program, instances, rate, inputs, outputs, parameters."""
    g = checked.graph
    robot = plan.team[0]
    lines = [f"{g.name}: {g.description}", f"  controller {g.controller}, task {plan.task}, from {g.source}",
             f"  answer: {g.answer} (the world waits for it every tick)",
             f"  nodes per robot ({robot} shown; {len(plan.nodes[robot])} processes):"]
    params = params_doc(checked)
    seen = set()
    for node in plan.nodes[robot]:
        d = node.decl
        if d.name in seen:
            continue
        seen.add(d.name)
        n = sum(1 for x in plan.nodes[robot] if x.decl.name == d.name)
        inst = f" x{n} ({d.name}-0 .. {d.name}-{n - 1})" if d.instances is not None else ""
        rate = f"every {node.period} tick{'s' if node.period > 1 else ''} ({node.period * TICK_S:.3f} s)"
        how = ("declared" if d.every is not None else "once its inputs of a tick are in") + (
            ", told of each tick by the world's clock" if node.clock_key else "") + (
            f"; in real time on a timer of its own, every {d.timer:g} s" if d.timer is not None else "")
        flags = [f for f, on in (("stateful", node.stateful), ("reads the model", node.uses_model)) if on]
        lines.append(f"    {d.name}{inst}: {d.program}")
        lines.append(f"      runs {rate}, {how}" + (f"; {', '.join(flags)}" if flags else ""))
        for i in d.inputs:
            b = next(b for b in node.bindings if b.port == i.port)
            frm = {"teammates": " from every teammate", "world": " from the world"}.get(i.scope, "")
            delay = ", the previous run's (delay 1)" if i.delay else ""
            lines.append(f"      in  {i.port:<10} <- {i.key}{frm} [{b.kind}{', many' if b.many else ''}{delay}]")
        for o in d.outputs:
            lines.append(f"      out {o.port:<10} -> {o.key} [{node.output_kinds[o.port]}]")
        nondefault = {k: v for k, v in params[d.name].items()}
        if nondefault:
            lines.append("      params " + ", ".join(f"{k}={v}" for k, v in nondefault.items()))
    lines.append("  the world publishes per robot: " + (", ".join(k.split("/", 2)[2] for k in plan.world_keys(robot))
                                                        or "no readings (the clock only)"))
    for w in plan.warnings:
        lines.append(f"  warning: {w}")
    return lines


@graph_group.command("show")
@click.argument("graph")
@click.option("--task", type=click.Choice(["navigation", "tracking"]), help="For a graph of any task.")
@click.option("--robots", default="2", show_default=True, type=RobotIds(count=True),
              help="The team: a count or ids (r1,r2,r3).")
@click.option("--json", "as_json", is_flag=True, help="The resolved graph as JSON (what a run spec carries).")
def show_cmd(graph: str, task: str | None, robots: tuple[str, ...], as_json: bool) -> None:
    """GRAPH (a shipped graph's name or a file): its nodes per robot, with program,
    instances, rate, inputs and outputs."""
    checked = _checked(graph)
    t = _task(checked, task)
    try:
        plan = checked.plan(robots, t)
    except GraphError as exc:
        raise FileRefused(str(exc)) from None
    if as_json:
        doc = plan.to_dict()
        doc["params"] = {k: dict(v) for k, v in checked.params.items()}
        click.echo(json.dumps(doc, indent=1))
        return
    click.echo("\n".join(describe(checked, plan)))


@graph_group.command("check")
@click.argument("graph")
@click.option("--task", type=click.Choice(["navigation", "tracking"]), help="For a graph of any task.")
def check_cmd(graph: str, task: str | None) -> None:
    """Check GRAPH: its file, its programs, their ports and parameters, keys, cycles,
    rates and answer; warnings for outputs nobody reads."""
    checked = _checked(graph)
    tasks = [task] if task else (["navigation", "tracking"] if checked.graph.task == "any" else [checked.graph.task])
    for t in tasks:
        try:
            plan = checked.plan(TEAM, t)
        except GraphError as exc:
            raise FileRefused(str(exc)) from None
        for w in plan.warnings:
            click.echo(f"warning: {w}", err=True)
        for name in checked.classes:
            asdict(checked.make_params(name))
    g = checked.graph
    click.echo(f"{g.source}: ok ({len(g.nodes)} nodes, controller {g.controller}, task {g.task})")


@graph_group.command("acl")
@click.argument("graphs", nargs=-1, required=True)
@click.option("--robots", default="r1,r2,r3,r4", show_default=True, type=RobotIds(count=True),
              help="The robot identities: a count or ids.")
@click.option("--tls", is_flag=True, help="Identities by certificate common name (deploy/tls) instead of user name.")
@click.option("--out", "out_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Write the router config here (default: stdout).")
def acl_cmd(graphs: tuple[str, ...], robots: tuple[str, ...], tls: bool, out_path: Path | None) -> None:
    """The Zenoh router config (access control included) that lets each robot identity
    publish only what the GRAPHS' nodes send and read only what they read (deploy/)."""
    try:
        text = router_config([_checked(g) for g in graphs], robots, tls=tls)
    except GraphError as exc:
        raise FileRefused(str(exc)) from None
    if out_path is None:
        click.echo(text, nl=False)
    else:
        prepare_out_file(out_path).write_text(text)
        click.echo(f"wrote {out_path}")


def shipped_router_config(robots: tuple[str, ...] = ("r1", "r2", "r3", "r4"), tls: bool = False) -> str:
    """The router config for every shipped graph (what deploy/ holds)."""
    return router_config([check_graph(str(p)) for _, p in sorted(shipped_graphs().items())], robots, tls=tls)
