"""Draw a run from its MCAP log: the arena (the geometry the world server stores in the
log's metadata), each robot's path from ``world/state``, goals and final poses."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from cekm_swarm.protocol import KeyKind, KeySpace, MessageError, decode
from cekm_swarm.runtime.mcap_log import read_messages


def read_geometry(path: str | Path) -> dict[str, Any] | None:
    """The geometry the world server recorded (metadata ``geometry``), None if absent."""
    from mcap.reader import make_reader

    try:
        with open(path, "rb") as f:
            for md in make_reader(f).iter_metadata():
                if md.name == "geometry":
                    return json.loads(md.metadata["json"])
    except Exception:  # an unfinished log has no index; draw the paths alone
        return None
    return None


def read_run(path: str | Path, keys: KeySpace = KeySpace()) -> dict[str, Any]:
    """Per robot the poses (t, x, y, theta) from ``world/state``, and the last state."""
    paths: dict[str, list[tuple[float, float, float, float]]] = {}
    last = None
    state_key = keys.world_state()
    for m in read_messages(path, topics=[state_key]):
        try:
            msg = decode(KeyKind.WORLD_STATE, m.data, keys=keys)
        except MessageError:
            continue
        for rid, r in msg.robots.items():
            paths.setdefault(rid, []).append((msg.stamp, r["x"], r["y"], r["theta"]))
        last = msg
    state = None
    if last is not None:
        state = {"time": last.stamp, "robots": last.robots, "targets": last.targets, "obstacles": last.obstacles}
    return {"paths": paths, "state": state, "geometry": read_geometry(path)}


def plot_log(path: str | Path, title: str | None = None, outcome: dict[str, Any] | None = None):
    """A matplotlib figure of the run in the log at ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    run = read_run(path)
    geometry = run["geometry"]
    if geometry is not None:
        xmin, ymin, xmax, ymax = geometry["bounds"]
        aspect = (ymax - ymin) / max(xmax - xmin, 1e-9)
    else:
        aspect = 1.0
    fig, ax = plt.subplots(figsize=(7, max(2.5, 7 * aspect)))
    if geometry is not None:
        from world.draw import draw_world

        draw_world(ax, geometry, run["state"])
    else:
        ax.set_aspect("equal")
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    robots = (outcome or {}).get("robots", {})
    for i, (rid, poses) in enumerate(run["paths"].items()):
        col = colours[i % len(colours)]
        xs = [p[1] for p in poses]
        ys = [p[2] for p in poses]
        status = ""
        if rid in robots:
            status = "" if "reached" not in robots[rid] else (" (reached)" if robots[rid]["reached"] else " (not reached)")
        ax.plot(xs, ys, "-", color=col, lw=1.2, label=f"{rid}{status}")
        ax.plot(xs[:1], ys[:1], "o", color=col, ms=5, alpha=0.6)
    t_end = run["state"]["time"] if run["state"] else 0.0
    ax.set_title(title or f"{Path(path).name}: {t_end:.1f} s of sim time")
    if run["paths"]:
        ax.legend(loc="best", fontsize=7)
    fig.tight_layout()
    return fig
