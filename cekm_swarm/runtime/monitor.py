"""``cekm monitor``: a live terminal view of a run, attachable from any terminal.

Per robot: pose, goal, status (moving / stopped / reached), last wheel command, its
modules' liveliness, and the sense-to-command latency (wall time from the first sensor
message of a tick to the motor command stamped with the same tick). Above them, the
run's phase: waiting for the world, running, no world state for a while, or ended (the
world server's liveliness token went away). Per key, with a filter: rate, age, stamp.
It fits an 80-column terminal and works the same on a live run and on ``cekm replay``.

:class:`MonitorState` is the pure part (fed with key, payload and arrival time, tested
without Zenoh); it validates what it draws: a ``world/state`` whose robots lack a finite
x, y or theta is dropped and counted like any malformed message. :func:`render` draws
it with rich; :func:`run_monitor` is the thin shell that subscribes and redraws.
"""

from __future__ import annotations

import io
import math
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import zenoh
from rich.console import Console, Group
from rich.text import Text

from cekm_swarm.protocol import (DEFAULT_KEYS, WORLD, DropCounter, KeyKind, KeySpace, SenseRange, SenseTarget, WheelCommand,
                                 WorldState)

from .topics import HzStats, hz_stats

WIDTH = 80
"""Columns the view is laid out for."""

STALE_AFTER = 3.0
"""Seconds without a world state after which the monitor says so."""

MAX_KEYS = 4096
"""Keys whose rates the monitor tracks; messages on keys beyond these are counted only (a
publisher inventing keys cannot grow the monitor without bound)."""

MAX_ROBOTS = 512
"""Robots the monitor tracks; others are counted in ``untracked``."""

FRESH = 1.0
"""A world state younger than this (s) means the run is going, whatever the tokens say."""


@dataclass
class RobotView:
    """What the monitor knows of one robot."""

    robot: str
    pose: tuple[float, float, float] | None = None
    goal: tuple[float, float] | None = None
    in_contact: bool = False
    command: tuple[float, float] | None = None
    command_stamp: float | None = None
    latencies: deque = field(default_factory=lambda: deque(maxlen=200))  # seconds
    sense_first: dict = field(default_factory=dict)  # stamp -> wall time of the first sense message

    @property
    def status(self) -> str:
        if self.command is None:
            return "waiting"
        if self.command == (0.0, 0.0):
            if self.pose is not None and self.goal is not None and math.dist(self.pose[:2], self.goal) < 0.01:
                return "reached"
            return "stopped"
        return "moving"

    def latency_ms(self, q: float) -> float:
        if not self.latencies:
            return math.nan
        xs = sorted(self.latencies)
        return 1e3 * xs[min(len(xs) - 1, int(q * len(xs)))]


def _finite(x: Any) -> bool:
    return type(x) in (int, float) and math.isfinite(x)


def robot_entry(rid: str, r: Any) -> tuple[tuple[float, float, float], tuple[float, float] | None, bool]:
    """(pose, goal, in_contact) of one robot of a world state; ValueError naming the field
    when it is not drawable (x, y, theta finite numbers; goal None or two finite numbers)."""
    if not isinstance(r, dict):
        raise ValueError(f"robots.{rid}: expected a map")
    for name in ("x", "y", "theta"):
        if not _finite(r.get(name)):
            raise ValueError(f"robots.{rid}.{name}: expected a finite number, got {r.get(name)!r}")
    goal = r.get("goal")
    if goal is not None:
        if not (isinstance(goal, list) and len(goal) == 2 and all(_finite(g) for g in goal)):
            raise ValueError(f"robots.{rid}.goal: expected null or [x, y], got {goal!r}")
        goal = (float(goal[0]), float(goal[1]))
    contact = r.get("in_contact", False)
    if not isinstance(contact, bool):
        raise ValueError(f"robots.{rid}.in_contact: expected a bool, got {contact!r}")
    return (float(r["x"]), float(r["y"]), float(r["theta"])), goal, contact


