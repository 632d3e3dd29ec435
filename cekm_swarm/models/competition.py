"""Competition with direction priority: the winner of an EKM for an input (Eqs. 2-4)."""

from __future__ import annotations

import numpy as np

from ..angles import wrap
from .params import CompetitionParams


def weighted_difference(u: np.ndarray, w: np.ndarray, p: CompetitionParams) -> np.ndarray:
    """D(u, w_i) = beta_alpha (alpha - alpha_i)^2 + beta_d (d - d_i)^2, angles wrapped (Eq. 3)."""
    da = wrap(u[0] - w[:, 0])
    dd = u[1] - w[:, 1]
    out: np.ndarray = p.beta_alpha * da * da + p.beta_d * dd * dd
    return out


def direction_set(u: np.ndarray, w: np.ndarray, p: CompetitionParams) -> np.ndarray:
    """A(alpha): neurons whose |wrapped angle difference| is within the tolerance of the smallest (Eq. 4)."""
    da = np.abs(wrap(u[0] - w[:, 0]))
    out: np.ndarray = da <= da.min() + p.direction_tolerance
    return out


def winner(u: np.ndarray, w: np.ndarray, p: CompetitionParams) -> int:
    """s = argmin over A(alpha) of D(u, w_i) (Eq. 2). Ties go to the lowest index."""
    dist = weighted_difference(u, w, p)
    dist = np.where(direction_set(u, w, p), dist, np.inf)
    return int(np.argmin(dist))
