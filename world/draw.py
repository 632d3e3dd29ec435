"""Matplotlib drawing of a world's static geometry and (optionally) its state.

``draw_world(ax, w.static_geometry(), w.state())``; the caller overlays robot paths.
Known items (those a planner may use) are drawn solid dark grey; unknown
(unforeseen) ones light orange with hatching; moving obstacles with their paths
dashed; goals as stars, other targets as crosses.
"""

from __future__ import annotations

import math
from typing import Any, Mapping

from matplotlib.axes import Axes
from matplotlib.patches import Circle, Polygon, Rectangle

KNOWN_FACE = "0.25"
UNKNOWN_FACE = "#f4b183"
UNKNOWN_EDGE = "#c55a11"
MOVING_FACE = "#9dc3e6"
MOVING_EDGE = "#2e75b6"
ROBOT_FACE = "#a9d18e"
ROBOT_EDGE = "#38761d"


def _style(known: bool) -> dict[str, Any]:
    if known:
        return {"facecolor": KNOWN_FACE, "edgecolor": KNOWN_FACE, "linewidth": 0.5}
    return {"facecolor": UNKNOWN_FACE, "edgecolor": UNKNOWN_EDGE, "linewidth": 0.8, "hatch": "////"}


def _pose_on_path(motion: Mapping[str, Any], t: float) -> tuple[float, float]:
    """Where a scripted motion is at time t (mirrors world.motion for plain dicts)."""
    if motion["type"] == "circle":
        s = 1.0 if motion.get("direction", "ccw") == "ccw" else -1.0
        a = motion.get("phase", 0.0) + s * motion["angular_speed"] * t
        cx, cy = motion["center"]
        return (cx + motion["radius"] * math.cos(a), cy + motion["radius"] * math.sin(a))
    (ax_, ay), (bx, by) = motion["a"], motion["b"]
    length = math.hypot(bx - ax_, by - ay)
    s_ = math.fmod(motion.get("phase", 0.0) * 2 * length + motion["speed"] * t, 2 * length)
    f = s_ / length if s_ <= length else (2 * length - s_) / length
    return (ax_ + (bx - ax_) * f, ay + (by - ay) * f)


def draw_world(ax: Axes, geometry: Mapping[str, Any], state: Mapping[str, Any] | None = None) -> Axes:
    """Draw walls, static obstacles (known vs unknown), moving obstacles with their
    paths, targets/goals and, if ``state`` is given, robots at their current poses.
    Sets equal aspect and the limits to the arena bounds (plus the walls)."""
    xmin, ymin, xmax, ymax = geometry["bounds"]
    for w in geometry.get("walls", []):
        ax.add_patch(Polygon(w["vertices"], closed=True, zorder=2, **_style(w["known"])))
    for p in geometry.get("polygons", []):
        ax.add_patch(Polygon(p["vertices"], closed=True, zorder=2, **_style(p["known"])))
    for d in geometry.get("discs", []):
        ax.add_patch(Circle(d["center"], d["radius"], zorder=2, **_style(d["known"])))

    t = float(state["time"]) if state is not None else 0.0
    obs_state = state.get("obstacles", {}) if state is not None else {}
    for m in geometry.get("moving_obstacles", []):
        motion = m["motion"]
        if motion["type"] == "circle":
            ax.add_patch(
                Circle(motion["center"], motion["radius"], fill=False, linestyle="--", edgecolor=MOVING_EDGE, linewidth=0.8, zorder=1)
            )
            # a direction arrow on the path, a quarter turn ahead of the obstacle
            s = 1.0 if motion.get("direction", "ccw") == "ccw" else -1.0
            a = motion.get("phase", 0.0) + s * motion["angular_speed"] * t + s * math.pi / 2
            cx, cy = motion["center"]
            r = motion["radius"]
            px, py = cx + r * math.cos(a), cy + r * math.sin(a)
            ax.annotate(
                "",
                xy=(px - s * 0.4 * r * math.sin(a), py + s * 0.4 * r * math.cos(a)),
                xytext=(px, py),
                arrowprops={"arrowstyle": "-|>", "color": MOVING_EDGE, "lw": 1.0},
                zorder=1,
            )
        else:
            ax.plot([motion["a"][0], motion["b"][0]], [motion["a"][1], motion["b"][1]], "--", color=MOVING_EDGE, lw=0.8, zorder=1)
        if m["id"] in obs_state:
            ox, oy = obs_state[m["id"]]["x"], obs_state[m["id"]]["y"]
            th = obs_state[m["id"]].get("theta", 0.0)
        else:
            ox, oy = _pose_on_path(motion, t)
            th = 0.0
        if m["shape"] == "disc":
            ax.add_patch(Circle((ox, oy), m["radius"], facecolor=MOVING_FACE, edgecolor=MOVING_EDGE, zorder=3))
        else:
            c, s_ = math.cos(th), math.sin(th)
            verts = [(ox + c * x - s_ * y, oy + s_ * x + c * y) for x, y in m["vertices"]]
            ax.add_patch(Polygon(verts, closed=True, facecolor=MOVING_FACE, edgecolor=MOVING_EDGE, zorder=3))

    goals: set[str] = {r["goal"] for r in geometry.get("robots", []) if r.get("goal")}
    tstate = state.get("targets", {}) if state is not None else {}
    for tg in geometry.get("targets", []):
        x, y = (tstate[tg["id"]]["x"], tstate[tg["id"]]["y"]) if tg["id"] in tstate else tg["position"]
        if tg["id"] in goals:
            ax.plot([x], [y], marker="*", markersize=12, color="#c00000", zorder=5, linestyle="none")
        else:
            ax.plot([x], [y], marker="X", markersize=8, color="#7030a0", zorder=5, linestyle="none")
    if state is not None:
        radius = geometry.get("body_radius", 0.03)
        for rid, r in state.get("robots", {}).items():
            ax.add_patch(Circle((r["x"], r["y"]), radius, facecolor=ROBOT_FACE, edgecolor=ROBOT_EDGE, zorder=4))
            ax.plot(
                [r["x"], r["x"] + radius * math.cos(r["theta"])],
                [r["y"], r["y"] + radius * math.sin(r["theta"])],
                color=ROBOT_EDGE,
                lw=1.0,
                zorder=4,
            )
            g = r.get("goal")
            if g is not None and not any(
                abs(g[0] - tv["x"]) < 1e-12 and abs(g[1] - tv["y"]) < 1e-12 for tv in tstate.values()
            ):
                ax.plot([g[0]], [g[1]], marker="*", markersize=12, color="#c00000", zorder=5, linestyle="none")
    pad = max(0.05, max((w["thickness"] for w in geometry.get("walls", [])), default=0.0) * 1.5)
    ax.set_xlim(xmin - pad, xmax + pad)
    ax.set_ylim(ymin - pad, ymax + pad)
    ax.set_aspect("equal")
    ax.add_patch(Rectangle((xmin, ymin), xmax - xmin, ymax - ymin, fill=False, edgecolor="0.8", linewidth=0.5, zorder=0))
    return ax
