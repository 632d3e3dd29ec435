"""The EKM lattice: n = N x N neurons on a 2-D grid and their initial input weights."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ParameterError

D_MAX_INIT = 0.16  # m: the farthest the robot moves in one step (section 4.1)


@dataclass(frozen=True)
class Lattice:
    """An N x N grid. Neuron i sits at lattice position r_i = (row, col), i = row * N + col.

    Rows span distance, columns span direction, so the initial input weights are
    "regularly spaced locations in the sensory input space" (section 4.1).
    """

    size: int

    def __post_init__(self) -> None:
        if not (isinstance(self.size, (int, np.integer)) and 2 <= self.size <= 64):
            raise ParameterError(f"Lattice.size must be an integer in [2, 64], got {self.size!r}")

    @property
    def n(self) -> int:
        return self.size * self.size

    def positions(self) -> np.ndarray:
        """r_i as an (n, 2) float array of (row, col); read-only, made once per lattice
        (every learning step asks for it)."""
        r = self.__dict__.get("_positions")
        if r is None:
            rows, cols = np.divmod(np.arange(self.n), self.size)
            r = np.stack([rows, cols], axis=1).astype(np.float64)
            r.flags.writeable = False
            self.__dict__["_positions"] = r  # a cache, not a field: the frozen lattice's value stays its size
        return r

    def initial_weights(self) -> np.ndarray:
        """w_i = (alpha_i, d_i): alpha on [-pi, pi) (no duplicate column at +-pi), d on [0, 0.16] m."""
        alphas = -np.pi + 2.0 * np.pi * np.arange(self.size) / self.size
        ds = np.linspace(0.0, D_MAX_INIT, self.size)
        rows, cols = np.divmod(np.arange(self.n), self.size)
        return np.stack([alphas[cols], ds[rows]], axis=1)


def neighbourhood(positions: np.ndarray, k: int, sigma: float) -> np.ndarray:
    """G(k, i): a Gaussian of the lattice distance ||r_k - r_i|| (Eqs. 12-17)."""
    d2 = np.sum((positions - positions[k]) ** 2, axis=1)
    out: np.ndarray = np.exp(-d2 / (2.0 * sigma * sigma))
    return out
