"""What a tool attached to a live run learns of its graph: the world serves the run spec on
``<root>/world/graph`` (:mod:`cekm_swarm.graph.runspec`), from which ``cekm node list``
and the monitor take the nodes each robot should have, and the view which fields to draw.
Plain data: nothing here imports node code."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from cekm_swarm.graph.spec import Graph, GraphError, graph_for, load_graph

from .record import fetch_json


@dataclass(frozen=True)
class RunGraph:
    """The graph of a live run, as tools need it."""

    name: str
    controller: str
    nodes: tuple[str, ...]  # one robot's node instances, in launch order
    team: tuple[str, ...]
    run_id: str | None
    sent: dict[str, str]  # key below a robot -> message kind, for every output of the graph

    @classmethod
    def from_spec(cls, doc: dict[str, Any]) -> RunGraph:
        g = Graph.from_dict(doc["graph"])
        sensors = len(doc.get("body", {}).get("sensor_angles", [])) or 12
        sent: dict[str, str] = {}
        for n in g.nodes:
            kinds = doc.get("ports", {}).get(n.name, {}).get("outputs", {})
            count = 1 if n.instances is None else (sensors if n.instances == "sensors" else int(n.instances))
            for o in n.outputs:
                for i in range(count):
                    sent[o.key.replace("{i}", str(i))] = kinds.get(o.port, "")
        return cls(g.name, g.controller, tuple(g.node_names(sensors)), tuple(doc.get("team", ())), doc.get("run_id"),
                   sent)


def fetch_run_graph(session: Any, key: str, timeout: float = 2.0) -> RunGraph | None:
    """The graph the world at ``key`` runs, or None (no world, an old one, a malformed answer)."""
    doc = fetch_json(session, key, timeout)
    if doc is None:
        return None
    try:
        return RunGraph.from_spec(doc)
    except (KeyError, TypeError, ValueError, GraphError):
        return None


def default_nodes(task: str = "navigation", sensors: int = 12) -> tuple[str, ...]:
    """The node instances of the default controller's graph (cekm) for ``task``: what a
    world started without a run spec waits for."""
    return tuple(load_graph(graph_for("cekm", task)).node_names(sensors))
