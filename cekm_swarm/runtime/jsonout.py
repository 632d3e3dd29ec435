"""JSON lines for the tools' ``--json`` output: plain data, strict JSON (no NaN)."""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np


def plain(x: Any) -> Any:
    """``x`` as strict-JSON data: arrays and tuples as lists, non-finite floats as None,
    bytes as hex, other objects as their string."""
    if isinstance(x, dict):
        return {str(k): plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [plain(v) for v in x]
    if isinstance(x, np.ndarray):
        return plain(x.tolist())
    if isinstance(x, np.generic):
        return plain(x.item())
    if isinstance(x, bool) or x is None or isinstance(x, (int, str)):
        return x
    if isinstance(x, float):
        return x if math.isfinite(x) else None
    if isinstance(x, (bytes, bytearray, memoryview)):
        return bytes(x).hex()
    return str(x)


def json_line(obj: Any) -> str:
    """One compact JSON line of :func:`plain` ``(obj)``."""
    return json.dumps(plain(obj), separators=(",", ":"), allow_nan=False)
