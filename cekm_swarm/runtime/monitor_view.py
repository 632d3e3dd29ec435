"""How ``cekm monitor`` draws a :class:`~cekm_swarm.runtime.monitor_state.MonitorState`:
:func:`render` (rich, every line at most 80 columns), :func:`render_text` (the same as
plain text, for ``--once``, pipes and tests) and :func:`snapshot` (what the view shows, as
plain data, for ``--once --json``).
"""

from __future__ import annotations

import io
import math
from collections.abc import Callable
from typing import Any

from rich.console import Console, Group
from rich.text import Text

from .monitor_state import MonitorState, natural_key

WIDTH = 80
"""Columns the view is laid out for."""

MAX_TARGET_LINES = 12
"""Target rows the tracking block draws; the rest are summed up in one line."""


def _fit(text: str, width: int, align: str = ">") -> str:
    """``text`` padded or cut (with an ellipsis) to exactly ``width`` columns."""
    if len(text) > width:
        text = text[:max(0, width - 1)] + "…"
    return f"{text:{align}{width}}"


def _num(x: float, width: int, digits: int) -> str:
    return _fit("-" if not math.isfinite(x) else f"{x:.{digits}f}", width)


_STATUS_STYLE = {"ended": "dim", "moving": "green", "reached": "bold cyan", "stopped": "yellow", "waiting": "dim"}
_PHASE_STYLE = {"running": "bold green", "replay": "bold green", "run ended": "bold red",
                "waiting for the world": "bold yellow", "waiting for the modules": "bold yellow"}
_HEADER = (f"{_fit('robot', 6, '<')} {_fit('x', 6)} {_fit('y', 6)} {_fit('theta', 5)} {_fit('goal', 13)} "
           f"{_fit('status', 7, '<')} {_fit('v_l', 6)} {_fit('v_r', 6)} {_fit('mods', 5)} {_fit('lat ms', 11)}")


def _packed(prefix: str, items: list[str], width: int) -> list[str]:
    """``items`` joined by two spaces after ``prefix``, over as many lines as ``width`` needs
    (continuation lines indented like the first; an item longer than a line is cut)."""
    pad = " " * len(prefix)
    lines, cur = [], prefix
    for it in items:
        it = _fit(it, min(len(it), width - len(pad)), "<")
        sep = "" if cur in (prefix, pad) else "  "
        if len(cur) + len(sep) + len(it) > width and cur not in (prefix, pad):
            lines.append(cur)
            cur, sep = pad, ""
        cur += sep + it
    lines.append(cur)
    return lines


def _tracking_lines(state: MonitorState, robots: set[str] | None, width: int) -> list[Text]:
    """The tracking block: A, then per target who observes it, then per robot how many it sees."""
    tr = state.tracking(robots)
    a = "-" if tr["A"] is None else f"{tr['A']:.2f}"
    head = Text(no_wrap=True, overflow="ellipsis")
    head.append("tracking", style="bold")
    head.append(f"  A {a}  observed {tr['observed']}/{tr['total']} targets", style="bold")
    if robots is not None:
        head.append("  (team; observers of --robot only)", style="dim")
    out = [head, Text(f"{_fit('target', 10, '<')} {_fit('x', 7)} {_fit('y', 7)}  observed by", style="bold",
                      no_wrap=True, overflow="ellipsis")]
    items = list(tr["targets"].items())
    for tid, t in items[:MAX_TARGET_LINES]:
        who = " ".join(t["observed_by"]) or "-"
        x = math.nan if t["x"] is None else t["x"]
        y = math.nan if t["y"] is None else t["y"]
        row = Text(no_wrap=True, overflow="ellipsis")
        row.append(f"{_fit(tid, 10, '<')} {_num(x, 7, 3)} {_num(y, 7, 3)}  ")
        row.append(_fit(who, width - 28, "<").rstrip(), style="green" if t["observed_by"] else "dim")
        out.append(row)
    if len(items) > MAX_TARGET_LINES:
        rest = items[MAX_TARGET_LINES:]
        seen = sum(1 for _, t in rest if t["observed_by"])
        out.append(Text(f"… {len(rest)} more targets, {seen} of them observed", style="dim", no_wrap=True,
                        overflow="ellipsis"))
    sees = [f"{rid} {p['sees']}" for rid, p in tr["per_robot"].items()]
    for line in _packed("sees  ", sees or ["-"], width):
        out.append(Text(line, no_wrap=True, overflow="ellipsis"))
    return out


def _head(state: MonitorState, phase: str, endpoint: str) -> Text:
    """The view's first line: the run's phase, sim time, drops, run ids, the endpoint."""
    head = Text(no_wrap=True, overflow="ellipsis")
    head.append("cekm monitor ", style="bold")
    head.append(_fit(phase, len(phase), "<"), style=_PHASE_STYLE.get(phase, "bold yellow"))
    sim = "-" if not math.isfinite(state.sim_time) else f"{state.sim_time:.2f} s"
    head.append(f"  sim {sim}  dropped {state.drops.total}")
    runs = state.runs()
    if runs:
        head.append(f"  run {','.join(runs)}")
    if state.untracked:
        head.append(f"  untracked {state.untracked}", style="yellow")
    if endpoint:
        head.append(f"  {endpoint}", style="dim")
    return head


