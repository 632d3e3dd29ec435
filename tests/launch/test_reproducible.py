"""``outcome.json``'s ``reproducible`` of a lockstep launch (``launch.reports.reproducible``):
a run may claim to equal ``cekm run`` only when it ran to its end and no node restarted
without what it had (its state across ticks, its own previous outputs)."""

from __future__ import annotations

from pathlib import Path

from cekm_swarm.launch.reports import reproducible
from cekm_swarm.launch.supervision import Child


def child(name: str, restarts: int = 0, stateful: bool = False) -> Child:
    return Child("r1", name, [], Path(f"{name}.log"), restarts=restarts, stateful=stateful)


def test_a_whole_run_whose_restarted_nodes_keep_no_state_equals_cekm_run():
    rep = reproducible([child("motor", restarts=2), child("target", stateful=True)], aborted=False)
    assert rep["equals_cekm_run"] is True and rep["stateful_restarts"] == [] and rep["aborted"] is False


def test_a_restarted_node_that_keeps_state_breaks_the_equality():
    rep = reproducible([child("motor", restarts=1), child("target", restarts=1, stateful=True)], aborted=False)
    assert rep["equals_cekm_run"] is False and rep["stateful_restarts"] == ["r1/target"]


def test_an_aborted_run_never_claims_to_equal_cekm_run():
    """A run stopped before its end (Ctrl-C, a timeout) said equals_cekm_run: true."""
    rep = reproducible([child("motor")], aborted=True)
    assert rep["equals_cekm_run"] is False and rep["aborted"] is True and "stopped before its end" in rep["why"]
