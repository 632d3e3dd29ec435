"""A Foxglove view of a learning run's maps (docs/learning.md): a channel of ``run.mcap``
(or a file of its own), one ``/view/lattice/<robot>`` SceneUpdate per map version, the lattice's
input weights w_i = (alpha_i, d_i) drawn as the displacements they stand for, (d cos alpha,
d sin alpha) in the robot's frame at the start of a step (metres, x ahead), each neuron
joined to its lattice neighbours: the picture of the paper's Fig. 6, as it changes."""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

from .errors import McapLogError
from .foxglove_view import _color, _need, _pose, _schema, _stamp
from .map_log import map_messages
from .mcap_log import McapRecorder
from .mcap_recover import recover_log

TOPIC = "/view/lattice/{robot}"
FRAME = "lattice/{robot}"
_LINE = (0.2, 0.45, 0.85, 1.0)
_NEURON = (0.85, 0.3, 0.2, 1.0)


def lattice_points(w: Any, size: int) -> list[tuple[float, float]]:
    """Each neuron's input weight as the displacement it stands for: (d cos alpha, d sin alpha)."""
    return [(float(w[2 * i + 1]) * math.cos(float(w[2 * i])), float(w[2 * i + 1]) * math.sin(float(w[2 * i])))
            for i in range(size * size)]


def lattice_edges(size: int) -> list[tuple[int, int]]:
    """Neighbouring neurons on the lattice (row-major, i = row * size + col)."""
    out = []
    for r in range(size):
        for c in range(size):
            i = r * size + c
            if c + 1 < size:
                out.append((i, i + 1))
            if r + 1 < size:
                out.append((i, i + size))
    return out


def write_lattice_log(log: str | Path, out: str | Path) -> int:
    """Every map version of ``log`` as a lattice view in ``out``; the number of views written."""
    with McapRecorder(Path(out), flush_interval=None) as rec:
        return write_views(rec, log)


def add_lattice_channel(log: str | Path) -> int:
    """Every map version of ``log`` as a lattice view, written into ``log`` itself (the file
    rewritten whole with the views added, then put in its place); the number of views."""
    log = Path(log)
    tmp = log.with_name(log.name + ".views.tmp")
    written: list[int] = []
    report = recover_log(log, tmp, extra=lambda rec: written.append(write_views(rec, log)))
    if not report.input_complete:
        tmp.unlink(missing_ok=True)
        raise McapLogError(str(log), f"not complete ({report.cut_reason}): the lattice views were not added")
    os.replace(tmp, log)
    return written[0]


def write_views(rec: McapRecorder, log: str | Path) -> int:
    """Write a lattice view of every map version of ``log`` with ``rec``; how many."""
    fm = _need()
    scene = _schema(fm.SceneUpdate)
    written = 0
    seen: dict[str, int] = {}
    for robot, msg in map_messages(log):
        if seen.get(robot) == msg.version:
            continue
        seen[robot] = msg.version
        size = math.isqrt(msg.w.shape[0] // 2)
        pts = lattice_points(msg.w, size)
        line_pts = [fm.Point3(x=pts[k][0], y=pts[k][1], z=0.0) for a, b in lattice_edges(size) for k in (a, b)]
        lines = fm.LinePrimitive(type=fm.LinePrimitiveLineType.LineList, pose=_pose(0, 0), thickness=0.0008,
                                 scale_invariant=False, points=line_pts, color=_color(_LINE))
        dots = [fm.SpherePrimitive(pose=_pose(x, y), size=fm.Vector3(x=0.002, y=0.002, z=0.002),
                                   color=_color(_NEURON)) for x, y in pts]
        text = fm.TextPrimitive(pose=_pose(0.0, -0.02), billboard=True, font_size=12.0, scale_invariant=True,
                                color=_color(_LINE), text=f"{robot} map v{msg.version}, {msg.applied} steps")
        entity = fm.SceneEntity(timestamp=_stamp(msg.stamp), frame_id=FRAME.format(robot=robot),
                                id=f"lattice/{robot}", lines=[lines], spheres=dots, texts=[text])
        rec.write_encoded(TOPIC.format(robot=robot), "protobuf", scene, fm.SceneUpdate(entities=[entity]).encode(),
                          msg.stamp)
        written += 1
    return written
