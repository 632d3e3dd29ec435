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

:class:`MonitorState` (:mod:`.monitor_state`) is the pure part, fed with key, payload
and arrival time and tested without Zenoh; :func:`render`, :func:`render_text` and
:func:`snapshot` (:mod:`.monitor_view`) draw it; :func:`run_monitor` (here) is the thin
shell that subscribes and redraws. All their names are importable from here.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any

import zenoh
from rich.live import Live

from cekm_swarm.protocol import KeySpace

from .jsonout import json_line
from .monitor_state import (
    FRESH,
    MAX_KEYS,
    MAX_ROBOTS,
    OBSERVATION_SPAN,
    STALE_AFTER,
    MonitorState,
    Observation,
    RobotView,
)
from .monitor_view import MAX_TARGET_LINES, WIDTH, render, render_text, snapshot
from .rungraph import fetch_run_graph

__all__ = ["FRESH", "MAX_KEYS", "MAX_ROBOTS", "MAX_TARGET_LINES", "OBSERVATION_SPAN", "STALE_AFTER", "WIDTH",
           "MonitorState", "Observation", "RobotView", "render", "render_text", "run_monitor", "snapshot"]


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
    kw: dict[str, Any] = {"robots": robots, "key_filter": key_filter, "endpoint": endpoint}
    seen_run: list[str | None] = [None]

    def learn_graph() -> None:
        """The nodes each robot should have: from the run's graph, asked again for a new run."""
        run = state.world_run()
        if run is not None and run != seen_run[0]:
            seen_run[0] = run
            g = fetch_run_graph(session, keys.world_graph())
            state.expected, state.graph = (g.nodes, g.name) if g is not None else (None, None)

    try:
        if once_after is not None:
            stop.wait(once_after)  # the observation window of a one-shot snapshot
            state.set_alive(current_tokens())
            learn_graph()
            if as_json:
                out(json_line(snapshot(state, time.monotonic(), robots=robots, key_filter=key_filter)))
            else:
                out(render_text(state, time.monotonic(), **kw))
            return state
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
