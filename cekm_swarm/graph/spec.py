"""A controller as a declared process graph: the file format and its typed loader.

One TOML file per controller (the shipped ones are in ``cekm_swarm/graph/shipped/``)::

    [graph]
    controller = "cekm"          # what --controller names
    task = "navigation"          # navigation | tracking | any
    description = "..."
    answer = "cmd/wheels"        # the output key that answers a tick for the world

    [params]                     # given to every node that declares them
    sigma_b_alpha = 0.495

    [[node]]
    name = "obstacle"            # the node's name; instances are obstacle-0, obstacle-1, ...
    program = "cekm_swarm.modules.obstacle"   # a module with one Node class, or "module:Class"
    instances = "sensors"        # one per distance sensor (or a number; default one)
    every = 1                    # runs every N ticks of 0.128 s (default: when its inputs of a tick are in)
    # timer = 0.5                # real time only: runs every 0.5 s of wall time, on a timer of its own
    inputs = { reading = "sense/range/{i}" }  # port -> key ({i}: the instance)
    outputs = { field = "field/obstacle/{i}" }
    params = { }                 # this node's parameters (over [params])

An input is a key of the robot's own (``"field/target"``; ``"field/obstacle/*"`` for every
instance), a key of every teammate (``{ key = "share", from = "teammates" }``, always the
previous tick's: ``delay = 1``), or a world key (``"world/clock"``, ``"world/state"``).
``delay = 1`` reads the value of the producer's previous run instead of this tick's;
``stale = S`` (seconds) is how old a value may be in real time before it counts as missing.

:func:`load_graph` parses a file into a :class:`Graph` (plain data, no imports of node
code), refusing a malformed one with a :class:`GraphError` that names the file, the node
and the field. What the graph means per robot (keys, periods, the lockstep rule) is
:mod:`cekm_swarm.graph.plan`; the checks that import the node programs are
:mod:`cekm_swarm.node.graph_check`.
"""

from __future__ import annotations

import re
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

from cekm_swarm.errors import CekmError

TASKS = ("navigation", "tracking", "any")
_NAME_RE = re.compile(r"[A-Za-z][A-Za-z0-9_]{0,47}\Z")
_PORT_RE = re.compile(r"[A-Za-z_][A-Za-z0-9_]{0,47}\Z")
_CHUNK_RE = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]*\Z")
SHIPPED = "shipped"
MIN_TIMER_S = 0.01
"""The shortest ``timer`` a node may declare (s): 100 runs a second at most."""


class GraphError(CekmError):
    """A graph file is malformed or inconsistent: names the file, the node and the field."""

    def __init__(self, source: str, where: str | None, problem: str) -> None:
        self.source, self.where, self.problem = str(source), where, problem
        super().__init__(f"{self.source}: {where}: {problem}" if where else f"{self.source}: {problem}")


@dataclass(frozen=True)
class InputDecl:
    """One input port's binding: ``key`` (relative to its owner), whose keys (``own``,
    ``teammates`` or ``world``), ``delay`` (0: this tick's value, 1: the previous run's)
    and the real-time staleness limit ``stale`` (s; None: two of the producer's periods)."""

    port: str
    key: str
    scope: str = "own"
    delay: int = 0
    stale: float | None = None


@dataclass(frozen=True)
class OutputDecl:
    """One output port and the key (relative to the robot) it sends on."""

    port: str
    key: str


@dataclass(frozen=True)
class NodeDecl:
    """One node as the graph declares it."""

    name: str
    program: str
    instances: int | str | None = None  # None: one; N; "sensors": one per distance sensor
    every: int | None = None
    inputs: tuple[InputDecl, ...] = ()
    outputs: tuple[OutputDecl, ...] = ()
    params: Mapping[str, Any] = field(default_factory=dict)
    index: int = 0  # its position in the file (node[index])
    timer: float | None = None  # real time: runs every `timer` s of wall time (lockstep: its `every`)

    @property
    def where(self) -> str:
        return f"node '{self.name}'"


