"""Controllers as declared process graphs: the file format (:mod:`.spec`), what a graph
means for a run (:mod:`.plan`, built by :mod:`.resolve`), and the checks that import its
programs (:mod:`.check`)."""

from .plan import Binding, NodePlan, PortTypes, RunPlan, Source, needed_tick
from .resolve import build_plan
from .spec import Graph, GraphError, InputDecl, NodeDecl, OutputDecl, graph_for, graph_path, load_graph, shipped_graphs

__all__ = ["Binding", "NodePlan", "PortTypes", "RunPlan", "Source", "build_plan", "needed_tick", "Graph", "GraphError",
           "InputDecl", "NodeDecl", "OutputDecl", "graph_for", "graph_path", "load_graph", "shipped_graphs"]
