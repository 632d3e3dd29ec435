"""The map versions of a learning run in its log (docs/learning.md): every learner's
``<robot>/model/update`` messages as recorded in ``run.mcap``, decoded; the versions a
robot went through, and its map at any moment (``cekm model extract``)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import cast

from cekm_swarm.protocol import DEFAULT_KEYS, KeyKind, MapVersion, decode

from .mcap_read import read_messages

MAP_KEY = "model/update"
"""The key below the robot a learning graph's learner sends its map versions on."""


def map_messages(log: str | Path, robot: str | None = None, root: str = DEFAULT_KEYS.root
                 ) -> Iterator[tuple[str, MapVersion]]:
    """(robot, message) for every map message of the log in log-time order (one robot's with ``robot``)."""
    tail = "/" + MAP_KEY
    head = f"{root}/"
    for m in read_messages(log):
        if not (m.topic.endswith(tail) and m.topic.startswith(head)):
            continue
        owner = m.topic[len(head):-len(tail)]
        if "/" in owner or (robot is not None and owner != robot):
            continue
        yield owner, cast(MapVersion, decode(m.topic, m.data, expect=KeyKind.MAP_VERSION))


def versions(log: str | Path, root: str = DEFAULT_KEYS.root) -> dict[str, list[tuple[int, str]]]:
    """Per robot, every map version in the log, in order: (version, digest)."""
    out: dict[str, list[tuple[int, str]]] = {}
    for robot, msg in map_messages(log, root=root):
        seen = out.setdefault(robot, [])
        if not seen or seen[-1][0] != msg.version:
            seen.append((msg.version, msg.digest))
    return out


def map_at(log: str | Path, robot: str, at: float | None = None, root: str = DEFAULT_KEYS.root) -> MapVersion | None:
    """The robot's map message in force at sim time ``at`` (the last one stamped before it;
    None: the last of the run), or None when the log has none."""
    last = None
    for _, msg in map_messages(log, robot, root):
        if at is not None and msg.stamp >= at:
            break
        last = msg
    return last
