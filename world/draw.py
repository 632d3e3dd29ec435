"""Matplotlib drawing of a world's static geometry and (optionally) its state.

``draw_world(ax, w.static_geometry(), w.state())``; the caller overlays robot paths.
Known items (those a planner may use) are drawn solid dark grey; unknown
(unforeseen) ones light orange with hatching; moving obstacles with their paths
dashed; goals as stars, other targets as crosses.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from matplotlib.axes import Axes

KNOWN_FACE = "0.25"
UNKNOWN_FACE = "#f4b183"
UNKNOWN_EDGE = "#c55a11"
MOVING_FACE = "#9dc3e6"
MOVING_EDGE = "#2e75b6"
ROBOT_FACE = "#a9d18e"
ROBOT_EDGE = "#38761d"


ROBOT_COLOURS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#17becf", "#8c564b", "#e377c2")
"""One colour per robot (its path, start, goal and body share it), in robot order."""


def robot_colours(robots: Sequence[str]) -> dict[str, str]:
    """Robot id -> its colour; the order of ``robots`` decides (sorted ids give a stable map)."""
    return {rid: ROBOT_COLOURS[i % len(ROBOT_COLOURS)] for i, rid in enumerate(robots)}


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


def draw_world(ax: Axes, geometry: Mapping[str, Any], state: Mapping[str, Any] | None = None,
               colours: Mapping[str, str] | None = None) -> Axes:
    """Draw walls, static obstacles (known vs unknown), moving obstacles with their
    paths, targets/goals and, if ``state`` is given, robots at their current poses.
    Each robot's goal and body take its colour from ``colours`` (default
    :func:`robot_colours` of the robots in id order). Sets equal aspect, the limits to
    the arena bounds (plus the walls) and the axes' labels in metres."""
    from matplotlib.patches import Circle, Polygon, Rectangle

    ids = sorted({r["id"] for r in geometry.get("robots", [])} | set((state or {}).get("robots", {})))
    colours = dict(colours) if colours is not None else robot_colours(ids)
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
                Circle(motion["center"], motion["radius"], fill=False, linestyle="--", edgecolor=MOVING_EDGE,
                       linewidth=0.8, zorder=1)
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
            ax.plot([motion["a"][0], motion["b"][0]], [motion["a"][1], motion["b"][1]], "--", color=MOVING_EDGE,
                    lw=0.8, zorder=1)
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

    goals: dict[str, str] = {r["goal"]: r["id"] for r in geometry.get("robots", []) if r.get("goal")}
    tstate = state.get("targets", {}) if state is not None else {}
    for tg in geometry.get("targets", []):
        x, y = (tstate[tg["id"]]["x"], tstate[tg["id"]]["y"]) if tg["id"] in tstate else tg["position"]
        if tg["id"] in goals:
            goal_marker(ax, (x, y), colours.get(goals[tg["id"]], "#c00000"), goals[tg["id"]])
        else:
            ax.plot([x], [y], marker="X", markersize=8, color="#7030a0", zorder=5, linestyle="none")
    if state is not None:
        radius = geometry.get("body_radius", 0.03)
        for rid, r in state.get("robots", {}).items():
            col = colours.get(rid, ROBOT_EDGE)
            ax.add_patch(Circle((r["x"], r["y"]), radius, facecolor=col, edgecolor="k", alpha=0.85, lw=0.6, zorder=4,
                                gid=f"robot:{rid}"))
            ax.plot(
                [r["x"], r["x"] + radius * math.cos(r["theta"])],
                [r["y"], r["y"] + radius * math.sin(r["theta"])],
                color="k",
                lw=1.0,
                zorder=4,
            )
            g = r.get("goal")
            if g is not None and not any(
                abs(g[0] - tv["x"]) < 1e-12 and abs(g[1] - tv["y"]) < 1e-12 for tv in tstate.values()
            ):
                goal_marker(ax, (g[0], g[1]), col, rid)
    pad = max(0.05, max((w["thickness"] for w in geometry.get("walls", [])), default=0.0) * 1.5)
    ax.set_xlim(xmin - pad, xmax + pad)
    ax.set_ylim(ymin - pad, ymax + pad)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.add_patch(Rectangle((xmin, ymin), xmax - xmin, ymax - ymin, fill=False, edgecolor="0.8", linewidth=0.5,
                           zorder=0))
    return ax


def goal_marker(ax: Axes, xy: Sequence[float], colour: str, robot: str | None = None) -> Any:
    """A robot's goal: a star in the robot's colour with a black edge."""
    return ax.plot([xy[0]], [xy[1]], marker="*", markersize=14, color=colour, markeredgecolor="k", markeredgewidth=0.6,
                   zorder=6, linestyle="none", gid=f"goal:{robot}" if robot else None)[0]


