"""numba fast path of the target-reaching networks: the same rules as
:mod:`cekm_swarm.models.networks`, one robot's arrays at a time, no Python objects.

A network's state is three arrays so that every kind shares one calling convention:

* ``w`` (n, 2): input weights (the BFN's centres);
* ``P`` (n, 2, 2): M_i for the indirect EKM (internal units); for the direct EKM
  ``P[i, 0]`` is c_i; for the BFN ``P[i, 0]`` is W_i and ``P[i, 1]`` its widths;
* ``R`` (n, 2, 2): R_i^-1 for RLS; for the BFN ``R[i, 0, 0]`` = 1 marks a centre that has won.

:func:`output` is a network's own output for an input; :func:`command` is the target-reaching
rule the controllers use, the same output except c = 0 at the goal state d = 0.

Parameters travel as one float64 vector (:func:`pack_params`); its layout is below.
The tests hold this module equal to the reference classes.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..angles import wrap_scalar
from .networks import DirectEKM, IndirectEKM, Network
from .params import CompetitionParams, LearningParams

KIND_GD, KIND_RLS, KIND_DIRECT, KIND_BFN = 0, 1, 2, 3
KIND_CODE = {"indirect-gd": KIND_GD, "indirect-rls": KIND_RLS, "direct": KIND_DIRECT, "bfn": KIND_BFN}

# layout of the parameter vector
(P_BETA_A, P_BETA_D, P_TOL, P_ETA_W, P_ETA_M, P_ETA_C, P_ETA_BFN, P_ETA_WIDTH, P_SIG0, P_SIGF, P_TAU, P_GMIN,
 P_LAMBDA, P_TRCAP, P_DSCALE, P_EXP_REL, P_EXP_ABS, P_VMAX, P_WIDTH_FLOOR, P_BFN_RULE) = range(20)
N_PARAMS = 20
BFN_RULE_CODE = {"trained-units": 0.0, "paper": 1.0}  # P_BFN_RULE (see networks.BFN_RULES)

PI = math.pi
TWO_PI = 2.0 * math.pi


def pack_params(comp: CompetitionParams, lp: LearningParams, v_max: float, width_floor: float,
                bfn_rule: str = "trained-units") -> np.ndarray:
    """The float64 parameter vector the kernels read (``bfn_rule``: the basis-function
    network's rule, :data:`cekm_swarm.models.networks.BFN_RULES`)."""
    p = np.empty(N_PARAMS)
    p[P_BETA_A], p[P_BETA_D], p[P_TOL] = comp.beta_alpha, comp.beta_d, comp.direction_tolerance
    p[P_ETA_W], p[P_ETA_M], p[P_ETA_C] = lp.eta_w, lp.eta_m, lp.eta_c
    p[P_ETA_BFN], p[P_ETA_WIDTH] = lp.eta_bfn, lp.eta_width
    p[P_SIG0], p[P_SIGF], p[P_TAU], p[P_GMIN] = lp.sigma_initial, lp.sigma_final, lp.sigma_tau, lp.g_min
    p[P_LAMBDA], p[P_TRCAP], p[P_DSCALE] = lp.forgetting, lp.rinv_trace_cap, lp.d_scale
    p[P_EXP_REL], p[P_EXP_ABS], p[P_VMAX], p[P_WIDTH_FLOOR] = lp.explore_rel, lp.explore_abs, v_max, width_floor
    p[P_BFN_RULE] = BFN_RULE_CODE[bfn_rule]
    return p


wrap = njit(cache=True)(wrap_scalar)  # (-pi, pi], the formula of cekm_swarm.angles


@njit(cache=True)
def winner(alpha: float, d: float, w: np.ndarray, p: np.ndarray) -> int:
    """Eqs. 2-4: the direction set A(alpha) first, then the smallest D over it."""
    n = w.shape[0]
    das = np.empty(n)
    best_da = np.inf
    for i in range(n):
        das[i] = wrap(alpha - w[i, 0])
        if abs(das[i]) < best_da:
            best_da = abs(das[i])
    limit = best_da + p[P_TOL]
    s = 0
    best = np.inf
    for i in range(n):
        da = das[i]
        if abs(da) <= limit:
            dd = d - w[i, 1]
            dist = p[P_BETA_A] * da * da + p[P_BETA_D] * dd * dd
            if dist < best:
                best = dist
                s = i
    return s


@njit(cache=True)
def bfn_activations(alpha: float, d: float, w: np.ndarray, P: np.ndarray, R: np.ndarray, p: np.ndarray,
                    out: np.ndarray) -> None:
    """Normalized Gaussian activations of the basis-function network (widths in P[:, 1]).

    R[i, 0, 0] > 0 marks a centre that has won for some training input; under the
    "trained-units" rule only those units take part (all, before the first), under the
    paper's rule every unit does. d is limited to the farthest taking part in the direction
    set A(alpha) (the network's local workspace in that direction).
    """
    n = w.shape[0]
    any_won = False
    if p[P_BFN_RULE] == 0.0:
        for i in range(n):
            if R[i, 0, 0] > 0.0:
                any_won = True
    da_min = np.inf
    for i in range(n):
        if R[i, 0, 0] > 0.0 or not any_won:
            da_min = min(da_min, abs(wrap(alpha - w[i, 0])))
    d_edge = -1.0
    for i in range(n):
        if (R[i, 0, 0] > 0.0 or not any_won) and abs(wrap(alpha - w[i, 0])) <= da_min + p[P_TOL] and w[i, 1] > d_edge:
            d_edge = w[i, 1]
    if d > d_edge:
        d = d_edge
    qmin = np.inf
    for i in range(n):
        if R[i, 0, 0] > 0.0 or not any_won:
            za = wrap(alpha - w[i, 0]) / P[i, 1, 0]
            zd = (d - w[i, 1]) / P[i, 1, 1]
            out[i] = 0.5 * (za * za + zd * zd)
            if out[i] < qmin:
                qmin = out[i]
        else:
            out[i] = np.inf
    total = 0.0
    for i in range(n):
        out[i] = math.exp(-(out[i] - qmin))
        total += out[i]
    for i in range(n):
        out[i] /= total


@njit(cache=True)
def output(kind: int, alpha: float, d: float, w: np.ndarray, P: np.ndarray, R: np.ndarray, p: np.ndarray,
           out: np.ndarray) -> None:
    """A network's own output for the input (alpha, d), written into out[0:2]: Eq. 11 with
    k = s (indirect EKM), the winner's c_s (direct EKM), the weighted sum (BFN)."""
    if kind == KIND_BFN:
        phis = np.empty(w.shape[0])
        bfn_activations(alpha, d, w, P, R, p, phis)
        out[0] = 0.0
        out[1] = 0.0
        for i in range(w.shape[0]):
            out[0] += phis[i] * P[i, 0, 0]
            out[1] += phis[i] * P[i, 0, 1]
        return
    s = winner(alpha, d, w, p)
    if kind == KIND_DIRECT:
        out[0] = P[s, 0, 0]
        out[1] = P[s, 0, 1]
        return
    # Eq. 11 with k = s
    x0 = w[s, 0] + wrap(alpha - w[s, 0])
    x1 = p[P_DSCALE] * d
    c0 = P[s, 0, 0] * x0 + P[s, 0, 1] * x1
    c1 = P[s, 1, 0] * x0 + P[s, 1, 1] * x1
    if abs(c0) <= p[P_VMAX] and abs(c1) <= p[P_VMAX]:
        out[0] = c0
        out[1] = c1
        return
    x0 = w[s, 0]
    x1 = p[P_DSCALE] * w[s, 1]
    out[0] = P[s, 0, 0] * x0 + P[s, 0, 1] * x1
    out[1] = P[s, 1, 0] * x0 + P[s, 1, 1] * x1


@njit(cache=True)
def command(kind: int, alpha: float, d: float, w: np.ndarray, P: np.ndarray, R: np.ndarray, p: np.ndarray,
            out: np.ndarray) -> None:
    """The target-reaching rule of each network kind, written into out[0:2]: its
    :func:`output`, except that the goal state (d = 0) gives c = 0 for every kind."""
    if d == 0.0:
        out[0] = 0.0
        out[1] = 0.0
        return
    output(kind, alpha, d, w, P, R, p, out)


@njit(cache=True)
def _update_input_weight(w: np.ndarray, i: int, va: float, vd: float, step: float) -> None:
    """Eq. 12 for one neuron."""
    w[i, 0] = wrap(w[i, 0] + step * wrap(va - w[i, 0]))
    w[i, 1] = w[i, 1] + step * (vd - w[i, 1])


@njit(cache=True)
def _rho(w: np.ndarray, i: int, q: int, p: np.ndarray) -> float:
    """Eq. 3's distance between centres i and q: sqrt(beta_alpha dalpha^2 + beta_d dd^2)."""
    da = wrap(w[i, 0] - w[q, 0])
    dd = w[i, 1] - w[q, 1]
    return math.sqrt(p[P_BETA_A] * da * da + p[P_BETA_D] * dd * dd)


@njit(cache=True)
def nearest_lattice_neighbour(w: np.ndarray, i: int, size: int, p: np.ndarray) -> float:
    """Eq. 3's distance from centre i to the nearest of its up to 4 lattice neighbours."""
    r = i // size
    c = i - r * size
    best = np.inf
    for side in range(4):
        rr = r + (side == 2) - (side == 3)
        cc = c + (side == 0) - (side == 1)
        if 0 <= rr < size and 0 <= cc < size:
            best = min(best, _rho(w, i, rr * size + cc, p))
    return best


@njit(cache=True)
def nearest_centre(w: np.ndarray, i: int, p: np.ndarray) -> float:
    """Eq. 3's distance from centre i to the nearest other centre (Moody & Darken's rule).
    The square root is taken once, of the smallest square (the same number: sqrt is
    correctly rounded and monotonic)."""
    best = np.inf
    for q in range(w.shape[0]):
        if q != i:
            da = wrap(w[i, 0] - w[q, 0])
            dd = w[i, 1] - w[q, 1]
            best = min(best, p[P_BETA_A] * da * da + p[P_BETA_D] * dd * dd)
    return math.sqrt(best)


@njit(cache=True)
def learn(kind: int, va: float, vd: float, c0: float, c1: float, t: float, w: np.ndarray, P: np.ndarray, R: np.ndarray,
          size: int, p: np.ndarray, idx_buf: np.ndarray, g_buf: np.ndarray) -> None:
    """One step of self-organized learning from displacement v = (va, vd) and executed c."""
    n = w.shape[0]
    k = winner(va, vd, w, p)
    sigma = p[P_SIGF] + (p[P_SIG0] - p[P_SIGF]) * math.exp(-t / p[P_TAU])
    gmin = p[P_GMIN]
    reach = int(math.ceil(sigma * math.sqrt(2.0 * math.log(1.0 / gmin))))
    rk = k // size
    ck = k - rk * size
    m = 0
    for r in range(max(0, rk - reach), min(size, rk + reach + 1)):
        for cc in range(max(0, ck - reach), min(size, ck + reach + 1)):
            d2 = float((r - rk) * (r - rk) + (cc - ck) * (cc - ck))
            g = math.exp(-d2 / (2.0 * sigma * sigma))
            if g >= gmin:
                idx_buf[m] = r * size + cc
                g_buf[m] = g
                m += 1
    eta_w = p[P_ETA_W]
    if kind in (KIND_GD, KIND_RLS):
        ds = p[P_DSCALE]
        x1 = ds * vd
        for j in range(m):
            i = idx_buf[j]
            g = g_buf[j]
            x0 = w[i, 0] + wrap(va - w[i, 0])
            if kind == KIND_GD:  # Eq. 15
                e0 = c0 - (P[i, 0, 0] * x0 + P[i, 0, 1] * x1)
                e1 = c1 - (P[i, 1, 0] * x0 + P[i, 1, 1] * x1)
                step = p[P_ETA_M] * g
                P[i, 0, 0] += step * e0 * x0
                P[i, 0, 1] += step * e0 * x1
                P[i, 1, 0] += step * e1 * x0
                P[i, 1, 1] += step * e1 * x1
            else:  # Eqs. 16-17
                lam = p[P_LAMBDA]
                a, b, cq, dq = R[i, 0, 0], R[i, 0, 1], R[i, 1, 0], R[i, 1, 1]
                px0 = a * x0 + b * x1
                px1 = cq * x0 + dq * x1
                denom = lam / g + (x0 * px0 + x1 * px1)
                a = (a - px0 * px0 / denom) / lam
                b = (b - px0 * px1 / denom) / lam
                cq = (cq - px1 * px0 / denom) / lam
                dq = (dq - px1 * px1 / denom) / lam
                tr = a + dq
                if tr > p[P_TRCAP]:
                    f = p[P_TRCAP] / tr
                    a *= f
                    b *= f
                    cq *= f
                    dq *= f
                R[i, 0, 0], R[i, 0, 1], R[i, 1, 0], R[i, 1, 1] = a, b, cq, dq
                e0 = c0 - (P[i, 0, 0] * x0 + P[i, 0, 1] * x1)
                e1 = c1 - (P[i, 1, 0] * x0 + P[i, 1, 1] * x1)
                xp0 = x0 * a + x1 * cq
                xp1 = x0 * b + x1 * dq
                P[i, 0, 0] += g * e0 * xp0
                P[i, 0, 1] += g * e0 * xp1
                P[i, 1, 0] += g * e1 * xp0
                P[i, 1, 1] += g * e1 * xp1
            _update_input_weight(w, i, va, vd, eta_w * g)
    elif kind == KIND_DIRECT:
        for j in range(m):
            i = idx_buf[j]
            step = p[P_ETA_C] * g_buf[j]
            P[i, 0, 0] += step * (c0 - P[i, 0, 0])
            P[i, 0, 1] += step * (c1 - P[i, 0, 1])
            _update_input_weight(w, i, va, vd, eta_w * g_buf[j])
    else:  # basis-function network
        o0 = 0.0
        o1 = 0.0
        phis = np.empty(n)
        bfn_activations(va, vd, w, P, R, p, phis)
        for i in range(n):
            o0 += phis[i] * P[i, 0, 0]
            o1 += phis[i] * P[i, 0, 1]
        e0 = c0 - o0
        e1 = c1 - o1
        eta = p[P_ETA_BFN]
        for i in range(n):
            P[i, 0, 0] += eta * phis[i] * e0
            P[i, 0, 1] += eta * phis[i] * e1
        paper_rule = p[P_BFN_RULE] != 0.0
        for j in range(m):  # widths, from the centres before this step's Eq. 12
            i = idx_buf[j]
            best = nearest_centre(w, i, p) if paper_rule else nearest_lattice_neighbour(w, i, size, p)
            rho_a = max(best / math.sqrt(p[P_BETA_A]), p[P_WIDTH_FLOOR])
            rho_d = max(best / math.sqrt(p[P_BETA_D]), p[P_WIDTH_FLOOR])
            P[i, 1, 0] += p[P_ETA_WIDTH] * g_buf[j] * (rho_a - P[i, 1, 0])
            P[i, 1, 1] += p[P_ETA_WIDTH] * g_buf[j] * (rho_d - P[i, 1, 1])
        for j in range(m):
            _update_input_weight(w, idx_buf[j], va, vd, eta_w * g_buf[j])
        R[k, 0, 0] = 1.0


def network_arrays(net: Network) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A reference network's state in this module's (w, P, R) convention (copies)."""
    n = net.w.shape[0]
    P = np.zeros((n, 2, 2))
    R = np.zeros((n, 2, 2))
    if isinstance(net, IndirectEKM):
        P[:] = net.M
        R[:] = net.Rinv
    elif isinstance(net, DirectEKM):
        P[:, 0] = net.C
    else:
        P[:, 0] = net.W
        P[:, 1] = net.widths
        R[:, 0, 0] = net.won
    return net.w.copy(), P, R


def load_arrays(net: Network, w: np.ndarray, P: np.ndarray, R: np.ndarray) -> None:
    """Write (w, P, R) back into a reference network of the same kind and size."""
    net.w[:] = w
    if isinstance(net, IndirectEKM):
        net.M[:] = P
        net.Rinv[:] = R
    elif isinstance(net, DirectEKM):
        net.C[:] = P[:, 0]
    else:
        net.W[:] = P[:, 0]
        net.widths[:] = P[:, 1]
        net.won[:] = R[:, 0, 0] > 0.0
