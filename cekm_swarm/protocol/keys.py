"""The Zenoh key space of docs/design.md section 6: build and parse every key.

Keys (root ``cekm`` by default, ``<robot>`` a robot id such as ``r1``):

========================================  ======================
``<root>/<robot>/sense/target``           KeyKind.SENSE_TARGET
``<root>/<robot>/sense/range/<j>``        KeyKind.SENSE_RANGE
``<root>/<robot>/sense/pose``             KeyKind.SENSE_POSE (tracking)
``<root>/<robot>/sense/targets``          KeyKind.SENSE_TARGETS (tracking)
``<root>/<robot>/sense/odometry``         KeyKind.SENSE_ODOMETRY (wheel encoders)
``<root>/<robot>/field/target``           KeyKind.FIELD_TARGET
``<root>/<robot>/field/obstacle/<j>``     KeyKind.FIELD_OBSTACLE
``<root>/<robot>/field/tracking``         KeyKind.FIELD_TRACKING (tracking)
``<root>/<robot>/cmd/wheels``             KeyKind.CMD_WHEELS
``<root>/<robot>/share``                  KeyKind.SHARE
``<root>/world/state``                    KeyKind.WORLD_STATE
``<root>/world/clock``                    KeyKind.WORLD_CLOCK
``<root>/<owner>/alive/<module>[/<run>]`` KeyKind.ALIVE (liveliness tokens)
``<root>/<robot>/<path>``                 KeyKind.NODE (a key a graph's node declares)
========================================  ======================

A controller's graph (:mod:`cekm_swarm.graph`) may give its nodes keys of their own
under the robot (``cekm/r1/fusion/avoid``): they parse as ``KeyKind.NODE`` and carry
the message kind their node declares (``KeyKind.DATA`` for a node's own named values).

A liveliness token carries the run id of the launch its process belongs to (a key space
built with ``run``), so the world server counts only its own run's modules: a process
left over from another run can never be taken for one of this run.

``world`` is reserved: it is not a robot id, but it may own liveliness tokens
(``cekm/world/alive/server``). Building a key validates every part, so a bad robot id
or sensor index fails where it is made, not somewhere downstream.
"""

from __future__ import annotations

import enum
import operator
import re
from dataclasses import dataclass

from .errors import KeySpaceError

WORLD = "world"
"""The reserved owner segment of the world server's keys."""

DEFAULT_ROOT = "cekm"
DEFAULT_RANGE_SENSORS = 12

_ROBOT_RE = re.compile(r"[A-Za-z][A-Za-z0-9_-]{0,63}\Z")
_MODULE_RE = re.compile(r"[A-Za-z][A-Za-z0-9_.-]{0,63}\Z")
_CHUNK_RE = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]*\Z")
_RUN_RE = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,63}\Z")


class KeyKind(str, enum.Enum):  # noqa: UP042 -- StrEnum would change what str() and format() of a member print
    """What a key carries; the value is the key's suffix after the robot segment."""

    SENSE_TARGET = "sense/target"
    SENSE_RANGE = "sense/range"
    SENSE_POSE = "sense/pose"
    SENSE_TARGETS = "sense/targets"
    SENSE_UNCHANGED = "sense/unchanged"
    SENSE_ODOMETRY = "sense/odometry"
    FIELD_TARGET = "field/target"
    FIELD_OBSTACLE = "field/obstacle"
    FIELD_TRACKING = "field/tracking"
    CMD_WHEELS = "cmd/wheels"
    SHARE = "share"
    WORLD_STATE = "world/state"
    WORLD_CLOCK = "world/clock"
    ALIVE = "alive"
    NODE = "node"
    """A key a graph declares for a node's output (``<root>/<robot>/<path>``); not a message kind."""
    DATA = "data"
    """The message kind of a node's own named values (:class:`~cekm_swarm.protocol.messages.Data`); no key has it."""
    MAP_VERSION = "map"
    """The message kind of a learner's map version (:class:`~cekm_swarm.protocol.messages.MapVersion`,
    docs/learning.md); it travels on a key its graph declares (``model/update``)."""

    @property
    def indexed(self) -> bool:
        """True for the kinds whose key ends with a sensor index."""
        return self in (KeyKind.SENSE_RANGE, KeyKind.FIELD_OBSTACLE)


