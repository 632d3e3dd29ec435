"""The plans of every shipped graph (and the documentation's example graphs) for teams of
one and three, pinned by a digest of their nodes, bindings and warnings: a change to how
:func:`cekm_swarm.graph.resolve.build_plan` resolves a graph shows here, whatever its form.
The digests were computed before ``build_plan`` was split into named phases (issue 43);
regenerate them only for a change of meaning, never to make a refactor pass (print
:func:`plan_digests` and review every changed entry)."""

from __future__ import annotations

import hashlib
from pathlib import Path

from cekm_swarm.graph import shipped_graphs
from cekm_swarm.node.graph_check import check_graph

EXAMPLES = Path(__file__).resolve().parents[2] / "docs" / "examples"


def _graphs() -> list[tuple[str, str]]:
    named = [(name, name) for name in sorted(shipped_graphs())]
    return named + [(f"docs/examples/{p.name}", str(p)) for p in sorted(EXAMPLES.glob("*.toml"))]


def plan_digests() -> dict[str, str]:
    """graph x task x team size x sensors -> sha256 of the plan's nodes and warnings."""
    out = {}
    for label, ref in _graphs():
        checked = check_graph(ref)
        tasks = ["navigation", "tracking"] if checked.graph.task == "any" else [checked.graph.task]
        for task in tasks:
            for n, sensors in ((1, 12), (3, 12), (3, 5)):
                team = tuple(f"r{i + 1}" for i in range(n))
                plan = checked.plan(team, task, sensors)
                text = repr((plan.nodes, plan.warnings, plan.world_keys("r1"), plan.held_readings("r1")))
                out[f"{label} {task} {n} {sensors}"] = hashlib.sha256(text.encode()).hexdigest()[:16]
    return out


PINNED: dict[str, str] = {
    "acmommt-tracking tracking 1 12": "f10a7d68d3a1cfb3",
    "acmommt-tracking tracking 3 12": "e9139745da002fb0",
    "acmommt-tracking tracking 3 5": "ff4b3e3ec3520e0c",
    "cekm-learning-navigation navigation 1 12": "d16825c75fe7dcdd",
    "cekm-learning-navigation navigation 3 12": "3f4b2e3f70256d0e",
    "cekm-learning-navigation navigation 3 5": "3f51e574e818c0f7",
    "cekm-learning-team-navigation navigation 1 12": "84226e05a519252b",
    "cekm-learning-team-navigation navigation 3 12": "cb6b6c25ac023d92",
    "cekm-learning-team-navigation navigation 3 5": "f7504485311abf89",
    "cekm-navigation navigation 1 12": "850514364ade5535",
    "cekm-navigation navigation 3 12": "3fd9cc650c9334ff",
    "cekm-navigation navigation 3 5": "df7e43c007961d46",
    "cekm-tuned-navigation navigation 1 12": "b5787a512c2981e8",
    "cekm-tuned-navigation navigation 3 12": "b3ffd8638cb97358",
    "cekm-tuned-navigation navigation 3 5": "4bdfed9d67dd39f8",
    "cekm-tracking tracking 1 12": "7a8935539ac44fb1",
    "cekm-tracking tracking 3 12": "f7c3fdc6b519bd5a",
    "cekm-tracking tracking 3 5": "b83e341d67a93f55",
    "fusion-navigation navigation 1 12": "3e417da8fd2b9553",
    "fusion-navigation navigation 3 12": "5c79edbf9bb3ed8d",
    "fusion-navigation navigation 3 5": "351d3cf774630032",
    "kmeans-global-tracking tracking 1 12": "0aca017f48799638",
    "kmeans-global-tracking tracking 3 12": "73e7543aaa68ffba",
    "kmeans-global-tracking tracking 3 5": "e57cc981cd03196e",
    "kmeans-tracking tracking 1 12": "45b8b7736cb9be15",
    "kmeans-tracking tracking 3 12": "0556ff13591f19fd",
    "kmeans-tracking tracking 3 5": "5f78e3ab315a95fe",
    "stay navigation 1 12": "c44b925ec804c730",
    "stay navigation 3 12": "790a217fa70b7830",
    "stay navigation 3 5": "790a217fa70b7830",
    "stay tracking 1 12": "c44b925ec804c730",
    "stay tracking 3 12": "790a217fa70b7830",
    "stay tracking 3 5": "790a217fa70b7830",
    "docs/examples/free.toml navigation 1 12": "b4d19c4af9076499",
    "docs/examples/free.toml navigation 3 12": "18ad96ac78727246",
    "docs/examples/free.toml navigation 3 5": "f9a30e224ba0d6bc",
    "docs/examples/nearest.toml navigation 1 12": "5c73d2c4626fc285",
    "docs/examples/nearest.toml navigation 3 12": "366d57fc7430a160",
    "docs/examples/nearest.toml navigation 3 5": "6296a5f9662d0045",
}


def test_every_plan_is_the_one_pinned():
    assert plan_digests() == PINNED
