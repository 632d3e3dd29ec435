"""The range check of a controller part's parameters, one message for all: the part and the
field named, what it must be, and what it got."""

from __future__ import annotations


def check_bounds(part: str, params: object, *, ticks: tuple[str, ...] = (), positive: tuple[str, ...] = (),
                 nonnegative: tuple[str, ...] = ()) -> None:
    """ValueError naming the first field of ``params`` out of its range: ``ticks`` >= 1,
    ``positive`` > 0, ``nonnegative`` >= 0 (NaN is out of every range)."""
    for name in ticks:
        if not getattr(params, name) >= 1:
            raise ValueError(f"{part} {name} must be >= 1 tick, got {getattr(params, name)!r}")
    for name in positive:
        if not getattr(params, name) > 0.0:
            raise ValueError(f"{part} {name} must be > 0, got {getattr(params, name)!r}")
    for name in nonnegative:
        if not getattr(params, name) >= 0.0:
            raise ValueError(f"{part} {name} must be >= 0, got {getattr(params, name)!r}")
