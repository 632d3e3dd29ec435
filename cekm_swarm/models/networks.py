"""Reference target-reaching networks of section 4.1, written to follow the equations.

* :class:`IndirectEKM`: the paper's indirect-mapping EKM (Eqs. 1, 11, 12, 15-17), trained
  by gradient descent (G9, G12, G15) or recursive least squares (R15).
* :class:`DirectEKM`: the direct-mapping EKM baseline (D15), one command c_i per neuron.
* :class:`BasisFunctionNetwork`: the basis-function network baseline (B15).

These are the readable reference; :mod:`cekm_swarm.models.fast` runs the same rules in
numba for the experiments, and the tests hold the two equal. All share one contract:
``output(u) -> c`` (the network's own output), ``command(u) -> c`` (the target-reaching
rule: the output, except c = 0 at the goal state d = 0) and ``learn(v, c, t)`` (one step of
self-organized learning from the displacement v that the executed command c produced).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

import numpy as np

from ..angles import wrap
from ..errors import ParameterError
from ..robot import KHEPERA
from . import learning
from .competition import winner
from .fields import motor_control
from .lattice import Lattice, neighbourhood
from .params import CompetitionParams, LearningParams

KINDS = ("indirect-gd", "indirect-rls", "direct", "bfn")
BFN_RULES = ("paper", "trained-units")
"""The basis-function network's rules (:class:`BasisFunctionNetwork`): "paper", as section 4.1
describes it (every unit drives the output; widths approach the distance to the nearest
centre); "trained-units", the project's earlier B15 (only units whose centre has won drive
the output; widths approach the distance to the nearest lattice neighbour)."""
_NAME = re.compile(r"^([BDGR])(\d{1,2})$")
_KIND_OF_LETTER = {"B": "bfn", "D": "direct", "G": "indirect-gd", "R": "indirect-rls"}
LETTER_OF_KIND = {v: k for k, v in _KIND_OF_LETTER.items()}


def parse_network_name(name: str) -> tuple[str, int]:
    """'R15' -> ('indirect-rls', 15); the paper's naming (B, D, G, R + lattice side)."""
    m = _NAME.match(name.strip().upper())
    if not m or not 2 <= int(m.group(2)) <= 64:
        raise ParameterError(f"unknown network {name!r}: expected a letter B, D, G or R and a lattice side 2-64, "
                             f"e.g. R15")
    return _KIND_OF_LETTER[m.group(1)], int(m.group(2))


def parameter_count(kind: str, size: int) -> int:
    """Trainable parameters, counted as Table 1 does (R^-1 is not counted)."""
    per_neuron = {"indirect-gd": 6, "indirect-rls": 6, "direct": 4, "bfn": 6}[kind]
    return per_neuron * size * size


def updated_neighbourhood(v: np.ndarray, w: np.ndarray, lattice: Lattice, comp: CompetitionParams,
                          learn_p: LearningParams, t: float) -> tuple[int, np.ndarray, np.ndarray]:
    """k = winner(v) for the training input v (step 4 of section 3.5), N_k = the neurons
    with G(k, i) >= g_min, and their G."""
    k = winner(v, w, comp)
    g = neighbourhood(lattice.positions(), k, learn_p.sigma(t))
    idx = np.flatnonzero(g >= learn_p.g_min)
    return k, idx, g[idx]


def at_goal(u: np.ndarray) -> bool:
    """The goal state u(T) = (alpha, 0): the target sensor reads d = 0 (section 3.1)."""
    return bool(u[1] == 0.0)