class MonitorState:
    """Everything the monitor shows, updated from (key, payload, arrival time)."""

    def __init__(self, keys: KeySpace = DEFAULT_KEYS, window: float = 5.0) -> None:
        self.keys = keys
        self.window = window
        self.robots: dict[str, RobotView] = {}
        self.arrivals: dict[str, deque] = {}
        self.last_stamp: dict[str, float] = {}
        self.alive: set[str] = set()
        self.sim_time = math.nan
        self.world_at: float | None = None  # arrival time of the newest world state
        self.world_token_seen = False
        self.untracked = 0  # messages on keys (or robots) beyond MAX_KEYS (MAX_ROBOTS)
        self.drops = DropCounter("monitor", keys=keys)
        self._lock = threading.Lock()

    def robot(self, rid: str) -> RobotView | None:
        """The view of robot ``rid``, made on first sight; None beyond :data:`MAX_ROBOTS`."""
        v = self.robots.get(rid)
        if v is None:
            if len(self.robots) >= MAX_ROBOTS:
                self.untracked += 1
                return None
            v = self.robots[rid] = RobotView(rid)
        return v

    def observe(self, key: str, payload: bytes, at: float) -> None:
        """One received message: decoded and checked (a malformed one is counted and dropped)."""
        with self._lock:
            q = self.arrivals.get(key)
            if q is None:
                if len(self.arrivals) >= MAX_KEYS:
                    self.untracked += 1
                    return
                q = self.arrivals[key] = deque()
            q.append(at)
            while q and at - q[0] > self.window:
                q.popleft()
            msg = self.drops.decode(key, payload)
            if msg is None:
                return
            robot = None
            try:
                parsed = self.keys.parse(key)
                robot = parsed.robot if parsed.robot != WORLD else None
            except Exception:  # decode accepted the key, so this does not happen; never crash on it
                return
            if isinstance(msg, WorldState):
                try:
                    entries = {rid: robot_entry(rid, r) for rid, r in msg.robots.items()}
                except ValueError as exc:
                    self.drops.drop(key, f"world state not drawable: {exc}")
                    return
                self.last_stamp[key] = msg.stamp
                self.sim_time = msg.stamp
                self.world_at = at
                for rid, (pose, goal, contact) in entries.items():
                    v = self.robot(rid)
                    if v is None:
                        continue
                    v.pose, v.in_contact = pose, contact
                    if goal is not None:
                        v.goal = goal
                return
            self.last_stamp[key] = msg.stamp
            v = self.robot(robot) if robot and isinstance(msg, (SenseRange, SenseTarget, WheelCommand)) else None
            if v is None:
                return
            if isinstance(msg, (SenseRange, SenseTarget)):
                v.sense_first.setdefault(round(msg.stamp, 6), at)
                if len(v.sense_first) > 64:
                    for s in sorted(v.sense_first)[:-64]:
                        del v.sense_first[s]
            elif isinstance(msg, WheelCommand):
                v.command = (msg.v_l, msg.v_r)
                v.command_stamp = msg.stamp
                first = v.sense_first.get(round(msg.stamp, 6))
                if first is not None:
                    v.latencies.append(at - first)

    def set_alive(self, tokens: set[str]) -> None:
        """The liveliness tokens alive now (of any run: ``<root>/<owner>/alive/<module>[/<run>]``)."""
        with self._lock:
            self.alive = set(tokens)
        if self._world_alive():
            self.world_token_seen = True

    def _world_alive(self) -> bool:
        return "server" in self._alive_modules().get(WORLD, set())

    def runs(self) -> list[str]:
        """The run ids in the liveliness tokens alive now."""
        out = set()
        for t in self.alive:
            try:
                run = self.keys.parse(t).run
            except Exception:
                continue
            if run:
                out.add(run)
        return sorted(out)

    def phase(self, now: float) -> str:
        """``waiting for the world``, ``running``, ``replay`` (world states with no world
        server alive), ``no world state for N s`` or ``run ended`` (the world server's token
        went away, or the states stopped with no module left)."""
        world_alive = self._world_alive()
        modules_alive = any(owner != WORLD for owner in self._alive_modules())
        if self.world_at is None:
            if self.world_token_seen and not world_alive:
                return "run ended"
            return "waiting for the world"
        age = now - self.world_at
        if age <= FRESH:
            return "running" if world_alive or modules_alive else "replay"
        if self.world_token_seen and not world_alive:
            return "run ended"
        if age > STALE_AFTER:
            if not world_alive and not modules_alive:
                return "run ended"
            return f"no world state for {age:.0f} s"
        return "running"

    def key_stats(self, now: float) -> list[HzStats]:
        with self._lock:
            return [hz_stats(k, [t for t in q if now - t <= self.window], now) if q else
                    HzStats(k, 0, 0.0, math.nan, math.nan, math.nan, math.nan, math.inf)
                    for k, q in sorted(self.arrivals.items())]

    def _alive_modules(self) -> dict[str, set[str]]:
        """{owner: module names} of the liveliness tokens alive now (parsed by the key space)."""
        out: dict[str, set[str]] = {}
        for t in self.alive:
            try:
                parsed = self.keys.parse(t)
            except Exception:
                continue
            if parsed.kind is KeyKind.ALIVE and parsed.robot and parsed.module:
                out.setdefault(parsed.robot, set()).add(parsed.module)
        return out

    def modules_alive(self, rid: str) -> tuple[int, list[str]]:
        """(number alive, the names of the missing ones) of a robot's modules."""
        names = self._alive_modules().get(rid, set())
        expected = self.keys.module_names()
        return len(names & set(expected)), [m for m in expected if m not in names]