def render(state: MonitorState, now: float, *, robots: set[str] | None = None, key_filter: Callable[[str], bool] | None
           = None, endpoint: str = "", width: int = WIDTH) -> Group:
    """The view as a rich renderable, every line at most ``width`` (80) columns: the run's
    phase, one row per robot (only ``robots`` if given), and, with ``key_filter``, the
    rate, age and stamp of every matching key."""
    phase = state.phase(now)
    lines: list[Text] = [_head(state, phase, endpoint)]
    if phase == "waiting for the world":
        lines.append(Text("waiting for the world server's first state (start a run or `cekm replay LOG`)",
                          style="dim", no_wrap=True, overflow="ellipsis"))
    elif phase == "waiting for the modules":
        lines.append(Text(f"the world server is up: tick 0 once every module is alive "
                          f"({state.module_tokens()} alive now)", style="dim", no_wrap=True, overflow="ellipsis"))
    shown = [r for r in sorted(state.robots, key=natural_key) if robots is None or r in robots]
    if robots is not None:
        for r in sorted(robots - set(state.robots), key=natural_key):
            lines.append(Text(f"{r}: not seen", style="dim", no_wrap=True, overflow="ellipsis"))
    if shown:
        lines.append(Text(_HEADER, style="bold", no_wrap=True, overflow="ellipsis"))
    expected = len(state.expected) if state.expected is not None else None
    for rid in shown:
        v = state.robots[rid]
        x, y, th = v.pose if v.pose else (math.nan,) * 3
        goal = f"({v.goal[0]:.2f},{v.goal[1]:.2f})" if v.goal else "-"
        vl, vr = v.command if v.command else (math.nan, math.nan)
        n, missing = state.modules_alive(rid)
        lat = f"{v.latency_ms(0.5):.1f}/{v.latency_ms(0.99):.1f}" if v.latencies else "-"
        row = Text(no_wrap=True, overflow="ellipsis")
        row.append(f"{_fit(rid, 6, '<')} {_num(x, 6, 3)} {_num(y, 6, 3)} {_num(th, 5, 2)} {_fit(goal, 13)} ")
        status = v.status if phase != "run ended" or v.status == "reached" else "ended"  # no robot moves any more
        row.append(_fit(status, 7, "<"), style=_STATUS_STYLE.get(status, ""))
        row.append(f" {_num(vl, 6, 3)} {_num(vr, 6, 3)} ")
        row.append(_fit(f"{n}/{expected}" if expected is not None else f"{n}", 5),
                   style="" if expected is None or n == expected else "bold red")
        row.append(f" {_fit(lat, 11)}")
        lines.append(row)
        if missing and n:
            lines.append(Text(f"       missing: {', '.join(missing)}", style="red", no_wrap=True,
                              overflow="ellipsis"))
        if v.map is not None:  # a learning robot (docs/learning.md)
            lines.append(Text(f"       map v{v.map[0]}, {v.map[1]} steps learned, error {v.map[2]:.4f} m/s",
                              style="cyan", no_wrap=True, overflow="ellipsis"))
    if state.is_tracking():
        lines.extend(_tracking_lines(state, robots, width))
    stats = state.key_stats(now)
    if key_filter is None:
        active = [s for s in stats if s.count]
        lines.append(Text(f"{len(active)} keys active, {sum(s.rate for s in active):.0f} msgs/s "
                          f"(--keys KEYEXPR lists them)", style="dim", no_wrap=True, overflow="ellipsis"))
    else:
        chosen = [s for s in stats if key_filter(s.key)]
        lines.append(Text(f"{_fit('key', 48, '<')} {_fit('rate Hz', 8)} {_fit('age s', 9)} {_fit('stamp', 10)}",
                          style="bold", no_wrap=True, overflow="ellipsis"))
        for s in chosen:
            stamp = state.last_stamp.get(s.key, math.nan)
            age = "-" if not math.isfinite(s.age) else f"{s.age:.2f}"
            lines.append(Text(f"{_fit(s.key, 48, '<')} {_num(s.rate, 8, 2)} {_fit(age, 9)} {_num(stamp, 10, 3)}",
                              no_wrap=True, overflow="ellipsis"))
        if not chosen:
            lines.append(Text("no key matches --keys yet", style="dim"))
    return Group(*lines)


def snapshot(state: MonitorState, now: float, *, robots: set[str] | None = None,
             key_filter: Callable[[str], bool] | None = None) -> dict[str, Any]:
    """What the view shows, as plain data (``cekm monitor --once --json``)."""
    out: dict[str, Any] = {"phase": state.phase(now), "sim_time": state.sim_time, "dropped": state.drops.total,
                           "robots": {}}
    for rid in sorted(state.robots, key=natural_key):
        if robots is not None and rid not in robots:
            continue
        v = state.robots[rid]
        n, missing = state.modules_alive(rid)
        status = v.status if out["phase"] != "run ended" or v.status == "reached" else "ended"
        out["robots"][rid] = {"pose": v.pose, "goal": v.goal, "in_contact": v.in_contact, "status": status,
                              "command": v.command, "modules_alive": n, "modules_missing": missing,
                              "latency_ms_p50": v.latency_ms(0.5), "latency_ms_p99": v.latency_ms(0.99)}
        if v.map is not None:
            out["robots"][rid]["map"] = {"version": v.map[0], "steps": v.map[1], "error_m_s": v.map[2]}
    if state.is_tracking():
        out["tracking"] = state.tracking(robots)
    if key_filter is not None:
        out["keys"] = [{"key": s.key, "rate_hz": s.rate, "age_s": s.age, "stamp": state.last_stamp.get(s.key)}
                       for s in state.key_stats(now) if key_filter(s.key)]
    return out


def render_text(state: MonitorState, now: float, width: int = WIDTH, **kw: Any) -> str:
    """The view as plain text, as an 80-column terminal shows it (for --once, pipes, tests)."""
    console = Console(width=width, record=True, file=io.StringIO(), color_system=None, force_terminal=False)
    console.print(render(state, now, width=width, **kw))
    return console.export_text().rstrip("\n")
