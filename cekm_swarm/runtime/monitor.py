"""``cekm monitor``: a live terminal view of a run, attachable from any terminal.

Per robot: pose, goal, status (moving / stopped / reached), last wheel command, its
modules' liveliness, and the sense-to-command latency (wall time from the first sensor
message of a tick to the motor command stamped with the same tick). Per key: rate and
age. It works the same on a live run and on ``cekm replay``.

:class:`MonitorState` is the pure part (fed with key, payload and arrival time, tested
without Zenoh); :func:`run_monitor` is the thin shell that subscribes and draws.
"""

from __future__ import annotations

import math
import threading
import time
from collections import deque
from dataclasses import dataclass, field

from cekm_swarm.protocol import DEFAULT_KEYS, DropCounter, KeySpace, SenseRange, SenseTarget, WheelCommand, WorldState

from .topics import HzStats, hz_stats

MODULES = ("target", *(f"obstacle-{j}" for j in range(12)), "motor")


@dataclass
class RobotView:
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
        self.drops = DropCounter("monitor", keys=keys)
        self._lock = threading.Lock()

    def robot(self, rid: str) -> RobotView:
        if rid not in self.robots:
            self.robots[rid] = RobotView(rid)
        return self.robots[rid]

    def observe(self, key: str, payload: bytes, at: float) -> None:
        """One received message: decoded (a malformed one is counted and dropped)."""
        with self._lock:
            q = self.arrivals.setdefault(key, deque())
            q.append(at)
            while q and at - q[0] > self.window:
                q.popleft()
            msg = self.drops.decode(key, payload)
            if msg is None:
                return
            self.last_stamp[key] = msg.stamp
            parsed = self.keys.parse(key)
            if parsed.robot == "world":
                parsed = type(parsed)(parsed.kind)
            if isinstance(msg, WorldState):
                self.sim_time = msg.stamp
                for rid, r in msg.robots.items():
                    v = self.robot(rid)
                    v.pose = (float(r["x"]), float(r["y"]), float(r["theta"]))
                    v.in_contact = bool(r.get("in_contact", False))
                    if r.get("goal") is not None:
                        v.goal = (float(r["goal"][0]), float(r["goal"][1]))
            elif isinstance(msg, (SenseRange, SenseTarget)) and parsed.robot:
                v = self.robot(parsed.robot)
                v.sense_first.setdefault(round(msg.stamp, 6), at)
                if len(v.sense_first) > 64:
                    for s in sorted(v.sense_first)[:-64]:
                        del v.sense_first[s]
            elif isinstance(msg, WheelCommand) and parsed.robot:
                v = self.robot(parsed.robot)
                v.command = (msg.v_l, msg.v_r)
                v.command_stamp = msg.stamp
                first = v.sense_first.get(round(msg.stamp, 6))
                if first is not None:
                    v.latencies.append(at - first)

    def set_alive(self, tokens: set[str]) -> None:
        with self._lock:
            self.alive = set(tokens)

    def key_stats(self, now: float) -> list[HzStats]:
        with self._lock:
            return [hz_stats(k, [t for t in q if now - t <= self.window], now) if q else
                    HzStats(k, 0, 0.0, math.nan, math.nan, math.nan, math.nan, math.inf)
                    for k, q in sorted(self.arrivals.items())]

    def modules_alive(self, rid: str) -> tuple[int, list[str]]:
        """(number alive, the names of the missing ones) of a robot's 14 modules."""
        prefix = f"{self.keys.root}/{rid}/alive/"
        names = {t[len(prefix):] for t in self.alive if t.startswith(prefix)}
        return len(names & set(MODULES)), [m for m in MODULES if m not in names]


def render_text(state: MonitorState, now: float) -> str:
    """The view as plain text (for --once, pipes and tests)."""
    lines = [f"sim time {state.sim_time:.2f} s    malformed messages dropped: {state.drops.total}"]
    lines.append(f"{'robot':<6} {'x':>7} {'y':>7} {'theta':>6} {'goal':>15} {'status':<8} {'cmd v_l,v_r':>15} "
                 f"{'modules':>8} {'lat p50/p99 ms':>15}")
    for rid in sorted(state.robots):
        v = state.robots[rid]
        x, y, th = v.pose if v.pose else (math.nan,) * 3
        goal = f"({v.goal[0]:.2f}, {v.goal[1]:.2f})" if v.goal else "-"
        cmd = f"{v.command[0]:+.3f},{v.command[1]:+.3f}" if v.command else "-"
        n, missing = state.modules_alive(rid)
        mods = f"{n}/14"
        lat = f"{v.latency_ms(0.5):.1f}/{v.latency_ms(0.99):.1f}"
        lines.append(f"{rid:<6} {x:7.3f} {y:7.3f} {th:6.2f} {goal:>15} {v.status:<8} {cmd:>15} {mods:>8} {lat:>15}")
        if missing and n:
            lines.append(f"       missing modules: {', '.join(missing)}")
    lines.append("")
    lines.append(f"{'key':<32} {'rate Hz':>8} {'age s':>7} {'stamp':>9}")
    for s in state.key_stats(now):
        stamp = state.last_stamp.get(s.key, math.nan)
        lines.append(f"{s.key:<32} {s.rate:8.2f} {s.age:7.2f} {stamp:9.3f}")
    return "\n".join(lines)


def run_monitor(session, root: str = "cekm", refresh: float = 0.5, once_after: float | None = None,
                out=print) -> MonitorState:
    """Subscribe to the run and draw it until Ctrl-C (or, with ``once_after``, print one
    snapshot after that many seconds and return)."""
    keys = KeySpace(root=root)
    state = MonitorState(keys)
    tokens: set[str] = set()
    lock = threading.Lock()

    def on_sample(sample) -> None:  # Zenoh's thread: record and return
        state.observe(str(sample.key_expr), sample.payload.to_bytes(), time.monotonic())

    def on_token(sample) -> None:
        import zenoh

        with lock:
            if sample.kind == zenoh.SampleKind.DELETE:
                tokens.discard(str(sample.key_expr))
            else:
                tokens.add(str(sample.key_expr))

    sub = session.declare_subscriber(f"{root}/**", on_sample)
    live = session.liveliness().declare_subscriber(f"{root}/*/alive/*", on_token, history=True)
    try:
        if once_after is not None:
            time.sleep(once_after)  # the observation window of a one-shot snapshot
            with lock:
                state.set_alive(set(tokens))
            out(render_text(state, time.monotonic()))
            return state
        from rich.live import Live
        from rich.text import Text

        with Live(Text(""), refresh_per_second=max(1, int(1 / refresh)), screen=False) as view:
            while True:
                with lock:
                    state.set_alive(set(tokens))
                view.update(Text(render_text(state, time.monotonic())))
                time.sleep(refresh)
    except KeyboardInterrupt:
        return state
    finally:
        sub.undeclare()
        live.undeclare()