@dataclass(frozen=True)
class Graph:
    """A controller's process graph, as declared."""

    name: str
    controller: str
    task: str
    description: str
    answer: str
    params: Mapping[str, Any]
    nodes: tuple[NodeDecl, ...]
    source: str

    def node(self, name: str) -> NodeDecl:
        for n in self.nodes:
            if n.name == name:
                return n
        raise KeyError(name)

    def node_names(self, sensors: int = 12) -> list[str]:
        """Every node instance one robot runs, in the file's order (``target``,
        ``obstacle-0`` .. ``obstacle-11``, ``motor``): its processes and tokens."""
        out = []
        for n in self.nodes:
            if n.instances is None:
                out.append(n.name)
            else:
                count = sensors if n.instances == "sensors" else int(n.instances)
                out += [f"{n.name}-{i}" for i in range(count)]
        return out

    def to_dict(self) -> dict[str, Any]:
        """Plain data (what a run spec carries to every process)."""
        return {"name": self.name, "controller": self.controller, "task": self.task, "description": self.description,
                "answer": self.answer, "params": dict(self.params), "source": self.source,
                "nodes": [{"name": n.name, "program": n.program, "instances": n.instances, "every": n.every,
                           **({"timer": n.timer} if n.timer is not None else {}),
                           "params": dict(n.params),
                           "inputs": [{"port": i.port, "key": i.key, "scope": i.scope, "delay": i.delay,
                                       "stale": i.stale} for i in n.inputs],
                           "outputs": [{"port": o.port, "key": o.key} for o in n.outputs]} for n in self.nodes]}

    @classmethod
    def from_dict(cls, doc: Mapping[str, Any]) -> Graph:
        """The inverse of :meth:`to_dict` (a run spec's graph, already checked)."""
        nodes = tuple(NodeDecl(n["name"], n["program"], n["instances"], n["every"],
                               tuple(InputDecl(i["port"], i["key"], i["scope"], i["delay"], i["stale"])
                                     for i in n["inputs"]),
                               tuple(OutputDecl(o["port"], o["key"]) for o in n["outputs"]), dict(n["params"]), k,
                               n.get("timer"))
                      for k, n in enumerate(doc["nodes"]))
        return cls(doc["name"], doc["controller"], doc["task"], doc["description"], doc["answer"], dict(doc["params"]),
                   nodes, doc["source"])


# --------------------------------------------------------------------------- loading


def shipped_graphs() -> dict[str, Path]:
    """The graphs shipped in the package: name -> file."""
    base = resources.files("cekm_swarm.graph") / SHIPPED
    return {Path(str(p)).stem: Path(str(p)) for p in base.iterdir() if str(p).endswith(".toml")}


def graph_path(name_or_path: str | Path) -> Path:
    """The file of a shipped graph's name, or the path given; GraphError if neither exists."""
    p = Path(name_or_path)
    if p.suffix == ".toml" or p.exists() or "/" in str(name_or_path):
        if p.is_dir():
            raise GraphError(str(p), None, "is a directory, not a graph file")
        if not p.is_file():
            raise GraphError(str(p), None, "no such file")
        return p
    shipped = shipped_graphs()
    if str(name_or_path) in shipped:
        return shipped[str(name_or_path)]
    raise GraphError(str(name_or_path), None, f"no such graph file, and no shipped graph of that name "
                                              f"(shipped: {', '.join(sorted(shipped))})")


def graph_for(controller: str, task: str) -> Path:
    """The shipped graph of ``--controller NAME`` for a scenario's task: ``NAME-<task>``, else ``NAME``."""
    shipped = shipped_graphs()
    for name in (f"{controller}-{task}", controller):
        if name in shipped:
            return shipped[name]
    names = sorted({n[:-len(f"-{task}")] for n in shipped if n.endswith(f"-{task}")}  # this task's, and any task's
                   | {n for n in shipped if not n.endswith(("-navigation", "-tracking"))})
    raise GraphError(f"--controller {controller}", None,
                     f"no shipped graph for a {task} scenario (controllers: {', '.join(names)}; or give --graph FILE)")