# --------------------------------------------------------------------------- drawing


def _fit(text: str, width: int, align: str = ">") -> str:
    """``text`` padded or cut (with an ellipsis) to exactly ``width`` columns."""
    if len(text) > width:
        text = text[:max(0, width - 1)] + "…"
    return f"{text:{align}{width}}"


def _num(x: float, width: int, digits: int) -> str:
    return _fit("-" if not math.isfinite(x) else f"{x:.{digits}f}", width)


_STATUS_STYLE = {"moving": "green", "reached": "bold cyan", "stopped": "yellow", "waiting": "dim"}
_PHASE_STYLE = {"running": "bold green", "replay": "bold green", "run ended": "bold red", "waiting for the world": "bold yellow"}
_HEADER = (f"{_fit('robot', 6, '<')} {_fit('x', 6)} {_fit('y', 6)} {_fit('theta', 5)} {_fit('goal', 13)} "
           f"{_fit('status', 7, '<')} {_fit('v_l', 6)} {_fit('v_r', 6)} {_fit('mods', 5)} {_fit('lat ms', 11)}")


def render(state: MonitorState, now: float, *, robots: set[str] | None = None, key_filter: Callable[[str], bool] | None
           = None, endpoint: str = "", width: int = WIDTH) -> Group:
    """The view as a rich renderable, every line at most ``width`` (80) columns: the run's
    phase, one row per robot (only ``robots`` if given), and, with ``key_filter``, the
    rate, age and stamp of every matching key."""
    phase = state.phase(now)
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
    lines: list[Text] = [head]
    if phase == "waiting for the world":
        lines.append(Text("waiting for the world server's first state (start a run or `cekm replay LOG`)",
                          style="dim", no_wrap=True, overflow="ellipsis"))
    shown = [r for r in sorted(state.robots) if robots is None or r in robots]
    if robots is not None:
        for r in sorted(robots - set(state.robots)):
            lines.append(Text(f"{r}: not seen", style="dim", no_wrap=True, overflow="ellipsis"))
    if shown:
        lines.append(Text(_HEADER, style="bold", no_wrap=True, overflow="ellipsis"))
    expected = len(state.keys.module_names())
    for rid in shown:
        v = state.robots[rid]
        x, y, th = v.pose if v.pose else (math.nan,) * 3
        goal = f"({v.goal[0]:.2f},{v.goal[1]:.2f})" if v.goal else "-"
        vl, vr = v.command if v.command else (math.nan, math.nan)
        n, missing = state.modules_alive(rid)
        lat = f"{v.latency_ms(0.5):.1f}/{v.latency_ms(0.99):.1f}" if v.latencies else "-"
        row = Text(no_wrap=True, overflow="ellipsis")
        row.append(f"{_fit(rid, 6, '<')} {_num(x, 6, 3)} {_num(y, 6, 3)} {_num(th, 5, 2)} {_fit(goal, 13)} ")
        row.append(_fit(v.status, 7, "<"), style=_STATUS_STYLE.get(v.status, ""))
        row.append(f" {_num(vl, 6, 3)} {_num(vr, 6, 3)} ")
        row.append(_fit(f"{n}/{expected}", 5), style="" if n == expected else "bold red")
        row.append(f" {_fit(lat, 11)}")
        lines.append(row)
        if missing and n:
            lines.append(Text(f"       missing: {', '.join(missing)}", style="red", no_wrap=True,
                              overflow="ellipsis"))
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
    for rid in sorted(state.robots):
        if robots is not None and rid not in robots:
            continue
        v = state.robots[rid]
        n, missing = state.modules_alive(rid)
        out["robots"][rid] = {"pose": v.pose, "goal": v.goal, "in_contact": v.in_contact, "status": v.status,
                              "command": v.command, "modules_alive": n, "modules_missing": missing,
                              "latency_ms_p50": v.latency_ms(0.5), "latency_ms_p99": v.latency_ms(0.99)}
    if key_filter is not None:
        out["keys"] = [{"key": s.key, "rate_hz": s.rate, "age_s": s.age, "stamp": state.last_stamp.get(s.key)}
                       for s in state.key_stats(now) if key_filter(s.key)]
    return out


