"""``cekm node list``: the live module processes of a run, from their liveliness tokens.

Every module process holds a token ``<root>/<robot>/alive/<module>`` (the world server
``<root>/world/alive/server``); :func:`group_tokens` (pure) sorts the tokens alive now
into owners and says which of a robot's modules are missing.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass

import zenoh

from cekm_swarm.protocol import WORLD, KeyKind, KeySpace, KeySpaceError


@dataclass(frozen=True, slots=True)
class OwnerNodes:
    """The live modules of one owner (a robot id or ``world``) and the missing ones."""

    owner: str
    alive: tuple[str, ...]
    missing: tuple[str, ...]
    expected: int = 0
    runs: tuple[str, ...] = ()

    def as_dict(self) -> dict[str, object]:
        return {"owner": self.owner, "alive": list(self.alive), "missing": list(self.missing), "runs": list(self.runs)}


def group_tokens(tokens: set[str] | list[str], keys: KeySpace,
                 expected: tuple[str, ...] | list[str] | None = None,
                 team: tuple[str, ...] | list[str] = ()) -> tuple[list[OwnerNodes], list[str]]:
    """(owners with their live and missing nodes, sorted; tokens that are not node tokens
    of ``keys``). A robot's ``expected`` nodes come from the run's graph (None: unknown,
    so nothing counts as missing); a robot of the run's ``team`` with no live node at all
    (its host not started, or gone) is listed with every node missing."""
    owners: dict[str, set[str]] = {}
    runs: dict[str, set[str]] = {}
    other: list[str] = []
    for t in sorted(tokens):
        try:
            parsed = keys.parse(t)
        except KeySpaceError:
            other.append(t)
            continue
        if parsed.kind is not KeyKind.ALIVE or parsed.robot is None or parsed.module is None:
            other.append(t)
            continue
        owners.setdefault(parsed.robot, set()).add(parsed.module)
        if parsed.run:
            runs.setdefault(parsed.robot, set()).add(parsed.run)
    known = expected is not None
    if known:
        for robot in team:
            owners.setdefault(robot, set())
    expected = list(expected or ())
    order = {m: i for i, m in enumerate(expected)}
    out = []
    for owner in sorted(owners, key=lambda o: (o != WORLD, o)):
        mods = owners[owner]
        alive = tuple(sorted(mods, key=lambda m: (order.get(m, len(order)), m)))
        missing = () if owner == WORLD or not known else tuple(m for m in expected if m not in mods)
        out.append(OwnerNodes(owner, alive, missing, 0 if owner == WORLD or not known else len(expected),
                              tuple(sorted(runs.get(owner, ())))))
    return out, other


def live_tokens(session: zenoh.Session, keys: KeySpace, timeout: float = 2.0) -> set[str]:
    """The liveliness tokens alive now under ``keys`` (a liveliness query)."""
    replies = session.liveliness().get(keys.alive_all(), timeout=timeout)
    return {str(r.ok.key_expr) for r in replies if r.ok is not None}


def wait_for_tokens(session: zenoh.Session, keys: KeySpace, timeout: float,
                    stop: threading.Event | None = None) -> set[str]:
    """Tokens alive now; if there are none, wait up to ``timeout`` s for the first to appear
    (then 0.3 s more for the rest of a starting run's tokens)."""
    tokens = live_tokens(session, keys)
    if tokens or timeout <= 0:
        return tokens
    # Only now a history subscriber: while one is declared, a liveliness query of the same
    # session was seen to come back empty (zenoh 1.x).
    seen: set[str] = set()
    arrived = threading.Event()
    lock = threading.Lock()

    def on_token(sample: zenoh.Sample) -> None:
        with lock:
            if sample.kind == zenoh.SampleKind.DELETE:
                seen.discard(str(sample.key_expr))
            else:
                seen.add(str(sample.key_expr))
                arrived.set()

    stopper = stop or threading.Event()
    sub = session.liveliness().declare_subscriber(keys.alive_all(), on_token, history=True)
    try:
        deadline = time.monotonic() + timeout
        while not stopper.is_set() and not arrived.wait(min(0.1, max(0.0, deadline - time.monotonic()))):
            if time.monotonic() >= deadline:
                break
        if arrived.is_set():
            stopper.wait(0.3)
    finally:
        sub.undeclare()
    with lock:
        return set(seen) | live_tokens(session, keys)


def short_names(names: tuple[str, ...]) -> list[str]:
    """Node names with each run of instances shortened: ``obstacle-0..11`` for obstacle-0 ... obstacle-11."""
    out: list[str] = []
    i = 0
    while i < len(names):
        base, _, n = names[i].rpartition("-")
        j = i
        if base and n.isdigit():
            while j + 1 < len(names) and names[j + 1] == f"{base}-{int(n) + j + 1 - i}":
                j += 1
        out.append(names[i] if j - i < 2 else f"{names[i]}..{names[j].rpartition('-')[2]}")
        i = j + 1
    return out


def format_nodes(groups: list[OwnerNodes], other: list[str]) -> str:
    """One line per owner: ``r1  14/14  target obstacle-0..11 motor``, missing ones named."""
    if not groups and not other:
        return "no live modules"
    lines = []
    for g in groups:
        run = f" (run {', '.join(g.runs)})" if g.runs else ""
        if g.owner == WORLD:
            lines.append(f"{g.owner:<8} {', '.join(g.alive)}{run}")
            continue
        line = (f"{g.owner:<8} {g.expected - len(g.missing):>2}/{g.expected} nodes alive{run}" if g.expected
                else f"{g.owner:<8} {len(g.alive):>2} nodes alive{run}")
        if g.alive:
            line += f": {', '.join(short_names(g.alive))}"
        if g.missing:
            line += f"; missing: {', '.join(g.missing)}"
        lines.append(line)
    for t in other:
        lines.append(f"other token: {t}")
    return "\n".join(lines)

