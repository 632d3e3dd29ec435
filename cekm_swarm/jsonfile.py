"""Strict JSON for the files the commands write (``outcome.json``, ``results.json``, ...).

JSON has no NaN or Infinity (Python's :mod:`json` writes them, strict parsers refuse
them): :func:`dumps` writes a non-finite float as ``null`` and refuses anything else
that is not JSON."""

from __future__ import annotations

import json
import math
from typing import Any


def finite(x: Any) -> Any:
    """``x`` with every non-finite float (NaN, +-Infinity) replaced by None, in dicts,
    lists and tuples at any depth; everything else as it is."""
    if isinstance(x, float):
        return x if math.isfinite(x) else None
    if isinstance(x, dict):
        return {k: finite(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [finite(v) for v in x]
    return x


def dumps(doc: Any, indent: int | None = 1) -> str:
    """``doc`` as strict JSON: non-finite floats as null (:func:`finite`)."""
    return json.dumps(finite(doc), indent=indent, allow_nan=False)