def render_text(state: MonitorState, now: float, width: int = WIDTH, **kw: Any) -> str:
    """The view as plain text, as an 80-column terminal shows it (for --once, pipes, tests)."""
    console = Console(width=width, record=True, file=io.StringIO(), color_system=None, force_terminal=False)
    console.print(render(state, now, width=width, **kw))
    return console.export_text().rstrip("\n")


def run_monitor(session: zenoh.Session, root: str = "cekm", refresh: float = 0.5, once_after: float | None = None,
                out: Callable[[str], None] = print, *, robots: set[str] | None = None,
                key_filter: Callable[[str], bool] | None = None, endpoint: str = "",
                stop: threading.Event | None = None, as_json: bool = False) -> MonitorState:
    """Subscribe to the run and draw it until Ctrl-C or ``stop`` (or, with ``once_after``,
    print one snapshot after that many seconds and return)."""
    keys = KeySpace(root=root)
    state = MonitorState(keys)
    tokens: set[str] = set()
    lock = threading.Lock()
    stop = stop or threading.Event()

    def on_sample(sample: zenoh.Sample) -> None:  # Zenoh's thread: record and return
        if sample.kind == zenoh.SampleKind.PUT:
            state.observe(str(sample.key_expr), sample.payload.to_bytes(), time.monotonic())

    def on_token(sample: zenoh.Sample) -> None:
        with lock:
            if sample.kind == zenoh.SampleKind.DELETE:
                tokens.discard(str(sample.key_expr))
            else:
                tokens.add(str(sample.key_expr))
        state.set_alive(current_tokens())

    def current_tokens() -> set[str]:
        with lock:
            return set(tokens)

    sub = session.declare_subscriber(keys.everything(), on_sample)
    live = session.liveliness().declare_subscriber(keys.alive_all(), on_token, history=True)
    kw = {"robots": robots, "key_filter": key_filter, "endpoint": endpoint}
    try:
        if once_after is not None:
            stop.wait(once_after)  # the observation window of a one-shot snapshot
            state.set_alive(current_tokens())
            if as_json:
                from .jsonout import json_line

                out(json_line(snapshot(state, time.monotonic(), robots=robots, key_filter=key_filter)))
            else:
                out(render_text(state, time.monotonic(), **kw))
            return state
        from rich.live import Live

        with Live(render(state, time.monotonic(), **kw), refresh_per_second=max(1, round(1 / refresh)),
                  screen=False, auto_refresh=False) as view:
            while not stop.is_set():
                state.set_alive(current_tokens())
                view.update(render(state, time.monotonic(), **kw), refresh=True)
                stop.wait(refresh)
    except KeyboardInterrupt:
        return state
    finally:
        sub.undeclare()
        live.undeclare()
    return state
