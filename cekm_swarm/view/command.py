"""``cekm view``: serve the live view of a running or replayed run on a local port."""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import click
import zenoh

from cekm_swarm.cli_support import seed_option
from cekm_swarm.errors import CekmError
from cekm_swarm.protocol import KeySpace
from cekm_swarm.runtime.mcap_log import is_complete
from cekm_swarm.runtime.mcap_read import read_geometry
from cekm_swarm.runtime.tool_session import _connect_options, _session


def _geometry(scenario: str | None, log: Path | None, seed: int | None) -> tuple[dict[str, Any], list[float]]:
    """(static geometry, sensing radii) from a scenario or from a run's MCAP log."""
    from world import ScenarioError, load_scenario  # noqa: PLC0415 -- lazy: cekm --help loads no world (pymunk)
    from world.sim import World  # noqa: PLC0415 -- lazy: cekm --help loads no world (pymunk)

    if log is not None:
        try:
            complete = is_complete(log)
        except CekmError as exc:  # a log it cannot read: a failure (exit 1), as in `cekm log info`
            raise click.ClickException(str(exc)) from None
        geometry = read_geometry(log)
        if geometry is None:
            why = "" if complete else " (an unfinished log has no index: `cekm log recover` it first)"
            raise click.BadParameter(f"{log}: no geometry in the log's metadata{why}", param_hint="--log")
        return geometry, sensing_radii(geometry, geometry.get("sensor_range"), geometry.get("target_range"))
    assert scenario is not None  # a scenario, or a log (above)
    try:
        sc = load_scenario(scenario)
    except ScenarioError as exc:
        raise click.BadParameter(str(exc), param_hint="SCENARIO") from None
    geometry = World(sc, seed=seed if seed is not None else sc.seed).static_geometry()
    return geometry, sensing_radii(geometry, sc.sensor_range, sc.target_range)


def sensing_radii(geometry: dict[str, Any], sensor_range: float | None, target_range: float | None) -> list[float]:
    """The circles the view draws about each robot: the obstacle sensors' reach from the
    robot's centre and the target sensing range (each when known and finite)."""
    r = geometry.get("body_radius", 0.03)
    out = []
    if isinstance(sensor_range, (int, float)) and math.isfinite(sensor_range):
        out.append(r + sensor_range)
    if isinstance(target_range, (int, float)) and math.isfinite(target_range):
        out.append(target_range)
    return out


def _lattice(session: Any, model_path: Path | None, root: str, timeout: float) -> Any:
    """The motor map's input weights w: from --model, else from the run's model queryable
    (None if nothing answers within ``timeout`` s: neurons are then placed by index)."""
    from cekm_swarm.models.io import load_model, load_model_bytes  # noqa: PLC0415 -- lazy: cekm --help loads no model code
    from cekm_swarm.runtime.model_service import fetch_model_bytes  # noqa: PLC0415 -- lazy: cekm --help loads no hashlib

    if model_path is not None:
        return load_model(model_path).w
    key = KeySpace(root=root).world_model()
    try:
        return load_model_bytes(fetch_model_bytes(session, key, timeout=timeout), key).w
    except CekmError as exc:
        click.echo(f"no model on {key} ({exc}); neurons placed by index", err=True)
        return None


@click.command("view")
@click.argument("scenario", required=False)
@click.option("--log", "log", type=click.Path(dir_okay=False, exists=True, path_type=Path),
              help="Take the arena from this run's MCAP log (e.g. for `cekm replay`) instead of a scenario.")
@seed_option()
@click.option("--robot", help="Robot whose fields are drawn (default: the first).")
@click.option("--model", "model_path", type=click.Path(dir_okay=False, exists=True, path_type=Path),
              help="Model file for the lattice (default: ask the run's model queryable).")
@_connect_options
@click.option("--root", default="cekm", show_default=True, help="Key-space root.")
@click.option("--http", "http_port", default=8470, show_default=True, type=click.IntRange(0, 65535),
              help="Local HTTP port of the page (0: any free one).")
