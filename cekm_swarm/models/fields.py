"""Target and obstacle fields, neural integration and motor control (Eqs. 5-11).

The localization EKMs and the motor control EKM share the trained input weights w, so
every field is a vector over the same n neurons.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..angles import wrap
from .learning import on_branch
from .params import FieldParams


def target_field(w: np.ndarray, s: int, p: FieldParams) -> np.ndarray:
    """a_i = G_a(w_s, w_i), an elongated Gaussian: angle-insensitive, distance-sensitive (Eqs. 5-6)."""
    da = wrap(w[s, 0] - w[:, 0])
    dd = w[s, 1] - w[:, 1]
    out: np.ndarray = np.exp(-da * da / (2.0 * p.sigma_a_alpha ** 2) - dd * dd / (2.0 * p.sigma_a_d ** 2))
    return out


def obstacle_field(w: np.ndarray, s: int, p: FieldParams) -> np.ndarray:
    """b_i = G_b(w_s, w_i), stretched along the obstacle direction beyond the obstacle (Eqs. 7-8)."""
    da = wrap(w[s, 0] - w[:, 0])
    dd = w[s, 1] - w[:, 1]
    sigma_d = np.where(w[:, 1] >= w[s, 1], p.sigma_b_d_beyond, p.sigma_b_d_near)
    out: np.ndarray = np.exp(-da * da / (2.0 * p.sigma_b_alpha ** 2) - dd * dd / (2.0 * sigma_d * sigma_d))
    return out


def integrate(a: np.ndarray, obstacle_fields: Sequence[np.ndarray] | np.ndarray) -> np.ndarray:
    """e_i = a_i - sum_j b_ji (Eq. 9). A sensor that sees nothing contributes no field."""
    e = np.array(a, dtype=np.float64, copy=True)
    for b in obstacle_fields:
        e -= b
    return e


def motor_winner(e: np.ndarray) -> int:
    """k = argmax_i e_i (Eq. 10)."""
    return int(np.argmax(e))


def motor_control(M: np.ndarray, w: np.ndarray, u: np.ndarray, k: int, s: int, v_max: float,
                  d_scale: float) -> np.ndarray:
    """Eq. 11: c = M_k u if k = s and |M_k u| <= c* (both wheels), else c = M_k w_k.

    Inputs go through the model's internal scaling (alpha on the neuron's branch,
    d_scale * d). The caller clips what the wheels execute to c*.
    """
    if k == s:
        c: np.ndarray = M[k] @ np.array([on_branch(u[0], w[k:k + 1, 0])[0], d_scale * u[1]])
        if np.all(np.abs(c) <= v_max):
            return c
    out: np.ndarray = M[k] @ np.array([w[k, 0], d_scale * w[k, 1]])
    return out
