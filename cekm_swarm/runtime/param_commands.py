"""``cekm param list|get|set``: a running node's parameters, read and changed while it runs
(:mod:`cekm_swarm.node.live_params`: validated against the node's ``Params``, applied
before its first run at or after ``--at``, logged and reported in ``outcome.json``)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import click

from cekm_swarm.cli_support import Finite, RunFailed
from cekm_swarm.protocol import KeySpace

from .tool_session import _connect_options, _session


def _target(node: str) -> tuple[str, str]:
    robot, _, name = node.partition("/")
    if not robot or not name:
        raise click.BadParameter(f"{node!r}: give ROBOT/NODE, e.g. r1/motor", param_hint="ROBOT/NODE")
    return robot, name


def _ask(session: Any, key: str, ask: dict[str, Any], timeout: float = 3.0) -> dict[str, Any]:
    """The node's JSON answer on its parameter queryable ``key``; RunFailed when none comes."""
    for r in session.get(key, payload=json.dumps(ask).encode(), timeout=timeout):
        if r.ok is not None:
            doc = json.loads(r.ok.payload.to_bytes())
            if "error" in doc:
                raise click.UsageError(doc["error"])
            return doc
    raise RunFailed(f"no node answered on {key} within {timeout:g} s (is it running? `cekm node list`)")


def _value(text: str) -> Any:
    """VALUE as TOML/JSON reads it (0.08, true, "fast", [1, 2]); a bare word is a string."""
    try:
        return json.loads(text)
    except ValueError:
        return text


@click.group("param")
def param_group() -> None:
    """A running node's parameters: list, get, set (docs/modules.md)."""


def _keys(root: str) -> KeySpace:
    return KeySpace(root=root)


@param_group.command("list")
@click.argument("node", metavar="ROBOT/NODE")
@_connect_options
@click.option("--root", default="cekm", show_default=True, help="Key-space root.")
def param_list_cmd(node: str, endpoint: str | None, config_file: Path | None, wait_s: float, root: str) -> None:
    """Every parameter of a running node: name, value, type; and the changes waiting for their time."""
    robot, name = _target(node)
    with _session(endpoint, config_file, wait_s) as session:
        doc = _ask(session, _keys(root).param(robot, name), {})
    click.echo(f"{doc['node']}: " + (f"last run at t={doc['t']:.3f} s" if doc["t"] is not None else "not run yet"))
    for p, d in doc["params"].items():
        click.echo(f"{p} = {json.dumps(d['value'])}  ({d['type']})")
    for c in doc["pending"]:
        click.echo(f"pending: {c['name']} = {json.dumps(c['value'])} from t={c['t']:.3f} s")


@param_group.command("get")
@click.argument("node", metavar="ROBOT/NODE")
@click.argument("name")
@_connect_options
@click.option("--root", default="cekm", show_default=True, help="Key-space root.")
def param_get_cmd(node: str, name: str, endpoint: str | None, config_file: Path | None, wait_s: float,
                  root: str) -> None:
    """One parameter's value."""
    robot, nm = _target(node)
    with _session(endpoint, config_file, wait_s) as session:
        doc = _ask(session, _keys(root).param(robot, nm), {})
    if name not in doc["params"]:
        known = ", ".join(doc["params"]) or "none"
        raise click.BadParameter(f"{node} has no parameter {name!r} (its parameters: {known})", param_hint="NAME")
    click.echo(json.dumps(doc["params"][name]["value"]))


@param_group.command("set")
@click.argument("node", metavar="ROBOT/NODE")
@click.argument("name")
@click.argument("value")
@click.option("--at", "at", type=Finite(0.0), default=None,
              help="Sim time (s) from which it applies: the node's first run at or after it (default: two of its "
                   "periods after its last run). Give it in lockstep for a reproducible run.")
@_connect_options
@click.option("--root", default="cekm", show_default=True, help="Key-space root.")
def param_set_cmd(node: str, name: str, value: str, at: float | None, endpoint: str | None, config_file: Path | None,
                  wait_s: float, root: str) -> None:
    """Set a parameter of a running node, checked against its declaration."""
    robot, nm = _target(node)
    with _session(endpoint, config_file, wait_s) as session:
        doc = _ask(session, _keys(root).param(robot, nm), {"set": name, "value": _value(value), "at": at})
    click.echo(f"{doc['node']}: {doc['name']} = {json.dumps(doc['value'])} from t={doc['t']:.3f} s")
