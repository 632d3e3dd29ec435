"""The graphs of ``--fields``: the shipped cooperative-EKM graph, and the same with its motor
node's program the field-policy motor (:mod:`.motor`): for navigation the shipped
``cekm-learned`` graph (a test keeps it the ``cekm`` graph node for node but the motor's
program), for tracking built here from the shipped file."""

from __future__ import annotations

from pathlib import Path

from ..errors import ParameterError
from ..experiments.graph_run import with_params
from ..graph.spec import Graph, graph_for, load_graph
from ..models.params import PAPER_SIGMA_B_ALPHA
from ..node.graph_check import CheckedGraph, check_graph
from .policy import FieldPolicy, check_task

FIELDS = ("paper", "tuned", "learned")
"""``--fields``: the paper's constants, today's hand-tuned ones, or the learned policy."""

PROGRAM = {"navigation": "cekm_swarm.tune.motor:FieldMotor", "tracking": "cekm_swarm.tune.motor:FieldTrackingMotor"}


def policy_graph(task: str) -> Graph:
    """The ``cekm`` graph of ``task`` with the field-policy motor node: for navigation the
    shipped ``cekm-learned`` graph (``--controller cekm-learned``, the same graph), for
    tracking the shipped ``cekm`` graph with its motor's program swapped here."""
    if check_task(task) == "navigation":
        return load_graph(graph_for("cekm-learned", task))
    doc = load_graph(graph_for("cekm", task)).to_dict()
    for n in doc["nodes"]:
        if n["name"] == "motor":
            n["program"] = PROGRAM[task]
    doc["description"] += " (field widths chosen by a field policy, docs/fields.md)"
    return Graph.from_dict(doc)


def fields_graph(fields: str, task: str, policy: Path | str | None = None) -> tuple[CheckedGraph, dict]:
    """The checked graph and parameter overrides of ``--fields FIELDS`` for ``task``.

    ``paper``: the paper's obstacle width (sigma_b_alpha 0.495) in the shipped graph;
    ``tuned``: the shipped graph as it is (today's default); ``learned``: the field-policy
    motor with ``policy`` (default: the policy shipped for the task)."""
    if fields not in FIELDS:
        raise ParameterError(f"--fields must be one of {list(FIELDS)}, got {fields!r}")
    if fields == "learned":
        return check_graph(policy_graph(task)), ({"policy": str(policy)} if policy else {})
    checked = check_graph(str(graph_for("cekm", check_task(task))))
    return checked, ({"sigma_b_alpha": PAPER_SIGMA_B_ALPHA} if fields == "paper" else {})


def with_fields(checked: CheckedGraph, fields: str | None, task: str,
                policy: Path | str | None = None) -> CheckedGraph:
    """``cekm run --fields [--policy FILE]``: ``checked`` (the run's graph) unless FIELDS is
    given, then the cooperative-EKM graph of :func:`fields_graph` with its parameters applied.
    A policy file goes with ``learned`` only, and is read here: a bad one is refused before
    the run starts, naming the file."""
    if policy is not None:
        if fields != "learned":
            raise ParameterError(f"--policy {policy} goes with --fields learned, not {fields or 'no --fields'}")
        FieldPolicy.load(policy).check_task(task, policy)
    if fields is None:
        return checked
    if checked.graph.controller != "cekm":
        raise ParameterError(f"--fields goes with --controller cekm, not {checked.graph.controller!r}")

    graph, params = fields_graph(fields, task, policy)
    return with_params(graph, params)
