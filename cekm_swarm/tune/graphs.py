"""``cekm run --fields [--policy FILE]``: the run's graph with the field widths asked for
(:mod:`cekm_swarm.experiments.field_widths` says which graph each choice is), a policy
file read before the run starts."""

from __future__ import annotations

from pathlib import Path

from ..errors import ParameterError
from ..experiments.field_widths import CONSTANT_GRAPH, fields_graph
from ..experiments.graph_run import with_params
from ..node.graph_check import CheckedGraph
from .policy import FieldPolicy

COOPERATIVE = frozenset({"cekm", *CONSTANT_GRAPH.values()})
"""The controllers ``--fields`` goes with: cooperative EKMs, learned widths or constant."""


def with_fields(checked: CheckedGraph, fields: str | None, task: str,
                policy: Path | str | None = None) -> CheckedGraph:
    """``checked`` (the run's graph) unless FIELDS is given, then the cooperative-EKM graph
    of :func:`~cekm_swarm.experiments.field_widths.fields_graph` with its parameters
    applied. A policy file goes with ``learned`` only, and is read here: a bad one is
    refused before the run starts, naming the file."""
    if policy is not None:
        if fields != "learned":
            raise ParameterError(f"--policy {policy} goes with --fields learned, not {fields or 'no --fields'}")
        FieldPolicy.load(policy).check_task(task, policy)
    if fields is None:
        return checked
    if checked.graph.controller not in COOPERATIVE:
        raise ParameterError(f"--fields goes with --controller cekm, not {checked.graph.controller!r}")

    graph, params = fields_graph(fields, task, policy)
    return with_params(graph, params)
