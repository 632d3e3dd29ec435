"""The module API: what a node of a robot's controller declares and what it computes.

A node is one module of a controller (target localization, one obstacle localization,
motor integration, or a user's own). It declares, as class attributes:

* ``inputs``: its input ports, ``{port: In(MessageType, many=False)}``; a graph binds each
  port to keys (the robot's own, or every teammate's);
* ``outputs``: its output ports, ``{port: Out(MessageType)}``; a graph gives each its key;
* ``Params``: a frozen dataclass of its parameters with their defaults (a graph may set
  them; a parameter the node does not declare is refused before anything starts);
* ``stateful``: True when its outputs depend on more than the inputs of the tick (a
  memory across ticks), so a restart changes what it computes;
* ``uses_model``: True when it reads the run's trained model (:meth:`Context.model`);
* ``pure``: True when its outputs at tick t are a function of its inputs' values alone (t
  only stamps them): a tick in which its one reading is unchanged may then leave its run
  out, its previous outputs restamped standing for the tick's (the paper's localization
  EKMs "remain activated until they are updated at the next sensing cycle");
* ``warm_setup``: True when :meth:`Node.setup` only computes data (the model, tables
  through :meth:`Context.shared`) and starts no thread, socket or open file: a warm start
  (:mod:`cekm_swarm.launch.forkserver`) then runs one setup in the fork server, and every
  node forked from it finds those shared values made.

and computes in :meth:`Node.step`: ``step(t, inputs) -> {port: message}``, one message per
output port every time it runs. The framework does the rest (the session, the liveliness
token, validation and drop counting, stamp checks, which inputs of which tick a step sees
in lockstep and in real time, restart and shutdown): :mod:`cekm_swarm.node.process` runs a
node as its own process, :mod:`cekm_swarm.node.inprocess` runs a whole graph in one
process, both by the same rule (:mod:`cekm_swarm.node.timing`). docs/modules.md walks
through writing one.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import os
import threading
import traceback
import types
import typing
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar

from cekm_swarm.errors import CekmError
from cekm_swarm.protocol import is_message_type
from cekm_swarm.robot import RobotBody


class NodeError(CekmError):
    """A node cannot be built or run as declared (a bad parameter, a model it cannot use);
    the message names the node and what is wrong. A node that raises it while starting is
    a permanent failure: the launch ends with this line, and the node is not restarted."""


class StepFailed(NodeError):
    """A node's step raised, returned what it may not, or ran past ``--step-timeout``: the
    run failed (``cekm: failed: ...``, exit code 1), in one line naming the node and the tick."""

    exit_code = 1


class NotReady(Exception):
    """Raised by a node's ``step`` when an input it cannot do without is missing: in real
    time a one-key input is None until its first value arrives (or while it is stale).
    The run gives no outputs, and the tick runs again when more of its values arrive; a tick
    still not ready when the next one begins is given up and counted as ``not_ready`` in the
    node's report. In lockstep and in one process every input of a run is there, so raising
    it there is a failure of the node like any other exception."""


@dataclass(frozen=True)
class In:
    """An input port: the message type it takes, and whether it takes many keys (every
    instance of a node, or every teammate) or one."""

    type: type
    many: bool = False
    doc: str = ""

    def __post_init__(self) -> None:
        if not is_message_type(self.type):
            raise TypeError(f"In({self.type!r}): not a message type of cekm_swarm.protocol, nor a UserMessage")


@dataclass(frozen=True)
class Out:
    """An output port: the message type it sends."""

    type: type
    doc: str = ""

    def __post_init__(self) -> None:
        if not is_message_type(self.type):
            raise TypeError(f"Out({self.type!r}): not a message type of cekm_swarm.protocol, nor a UserMessage")


@dataclass(frozen=True)
class NoParams:
    """A node without parameters."""


_MODELS: dict[str, Any] = {}
_SHARED: dict[Any, Any] = {}
_LOCK = threading.Lock()


@dataclass(frozen=True)
class Context:
    """What a node knows of where it runs (``self.ctx``):

    * ``robot``: its robot's id (``r1``); ``node``: its name in the graph; ``instance``: its
      instance number (0..11 for ``obstacle-0..11``; None for a node of one instance);
      :attr:`name` and :attr:`sender` (``r1/obstacle-3``);
    * ``team``: every robot of the run, in scenario order; :attr:`teammates`: the others;
    * ``body``: its body and sensors, a :class:`cekm_swarm.robot.RobotBody` (``body_radius``,
      ``axle``, ``v_max``, ``sensor_angles``, ``sensor_range``, ``target_range``, in m,
      m/s and rad), from the scenario;
    * ``mode``: ``lockstep``, ``realtime``, ``inprocess`` (``cekm run``) or ``check`` (the
      launcher's build of the node before anything starts: skip side effects there);
    * :meth:`model`: the run's trained model; :meth:`shared`: a value computed once per process;
    * ``log``: a logger whose lines go to the node's log;
    * ``backend``: how EKM winners are found: ``numba`` in one process, ``numpy`` in a
      module process (a third of the memory); both give the same winners bit for bit."""

    robot: str
    node: str
    instance: int | None = None
    team: tuple[str, ...] = ()
    body: RobotBody = field(default_factory=RobotBody)
    mode: str = "inprocess"
    model_source: Any = None
    backend: str = "numba"
    log: logging.Logger = field(default_factory=lambda: logging.getLogger("cekm_swarm.node"), compare=False)

    @property
    def name(self) -> str:
        """The node's name in the run: ``obstacle-3`` for instance 3 of ``obstacle``."""
        return self.node if self.instance is None else f"{self.node}-{self.instance}"

    @property
    def sender(self) -> str:
        """The ``sender`` of every message this node sends: ``r1/obstacle-3``."""
        return f"{self.robot}/{self.name}"

    @property
    def teammates(self) -> tuple[str, ...]:
        """The other robots of the team, in scenario order."""
        return tuple(r for r in self.team if r != self.robot)

    def model(self) -> Any:
        """The run's trained model (loaded once per process, shared by its nodes)."""
        src = self.model_source
        if src is None:
            raise NodeError(f"{self.sender}: this run has no model (give --model)")
        if not isinstance(src, (str, tuple)):
            return src  # an in-process run hands the model object itself
        key = src if isinstance(src, str) else src[0]
        with _LOCK:
            held = _MODELS.get(key)
        if held is None:
            from cekm_swarm.models.io import load_model, load_model_bytes  # noqa: PLC0415 -- lazy: ~25 ms, for a node that reads the model

            held = load_model(src) if isinstance(src, str) else load_model_bytes(src[1], src[0])
            with _LOCK:
                if len(_MODELS) >= 8:
                    _MODELS.clear()
                _MODELS[key] = held
        return held

    def shared(self, key: Any, make: Callable[[], Any]) -> Any:
        """A value computed once per process for ``key`` (say the EKM tables of a model
        and its field parameters) and shared by every node of the process: what a pure
        function of the key gives, so sharing never changes a result."""
        with _LOCK:
            if key in _SHARED:
                return _SHARED[key]
        value = make()
        with _LOCK:
            if len(_SHARED) >= 64:
                _SHARED.clear()
            return _SHARED.setdefault(key, value)


class Node:
    """Base class of a node (see the module's docstring). A subclass sets ``inputs``,
    ``outputs`` and, when it has any, ``Params``; it may override :meth:`setup` (called
    once, before the first step) and must override :meth:`step`."""

    inputs: ClassVar[Mapping[str, In]] = {}
    outputs: ClassVar[Mapping[str, Out]] = {}
    Params: ClassVar[type] = NoParams
    stateful: ClassVar[bool] = False
    uses_model: ClassVar[bool] = False
    pure: ClassVar[bool] = False
    warm_setup: ClassVar[bool] = False

    def __init__(self, ctx: Context, params: Any = None) -> None:
        self.ctx = ctx
        self.params = params if params is not None else self.Params()
        try:
            self.setup()
        except Exception as exc:  # noqa: BLE001 - a user's node may fail in any way while starting
            raise NodeError(cannot_start(ctx.sender, exc)) from exc

    def setup(self) -> None:
        """Build what the node needs (load the model, tabulate fields). Raise
        :class:`NodeError` for a configuration it cannot use."""

    def step(self, t: float, inputs: Inputs) -> dict[str, Any]:
        """Compute the outputs of the tick at sim time ``t``: one message per output port."""
        raise NotImplementedError

    def check_input(self, port: str, msg: Any) -> str | None:
        """Why a well-formed message on input ``port`` cannot be used here (None: it can),
        say a field whose vector does not fit this model's lattice: the framework drops and
        counts it before it can take the place of the real one."""
        return None

    def teammate_left(self, robot: str) -> None:
        """Every process of teammate ``robot`` is gone (its liveliness tokens vanished)."""

    def close(self) -> None:
        """Called once when the node stops."""


def cannot_start(label: str, exc: BaseException) -> str:
    """The one line of node ``label`` that cannot start because building or setting it up
    raised ``exc``: a :class:`NodeError` or another of the package's errors says what is
    wrong, after the node's name; any other exception is a fault of the node's code, named
    by its type and the file and line that raised it (:func:`raised_at`). The same line in
    ``cekm run``, the launcher's check of a graph and a node's process; the traceback goes
    to the node's log (:func:`traceback_text`)."""
    what = " ".join(str(exc).split())
    if not isinstance(exc, CekmError):
        at = raised_at(exc)
        return f"{label}: cannot start: {type(exc).__name__}: {what}" + (f" ({at})" if at else "")
    return what if what.startswith(f"{label}:") else f"{label}: {what}"


_PLUMBING = tuple(os.path.join(os.path.dirname(os.path.dirname(__file__)), d) + os.sep for d in ("node", "protocol"))


def raised_at(exc: BaseException) -> str:
    """``file.py:line`` of the innermost frame of ``exc``'s traceback in the node's own code
    (not the framework's checks), "" when it has none."""
    frames = traceback.extract_tb(exc.__traceback__)
    own = [f for f in frames if not f.filename.startswith(_PLUMBING + ("<",))] or frames
    if not own:
        return ""
    return f"{os.path.basename(own[-1].filename)}:{own[-1].lineno}"


def traceback_text(exc: BaseException) -> str:
    """The traceback of what made ``exc`` (its cause when it wraps one), for a node's log."""
    cause = exc.__cause__ if exc.__cause__ is not None else exc
    return "".join(traceback.format_exception(type(cause), cause, cause.__traceback__))


def start_node(cls: type[Node], ctx: Context, params: Any = None) -> Node:
    """``cls(ctx, params)``, built and set up; a :class:`NodeError` with the node's one line
    (:func:`cannot_start`) when that fails."""
    try:
        return cls(ctx, params)
    except Exception as exc:  # noqa: BLE001 - a user's node (its own __init__) may fail in any way
        raise NodeError(cannot_start(ctx.sender, exc)) from exc


class Inputs(Mapping[str, Any]):
    """The inputs a step sees: ``inputs[port]`` is the message (None when it is missing:
    not sent yet, or stale in real time) for a one-key port, and a dict ``{source:
    message}`` for a many-key port (sources are instance numbers or robot ids, in
    instance or team order; missing ones left out)."""

    __slots__ = ("_values",)

    def __init__(self, values: dict[str, Any]) -> None:
        self._values = values

    def __getitem__(self, port: str) -> Any:
        try:
            return self._values[port]
        except KeyError:
            raise KeyError(f"no input port {port!r} (ports: {', '.join(self._values) or 'none'})") from None

    def __iter__(self) -> Iterator[str]:
        return iter(self._values)

    def __len__(self) -> int:
        return len(self._values)


def need(inputs: Mapping[str, Any], *ports: str) -> Any:
    """The messages of one-key ``ports`` of a step's ``inputs``, raising :class:`NotReady`
    if one is missing (real time: not arrived yet, or stale), so the run waits rather than
    computing from nothing: ``pose, sensed = need(inputs, "pose", "targets")``."""
    got = tuple(inputs[p] for p in ports)
    if any(m is None for m in got):
        raise NotReady(", ".join(p for p, m in zip(ports, got, strict=True) if m is None))
    return got[0] if len(got) == 1 else got


# --------------------------------------------------------------------------- parameters


def param_fields(cls: type[Node]) -> dict[str, dataclasses.Field[Any]]:
    """The declared parameters of a node class: name -> dataclass field."""
    P = cls.Params
    if not dataclasses.is_dataclass(P):
        raise TypeError(f"{cls.__qualname__}.Params must be a dataclass, got {P!r}")
    return {f.name: f for f in dataclasses.fields(P)}


def param_default(f: dataclasses.Field[Any]) -> Any:
    if f.default is not dataclasses.MISSING:
        return f.default
    if f.default_factory is not dataclasses.MISSING:
        return f.default_factory()
    return dataclasses.MISSING


def _type_of(cls: type[Node], name: str) -> Any:
    hints = typing.get_type_hints(cls.Params)
    return hints.get(name, Any)


def _exactly(kind: type, what: str) -> Callable[[Any, str], Any]:
    def check(value: Any, where: str) -> Any:
        if type(value) is not kind:
            raise ValueError(f"{where}: expected {what}, got {value!r}")
        return value

    return check


def _number(value: Any, where: str) -> float:
    if type(value) not in (int, float):
        raise ValueError(f"{where}: expected a number, got {value!r}")
    number = float(value)
    if math.isnan(number):
        raise ValueError(f"{where}: expected a number, got NaN")
    return number


_SCALARS: dict[type, Callable[[Any, str], Any]] = {
    bool: _exactly(bool, "true or false"), int: _exactly(int, "an integer"), float: _number,
    str: _exactly(str, "a string"),
}
"""A parameter of a scalar type: its check (a bool is not an int, an int is a float)."""


def _coerce(value: Any, kind: Any, where: str) -> Any:
    """``value`` as a parameter of type ``kind`` (bool, int, float, str, tuples of them), or
    a ValueError naming ``where``."""
    if kind is Any:
        return value
    scalar = _SCALARS.get(kind) if isinstance(kind, type) else None
    if scalar is not None:
        return scalar(value, where)
    origin = typing.get_origin(kind)
    if origin is tuple:
        if not isinstance(value, (list, tuple)):
            raise ValueError(f"{where}: expected a list, got {value!r}")
        args = typing.get_args(kind)
        item = args[0] if args else Any
        return tuple(_coerce(v, item, f"{where}[{i}]") for i, v in enumerate(value))
    if origin in (typing.Union, types.UnionType):
        return _coerce_union(value, kind, where)
    return value


def _coerce_union(value: Any, kind: Any, where: str) -> Any:
    """``value`` as the first arm of union ``kind`` it fits (None for an optional's None)."""
    errors = []
    for arm in typing.get_args(kind):
        if arm is type(None):
            if value is None:
                return None
            continue
        try:
            return _coerce(value, arm, where)
        except ValueError as exc:
            errors.append(str(exc))
    raise ValueError(errors[0] if errors else f"{where}: {value!r} does not fit {kind}")


def make_params(cls: type[Node], values: Mapping[str, Any], where: str) -> Any:
    """The node's ``Params`` from ``values`` (a graph's settings), checked: an undeclared
    name or a value of the wrong type is a ValueError naming ``where`` and the field."""
    declared = param_fields(cls)
    unknown = sorted(set(values) - set(declared))
    if unknown:
        raise ValueError(f"{where}: parameter {unknown[0]!r} is not declared by {cls.__module__}.{cls.__qualname__} "
                         f"(its parameters: {', '.join(declared) or 'none'})")
    kw = {name: _coerce(v, _type_of(cls, name), f"{where}.{name}") for name, v in values.items()}
    try:
        return cls.Params(**kw)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{where}: {exc}") from None