def load_graph(name_or_path: str | Path) -> Graph:
    """Parse a graph file (or a shipped graph's name) into a :class:`Graph`."""
    path = graph_path(name_or_path)
    try:
        doc = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise GraphError(str(path), None, f"not valid TOML ({exc})") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise GraphError(str(path), None, f"cannot read it ({exc})") from None
    return parse_graph(doc, str(path))


def parse_graph(doc: Mapping[str, Any], source: str) -> Graph:
    """A parsed TOML document as a :class:`Graph` (the structural checks only)."""
    p = _Parser(source)
    p.keys(doc, "the file", {"graph", "params", "node"})
    head = p.table(doc.get("graph"), "[graph]")
    p.keys(head, "[graph]", {"controller", "task", "description", "answer", "name"})
    controller = p.text(head.get("controller"), "[graph].controller")
    if not _NAME_RE.match(controller.replace("-", "_")):
        raise GraphError(source, "[graph].controller", f"{controller!r} is not a plain name")
    task = head.get("task", "any")
    if task not in TASKS:
        raise GraphError(source, "[graph].task", f"{task!r}: expected one of {', '.join(TASKS)}")
    answer = p.key(head.get("answer", "cmd/wheels"), "[graph].answer")
    params = p.table(doc.get("params", {}), "[params]")
    raw_nodes = doc.get("node")
    if not isinstance(raw_nodes, list) or not raw_nodes:
        raise GraphError(source, "[[node]]", "a graph needs at least one [[node]] table")
    nodes = []
    seen: dict[str, int] = {}
    for k, raw in enumerate(raw_nodes):
        where = f"node[{k}]"
        raw = p.table(raw, where)
        name = raw.get("name")
        if isinstance(name, str) and name:
            where = f"node '{name}'"
        p.keys(raw, where, {"name", "program", "instances", "every", "timer", "inputs", "outputs", "params"})
        name = p.text(name, f"{where}.name")
        if not _NAME_RE.match(name):
            raise GraphError(source, f"{where}.name", "a letter, then letters, digits or '_' (at most 48)")
        if name in seen:
            raise GraphError(source, f"{where}.name", f"duplicate node name (also node[{seen[name]}])")
        seen[name] = k
        program = p.text(raw.get("program"), f"{where}.program")
        instances = raw.get("instances")
        counted = type(instances) is int and 1 <= instances <= 1024
        if instances is not None and not (instances == "sensors" or counted):
            raise GraphError(source, f"{where}.instances", f"{instances!r}: expected a number 1..1024 or \"sensors\"")
        every = raw.get("every")
        if every is not None and not (type(every) is int and 1 <= every <= 10_000):
            raise GraphError(source, f"{where}.every", f"{every!r}: expected a whole number of ticks >= 1")
        timer = raw.get("timer")
        if timer is not None and not (type(timer) in (int, float) and MIN_TIMER_S <= timer <= 3600):
            raise GraphError(source, f"{where}.timer", f"{timer!r}: expected seconds between {MIN_TIMER_S} and 3600")
        ins = tuple(p.input(port, v, f"{where}.inputs.{port}", instances is not None)
                    for port, v in p.table(raw.get("inputs", {}), f"{where}.inputs").items())
        outs = []
        for port, v in p.table(raw.get("outputs", {}), f"{where}.outputs").items():
            p.port(port, f"{where}.outputs")
            key = p.key(v, f"{where}.outputs.{port}")
            if "*" in key:
                raise GraphError(source, f"{where}.outputs.{port}", f"{key!r}: an output is one key, no '*'")
            p.placeholder(key, f"{where}.outputs.{port}", instances is not None)
            outs.append(OutputDecl(port, key))
        nparams = p.table(raw.get("params", {}), f"{where}.params")
        nodes.append(NodeDecl(name, program, instances, every, ins, tuple(outs), dict(nparams), k,
                              None if timer is None else float(timer)))
    return Graph(head.get("name", Path(source).stem), controller, task, p.text(head.get("description", controller),
                 "[graph].description"), answer, dict(params), tuple(nodes), source)


