"""Named parameters of the EKMs, with the defaults the project uses and why.

Every number the paper leaves open is resolved here (docs/design.md sections 3 and 7).
Internally the control model sees the input as (alpha, d_scale * d), so that both
components span about +-pi; ``d_scale`` is that factor.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields

from ..errors import ParameterError


def _check_positive(obj, *names: str) -> None:
    for name in names:
        value = getattr(obj, name)
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            raise ParameterError(f"{type(obj).__name__}.{name} must be a positive finite number, got {value!r}")


@dataclass(frozen=True)
class CompetitionParams:
    """Competition with direction priority (Eqs. 2-4).

    beta_d = (2 pi / 0.16)^2 puts alpha in [-pi, pi] and d in [0, 0.16 m] on one scale.
    direction_tolerance: neurons whose wrapped angular difference is within this of the
    smallest one form A(alpha) (Eq. 4); 0.05-0.15 rad worked, 0 ignores distance.
    """

    beta_alpha: float = 1.0
    beta_d: float = (2.0 * math.pi / 0.16) ** 2
    direction_tolerance: float = 0.1

    def __post_init__(self) -> None:
        _check_positive(self, "beta_alpha", "beta_d")
        if not (0.0 <= self.direction_tolerance < math.pi):
            raise ParameterError(f"CompetitionParams.direction_tolerance must be in [0, pi), got {self.direction_tolerance!r}")


@dataclass(frozen=True)
class LearningParams:
    """Self-organized learning (section 3.5, Eqs. 12-17) and its schedule.

    sigma_*: neighbourhood width G(k, i) in lattice units, sigma(t) = final + (initial -
    final) exp(-t / tau). g_min: N_k = {i : G(k, i) >= g_min}; only these update.
    eta_w: Eq. 12. eta_m: gradient descent, Eq. 15. forgetting: lambda of Eq. 16.
    eta_c: the direct-mapping EKM's output rule. eta_bfn/eta_width: the basis-function
    network's output weights and widths. rinv_trace_cap bounds trace(R^-1) (safeguard).
    d_scale: d is multiplied by it inside the control model (docs/design.md section 7: the
    paper's R^-1 = I does not say in which units). explore_rel/explore_abs: training-only
    exploration noise on executed wheel speeds, N(0, (rel |c| + abs)^2) per wheel.
    m_init_scale: initial M entries are uniform in +- m_init_scale * v_max / pi, so random
    commands span about half the wheel range (untrained maps, as the paper's).
    """

    eta_w: float = 0.05
    eta_m: float = 0.05
    eta_c: float = 0.05
    eta_bfn: float = 0.2
    eta_width: float = 0.05
    sigma_initial: float = 1.0
    sigma_final: float = 0.3
    sigma_tau: float = 1.0e4
    g_min: float = 0.01
    forgetting: float = 0.999
    rinv_trace_cap: float = 1.0e4
    d_scale: float = math.pi / 0.16
    explore_rel: float = 0.2
    explore_abs: float = 0.005
    m_init_scale: float = 0.5

    def __post_init__(self) -> None:
        _check_positive(self, "eta_w", "eta_m", "eta_c", "eta_bfn", "eta_width", "sigma_initial", "sigma_final",
                        "sigma_tau", "g_min", "forgetting", "rinv_trace_cap", "d_scale", "m_init_scale")
        if not self.forgetting <= 1.0:
            raise ParameterError(f"LearningParams.forgetting (lambda) must be in (0, 1], got {self.forgetting!r}")
        if not self.g_min < 1.0:
            raise ParameterError(f"LearningParams.g_min must be in (0, 1), got {self.g_min!r}")
        if self.explore_rel < 0 or self.explore_abs < 0:
            raise ParameterError("LearningParams.explore_rel and explore_abs must be >= 0")

    def sigma(self, t: float) -> float:
        """Neighbourhood width at training step t."""
        return self.sigma_final + (self.sigma_initial - self.sigma_final) * math.exp(-t / self.sigma_tau)


@dataclass(frozen=True)
class FieldParams:
    """Target field (Eq. 6) and obstacle field (Eq. 8) widths.

    The paper's values, except ``sigma_b_alpha``: 0.6 rad, not the paper's 0.495. Over
    seeds 1-10 of ``cekm experiment obstacles`` 0.6 took ``checkpoints`` from 5/10 to 10/10
    successes (the middle room's U is negotiated) and kept ``concave`` and ``doorway`` at
    10/10 (the 86 mm doorway still looks open); 0.55 gave 9/10 and 0.75 lost ``rooms``
    (4/10: its 0.14 m doorways start to look closed). docs/reproduction-4.2.md has the
    whole search.
    """

    sigma_a_alpha: float = 2.475
    sigma_a_d: float = 0.0495
    sigma_b_alpha: float = 0.6
    sigma_b_d_beyond: float = 2.475  # d_i >= d_s: neurons beyond the obstacle are inhibited too
    sigma_b_d_near: float = 0.02475  # d_i < d_s

    def __post_init__(self) -> None:
        _check_positive(self, *(f.name for f in fields(self)))


def params_to_dict(*objs) -> dict:
    """A JSON-ready dict of several parameter dataclasses, keyed by class name."""
    return {type(o).__name__: asdict(o) for o in objs}