@dataclass(frozen=True, slots=True)
class ParsedKey:
    """A key taken apart: its kind, robot (or ``world`` owner), sensor index and module."""

    kind: KeyKind
    robot: str | None = None
    index: int | None = None
    module: str | None = None
    run: str | None = None
    path: str | None = None  # KeyKind.NODE: the key below the robot


def validate_robot_id(robot: object) -> str:
    """Return ``robot`` if it is a valid robot id (a letter, then letters, digits, ``_`` or ``-``)."""
    if not isinstance(robot, str):
        raise KeySpaceError("robot id", f"expected a string, got {type(robot).__name__}")
    if robot == WORLD:
        raise KeySpaceError(f"robot id '{robot}'", "'world' is reserved for the world server's keys")
    if not _ROBOT_RE.match(robot):
        raise KeySpaceError(f"robot id {robot!r}",
                            "must start with a letter and hold only letters, digits, '_' or '-' (at most 64)")
    return robot


def validate_module_name(module: object) -> str:
    """Return ``module`` if it is a valid module name (e.g. ``target``, ``obstacle-3``, ``motor``)."""
    if not isinstance(module, str):
        raise KeySpaceError("module name", f"expected a string, got {type(module).__name__}")
    if not _MODULE_RE.match(module):
        raise KeySpaceError(f"module name {module!r}",
                            "must start with a letter and hold only letters, digits, '_', '.' or '-' (at most 64)")
    return module


def validate_run_id(run: object) -> str:
    """Return ``run`` if it is a valid run id (a letter or digit, then letters, digits,
    ``_``, ``.`` or ``-``; at most 64): one plain chunk of a key."""
    if not isinstance(run, str):
        raise KeySpaceError("run id", f"expected a string, got {type(run).__name__}")
    if not _RUN_RE.match(run):
        raise KeySpaceError(f"run id {run!r}", "must start with a letter or digit and hold only letters, digits, "
                                               "'_', '.' or '-' (at most 64)")
    return run


def validate_root(root: object) -> str:
    """Return ``root`` if it is a valid key root: '/'-separated plain chunks, no wildcards."""
    if not isinstance(root, str) or not root:
        raise KeySpaceError("key root", f"expected a non-empty string, got {root!r}")
    for chunk in root.split("/"):
        if not _CHUNK_RE.match(chunk):
            raise KeySpaceError(f"key root {root!r}",
                                f"chunk {chunk!r} must be letters, digits, '_', '.' or '-' "
                                f"(no wildcards, no empty chunks)")
    return root


_TWO_PART = {k.value: k for k in (KeyKind.SENSE_TARGET, KeyKind.FIELD_TARGET, KeyKind.CMD_WHEELS,
                                    KeyKind.SENSE_POSE, KeyKind.SENSE_TARGETS, KeyKind.SENSE_UNCHANGED,
                                    KeyKind.FIELD_TRACKING, KeyKind.SENSE_ODOMETRY)}
"""A robot's keys of two parts (``sense/target``): their kinds."""
_INDEXED = {k.value: k for k in (KeyKind.SENSE_RANGE, KeyKind.FIELD_OBSTACLE)}
"""A robot's keys of two parts and a sensor index (``sense/range/3``): their kinds."""


