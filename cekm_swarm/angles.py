"""Angle helpers. Every angle in the project is wrapped to (-pi, pi]."""

from __future__ import annotations

import math
from typing import overload

import numpy as np

PI = math.pi
TWO_PI = 2.0 * math.pi


@overload
def wrap(a: float) -> float: ...
@overload
def wrap(a: np.ndarray) -> np.ndarray: ...


def wrap(a: float | np.ndarray) -> float | np.ndarray:
    """Wrap an angle (scalar or array) to (-pi, pi]."""
    b = np.pi - a
    return np.pi - (b - TWO_PI * np.floor(b / TWO_PI))


def wrap_scalar(a: float) -> float:
    """:func:`wrap` for one Python float, the same formula bit for bit, without numpy's
    per-call cost (the controller's hot path); numba compiles it as it stands."""
    b = PI - a
    return PI - (b - TWO_PI * math.floor(b / TWO_PI))