@click.option("--host", default="127.0.0.1", show_default=True, help="Address the page is served on.")
@click.option("--foxglove", "foxglove_port", type=click.IntRange(0, 65535), default=None, metavar="PORT",
              help="Also serve the view channels live on a Foxglove WebSocket server on this port "
                   "(for the Foxglove desktop app).")
def view_cmd(scenario: str | None, log: Path | None, seed: int | None, robot: str | None, model_path: Path | None,
             endpoint: str | None, config_file: Path | None, root: str, http_port: int, host: str,
             wait_s: float, foxglove_port: int | None) -> None:
    """A live 2-D view of a running or replayed run in the browser: arena, obstacles,
    robots with headings, paths and sensing circles, targets, and for one robot its
    target field, obstacle fields and motor-EKM activity (the paper's Fig. 4).

    The arena is the run's (the world server serves it): without SCENARIO the view waits
    for a run and draws its arena; a SCENARIO that is not the run's is drawn until the run
    is seen, then replaced by the run's, with a warning."""
    from world.draw import robot_colours  # noqa: PLC0415 -- lazy: cekm --help loads no world (pymunk)

    from .live import LiveView  # noqa: PLC0415 -- lazy: cekm --help loads no view server
    from .server import ViewServer  # noqa: PLC0415 -- lazy: cekm --help loads no view server

    if scenario is not None and log is not None:
        raise click.UsageError("give a SCENARIO (name or TOML file) or --log RUN.mcap, not both")
    geometry, ranges = _geometry(scenario, log, seed) if scenario or log else (None, [])
    ids = [r["id"] for r in (geometry or {}).get("robots", [])]
    if robot is not None and geometry is not None and robot not in ids:
        raise click.BadParameter(f"{robot!r} is not a robot of this arena ({', '.join(ids)})", param_hint="--robot")
    with _session(endpoint, config_file, wait_s) as session:
        keys = KeySpace(root=root)
        if geometry is None:  # the run's arena: wait for a world server to serve it
            geometry = _run_geometry(session, keys, wait_s)
            if geometry is None:
                raise click.ClickException(f"no run's world server answered on {keys.world_geometry()} within "
                                           f"{wait_s:g} s: start a run, or give a SCENARIO or --log")
            ranges = sensing_radii(geometry, geometry.get("sensor_range"), geometry.get("target_range"))
            ids = [r["id"] for r in geometry.get("robots", [])]
        view = LiveView(geometry, robot=robot, ranges=ranges, colours=robot_colours(sorted(ids)), keys=keys)
        fox = None

        def observe(s: Any) -> None:
            key, data = str(s.key_expr), s.payload.to_bytes()
            view.observe(key, data)
            if fox is not None:  # a user's typed messages, as JSON with their schema
                fox.observe(key, data)

        sub = session.declare_subscriber(f"{root}/**", observe)
        try:
            server = ViewServer(view, host, http_port)
        except OSError as exc:
            raise click.ClickException(f"--http {http_port}: cannot serve on {host}: {exc.strerror}") from None
        if foxglove_port is not None:
            fox = _foxglove(view, host, foxglove_port, server)
        click.echo(f"live view on {server.url} (Ctrl-C to stop)", err=True)
        # a new run starts the view afresh as soon as its world's token is seen (on Zenoh's
        # thread, before the run's first state), not after the graph is fetched: by then a
        # lockstep run can be seconds into its sim time, and its path would be lost; the
        # first token seen names the run the view joined
        runs = RunWatch(session, keys, on_run=view.run_seen, on_end=view.run_ended)
        view.w = _lattice(session, model_path, root, timeout=5.0)
        try:
            while True:
                run = runs.changed(timeout=0.5)
                if run is not None:
                    _new_run(session, keys, view, fox, run, own_arena=log is None)
        except KeyboardInterrupt:
            pass
        finally:
            runs.close()
            if fox is not None:
                fox.close()
            server.close()
            sub.undeclare()