@dataclass(frozen=True, slots=True)
class KeySpace:
    """The key space under one root, for robots with ``range_sensors`` distance sensors."""

    root: str = DEFAULT_ROOT
    range_sensors: int = DEFAULT_RANGE_SENSORS
    run: str | None = None
    """The run id in liveliness tokens (None: tokens without one, and selectors matching any run)."""

    def __post_init__(self) -> None:
        validate_root(self.root)
        if self.run is not None:
            validate_run_id(self.run)
        if isinstance(self.range_sensors, bool) or not isinstance(self.range_sensors, int) or self.range_sensors < 1:
            raise KeySpaceError("range_sensors", f"expected a positive integer, got {self.range_sensors!r}")

    # ------------------------------------------------------------------ checks

    def check_index(self, index: object, what: str = "sensor index") -> int:
        """Return ``index`` as an int if it is a sensor index 0 .. range_sensors-1."""
        if isinstance(index, bool):
            raise KeySpaceError(what, "expected an integer, got bool")
        try:
            j = operator.index(index)  # type: ignore[arg-type]
        except TypeError:
            raise KeySpaceError(what, f"expected an integer, got {type(index).__name__}") from None
        if not 0 <= j < self.range_sensors:
            raise KeySpaceError(f"{what} {j}", f"out of range 0..{self.range_sensors - 1}")
        return j

    def _robot(self, robot: str) -> str:
        return f"{self.root}/{validate_robot_id(robot)}"

    # ------------------------------------------------------------------ builders

    def sense_target(self, robot: str) -> str:
        """World -> target module: the robot's target reading."""
        return f"{self._robot(robot)}/sense/target"

    def sense_range(self, robot: str, j: int) -> str:
        """World -> obstacle module j: distance sensor j's reading."""
        return f"{self._robot(robot)}/sense/range/{self.check_index(j)}"

    def sense_pose(self, robot: str) -> str:
        """World -> tracking module: the robot's own pose (tracking scenarios)."""
        return f"{self._robot(robot)}/sense/pose"

    def sense_targets(self, robot: str) -> str:
        """World -> tracking module: every target within sensing range (tracking scenarios)."""
        return f"{self._robot(robot)}/sense/targets"

    def sense_odometry(self, robot: str) -> str:
        """World -> the learner: the wheel encoders' travel over the tick (docs/learning.md)."""
        return f"{self._robot(robot)}/sense/odometry"

    def sense_unchanged(self, robot: str) -> str:
        """World -> the readers of a robot's held readings: which of its readings this tick
        left out because they equal the last ones sent (:class:`~.messages.Unchanged`)."""
        return f"{self._robot(robot)}/sense/unchanged"

    def share_all(self) -> str:
        """Key expression matching every robot's share (what teammates subscribe to)."""
        return f"{self.root}/*/share"

    def field_target(self, robot: str) -> str:
        """Target module -> motor module: the target field."""
        return f"{self._robot(robot)}/field/target"

    def field_tracking(self, robot: str) -> str:
        """Tracking target module -> motor module: the weighted target and teammate fields (tracking scenarios)."""
        return f"{self._robot(robot)}/field/tracking"

    def field_obstacle(self, robot: str, j: int) -> str:
        """Obstacle module j -> motor module: sensor j's obstacle field."""
        return f"{self._robot(robot)}/field/obstacle/{self.check_index(j)}"

    def node_key(self, robot: str, path: str) -> str:
        """A key a graph declares for a node of ``robot`` (``path`` below the robot, e.g. ``fusion/avoid``)."""
        return f"{self._robot(robot)}/{path}"

    def cmd_wheels(self, robot: str) -> str:
        """Motor module -> world: the wheel command."""
        return f"{self._robot(robot)}/cmd/wheels"

    def share(self, robot: str) -> str:
        """Robot -> teammates: own pose and targets seen."""
        return f"{self._robot(robot)}/share"

    def world_state(self) -> str:
        """World -> monitors: ground-truth state."""
        return f"{self.root}/{WORLD}/state"

    def world_clock(self) -> str:
        """World -> all: sim time (lockstep)."""
        return f"{self.root}/{WORLD}/clock"

    def world_model(self) -> str:
        """Launcher -> modules: the queryable serving the trained model's file (a query,
        not a publication: ``--model zenoh``; see :mod:`cekm_swarm.runtime.model_service`)."""
        return f"{self.root}/{WORLD}/model"

    def param(self, robot: str, node: str) -> str:
        """Tools -> a node: the queryable of its parameters (``cekm param``; JSON both ways)."""
        return f"{self._robot(robot)}/param/{validate_module_name(node)}"

    def world_geometry(self) -> str:
        """World -> recorders: the queryable serving the static scene as JSON (walls, fixed
        obstacles; what the world's own log keeps as metadata; see
        :mod:`cekm_swarm.runtime.record`)."""
        return f"{self.root}/{WORLD}/geometry"

    def world_graph(self) -> str:
        """World -> tools: the queryable serving the run spec as JSON (the graph the run
        runs: which nodes ``cekm node list`` and the monitor expect, which fields the view
        draws)."""
        return f"{self.root}/{WORLD}/graph"

    def alive(self, owner: str, module: str) -> str:
        """Liveliness token of a module of robot ``owner`` (or of the world server, owner
        ``world``) in this key space's run."""
        head = f"{self.root}/{WORLD}" if owner == WORLD else self._robot(owner)
        key = f"{head}/alive/{validate_module_name(module)}"
        return key if self.run is None else f"{key}/{self.run}"

    def world_ended(self) -> str:
        """Liveliness token the world server declares as its run ends, before its own token
        goes: a robots-only host that sees it knows the run is over, not that the router it
        shared with the world host was lost (so it does not wait for that router to return)."""
        return self.alive(WORLD, "ended")

    def with_run(self, run: str | None) -> KeySpace:
        """This key space for the run ``run``."""
        return KeySpace(self.root, self.range_sensors, run)

    def key(self, kind: KeyKind | str, robot: str | None = None, index: int | None = None,
            module: str | None = None) -> str:
        """Build the key of ``kind`` (the inverse of :meth:`parse`)."""
        kind = KeyKind(kind)
        if kind is KeyKind.WORLD_STATE:
            return self.world_state()
        if kind is KeyKind.WORLD_CLOCK:
            return self.world_clock()
        if robot is None:
            raise KeySpaceError(f"key of kind '{kind.value}'", "needs a robot id")
        if kind is KeyKind.ALIVE:
            if module is None:
                raise KeySpaceError("liveliness key", "needs a module name")
            return self.alive(robot, module)
        if kind.indexed:
            if index is None:
                raise KeySpaceError(f"key of kind '{kind.value}'", "needs a sensor index")
            return f"{self._robot(robot)}/{kind.value}/{self.check_index(index)}"
        return f"{self._robot(robot)}/{kind.value}"

    # ------------------------------------------------------------------ selectors

    def everything(self) -> str:
        """Key expression matching every key under the root."""
        return f"{self.root}/**"

    def robot_keys(self, robot: str) -> str:
        """Key expression matching every key of one robot."""
        return f"{self._robot(robot)}/**"

    def cmd_wheels_all(self) -> str:
        """Key expression matching every robot's wheel command (what the world listens to)."""
        return f"{self.root}/*/cmd/wheels"

    def alive_all(self) -> str:
        """Key expression matching every liveliness token (robots' and the world's) of this
        key space's run; of any run (and tokens without one) when ``run`` is None."""
        return f"{self.root}/*/alive/**" if self.run is None else f"{self.root}/*/alive/*/{self.run}"

    def world_alive_any_run(self) -> str:
        """Key expression matching the world server's token of any run (how a robots-only
        host learns the run it joins)."""
        return f"{self.root}/{WORLD}/alive/server/*"

    # ------------------------------------------------------------------ parser

    def parse(self, key: str) -> ParsedKey:
        """Take ``key`` apart; raise KeySpaceError naming the key when it is not in this key space."""
        if not isinstance(key, str):
            raise KeySpaceError("key", f"expected a string, got {type(key).__name__}")
        prefix = self.root + "/"
        if not key.startswith(prefix):
            raise KeySpaceError(f"key '{key}'", f"not under the root '{self.root}'")
        parts = key[len(prefix):].split("/")
        owner, rest = parts[0], parts[1:]
        if owner == WORLD:
            return self._world_key(key, rest)
        try:
            validate_robot_id(owner)
        except KeySpaceError as exc:
            raise KeySpaceError(f"key '{key}'", f"bad robot id: {exc.problem}") from None
        return self._robot_key(key, owner, rest)

    def _world_key(self, key: str, rest: list[str]) -> ParsedKey:
        """A key under ``<root>/world/``: its state, its clock, a token of one of its modules."""
        if rest == ["state"]:
            return ParsedKey(KeyKind.WORLD_STATE)
        if rest == ["clock"]:
            return ParsedKey(KeyKind.WORLD_CLOCK)
        if len(rest) in (2, 3) and rest[0] == "alive":
            return ParsedKey(KeyKind.ALIVE, WORLD, None, self._module_in(key, rest[1]), self._run_in(key, rest[2:]))
        raise KeySpaceError(f"key '{key}'", "unknown world key (expected world/state, world/clock or "
                                            "world/alive/<module>[/<run>])")

    def _robot_key(self, key: str, owner: str, rest: list[str]) -> ParsedKey:
        """A key under ``<root>/<robot>/``: a kind of its own, a token, or a graph node's key."""
        n = len(rest)
        if n == 1 and rest[0] == "share":
            return ParsedKey(KeyKind.SHARE, owner)
        if n == 2:
            kind = _TWO_PART.get(f"{rest[0]}/{rest[1]}")
            if kind is not None:
                return ParsedKey(kind, owner)
            if rest[0] == "alive":
                return ParsedKey(KeyKind.ALIVE, owner, None, self._module_in(key, rest[1]))
        if n == 3 and rest[0] == "alive":
            return ParsedKey(KeyKind.ALIVE, owner, None, self._module_in(key, rest[1]), self._run_in(key, rest[2:]))
        if n == 3:
            kind = _INDEXED.get(f"{rest[0]}/{rest[1]}")
            if kind is not None:
                return ParsedKey(kind, owner, self._index_in(key, rest[2]))
        if 1 <= n <= 8 and rest[0] not in ("alive", "sense") and all(_CHUNK_RE.match(c) for c in rest):
            return ParsedKey(KeyKind.NODE, owner, path="/".join(rest))
        raise KeySpaceError(f"key '{key}'", "not a key of the cekm key space (docs/design.md section 6)")

    def _index_in(self, key: str, text: str) -> int:
        if not text.isdigit() or (len(text) > 1 and text[0] == "0") or not text.isascii():
            raise KeySpaceError(f"key '{key}'", f"sensor index {text!r} is not a plain non-negative integer")
        j = int(text)
        if j >= self.range_sensors:
            raise KeySpaceError(f"key '{key}'", f"sensor index {j} out of range 0..{self.range_sensors - 1}")
        return j

    @staticmethod
    def _run_in(key: str, rest: list[str]) -> str | None:
        if not rest:
            return None
        try:
            return validate_run_id(rest[0])
        except KeySpaceError as exc:
            raise KeySpaceError(f"key '{key}'", f"bad run id: {exc.problem}") from None

    @staticmethod
    def _module_in(key: str, text: str) -> str:
        try:
            return validate_module_name(text)
        except KeySpaceError as exc:
            raise KeySpaceError(f"key '{key}'", f"bad module name: {exc.problem}") from None


DEFAULT_KEYS = KeySpace()
"""The key space with root ``cekm`` and 12 distance sensors."""