def nice_step(span: float, marks: int = 12) -> float:
    """A round time step (1, 2 or 5 times a power of ten) giving about ``marks`` marks over ``span``."""
    if not span > 0:
        return 1.0
    raw = span / marks
    p = 10 ** math.floor(math.log10(raw))
    return next(m * p for m in (1, 2, 5, 10) if m * p >= raw)


def draw_paths(ax: Axes, paths: Mapping[str, tuple[Sequence[float], Sequence[float], Sequence[float]]],
               colours: Mapping[str, str], labels: Mapping[str, str] | None = None,
               time_step: float | None = None) -> float:
    """Each robot's path (t, x, y) in its colour: the line, a filled circle at the start and
    time marks (small dots) every ``time_step`` s of sim time, the same instants on every
    robot so crossings can be told apart; every other mark is labelled with its time.
    Returns the time step used (default :func:`nice_step` of the longest run)."""
    t_end = max((ts[-1] for ts, _, _ in paths.values() if len(ts)), default=0.0)
    step = time_step or nice_step(t_end)
    for rid, (ts, xs, ys) in paths.items():
        if not len(ts):
            continue
        col = colours[rid]
        ax.plot(xs, ys, "-", color=col, lw=1.3, zorder=3, label=(labels or {}).get(rid, rid), gid=f"path:{rid}")
        ax.plot(xs[:1], ys[:1], "o", color=col, ms=7, markeredgecolor="k", markeredgewidth=0.6, zorder=6,
                gid=f"start:{rid}")
        last = len(ts) - 1  # no marks once the robot has stopped for good (they would pile up)
        while last > 0 and math.hypot(xs[last - 1] - xs[-1], ys[last - 1] - ys[-1]) < 1e-3:
            last -= 1
        mx, my, mt = [], [], []
        i = 0
        for n in range(1, int(ts[last] / step) + 1):
            while i < len(ts) - 1 and ts[i] < n * step:
                i += 1
            mx.append(xs[i])
            my.append(ys[i])
            mt.append(n * step)
        ax.plot(mx, my, "o", color=col, ms=3.5, markeredgecolor="white", markeredgewidth=0.4, zorder=5,
                gid=f"time:{rid}")
        for x, y, t in list(zip(mx, my, mt, strict=True))[1::2]:
            if math.hypot(x - xs[-1], y - ys[-1]) < 0.02:
                continue  # not on the final pose's goal star
            ax.annotate(f"{t:g}", (x, y), xytext=(3, 3), textcoords="offset points", fontsize=6, color=col, zorder=7)
    widen_to(ax, [x for _, xs, _ in paths.values() for x in xs], [y for _, _, ys in paths.values() for y in ys])
    return step


def widen_to(ax: Axes, xs: Sequence[float], ys: Sequence[float], pad: float = 0.1) -> None:
    """Widen the axes' limits, where they do not reach, to every point (plus ``pad`` m):
    a robot that left an arena without boundary walls stays on the picture."""
    if not len(xs):
        return
    x0, x1 = ax.get_xlim()
    y0, y1 = ax.get_ylim()
    ax.set_xlim(min(x0, min(xs) - pad), max(x1, max(xs) + pad))
    ax.set_ylim(min(y0, min(ys) - pad), max(y1, max(ys) + pad))


def draw_tracking(ax: Axes, paths: Mapping[str, tuple[Sequence[float], Sequence[float]]],
                  target_paths: Mapping[str, Sequence[Sequence[float]]], target_range: float | None,
                  colours: Mapping[str, str], instants: int = 4) -> None:
    """The paper's Fig. 13 on top of :func:`draw_world` and :func:`draw_paths`: each
    target's path (grey, a dot at its start, a black cross and its id at its end) and each
    robot's target-sensing circle of radius ``target_range`` at ``instants`` evenly spaced
    points of its path ``(xs, ys)`` (fainter earlier; none if the range is unknown)."""
    from matplotlib.patches import Circle

    for tid, pts in target_paths.items():
        if not len(pts):
            continue
        txs, tys = [p[0] for p in pts], [p[1] for p in pts]
        ax.plot(txs, tys, "-", color="0.45", lw=1.0, gid=f"target:{tid}")
        ax.plot(txs[0], tys[0], "o", color="0.45", ms=3)
        ax.plot(txs[-1], tys[-1], "X", color="k", ms=6)
        ax.annotate(tid, (txs[-1], tys[-1]), fontsize=7, xytext=(3, 3), textcoords="offset points")
    for rid, (xs, ys) in paths.items():
        n = len(xs)
        if not n:
            continue
        for j in range(instants):
            k = min(n - 1, round(j * (n - 1) / max(1, instants - 1)))
            fade = 0.25 + 0.6 * j / max(1, instants - 1)
            if target_range is not None:
                ax.add_patch(Circle((xs[k], ys[k]), target_range, fill=False, edgecolor=colours[rid], lw=0.8,
                                    alpha=fade, ls="--", gid=f"sensing:{rid}"))
            ax.add_patch(Circle((xs[k], ys[k]), 0.03, color=colours[rid]))


