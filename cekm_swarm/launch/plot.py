"""Draw a run from its MCAP log: the arena (the geometry the world server stores in the
log's metadata), each robot's path from ``world/state``, goals and final poses; in a
tracking run also the targets' paths and the robots' sensing circles, as ``cekm run``
draws them (the paper's Fig. 13)."""

from __future__ import annotations

from pathlib import Path
from typing import Any, cast

from cekm_swarm.protocol import DEFAULT_ROOT, KeyKind, KeySpace, MessageError, WorldState, decode
from cekm_swarm.runtime.mcap_log import log_root, read_messages, without_resends
from cekm_swarm.runtime.mcap_read import read_geometry


def read_run(path: str | Path, keys: KeySpace | None = None) -> dict[str, Any]:
    """Per robot the poses (t, x, y, theta) and per target the positions (x, y) from
    ``world/state``, and the last state; ``keys``: default, the log's own root."""
    if keys is None:
        keys = KeySpace(log_root(path) or DEFAULT_ROOT)
    paths: dict[str, list[tuple[float, float, float, float]]] = {}
    target_paths: dict[str, list[tuple[float, float]]] = {}
    last = None
    state_key = keys.world_state()
    for m in without_resends(read_messages(path, topics=[state_key])):  # one state a tick
        try:
            msg = cast(WorldState, decode(KeyKind.WORLD_STATE, m.data, keys=keys))
        except MessageError:
            continue
        for rid, r in msg.robots.items():
            paths.setdefault(rid, []).append((msg.stamp, r["x"], r["y"], r["theta"]))
        for tid, tg in msg.targets.items():
            target_paths.setdefault(tid, []).append((tg["x"], tg["y"]))
        last = msg
    state = None
    if last is not None:
        state = {"time": last.stamp, "robots": last.robots, "targets": last.targets, "obstacles": last.obstacles}
    return {"paths": paths, "target_paths": target_paths, "state": state, "geometry": read_geometry(path)}


def plot_log(path: str | Path, title: str | None = None, outcome: dict[str, Any] | None = None):
    """A matplotlib figure of the run in the log at ``path``: one colour per robot for its
    path, start and goal, time marks along the paths, axes in metres, the legend outside
    the arena and the limits fitted to what the robots covered."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from world.draw import draw_paths, draw_tracking, draw_world, figure_size, fit_bounds, legend_outside, robot_colours  # noqa: PLC0415 -- lazy: matplotlib, pymunk, world

    run = read_run(path)
    geometry = run["geometry"]
    colours = robot_colours(sorted(set(run["paths"]) | {r["id"] for r in (geometry or {}).get("robots", [])}))
    robots = (outcome or {}).get("robots", {})
    labels = {rid: f"{rid} ({'reached' if robots[rid]['reached'] else 'not reached'})"
              if "reached" in robots.get(rid, {}) else rid for rid in run["paths"]}  # a tracking robot has no goal
    fig, ax = plt.subplots(figsize=(7, 6))
    if geometry is not None:
        draw_world(ax, geometry, run["state"], colours)
    else:
        ax.set_aspect("equal")
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
    paths = {rid: ([p[0] for p in ps], [p[1] for p in ps], [p[2] for p in ps]) for rid, ps in run["paths"].items()}
    step = draw_paths(ax, paths, colours, labels)
    points = [(x, y) for _, xs, ys in paths.values() for x, y in zip(xs, ys, strict=True)]
    goals = {r["goal"] for r in (geometry or {}).get("robots", []) if r.get("goal")}
    tracked = {tid: ps for tid, ps in run["target_paths"].items() if tid not in goals}
    if tracked:  # a tracking run: the targets are followed, not reached
        draw_tracking(ax, {rid: (xs, ys) for rid, (_, xs, ys) in paths.items()}, tracked,
                      (geometry or {}).get("target_range"), colours)
        points += [p for ps in tracked.values() for p in ps]
    if run["state"] is not None:
        points += [tuple(r["goal"]) for r in run["state"]["robots"].values() if r.get("goal") is not None]
    x0, x1, y0, y1 = fit_bounds(ax, geometry, points)
    t_end = run["state"]["time"] if run["state"] else 0.0
    ax.set_title(title or f"{Path(path).name}: {t_end:.1f} s of sim time", fontsize=9)
    legend_outside(ax, time_step=step if paths else None)
    fig.set_size_inches(figure_size(x0, x1, y0, y1))
    fig.tight_layout()
    return fig


def draw_trajectory(out: Path, title: str, outcome: dict[str, Any]) -> str | None:
    """``out/trajectory.png`` from the run's log (``run.mcap``, or the first of a set);
    None when drawn or there is no log, else why it could not be (the run's results stand
    without the picture)."""
    log_path = out / "run.mcap" if (out / "run.mcap").is_file() else out / "run_0.mcap"
    if not log_path.is_file():
        return None
    try:
        plot_log(log_path, title=title, outcome=outcome).savefig(out / "trajectory.png", dpi=130)
    except Exception as exc:  # noqa: BLE001 - the caller says it and goes on
        return f"{type(exc).__name__}: {exc}"
    return None