def _foxglove(view: Any, host: str, port: int, server: Any) -> Any:
    """The live Foxglove WebSocket server of ``--foxglove PORT`` (the page's server closed
    and a failure raised when it cannot serve)."""
    from .foxglove_live import FoxgloveLive  # noqa: PLC0415 -- lazy: cekm --help loads no foxglove server

    try:
        fox = FoxgloveLive(view, host, port)
    except Exception as exc:  # noqa: BLE001 - foxglove's own error types; the page still serves
        server.close()
        raise click.ClickException(f"--foxglove {port}: cannot serve on {host}: {exc}") from None
    click.echo(f"foxglove WebSocket server on ws://{host}:{fox.port}", err=True)
    return fox


def _new_run(session: Any, keys: KeySpace, view: Any, fox: Any, run: str, own_arena: bool) -> None:
    """A new run seen: the arena it runs in (unless the view draws a log's, ``own_arena``
    False), the graph it runs, and its user messages' schemas for Foxglove."""
    from cekm_swarm.runtime.record import fetch_json  # noqa: PLC0415 -- lazy: cekm --help loads no recorder
    from cekm_swarm.runtime.rungraph import fetch_run_graph  # noqa: PLC0415 -- lazy: cekm --help loads no graph reader
    from world.draw import robot_colours  # noqa: PLC0415 -- lazy: cekm --help loads no world (pymunk)

    g = fetch_json(session, keys.world_geometry()) if own_arena else None
    if g is not None and "bounds" in g and g.get("name") != view.geometry.get("name"):
        given = view.geometry.get("name")
        gids = sorted(r["id"] for r in g.get("robots", []))
        view.set_geometry(g, sensing_radii(g, g.get("sensor_range"), g.get("target_range")),
                          robot_colours(gids))  # drawn before it is said
        click.echo(f"the run {run} is of arena {g.get('name')!r}, not {given!r}: drawing the run's", err=True)
    graph = fetch_run_graph(session, keys.world_graph())
    view.set_graph(None if graph is None else f"{graph.name} ({graph.controller})")
    if fox is not None:
        fox.set_schemas((fetch_json(session, keys.world_graph()) or {}).get("schemas") or {})


def _run_geometry(session: Any, keys: KeySpace, wait_s: float) -> dict[str, Any] | None:
    """The arena the run's world server serves, waiting up to ``wait_s`` s for one."""
    from cekm_swarm.runtime.record import fetch_json  # noqa: PLC0415 -- lazy: cekm --help loads no recorder

    end = time.monotonic() + wait_s
    while True:
        g = fetch_json(session, keys.world_geometry(), timeout=1.0)
        if g is not None and "bounds" in g:
            return g
        if time.monotonic() >= end:
            return None
        time.sleep(0.5)


class RunWatch:
    """The run id of the world server alive on the router, from its liveliness token
    (``<root>/world/alive/server/<run>``); :meth:`changed` returns a new one once, and
    ``on_run(run)`` is called on Zenoh's thread for every token seen."""

    def __init__(self, session: Any, keys: KeySpace, on_run: Callable[[str], None] | None = None,
                 on_end: Callable[[str], None] | None = None) -> None:
        self._lock = threading.Lock()
        self._event = threading.Event()
        self._current: str | None = None
        self._seen: str | None = None
        any_run = keys.with_run(None)

        def on_token(sample: Any) -> None:  # Zenoh's thread: note it and return
            try:
                run = any_run.parse(str(sample.key_expr)).run
            except CekmError:
                return
            if sample.kind != zenoh.SampleKind.PUT:  # the world server went away: its run ended
                if run and on_end is not None:
                    on_end(run)
                return
            if run:
                with self._lock:
                    self._current = run
                if on_run is not None:
                    on_run(run)
                self._event.set()

        self._sub = session.liveliness().declare_subscriber(any_run.world_alive_any_run(), on_token, history=True)

    def changed(self, timeout: float) -> str | None:
        self._event.wait(timeout)
        self._event.clear()
        with self._lock:
            run = self._current
        if run is not None and run != self._seen:
            self._seen = run
            return run
        return None

    def close(self) -> None:
        self._sub.undeclare()
