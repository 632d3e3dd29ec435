"""One percentile convention for every number the project reports (the outcome's latency,
the monitor, the benchmarks): numpy's ``linear`` method (the sample quantile of Hyndman and
Fan's definition 7, numpy's default), on the values as given."""

from __future__ import annotations

import math
from array import array
from collections.abc import Sequence
from typing import Final

import numpy as np

METHOD: Final = "linear"


def percentile(values: Sequence[float], q: float) -> float:
    """The ``q`` quantile (0 <= q <= 1) of ``values``; NaN for none."""
    if not 0.0 <= q <= 1.0:
        raise ValueError(f"q must be in [0, 1], got {q}")
    if len(values) == 0:
        return float("nan")
    return float(np.quantile(np.asarray(values, dtype=np.float64), q, method=METHOD))


class Samples:
    """Samples for :func:`percentile` in fixed memory, for runs of any length: the first
    :attr:`exact_max` values are kept as packed doubles (the percentiles of up to that many
    are exact, as :func:`percentile` of a list); every value also goes into a histogram of
    logarithmic bins :attr:`resolution` wide (relative) from :attr:`low` to :attr:`high`,
    from which the percentiles of more samples are read (within that resolution; values
    outside the range fall in the end bins). Both are allocated whole when it is made, so
    a process that keeps one for hours does not grow with it (the bad-link hour in
    docs/faults.md counts every megabyte of the world server)."""

    exact_max = 65536
    low, high, resolution = 1e-6, 1e3, 0.005

    def __init__(self) -> None:
        self._exact = array("d", bytes(8 * self.exact_max))  # filled up to n, allocated and touched once
        self._step = math.log1p(self.resolution)
        self._bins = np.zeros(int(math.log(self.high / self.low) / self._step) + 2, dtype=np.int64)
        self.n = 0

    def append(self, v: float) -> None:
        if self.n < self.exact_max:
            self._exact[self.n] = v
        i = int(math.log(v / self.low) / self._step) + 1 if v > self.low else 0
        self._bins[min(i, len(self._bins) - 1)] += 1
        self.n += 1

    def __len__(self) -> int:
        return self.n

    @property
    def exact(self) -> bool:
        """True while every sample is kept (the percentiles are exact)."""
        return self.n <= self.exact_max

    def percentile(self, q: float) -> float:
        """The ``q`` quantile: :func:`percentile` of the samples while :attr:`exact`, else
        the geometric middle of the histogram bin holding it."""
        if self.exact:
            return percentile(self._exact[:self.n], q)
        if not 0.0 <= q <= 1.0:
            raise ValueError(f"q must be in [0, 1], got {q}")
        rank = q * (self.n - 1)  # the linear method's position, 0-based
        i = int(np.searchsorted(np.cumsum(self._bins), math.floor(rank) + 1))
        if i == 0:
            return self.low
        return self.low * math.exp((i - 0.5) * self._step)
