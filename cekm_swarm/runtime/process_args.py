"""Command lines of the runtime's processes, declared once.

A process (the world server, a module) declares its parameters as a tuple of
:class:`Param`; its own parser is built from the declaration (:func:`add_params`) and
the launcher builds the argv that starts it from the same declaration
(:func:`to_argv`), so the two cannot drift apart: an unknown or missing parameter is a
``TypeError`` in the launcher, not a process that dies on start-up.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

from cekm_swarm.protocol import KeySpaceError, validate_run_id


@dataclass(frozen=True)
class Param:
    """One parameter of a process: ``name`` is the attribute in the parsed namespace and,
    with ``-`` for ``_``, the flag (``--name``); ``positional`` ones come first, in order."""

    name: str
    type: Callable[[str], Any] = str
    default: Any = None
    help: str = ""
    required: bool = False
    choices: tuple[str, ...] | None = None
    metavar: str | None = None
    positional: bool = False
    exclusive: str | None = None  # parameters sharing a group name are mutually exclusive

    @property
    def flag(self) -> str:
        return self.name if self.positional else "--" + self.name.replace("_", "-")


def add_params(parser: argparse.ArgumentParser, params: Iterable[Param]) -> argparse.ArgumentParser:
    """Add ``params`` to ``parser`` (positional ones as arguments, the rest as options)."""
    groups: dict[str, Any] = {}
    for p in params:
        target: Any = parser
        if p.exclusive is not None:
            if p.exclusive not in groups:
                groups[p.exclusive] = parser.add_mutually_exclusive_group()
            target = groups[p.exclusive]
        kw: dict[str, Any] = {"type": p.type, "help": p.help}
        if p.choices is not None:
            kw["choices"] = p.choices
        if p.metavar is not None:
            kw["metavar"] = p.metavar
        if p.positional:
            target.add_argument(p.name, **kw)
        else:
            target.add_argument(p.flag, dest=p.name, default=p.default, required=p.required, **kw)
    return parser


def to_argv(params: Iterable[Param], **values: Any) -> list[str]:
    """The argv that gives ``values`` to a parser built from ``params``. Values that are
    None are left out (the process takes its default); a name not declared, or a
    required one missing, raises TypeError."""
    params = tuple(params)
    known = {p.name for p in params}
    unknown = sorted(set(values) - known)
    if unknown:
        raise TypeError(f"not parameters of this process: {', '.join(unknown)}")
    head: list[str] = []
    tail: list[str] = []
    for p in params:
        value = values.get(p.name)
        if value is None:
            if p.required or p.positional:
                raise TypeError(f"parameter {p.flag} is required")
            continue
        if p.positional:
            head.append(str(value))
        else:
            tail += [p.flag, str(value)]
    return head + tail


def run_id_arg(text: str) -> str:
    """argparse type of ``--run-id``: a run id usable in a key (one plain chunk)."""
    try:
        return validate_run_id(text)
    except KeySpaceError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
