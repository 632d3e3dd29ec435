"""``--fields``: which field widths a cooperative-EKM run uses (docs/fields.md).

* ``learned``: the motor node's field policy chooses the widths every tick
  (``cekm_swarm.tune.motor``; named here by program only, so this module, which the
  paper's experiments use, reaches no training code);
* ``tuned``: every width a constant, today's hand-tuned ones -- the paper's method;
* ``paper``: the same with the paper's obstacle width sigma_b_alpha = 0.495.

Navigation's ``cekm`` graph is ``learned`` (the default since the fourth round won on
held-out seeds and geometries) and ``cekm-tuned`` its constant-width twin; tracking's
``cekm`` graph is ``tuned`` (its learned policy did not win) and ``learned`` swaps its
motor's program. The paper's reproductions pin ``tuned`` (:data:`REPRODUCTION`).
"""

from __future__ import annotations

from pathlib import Path

from ..errors import ParameterError
from ..graph.spec import Graph, graph_for, load_graph
from ..models.params import PAPER_SIGMA_B_ALPHA
from ..node.graph_check import CheckedGraph, check_graph

FIELDS = ("paper", "tuned", "learned")
"""``--fields``: the paper's constants, today's hand-tuned ones, or the learned policy."""

DEFAULT_FIELDS = {"navigation": "learned", "tracking": "tuned"}
"""What ``--controller cekm`` runs for each task."""

REPRODUCTION = "tuned"
"""The widths of the paper's reproductions (section 4.2's table, Fig. 9's sweep, Fig. 4's
fields): constant ones, the paper's method."""

CONSTANT_GRAPH = {"navigation": "cekm-tuned", "tracking": "cekm"}
"""The shipped graph with every field width a constant, by task."""

POLICY_PROGRAM = {"navigation": "cekm_swarm.tune.motor:FieldMotor",
                  "tracking": "cekm_swarm.tune.motor:FieldTrackingMotor"}
"""The motor node's program when a field policy chooses the widths."""


def check_fields(fields: str) -> str:
    """``fields`` if it is one of :data:`FIELDS`, else a ParameterError naming it."""
    if fields not in FIELDS:
        raise ParameterError(f"--fields must be one of {list(FIELDS)}, got {fields!r}")
    return fields


def _task(task: str) -> str:
    if task not in DEFAULT_FIELDS:
        raise ParameterError(f"task must be one of {sorted(DEFAULT_FIELDS)}, got {task!r}")
    return task


def policy_graph(task: str) -> Graph:
    """The cooperative-EKM graph of ``task`` whose motor node is the field-policy motor:
    navigation's shipped ``cekm`` graph; for tracking the shipped ``cekm`` graph with its
    motor's program swapped here."""
    if _task(task) == "navigation":
        return load_graph(graph_for("cekm", task))
    doc = load_graph(graph_for("cekm", task)).to_dict()
    for n in doc["nodes"]:
        if n["name"] == "motor":
            n["program"] = POLICY_PROGRAM[task]
    doc["description"] += " (field widths chosen by a field policy, docs/fields.md)"
    return Graph.from_dict(doc)


def fields_graph(fields: str, task: str, policy: Path | str | None = None) -> tuple[CheckedGraph, dict]:
    """The checked graph and parameter overrides of ``--fields FIELDS`` for ``task``.

    ``paper``: the constant-width graph with the paper's obstacle width (sigma_b_alpha
    0.495); ``tuned``: the constant-width graph as shipped; ``learned``: the field-policy
    motor with ``policy`` (default: the policy shipped for the task)."""
    check_fields(fields)
    if policy is not None and fields != "learned":
        raise ParameterError(f"a policy file ({policy}) goes with --fields learned, not {fields}")
    if fields == "learned":
        return check_graph(policy_graph(task)), ({"policy": str(policy)} if policy else {})
    checked = check_graph(str(graph_for(CONSTANT_GRAPH[_task(task)], task)))
    return checked, ({"sigma_b_alpha": PAPER_SIGMA_B_ALPHA} if fields == "paper" else {})
