"""Scenario files: TOML schema, loading and strict validation.

A scenario with any error is refused before anything starts: :class:`ScenarioError`
names the file, the field path (``obstacles[1].motion.radius``) and what is wrong.
The schema reference is ``world/scenarios/README.md``.
"""

from __future__ import annotations

import copy
import re
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from .scenario_parser import Parser
from .scenario_spec import ID_RE, WHEEL_SPEED_UNIT, Scenario, ScenarioError

# the specs themselves (RobotSpec, ObstacleSpec, ...) are world.scenario_spec's
__all__ = ["SCENARIO_DIR", "WHEEL_SPEED_UNIT", "Scenario", "ScenarioError", "load_scenario", "parse_scenario",
           "resolve_scenario_path", "scenario_names"]

SCENARIO_DIR = Path(__file__).resolve().parent / "scenarios"


# ------------------------------------------------------------------ public loading


def scenario_names() -> list[str]:
    """Names of the shipped scenarios (files in ``world/scenarios``)."""
    return sorted(p.stem for p in SCENARIO_DIR.glob("*.toml"))


def resolve_scenario_path(path_or_name: str | Path) -> Path:
    """A file path, or a bare name resolved to ``world/scenarios/<name>.toml``."""
    p = Path(path_or_name)
    if p.is_file():
        return p
    name = str(path_or_name)
    if ID_RE.match(name):
        q = SCENARIO_DIR / f"{name}.toml"
        if q.is_file():
            return q
    if p.is_dir():
        raise ScenarioError(f"{path_or_name}: is a directory, not a scenario file")
    raise ScenarioError(
        f"{path_or_name}: no such scenario file or shipped scenario name (shipped: {', '.join(scenario_names())})"
    )


def load_scenario(path_or_name: str | Path, overrides: Mapping[str, Any] | None = None) -> Scenario:
    """Load and validate a scenario.

    ``path_or_name``: a TOML file path, or a shipped name like ``"concave"``.
    ``overrides``: optional ``{field path: value}`` applied to the raw TOML before
    validation, e.g. ``{"obstacles[0].width": 0.5, "sensors.range": 0.25}`` (used by
    parameter sweeps); overridden values are validated like the file's own.
    """
    path = resolve_scenario_path(path_or_name)
    fname = str(path)
    try:
        with open(path, "rb") as f:
            raw = tomllib.load(f)
    except tomllib.TOMLDecodeError as e:
        raise ScenarioError(f"{fname}: TOML syntax error: {e}") from None
    if overrides:
        raw = copy.deepcopy(raw)
        for k, v in overrides.items():
            _apply_override(raw, k, v, fname)
    return parse_scenario(raw, source=fname, default_name=path.stem)


def parse_scenario(raw: Mapping[str, Any], source: str = "<dict>", default_name: str = "scenario") -> Scenario:
    """Validate an already-parsed TOML document (a dict) into a :class:`Scenario`."""
    return Parser(source).scenario(raw, default_name)


# ------------------------------------------------------------------ overrides

_TOKEN_RE = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)((?:\[\d+\])*)$")


def _apply_override(raw: dict[str, Any], key: str, value: Any, fname: str) -> None:
    steps: list[str | int] = []
    for tok in key.split("."):
        m = _TOKEN_RE.match(tok)
        if not m:
            raise ScenarioError(f"{fname}: override {key!r}: malformed field path")
        steps.append(m.group(1))
        steps.extend(int(i) for i in re.findall(r"\[(\d+)\]", m.group(2)))
    cur: Any = raw
    for i, s in enumerate(steps[:-1]):
        nxt = steps[i + 1]
        if isinstance(s, int):
            if not isinstance(cur, list) or s >= len(cur):
                raise ScenarioError(f"{fname}: override {key!r}: index [{s}] does not exist")
            cur = cur[s]
        else:
            if not isinstance(cur, dict):
                raise ScenarioError(f"{fname}: override {key!r}: {s!r} is not inside a table")
            if s not in cur:
                cur[s] = [] if isinstance(nxt, int) else {}
            cur = cur[s]
    last = steps[-1]
    if isinstance(last, int):
        if not isinstance(cur, list) or last >= len(cur):
            raise ScenarioError(f"{fname}: override {key!r}: index [{last}] does not exist")
        cur[last] = value
    else:
        if not isinstance(cur, dict):
            raise ScenarioError(f"{fname}: override {key!r}: {last!r} is not inside a table")
        cur[last] = value


