"""The checks of a graph that need its node programs: import each program, read its
ports and parameters, and refuse what cannot run before anything starts (an unknown
program, a parameter a node does not declare, a value of the wrong type, a port bound to
the wrong message type), then resolve the graph for a team (:func:`cekm_swarm.graph.resolve.build_plan`).

What the checks produce (:class:`CheckedGraph`) is what a run spec carries to every
process, so nothing imports a program it does not run. These checks live with the node
API they check: :mod:`cekm_swarm.graph` is plain data and imports no node code.
"""

from __future__ import annotations

import importlib
import inspect
import sys
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from cekm_swarm.graph.plan import PortTypes, RunPlan
from cekm_swarm.graph.resolve import build_plan
from cekm_swarm.graph.spec import Graph, GraphError, load_graph
from cekm_swarm.protocol import KeySpace, kind_of

from .api import Node, make_params, param_fields, raised_at


def node_class(program: str, source: str = "", where: str = "") -> type[Node]:
    """The node class of ``program``: ``module:Class``, or a module holding exactly one
    :class:`Node` subclass of its own (or naming it ``NODE``)."""
    mod_name, _, cls_name = program.partition(":")
    _beside(source)
    try:
        mod = importlib.import_module(mod_name)
    except ImportError as exc:
        missing = getattr(exc, "name", None)
        if missing is not None and missing != mod_name and not mod_name.startswith(missing + "."):
            # the program's module was found, and an import of its own failed
            raise GraphError(source, f"{where}.program", _failed_import(program, exc)) from None
        raise GraphError(source, f"{where}.program", f"unknown program {program!r}: cannot import {mod_name!r} "
                                                    f"({exc})") from None
    except Exception as exc:  # noqa: BLE001 - a user's module may fail in any way on import
        raise GraphError(source, f"{where}.program", _failed_import(program, exc)) from None
    if cls_name:
        cls = getattr(mod, cls_name, None)
        if not (inspect.isclass(cls) and issubclass(cls, Node)):
            raise GraphError(source, f"{where}.program", f"{program!r}: {mod_name} has no Node class {cls_name!r}")
        return cls
    named = getattr(mod, "NODE", None)
    if inspect.isclass(named) and issubclass(named, Node):
        return named
    own = [c for _, c in inspect.getmembers(mod, inspect.isclass)
           if issubclass(c, Node) and c is not Node and c.__module__ == mod.__name__]
    if len(own) != 1:
        raise GraphError(source, f"{where}.program", f"{program!r} defines {len(own)} Node classes "
                                                    f"({', '.join(c.__name__ for c in own) or 'none'}): name one as "
                                                    f"'{mod_name}:Class'")
    return own[0]


def _failed_import(program: str, exc: BaseException) -> str:
    """What went wrong importing a program's module: the exception and where it was raised."""
    at = raised_at(exc)
    return f"program {program!r} failed to import: {type(exc).__name__}: {exc}" + (f" ({at})" if at else "")


def _beside(source: str) -> None:
    """A graph's own programs may sit beside its file: that folder is searched too (after
    the installed packages, so a file there never hides one of the package's modules)."""
    if not source:
        return
    folder = str(Path(source).resolve().parent)
    if Path(source).is_file() and folder not in sys.path:
        sys.path.append(folder)


def port_types(cls: type[Node]) -> PortTypes:
    """A node class's ports as plain data."""
    return PortTypes({p: (kind_of(i.type), i.many) for p, i in cls.inputs.items()},
                     {p: kind_of(o.type) for p, o in cls.outputs.items()}, bool(cls.stateful), bool(cls.uses_model),
                     bool(getattr(cls, "pure", False)))


@dataclass
class CheckedGraph:
    """A graph whose programs were imported and whose parameters are checked: its
    classes, their ports, and every node's parameter values (the graph's ``[params]``
    that the node declares, overridden by its own)."""

    graph: Graph
    classes: dict[str, type[Node]]
    ports: dict[str, PortTypes]
    params: dict[str, dict[str, Any]]

    def plan(self, team: tuple[str, ...] | list[str], task: str, sensors: int = 12,
             keys: KeySpace | None = None) -> RunPlan:
        return build_plan(self.graph, tuple(team), task, self.ports, sensors, keys)

    def make_params(self, node: str) -> Any:
        return make_params(self.classes[node], self.params[node], f"node '{node}'.params")

    @property
    def uses_model(self) -> bool:
        return any(p.uses_model for p in self.ports.values())


def check_graph(graph: Graph | str) -> CheckedGraph:
    """Import every program of ``graph`` and check its ports and parameters."""
    if not isinstance(graph, Graph):
        graph = load_graph(graph)
    src = graph.source
    classes, ports, params = {}, {}, {}
    used: set[str] = set()
    for n in graph.nodes:
        cls = node_class(n.program, src, n.where)
        try:
            ports[n.name] = port_types(cls)
            declared = param_fields(cls)
        except (TypeError, AttributeError) as exc:
            raise GraphError(src, f"{n.where}.program", f"{n.program!r}: {exc}") from None
        values = {k: v for k, v in graph.params.items() if k in declared}
        used.update(values)
        values.update(n.params)
        try:
            make_params(cls, values, f"{n.where}.params")
        except ValueError as exc:
            raise GraphError(src, None, str(exc)) from None
        classes[n.name], params[n.name] = cls, values
    unused = sorted(set(graph.params) - used)
    if unused:
        raise GraphError(src, f"[params].{unused[0]}", "no node of the graph declares this parameter")
    return CheckedGraph(graph, classes, ports, params)


def params_doc(checked: CheckedGraph) -> dict[str, dict[str, Any]]:
    """Every node's full parameters, defaults included (what ``cekm graph show`` prints)."""
    return {name: asdict(checked.make_params(name)) for name in checked.classes}


def spec_ports(doc: Mapping[str, Any]) -> dict[str, PortTypes]:
    """The ports of a run spec's graph."""
    return {k: PortTypes.from_dict(v) for k, v in doc.items()}
