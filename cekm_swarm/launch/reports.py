"""What the launcher says about the nodes: who it still waits for (:func:`missing_by_robot`),
and what the nodes said about themselves as they stopped: each node process writes one
``DROPS {json}`` line to its log (:meth:`cekm_swarm.node.process.NodeShell.report`), and
the launcher sums them up, so a node whose step raised, that skipped runs or that dropped
messages is named at the end of the launch and in ``outcome.json``, not only in its log;
and whether a lockstep run may claim to equal ``cekm run`` (:func:`reproducible`)."""

from __future__ import annotations

import json
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from cekm_swarm.node.process import REPORT
from cekm_swarm.protocol import KeySpace


def missing_by_robot(keys: KeySpace, plan: Any, missing: Iterable[str]) -> str:
    """``r3 (all 14 nodes not alive), r2 (1 node not alive: motor)``: the robots still
    waited for, from the liveliness tokens not seen (``plan``: the run's plan, or None)."""
    by_robot: dict[str, list[str]] = {}
    for key in missing:
        try:
            parsed = keys.parse(key)
            robot, node = parsed.robot or key, parsed.module or key
        except Exception:  # noqa: BLE001 - a token of another shape: named as it is
            robot, node = key, key
        by_robot.setdefault(robot, []).append(node)
    parts = []
    for robot in sorted(by_robot):
        nodes = sorted(by_robot[robot])
        n = len(nodes)
        every = plan is not None and robot in plan.nodes and n == len(plan.nodes[robot])
        named = "" if every or n > 3 else f": {', '.join(nodes)}"
        parts.append(f"{robot} ({'all ' if every and n > 1 else ''}{n} node{'s' if n != 1 else ''} not alive{named})")
    return ", ".join(parts)


def read_reports(log_path: Path) -> list[dict[str, Any]]:
    """Every report line in one node's log (one per life of the process; a killed one writes none)."""
    try:
        text = log_path.read_text(errors="replace")
    except OSError:
        return []
    out = []
    for line in text.splitlines():
        if line.startswith(REPORT + " {"):
            try:
                doc = json.loads(line[len(REPORT) + 1:])
            except ValueError:
                continue
            if isinstance(doc, dict):
                out.append(doc)
    return out


def node_summary(reports: Iterable[dict[str, Any]]) -> dict[str, Any]:
    """One node's lives summed: runs, runs whose step failed (by kind of failure), runs
    skipped as not ready, messages dropped (malformed, unbelievable stamps, wrong keys)."""
    runs, not_ready, dropped = 0, 0, 0
    failures: dict[str, int] = {}
    ran_without: set[str] = set()
    changes: list[dict[str, Any]] = []
    for r in reports:
        changes += [c for c in (r.get("param_changes") or ()) if isinstance(c, dict)]
        runs += int(r.get("runs", 0))
        ran_without.update(str(k) for k in (r.get("ran_without") or ()))
        not_ready += int(r.get("not_ready", 0))
        dropped += sum(int(n) for n in (r.get("dropped") or {}).values())
        for what, n in (r.get("step_failures") or {}).items():
            failures[what] = failures.get(what, 0) + int(n)
    return {"runs": runs, "step_failures": failures, "not_ready": not_ready, "dropped": dropped,
            "ran_without": sorted(ran_without), **({"param_changes": changes} if changes else {})}


def notable(summaries: dict[str, dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """The nodes worth a line: any failed or skipped run, or any dropped message."""
    return {label: s for label, s in summaries.items()
            if s["step_failures"] or s["not_ready"] or s["dropped"] or s.get("ran_without") or s.get("param_changes")}


def summary_lines(summaries: dict[str, dict[str, Any]], logs: dict[str, Path]) -> list[str]:
    """One line per notable node, failures first, naming its log."""
    lines = []
    for label, s in sorted(notable(summaries).items(), key=lambda kv: (not kv[1]["step_failures"], kv[0])):
        parts = []
        if s["step_failures"]:
            n = sum(s["step_failures"].values())
            kinds = "; ".join(f"{what} x{k}" for what, k in sorted(s["step_failures"].items(), key=lambda kv: -kv[1]))
            parts.append(f"{n} of {n + s['runs']} run{'s' if n + s['runs'] != 1 else ''} failed ({kinds})")
        if s["not_ready"]:
            n = s["not_ready"]
            parts.append(f"{n} tick{'s' if n != 1 else ''} not run (an input it needs had not arrived)")
        if s["dropped"]:
            parts.append(f"{s['dropped']} message{'s' if s['dropped'] != 1 else ''} dropped")
        if s.get("ran_without"):
            parts.append(f"a run after its restart went without {', '.join(s['ran_without'])} of the tick "
                         f"before (its producer restarted too)")
        for c in s.get("param_changes", ()):
            parts.append(f"parameter {c.get('name')} = {c.get('value')!r} from t={c.get('t')} s")
        where = f" (see {logs[label]})" if label in logs else ""
        lines.append(f"node {label}: " + ", ".join(parts) + where)
    return lines


def reproducible(children: Iterable[Any], aborted: bool,
                 summaries: dict[str, dict[str, Any]] | None = None) -> dict[str, Any]:
    """``outcome.json``'s ``reproducible`` of a lockstep run: whether it may claim to equal
    ``cekm run``. Not when a node restarted without what it had (its state across ticks, or
    its own previous outputs, or a world reading of the tick before, which nobody sends
    again: ``node.timing.lost_on_restart``; or a delayed value whose producer restarted
    too: ``ran_without`` in its summary), nor when the run was stopped before its end."""
    without = sorted(label for label, s in (summaries or {}).items() if s.get("ran_without"))
    lost = sorted(ch.label for ch in children if ch.restarts and ch.stateful)
    whys = []
    if aborted:
        whys.append("the run was stopped before its end, so it is not the whole run cekm run makes")
    if lost:
        whys.append("a node that keeps state across ticks (or reads its own previous outputs) restarted without "
                    "it, so what it computed after its restart may differ from cekm run")
    if without:
        whys.append("a restarted node ran without a delayed value whose producer restarted too (went_without)")
    return {"equals_cekm_run": not whys, "stateful_restarts": lost, "went_without": without, "aborted": aborted,
            "why": "; ".join(whys) or "every restarted node keeps no state across ticks"}