class TargetReaching:
    """What the three networks share: :meth:`command` for target reaching, their output
    but exactly c = 0 at the goal state (section 3.1)."""

    def output(self, u: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def command(self, u: np.ndarray) -> np.ndarray:
        """Obstacle-free target reaching: :meth:`output`, exactly 0 at the goal state."""
        if at_goal(u):
            return np.zeros(2)
        return self.output(u)


@dataclass
class IndirectEKM(TargetReaching):
    """Indirect-mapping EKM: input weights w_i and control parameters M_i per neuron.

    M is kept in the model's internal units (the input is (alpha, d_scale * d)); R^-1
    starts at I in those units.
    """

    lattice: Lattice
    rule: str  # "gd" (Eq. 15) or "rls" (Eqs. 16-17)
    w: np.ndarray
    M: np.ndarray
    Rinv: np.ndarray
    comp: CompetitionParams = field(default_factory=CompetitionParams)
    learn_p: LearningParams = field(default_factory=LearningParams)
    v_max: float = KHEPERA.v_max
    # bool per neuron: its command M_i w_i moves the robot by w_i (section 3.5's converged
    # state), checked after training; None when unknown (not a parameter, like R^-1)
    converged: np.ndarray | None = None

    @classmethod
    def untrained(cls, size: int, rule: str, rng: np.random.Generator, comp: CompetitionParams | None = None,
                  learn_p: LearningParams | None = None, v_max: float = KHEPERA.v_max) -> IndirectEKM:
        """Regular input weights and uninformed random M_i (docs/design.md section 3, item 7)."""
        if rule not in ("gd", "rls"):
            raise ParameterError(f"IndirectEKM.rule must be 'gd' or 'rls', got {rule!r}")
        lat = Lattice(size)
        lp = learn_p or LearningParams()
        scale = lp.m_init_scale * v_max / math.pi
        M = rng.uniform(-scale, scale, size=(lat.n, 2, 2))
        Rinv = np.tile(np.eye(2), (lat.n, 1, 1))
        return cls(lat, rule, lat.initial_weights(), M, Rinv, comp or CompetitionParams(), lp, v_max)

    @classmethod
    def kinematic(cls, size: int, comp: CompetitionParams | None = None, learn_p: LearningParams | None = None,
                  v_max: float = KHEPERA.v_max, axle: float = KHEPERA.axle, step_s: float = 1.024) -> IndirectEKM:
        """The kinematic initial guess M0 = (1/T) [[-axle, 1], [axle, 1]] (in SI units): a labelled option,
        not the paper's untrained start."""
        lat = Lattice(size)
        lp = learn_p or LearningParams()
        m_si = np.array([[-axle, 1.0], [axle, 1.0]]) / step_s  # turn by 2 alpha (chord convention), move d
        M = np.tile(m_si @ np.diag([1.0, 1.0 / lp.d_scale]), (lat.n, 1, 1))
        return cls(lat, "rls", lat.initial_weights(), M, np.tile(np.eye(2), (lat.n, 1, 1)), comp or CompetitionParams(),
                   lp, v_max)

    @property
    def kind(self) -> str:
        return "indirect-" + self.rule

    def control(self, u: np.ndarray, k: int, s: int) -> np.ndarray:
        """Eq. 11: c = M_k u if k = s and |M_k u| <= c*, else M_k w_k."""
        return motor_control(self.M, self.w, u, k, s, self.v_max, self.learn_p.d_scale)

    def output(self, u: np.ndarray) -> np.ndarray:
        """Eq. 11 with k = s, the winner for u (no other field competes). At the goal state
        u = (0, 0) this is M_s 0 = 0 by Eq. 1 itself."""
        s = winner(u, self.w, self.comp)
        return self.control(u, s, s)

    def learn(self, v: np.ndarray, c: np.ndarray, t: float) -> None:
        """One step of self-organized learning: winner k for v, then Eqs. 15 or 16-17, then Eq. 12."""
        _, idx, g = updated_neighbourhood(v, self.w, self.lattice, self.comp, self.learn_p, t)
        x = learning.model_inputs(v, self.w[idx], self.learn_p.d_scale)
        if self.rule == "gd":
            learning.gradient_descent(self.M, x, c, idx, g, self.learn_p.eta_m)
        else:
            learning.recursive_least_squares(self.M, self.Rinv, x, c, idx, g, self.learn_p.forgetting,
                                             self.learn_p.rinv_trace_cap)
        learning.update_input_weights(self.w, v, idx, g, self.learn_p.eta_w)


@dataclass
class DirectEKM(TargetReaching):
    """Direct-mapping EKM (D15): the winner s outputs its stored command c_s."""

    lattice: Lattice
    w: np.ndarray
    C: np.ndarray
    comp: CompetitionParams = field(default_factory=CompetitionParams)
    learn_p: LearningParams = field(default_factory=LearningParams)

    kind = "direct"

    @classmethod
    def untrained(cls, size: int, rng: np.random.Generator, comp: CompetitionParams | None = None,
                  learn_p: LearningParams | None = None, v_max: float = KHEPERA.v_max) -> DirectEKM:
        lat = Lattice(size)
        lp = learn_p or LearningParams()
        C = rng.uniform(-lp.m_init_scale * v_max, lp.m_init_scale * v_max, size=(lat.n, 2))
        return cls(lat, lat.initial_weights(), C, comp or CompetitionParams(), lp)

    def output(self, u: np.ndarray) -> np.ndarray:
        """The winner's stored command c_s (also at the goal state)."""
        out: np.ndarray = self.C[winner(u, self.w, self.comp)].copy()
        return out

    def learn(self, v: np.ndarray, c: np.ndarray, t: float) -> None:
        """c_i += eta G(k, i) (c - c_i), then Eq. 12, k the winner for v."""
        _, idx, g = updated_neighbourhood(v, self.w, self.lattice, self.comp, self.learn_p, t)
        learning.direct_output_update(self.C, c, idx, g, self.learn_p.eta_c)
        learning.update_input_weights(self.w, v, idx, g, self.learn_p.eta_w)


BFN_WIDTH_FLOOR = 1e-3  # smallest basis width (raw (alpha [rad], d [m]) units), so no width collapses to 0


def neighbour_widths(w: np.ndarray, size: int, i: int, comp: CompetitionParams) -> np.ndarray:
    """(sigma_alpha, sigma_d) that unit i's widths move toward: rho, the distance from centre i
    to its nearest of up to 4 lattice neighbours measured as the competition measures it
    (Eq. 3: rho^2 = beta_alpha dalpha^2 + beta_d dd^2, angles wrapped), expressed per axis
    (rho / sqrt(beta_alpha) rad, rho / sqrt(beta_d) m) and floored. Measured in raw (rad, m)
    units instead, a neighbour's angle difference would set a width in metres many times the
    whole distance range, and that unit would swamp the normalized activations."""
    r, c = divmod(int(i), size)
    best = np.inf
    for rr, cc in ((r, c - 1), (r, c + 1), (r - 1, c), (r + 1, c)):
        if 0 <= rr < size and 0 <= cc < size:
            j = rr * size + cc
            da = wrap(w[i, 0] - w[j, 0])
            dd = w[i, 1] - w[j, 1]
            best = min(best, math.sqrt(comp.beta_alpha * da * da + comp.beta_d * dd * dd))
    return np.maximum([best / math.sqrt(comp.beta_alpha), best / math.sqrt(comp.beta_d)], BFN_WIDTH_FLOOR)


def nearest_centre_widths(w: np.ndarray, i: int, comp: CompetitionParams) -> np.ndarray:
    """(sigma_alpha, sigma_d) that unit i's widths move toward under the paper's rule: rho, the
    distance from centre i to the nearest other centre (Moody & Darken's nearest-neighbour
    width), measured as the competition measures it (Eq. 3), expressed per axis and floored
    as in :func:`neighbour_widths`."""
    da = wrap(w[i, 0] - w[:, 0])
    dd = w[i, 1] - w[:, 1]
    rho = np.sqrt(comp.beta_alpha * da * da + comp.beta_d * dd * dd)
    rho[i] = np.inf
    best = float(rho.min())
    return np.maximum([best / math.sqrt(comp.beta_alpha), best / math.sqrt(comp.beta_d)], BFN_WIDTH_FLOOR)


@dataclass
class BasisFunctionNetwork(TargetReaching):
    """Basis-function network (B15): c = sum_i phi_i(u) W_i, phi_i a normalized Gaussian with per-axis widths.

    Section 4.1: centres trained like the EKM's input weights (Eq. 12: winner and lattice
    neighbourhood), each width moving toward the distance to its nearest neighbour, output
    weights by gradient descent on every unit at every step. 6 parameters per unit: centre
    2, widths 2 (the nearest-neighbour distance, measured in Eq. 3's metric, expressed per
    axis), output weights 2. ``rule`` (:data:`BFN_RULES`): "paper", every unit drives the
    output and the nearest neighbour is the nearest centre; "trained-units", only units
    whose centre has won for a training input drive it and the nearest neighbour is the
    nearest of the unit's lattice neighbours. Under both, an input beyond the local
    workspace in its direction is presented at that edge (:meth:`activations`).
    """

    lattice: Lattice
    w: np.ndarray  # centres (alpha, d)
    widths: np.ndarray  # (sigma_alpha, sigma_d)
    W: np.ndarray  # output weights
    won: np.ndarray  # bool: the centre has won for some training input (not a parameter, like R^-1)
    comp: CompetitionParams = field(default_factory=CompetitionParams)
    learn_p: LearningParams = field(default_factory=LearningParams)
    rule: str = "trained-units"

    kind = "bfn"

    def __post_init__(self) -> None:
        if self.rule not in BFN_RULES:
            raise ParameterError(f"BasisFunctionNetwork.rule must be one of {', '.join(BFN_RULES)}, got {self.rule!r}")

    @classmethod
    def untrained(cls, size: int, rng: np.random.Generator, comp: CompetitionParams | None = None,
                  learn_p: LearningParams | None = None, v_max: float = KHEPERA.v_max,
                  rule: str = "trained-units") -> BasisFunctionNetwork:
        lat = Lattice(size)
        lp = learn_p or LearningParams()
        w0 = lat.initial_weights()
        widths = np.tile([2.0 * np.pi / size, 0.16 / (size - 1)], (lat.n, 1))
        # full wheel range: the normalized output averages a few units, which would shrink half-range commands
        W = rng.uniform(-2.0 * lp.m_init_scale * v_max, 2.0 * lp.m_init_scale * v_max, size=(lat.n, 2))
        return cls(lat, w0, widths, W, np.zeros(lat.n, dtype=bool), comp or CompetitionParams(), lp, rule)

    def activations(self, u: np.ndarray) -> np.ndarray:
        """Normalized Gaussian activations phi_i(u) / sum_j phi_j(u), computed stably.

        Under the "trained-units" rule only units whose centre has won for a training input
        take part (all, before the first): a unit no data reached keeps its random initial
        output, which would steer the robot away from ever producing such data. Under the
        paper's rule every unit takes part. Normalized, so that every input
        activates its nearest units however far it is; and an input beyond the network's
        local workspace in its direction (the farthest active centre in the direction set
        A(alpha) of Eq. 4) is presented at that edge, as the EKM's winner stands in for a
        target outside U' (section 3.2).
        """
        active = self.won if self.rule == "trained-units" and np.any(self.won) else np.ones(len(self.w), dtype=bool)
        da = np.abs(wrap(u[0] - self.w[:, 0]))
        da_min = da[active].min()
        edge = active & (da <= da_min + self.comp.direction_tolerance)  # A(alpha) of Eq. 4 among active units
        d = min(u[1], float(self.w[edge, 1].max()))
        za = wrap(u[0] - self.w[:, 0]) / self.widths[:, 0]
        zd = (d - self.w[:, 1]) / self.widths[:, 1]
        q = np.where(active, 0.5 * (za * za + zd * zd), np.inf)
        phi = np.exp(-(q - q.min()))
        out: np.ndarray = phi / phi.sum()
        return out

    def output(self, u: np.ndarray) -> np.ndarray:
        """The weighted sum of the output weights (also at the goal state)."""
        out: np.ndarray = self.activations(u) @ self.W
        return out

    def learn(self, v: np.ndarray, c: np.ndarray, t: float) -> None:
        """Output weights by gradient descent, widths toward the nearest-centre distance, centres by Eq. 12."""
        phi = self.activations(v)
        err = c - phi @ self.W
        k, idx, g = updated_neighbourhood(v, self.w, self.lattice, self.comp, self.learn_p, t)
        if self.rule == "paper":
            rho = np.array([nearest_centre_widths(self.w, i, self.comp) for i in idx])
        else:
            rho = np.array([neighbour_widths(self.w, self.lattice.size, i, self.comp) for i in idx])
        self.W += self.learn_p.eta_bfn * phi[:, None] * err[None, :]
        self.widths[idx] += (self.learn_p.eta_width * g)[:, None] * (rho - self.widths[idx])
        learning.update_input_weights(self.w, v, idx, g, self.learn_p.eta_w)
        self.won[k] = True


Network = IndirectEKM | DirectEKM | BasisFunctionNetwork
"""A network of any kind the library trains, saves and loads."""


def make_network(name: str, rng: np.random.Generator, comp: CompetitionParams | None = None,
                 learn_p: LearningParams | None = None, bfn_rule: str = "trained-units") -> Network:
    """An untrained network by the paper's name (B15, D15, G9, G12, G15, R15, ...);
    ``bfn_rule`` applies to a basis-function network (:data:`BFN_RULES`)."""
    kind, size = parse_network_name(name)
    if kind == "bfn":
        return BasisFunctionNetwork.untrained(size, rng, comp, learn_p, rule=bfn_rule)
    if kind == "direct":
        return DirectEKM.untrained(size, rng, comp, learn_p)
    return IndirectEKM.untrained(size, kind.split("-")[1], rng, comp, learn_p)
