"""The run spec: one declaration of everything the processes of a launch need, written once
by the launcher (``OUT/run-spec.json``) and read by every node process and the world
server: the graph with its node programs' ports and parameters (checked by the launcher,
so no process imports a program it does not run), the team, the task, the robots' body
and sensors, the key space and run id, the time mode, where to connect, the model.

Plain data, no node code: the world server reads it too (it derives its wait set, what
it publishes and what it records from the graph).
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from cekm_swarm.protocol import KeySpace
from cekm_swarm.robot import RobotBody

from .plan import PortTypes, RunPlan
from .resolve import build_plan
from .spec import Graph, GraphError

SPEC_VERSION = 1


@dataclass(frozen=True)
class RunSpec:
    """What every process of a run is started with (see the module docstring)."""

    graph: Graph
    ports: Mapping[str, PortTypes]
    params: Mapping[str, Mapping[str, Any]]
    team: tuple[str, ...]
    task: str
    body: RobotBody = field(default_factory=RobotBody)
    root: str = "cekm"
    run_id: str | None = None
    mode: str = "lockstep"
    connect: str = "tcp/127.0.0.1:7447"
    zenoh_config: str | None = None
    model: str | None = None  # a file, or "zenoh" (fetched from the world host's launcher)
    model_timeout: float = 30.0
    log_level: str = "INFO"
    hold_readings: bool = True  # the world leaves unchanged readings out (RunPlan.held_readings)
    schemas: Mapping[str, Any] = field(default_factory=dict)  # a user message kind -> its JSON Schema (for the log)

    @property
    def keys(self) -> KeySpace:
        return KeySpace(self.root, self.body.sensors, self.run_id)

    def plan(self) -> RunPlan:
        """The graph resolved for the team (built once per spec object: a node process
        forked warm inherits the fork server's)."""
        held = self.__dict__.get("_plan")
        if held is None:
            held = build_plan(self.graph, self.team, self.task, self.ports, self.body.sensors, self.keys,
                              self.hold_readings)
            object.__setattr__(self, "_plan", held)
        return held

    def with_(self, **changes: Any) -> RunSpec:
        return replace(self, **changes)

    def to_dict(self) -> dict[str, Any]:
        return {"version": SPEC_VERSION, "graph": self.graph.to_dict(),
                "ports": {k: v.to_dict() for k, v in self.ports.items()},
                "params": {k: dict(v) for k, v in self.params.items()}, "team": list(self.team), "task": self.task,
                "body": self.body.to_dict(), "root": self.root, "run_id": self.run_id, "mode": self.mode,
                "connect": self.connect, "zenoh_config": self.zenoh_config, "model": self.model,
                "model_timeout": self.model_timeout, "log_level": self.log_level,
                "hold_readings": self.hold_readings, **({"schemas": dict(self.schemas)} if self.schemas else {})}

    @classmethod
    def from_dict(cls, doc: Mapping[str, Any], source: str = "run spec") -> RunSpec:
        if doc.get("version") != SPEC_VERSION:
            raise GraphError(source, "version",
                             f"{doc.get('version')!r}: this code reads run spec version {SPEC_VERSION}")
        try:
            return cls(Graph.from_dict(doc["graph"]), {k: PortTypes.from_dict(v) for k, v in doc["ports"].items()},
                       {k: dict(v) for k, v in doc["params"].items()}, tuple(doc["team"]), doc["task"],
                       RobotBody.from_dict(doc["body"]), doc["root"], doc["run_id"], doc["mode"], doc["connect"],
                       doc["zenoh_config"], doc["model"], float(doc["model_timeout"]), doc["log_level"],
                       bool(doc.get("hold_readings", True)), dict(doc.get("schemas") or {}))
        except (KeyError, TypeError, ValueError) as exc:
            raise GraphError(source, None, f"not a run spec ({type(exc).__name__}: {exc})") from None

    def write(self, path: str | Path) -> Path:
        path = Path(path)
        tmp = path.with_suffix(path.suffix + ".tmp")
        tmp.write_text(json.dumps(self.to_dict(), indent=1))
        tmp.replace(path)
        return path

    @classmethod
    def read(cls, path: str | Path) -> RunSpec:
        """The run spec in ``path``; the same object again while the file is unchanged (a
        fork server reads it once for all the nodes it forks)."""
        try:
            st = os.stat(path)
            stamp = (os.path.realpath(path), st.st_mtime_ns, st.st_size, st.st_ino)
            held = _READ.get(stamp)
            if held is not None:
                return held
            doc = json.loads(Path(path).read_text())
        except (OSError, json.JSONDecodeError) as exc:
            raise GraphError(str(path), None, f"cannot read the run spec ({exc})") from None
        spec = cls.from_dict(doc, str(path))
        _READ.clear()
        _READ[stamp] = spec
        return spec


_READ: dict[tuple[Any, ...], RunSpec] = {}
