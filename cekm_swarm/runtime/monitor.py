"""``cekm monitor``: a live terminal view of a run, attachable from any terminal.

Per robot: pose, goal, status (moving / stopped / reached), last wheel command, its
modules' liveliness, and the sense-to-command latency (wall time from the first sensor
message of a tick to the motor command stamped with the same tick). Above them, the
run's phase: waiting for the world, running, no world state for a while, or ended (the
world server's liveliness token went away). Per key, with a filter: rate, age, stamp.
It fits an 80-column terminal and works the same on a live run and on ``cekm replay``.
In a tracking run (targets in the world state, and robots' ``share`` or
``sense/targets`` seen) a tracking block says, per target, which robots observe it, how
many targets at least one robot observes (the instantaneous A), and per robot how many
targets it sees.

:class:`MonitorState` is the pure part (fed with key, payload and arrival time, tested
without Zenoh); what it draws comes typed from the protocol's decoder (a ``world/state``
whose robots lack a finite x, y or theta does not decode: it is dropped and counted like
any malformed message). :func:`render` draws
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

from cekm_swarm.protocol import (
    DEFAULT_KEYS,
    WORLD,
    DropCounter,
    KeyKind,
    KeySpace,
    SenseRange,
    SenseTarget,
    SenseTargets,
    Share,
    WheelCommand,
    WorldState,
)

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

OBSERVATION_SPAN = 2.0
"""Sim seconds: a robot's share or sense/targets older than this against the newest world
state no longer counts as observing (a robot whose modules died stops observing)."""

MAX_TARGET_LINES = 12
"""Target rows the tracking block draws; the rest are summed up in one line."""


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


@dataclass
class Observation:
    """The targets one robot observes, from its latest message of one ``source``."""

    stamp: float
    targets: frozenset[str]
    source: str  # "share" (what the robot reports) or "sense" (what the world says it senses)


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
        self.targets: dict[str, tuple[float, float]] = {}  # target id -> (x, y), from the newest world state
        self.shares: dict[str, Observation] = {}  # robot -> its latest share
        self.sensed: dict[str, Observation] = {}  # robot -> its latest sense/targets
        self.untracked = 0  # messages on keys (or robots) beyond MAX_KEYS (MAX_ROBOTS)
        self.drops = DropCounter("monitor", keys=keys)
        self.expected: tuple[str, ...] | None = None  # one robot's nodes, from the run's graph (None: not known)
        self.graph: str | None = None  # the run's graph's name
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
            if isinstance(msg, WorldState):  # typed: every robot has a finite pose (protocol.messages)
                if math.isfinite(self.sim_time) and msg.stamp < self.sim_time:  # a new run or replay
                    self.shares.clear()
                    self.sensed.clear()
                self.targets = {tid: (t.x, t.y) for tid, t in msg.targets.items()}
                self.last_stamp[key] = msg.stamp
                self.sim_time = msg.stamp
                self.world_at = at
                for rid, r in msg.robots.items():
                    v = self.robot(rid)
                    if v is None:
                        continue
                    v.pose, v.in_contact = (r.x, r.y, r.theta), r.in_contact
                    if r.goal is not None:
                        v.goal = r.goal
                return
            self.last_stamp[key] = msg.stamp
            if robot and isinstance(msg, (Share, SenseTargets)):
                book = self.shares if isinstance(msg, Share) else self.sensed
                if robot in book or self.robot(robot) is not None:
                    book[robot] = Observation(msg.stamp, frozenset(msg.targets),
                                              "share" if isinstance(msg, Share) else "sense")
                return
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

    def is_tracking(self) -> bool:
        """A tracking run: targets in the world state, and shares or sense/targets seen."""
        return bool(self.targets) and bool(self.shares or self.sensed)

    def observations(self) -> dict[str, Observation]:
        """{robot: what it observes now}: the newer (by stamp) of its latest share and its
        latest sense/targets (the share on a tie), skipping those older than
        :data:`OBSERVATION_SPAN` sim seconds against the newest world state."""
        with self._lock:
            out: dict[str, Observation] = {}
            for rid in set(self.shares) | set(self.sensed):
                cands = [o for o in (self.shares.get(rid), self.sensed.get(rid)) if o is not None]
                best = max(cands, key=lambda o: (o.stamp, o.source == "share"))
                if math.isfinite(self.sim_time) and self.sim_time - best.stamp > OBSERVATION_SPAN:
                    continue
                out[rid] = best
            return out

    def tracking(self, robots: set[str] | None = None) -> dict[str, Any]:
        """The tracking status: ``targets`` {id: {x, y, observed_by}} (observers among
        ``robots`` if given), ``observed`` (targets observed by at least one robot of the
        whole team) out of ``total`` (the world's targets), ``A`` their ratio, and
        ``per_robot`` {robot: targets it sees, source}."""
        obs = self.observations()
        with self._lock:
            targets = dict(self.targets)
        by: dict[str, list[str]] = {tid: [] for tid in targets}
        for rid in sorted(obs):
            for tid in obs[rid].targets:
                by.setdefault(tid, []).append(rid)
        observed = sum(1 for tid in targets if by[tid])
        shown = (lambda r: robots is None or r in robots)
        return {
            "targets": {tid: {"x": targets[tid][0] if tid in targets else None,
                              "y": targets[tid][1] if tid in targets else None,
                              "observed_by": [r for r in by[tid] if shown(r)]} for tid in sorted(by)},
            "observed": observed, "total": len(targets), "A": observed / len(targets) if targets else None,
            "per_robot": {rid: {"sees": len(o.targets), "source": o.source} for rid, o in sorted(obs.items())
                          if shown(rid)},
        }

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
        """(number alive, the names of the missing ones) of a robot's nodes: those of the
        run's graph (all that are alive when the graph is not known)."""
        names = self._alive_modules().get(rid, set())
        if self.expected is None:
            return len(names), []
        return len(names & set(self.expected)), [m for m in self.expected if m not in names]

    def world_run(self) -> str | None:
        """The run id of the world server alive now (its token's last chunk)."""
        for t in self.alive:
            try:
                parsed = self.keys.parse(t)
            except Exception:
                continue
            if parsed.kind is KeyKind.ALIVE and parsed.robot == WORLD and parsed.run:
                return parsed.run
        return None


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
        row.append(_fit(v.status, 7, "<"), style=_STATUS_STYLE.get(v.status, ""))
        row.append(f" {_num(vl, 6, 3)} {_num(vr, 6, 3)} ")
        row.append(_fit(f"{n}/{expected}" if expected is not None else f"{n}", 5),
                   style="" if expected is None or n == expected else "bold red")
        row.append(f" {_fit(lat, 11)}")
        lines.append(row)
        if missing and n:
            lines.append(Text(f"       missing: {', '.join(missing)}", style="red", no_wrap=True,
                              overflow="ellipsis"))
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
    for rid in sorted(state.robots):
        if robots is not None and rid not in robots:
            continue
        v = state.robots[rid]
        n, missing = state.modules_alive(rid)
        out["robots"][rid] = {"pose": v.pose, "goal": v.goal, "in_contact": v.in_contact, "status": v.status,
                              "command": v.command, "modules_alive": n, "modules_missing": missing,
                              "latency_ms_p50": v.latency_ms(0.5), "latency_ms_p99": v.latency_ms(0.99)}
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
    seen_run: list[str | None] = [None]

    def learn_graph() -> None:
        """The nodes each robot should have: from the run's graph, asked again for a new run."""
        run = state.world_run()
        if run is not None and run != seen_run[0]:
            seen_run[0] = run
            from .rungraph import fetch_run_graph

            g = fetch_run_graph(session, keys.world_graph())
            state.expected, state.graph = (g.nodes, g.name) if g is not None else (None, None)

    try:
        if once_after is not None:
            stop.wait(once_after)  # the observation window of a one-shot snapshot
            state.set_alive(current_tokens())
            learn_graph()
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
                learn_graph()
                view.update(render(state, time.monotonic(), **kw), refresh=True)
                stop.wait(refresh)
    except KeyboardInterrupt:
        return state
    finally:
        sub.undeclare()
        live.undeclare()
    return state