class _Parser:
    def __init__(self, source: str) -> None:
        self.source = source

    def fail(self, where: str, problem: str) -> GraphError:
        return GraphError(self.source, where, problem)

    def table(self, x: Any, where: str) -> dict[str, Any]:
        if x is None:
            raise self.fail(where, "missing")
        if not isinstance(x, dict):
            raise self.fail(where, f"expected a table, got {type(x).__name__}")
        return x

    def keys(self, x: Mapping[str, Any], where: str, allowed: set[str]) -> None:
        extra = sorted(set(x) - allowed)
        if extra:
            raise self.fail(f"{where}.{extra[0]}", f"unknown field (expected: {', '.join(sorted(allowed))})")

    def text(self, x: Any, where: str) -> str:
        if not isinstance(x, str) or not x:
            raise self.fail(where, "missing" if x is None else f"expected a non-empty string, got {x!r}")
        return x

    def port(self, port: str, where: str) -> None:
        if not _PORT_RE.match(port):
            raise self.fail(f"{where}.{port}", "a port name is a letter or '_', then letters, digits or '_'")

    def key(self, x: Any, where: str) -> str:
        key = self.text(x, where)
        chunks = key.split("/")
        for c in chunks:
            if c in ("*", "{i}"):
                continue
            if not _CHUNK_RE.match(c):
                raise self.fail(where, f"key {key!r}: chunk {c!r} must be letters, digits, '_', '.' or '-' "
                                       "(or '*', '{i}')")
        if "*" in chunks[:-1] or chunks.count("*") > 1:
            raise self.fail(where, f"key {key!r}: '*' may only be its last chunk")
        if chunks[0] == "alive":
            raise self.fail(where, f"key {key!r}: 'alive/...' is the liveliness tokens' space")
        return key

    def placeholder(self, key: str, where: str, instanced: bool) -> None:
        if "{i}" in key and not instanced:
            raise self.fail(where, f"key {key!r} uses {{i}} but the node has no instances")

    def input(self, port: str, v: Any, where: str, instanced: bool) -> InputDecl:
        self.port(port, where.rsplit(".", 1)[0])
        if isinstance(v, str):
            v = {"key": v}
        v = self.table(v, where)
        self.keys(v, where, {"key", "from", "delay", "stale"})
        key = self.key(v.get("key"), f"{where}.key")
        self.placeholder(key, f"{where}.key", instanced)
        scope = v.get("from", "world" if key.startswith(("world/",)) else "own")
        if scope not in ("own", "teammates", "world"):
            raise self.fail(f"{where}.from", f"{scope!r}: expected own, teammates or world")
        if key.startswith("world/"):
            scope = "world"
        delay = v.get("delay", 1 if scope == "teammates" else 0)
        if delay not in (0, 1) or type(delay) is not int:
            raise self.fail(f"{where}.delay", f"{delay!r}: expected 0 (this tick's value) or 1 (the previous run's)")
        if scope == "teammates" and delay != 1:
            raise self.fail(f"{where}.delay", "a teammate's value is always the previous tick's (delay = 1): robots "
                                              "never wait for each other within a tick")
        stale = v.get("stale")
        if stale is not None and not (type(stale) in (int, float) and 0 < stale < 1e6):
            raise self.fail(f"{where}.stale", f"{stale!r}: expected seconds > 0")
        return InputDecl(port, key, scope, delay, None if stale is None else float(stale))
