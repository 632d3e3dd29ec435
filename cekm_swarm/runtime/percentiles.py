"""One percentile convention for every number the project reports (the outcome's latency,
the monitor, the benchmarks): numpy's ``linear`` method (the sample quantile of Hyndman and
Fan's definition 7, numpy's default), on the values as given."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

METHOD = "linear"


def percentile(values: Sequence[float], q: float) -> float:
    """The ``q`` quantile (0 <= q <= 1) of ``values``; NaN for none."""
    if not 0.0 <= q <= 1.0:
        raise ValueError(f"q must be in [0, 1], got {q}")
    if len(values) == 0:
        return float("nan")
    return float(np.quantile(np.asarray(values, dtype=np.float64), q, method=METHOD))
