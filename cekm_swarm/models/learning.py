"""Self-organized learning rules (section 3.5), each a small named function.

All act in place on the neurons of the neighbourhood N_k given as an index array ``idx``
with their weights ``g`` = G(k, i).
"""

from __future__ import annotations

import hashlib
import math

import numpy as np

from ..angles import wrap, wrap_scalar

SMALL_D = 1e-4  # m: below it a displacement's direction is dtheta / 2 (docs/design.md section 3, item 2)


def on_branch(alpha: float, alpha_i: np.ndarray) -> np.ndarray:
    """alpha taken on each neuron's own branch, alpha_i + wrap(alpha - alpha_i), so the
    linear model c = M_i u does not jump at +-pi (docs/design.md section 3)."""
    out: np.ndarray = alpha_i + wrap(alpha - alpha_i)
    return out


def model_inputs(u: np.ndarray, w_idx: np.ndarray, d_scale: float) -> np.ndarray:
    """The control model's input for each neuron: (alpha on its branch, d_scale * d), shape (m, 2)."""
    return np.stack([on_branch(u[0], w_idx[:, 0]), np.full(len(w_idx), d_scale * u[1])], axis=1)


def update_input_weights(w: np.ndarray, v: np.ndarray, idx: np.ndarray, g: np.ndarray, eta: float) -> None:
    """Eq. 12: w_i += eta G(k, i) (v - w_i), the angular part wrapped and kept in (-pi, pi]."""
    step = eta * g
    w[idx, 0] = wrap(w[idx, 0] + step * wrap(v[0] - w[idx, 0]))
    w[idx, 1] = w[idx, 1] + step * (v[1] - w[idx, 1])


def gradient_descent(M: np.ndarray, x: np.ndarray, c: np.ndarray, idx: np.ndarray, g: np.ndarray, eta: float) -> None:
    """Eq. 15: M_i += eta G(k, i) (c - M_i v) v^T, with v = x[j] the model input of neuron idx[j]."""
    err = c[None, :] - np.einsum("mab,mb->ma", M[idx], x)
    M[idx] += (eta * g)[:, None, None] * err[:, :, None] * x[:, None, :]


def recursive_least_squares(M: np.ndarray, Rinv: np.ndarray, x: np.ndarray, c: np.ndarray, idx: np.ndarray,
                            g: np.ndarray, forgetting: float, trace_cap: float) -> None:
    """Eqs. 16-17 for each neuron in N_k.

    Eq. 16: R^-1 <- (R^-1 - R^-1 v v^T R^-1 / (lambda / G + v^T R^-1 v)) / lambda.
    Eq. 17: M_i += G (c - M_i v) v^T R^-1, with R^-1 after the Eq. 16 update.
    trace(R^-1) is capped (a safeguard against covariance wind-up).
    """
    P = Rinv[idx]
    Px = np.einsum("mab,mb->ma", P, x)
    denom = forgetting / g + np.einsum("ma,ma->m", x, Px)
    P = (P - Px[:, :, None] * Px[:, None, :] / denom[:, None, None]) / forgetting
    tr = P[:, 0, 0] + P[:, 1, 1]
    over = tr > trace_cap
    if np.any(over):
        P[over] *= (trace_cap / tr[over])[:, None, None]
    Rinv[idx] = P
    err = c[None, :] - np.einsum("mab,mb->ma", M[idx], x)
    xP = np.einsum("ma,mab->mb", x, P)
    M[idx] += g[:, None, None] * err[:, :, None] * xP[:, None, :]


def direct_output_update(C: np.ndarray, c: np.ndarray, idx: np.ndarray, g: np.ndarray, eta: float) -> None:
    """Direct-mapping EKM output rule: c_i += eta G(k, i) (c - c_i)."""
    C[idx] += (eta * g)[:, None] * (c[None, :] - C[idx])


def wheel_displacement(left: float, right: float, dt: float, axle: float, step_s: float) -> np.ndarray:
    """v (section 3.5, step 3) from wheel odometry: the displacement one step of the map
    (``step_s``, 1.024 s) makes at the wheel speeds the encoders measured, left / dt and
    right / dt, on the exact differential-drive arc, in polar form (alpha_v, d_v) in the
    robot frame at the step's start. Below 1e-4 m, alpha_v = dtheta / 2, the limit of the
    chord's direction, so pure turns still train the d = 0 neurons."""
    v = 0.5 * (left + right) / dt
    om = (right - left) / (axle * dt)
    dth = om * step_s
    if abs(om) > 1e-12:
        r = v / om
        lx, ly = r * math.sin(dth), r * (1.0 - math.cos(dth))
    else:
        lx, ly = v * step_s, 0.0
    d = math.hypot(lx, ly)
    if d < SMALL_D:
        return np.array([wrap_scalar(0.5 * dth), d])
    return np.array([math.atan2(ly, lx), d])


def map_digest(w: np.ndarray, M: np.ndarray) -> str:
    """A map's digest: the first 16 hex digits of the SHA-256 of its input weights and
    control parameters as float64 little-endian bytes, in that order (what every EKM of
    the robot uses; R^-1 is the learner's own)."""
    h = hashlib.sha256()
    for a in (w, M):
        h.update(np.ascontiguousarray(a, dtype="<f8").data)  # the array's own bytes, no copy when already so laid out
    return h.hexdigest()[:16]
