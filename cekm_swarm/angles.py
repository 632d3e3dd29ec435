"""Angle helpers. Every angle in the project is wrapped to (-pi, pi]."""

from __future__ import annotations

import numpy as np

TWO_PI = 2.0 * np.pi


def wrap(a):
    """Wrap an angle (scalar or array) to (-pi, pi]."""
    b = np.pi - a
    return np.pi - (b - TWO_PI * np.floor(b / TWO_PI))
