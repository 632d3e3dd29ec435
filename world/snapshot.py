"""The world as plain data: the state of a moment (for the world's ``state`` messages, the
log, the monitors) and the static geometry (for drawing and planning; see
world/scenarios/README.md). Floats, bools, strings, lists, dicts and None only."""

from __future__ import annotations

from typing import Any

from . import geometry as geo


def world_state(w: Any) -> dict[str, Any]:
    """time; robots {id: x, y, theta, v_l, v_r (commanded, clipped), v_l_exec, v_r_exec
    (executed with noise in the last sub-step), in_contact, goal}; targets {id: x, y};
    moving obstacles {id: x, y, theta} of the :class:`world.sim.World` ``w``."""
    n = w._n
    st = w._state
    robots = {}
    for i, rid in enumerate(w._ids):
        g = w._goal[i]
        robots[rid] = {
            "x": w._px[i],
            "y": w._py[i],
            "theta": geo.wrap_angle(w._pth[i]),
            "v_l": float(w._cmd[i, 0]),
            "v_r": float(w._cmd[i, 1]),
            "v_l_exec": float(w._exec[i, 0]),
            "v_r_exec": float(w._exec[i, 1]),
            "in_contact": w._touching[i] > 0,
            "goal": list(w._goal_xy(i)) if g is not None else None,
        }
    targets = {t.id: {"x": float(w._tpos[k, 0]), "y": float(w._tpos[k, 1])} for k, t in enumerate(w.scenario.targets)}
    obstacles = {o.id: {"x": float(st[2 * n + k, 0]), "y": float(st[2 * n + k, 1]), "theta": float(st[2 * n + k, 2])}
                 for k, o in enumerate(w._movers)}
    return {"time": w.time, "robots": robots, "targets": targets, "obstacles": obstacles}


def static_geometry(sc: Any, body_radius: float, sensor_range: float) -> dict[str, Any]:
    """Walls, static polygons and discs, moving obstacles with their motion, targets and
    robots of scenario ``sc``, with the robot's body radius and the sensing ranges."""
    walls = [{"a": list(w.a), "b": list(w.b), "thickness": w.thickness, "known": w.known,
              "vertices": [list(p) for p in w.outline], "source": w.source} for w in sc.walls]
    polygons, discs, moving = [], [], []
    for o in sc.obstacles:
        if o.motion is not None:
            moving.append({"id": o.id, "shape": o.shape, "radius": o.radius,
                           "vertices": [list(p) for p in o.outline] if o.outline else None,
                           "motion": o.motion.to_dict()})
        elif o.shape == "disc":
            assert o.center is not None
            discs.append({"id": o.id, "center": list(o.center), "radius": o.radius, "known": o.known,
                          "source": o.source})
        else:
            assert o.outline is not None
            polygons.append({"id": o.id, "shape": o.shape, "vertices": [list(p) for p in o.outline],
                             "parts": [[list(p) for p in part] for part in o.parts], "known": o.known,
                             "source": o.source})
    targets = [{"id": t.id, "position": list(t.position), "motion": t.motion.to_dict()} for t in sc.targets]
    robots = [{"id": r.id, "start": list(r.start), "goal": r.goal} for r in sc.robots]
    return {"name": sc.name, "bounds": list(sc.bounds), "body_radius": body_radius, "target_range": sc.target_range,
            "sensor_range": sensor_range, "walls": walls, "polygons": polygons, "discs": discs,
            "moving_obstacles": moving, "targets": targets, "robots": robots}