def content_points(geometry: Mapping[str, Any]) -> list[tuple[float, float]]:
    """Extreme points of what is inside the arena: static obstacles, the reach of moving
    obstacles' paths, targets (the walls are the frame, not content)."""
    pts: list[tuple[float, float]] = []
    for p in geometry.get("polygons", []):
        pts += [(v[0], v[1]) for v in p["vertices"]]
    for d in geometry.get("discs", []):
        (cx, cy), r = d["center"], d["radius"]
        pts += [(cx - r, cy - r), (cx + r, cy + r)]
    for m in geometry.get("moving_obstacles", []):
        mo = m["motion"]
        if mo["type"] == "circle":
            (cx, cy), r = mo["center"], mo["radius"]
            pts += [(cx - r, cy - r), (cx + r, cy + r)]
        else:
            pts += [tuple(mo["a"]), tuple(mo["b"])]
    pts += [tuple(t["position"]) for t in geometry.get("targets", [])]
    return [(float(x), float(y)) for x, y in pts]


def fit_bounds(ax: Axes, geometry: Mapping[str, Any] | None, points: Sequence[Sequence[float]],
               margin: float = 0.15) -> tuple[float, float, float, float]:
    """Limits that fit the content: the bounding box of ``points`` (paths, starts, goals)
    and of the arena's obstacles and targets (:func:`content_points`, walls excluded)
    plus ``margin`` m, clipped to the arena (plus its walls) when ``geometry`` is given.
    Returns (xmin, xmax, ymin, ymax)."""
    pts = [(float(p[0]), float(p[1])) for p in points]
    if geometry is not None and pts:
        pts += content_points(geometry)
    xs = [p[0] for p in pts]
    ys = [p[1] for p in pts]
    if not xs:
        x0, x1 = ax.get_xlim()
        y0, y1 = ax.get_ylim()
        return x0, x1, y0, y1
    margin = max(margin, 0.03 * max(max(xs) - min(xs), max(ys) - min(ys)))  # a marker's size on a large map
    x0, x1, y0, y1 = min(xs) - margin, max(xs) + margin, min(ys) - margin, max(ys) + margin
    # the arena clips the content, never the paths (no boundary walls: robots leave)
    if geometry is not None and points:
        bx0, by0, bx1, by1 = geometry["bounds"]
        wall = max((w["thickness"] for w in geometry.get("walls", [])), default=0.0) + 0.02
        px = [float(p[0]) for p in points]
        py = [float(p[1]) for p in points]
        lo_x, hi_x = bx0 - wall, bx1 + wall
        lo_y, hi_y = by0 - wall, by1 + wall
        x0 = max(x0, lo_x if min(px) >= lo_x else min(px) - margin)
        x1 = min(x1, hi_x if max(px) <= hi_x else max(px) + margin)
        y0 = max(y0, lo_y if min(py) >= lo_y else min(py) - margin)
        y1 = min(y1, hi_y if max(py) <= hi_y else max(py) + margin)
        # content near a side of the arena shows that side's wall whole, not cut at its inner face
        x0 = min(x0, lo_x) if x0 < bx0 + margin else x0
        x1 = max(x1, hi_x) if x1 > bx1 - margin else x1
        y0 = min(y0, lo_y) if y0 < by0 + margin else y0
        y1 = max(y1, hi_y) if y1 > by1 - margin else y1
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_aspect("equal")
    return x0, x1, y0, y1


def legend_outside(ax: Axes, title: str | None = None, time_step: float | None = None) -> Any:
    """The legend to the right of the axes (never over the arena); with ``time_step`` an
    entry says what the dots mean."""
    handles, labels = ax.get_legend_handles_labels()
    if len(handles) > LEGEND_ROWS:  # a large team: one entry, not a list no figure can hold
        handles = [ax.plot([], [], "-", color="0.4", lw=1.3)[0]]
        labels = [f"{len(labels)} robots' paths"]
    if time_step is not None:
        h = ax.plot([], [], "o", color="0.4", ms=3.5, linestyle="none")[0]
        handles.append(h)
        labels.append(f"dot every {time_step:g} s")
    if not handles:
        return None
    return ax.legend(handles, labels, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0, fontsize=7,
                     title=title, title_fontsize=7, frameon=False)


LEGEND_ROWS = 30
"""The most robots the legend names one by one: a figure 5.5 inches high holds about 40
entries at font size 7; a larger team gets one entry for all its paths."""


def figure_size(x0: float, x1: float, y0: float, y1: float, height: float = 5.5,
                legend_width: float = 1.7) -> tuple[float, float]:
    """Figure (width, height) in inches for an equal-aspect map of these limits with the
    legend to its right, so the map fills its axes without empty margins."""
    aspect = (x1 - x0) / max(y1 - y0, 1e-9)
    h = height if aspect <= 1.6 else max(2.5, 8.0 / aspect)
    return (1.0 + (h - 0.9) * aspect + legend_width, h)
