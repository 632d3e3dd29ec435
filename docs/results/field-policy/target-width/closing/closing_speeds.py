"""The largest per-field closing speed of each tick (docs/fields.md, the third round), on a
scenario with movers and one without, run from the repository's root:

  python docs/results/field-policy/target-width/closing/closing_speeds.py

Today's constants with a V of 1e-9 on `closing` (so the motor computes the features each
tick; the widths move by a part in 1e9) and the field-policy graph; it prints the quantiles
of the largest closing speed (m/s) over the run's ticks.
"""

from __future__ import annotations

import numpy as np

from cekm_swarm.experiments.graph_run import run_graph
from cekm_swarm.node.graph_check import check_graph
from cekm_swarm.tune import features
from cekm_swarm.tune.graphs import policy_graph
from cekm_swarm.tune.policy import FieldPolicy
from world import load_scenario


def largest_per_tick(name: str, max_time: float) -> np.ndarray:
    seen: list[float] = []
    update = features.ClosingSpeeds.update

    def recording(self, w, readings, forward):
        out = update(self, w, readings, forward)
        seen.append(max(out, default=0.0))
        return out

    features.ClosingSpeeds.update = recording  # type: ignore[method-assign]
    try:
        V = np.zeros((3, len(features.FIELD_FEATURES)))
        V[0, features.FIELD_FEATURES.index("closing")] = 1e-9
        weights = (0.0,) * FieldPolicy.size("navigation") + tuple(V.ravel().tolist())
        run_graph(load_scenario(name), graph=check_graph(policy_graph("navigation")), params={"weights": weights},
                  max_time=max_time)
    finally:
        features.ClosingSpeeds.update = update  # type: ignore[method-assign]
    return np.array(seen)


if __name__ == "__main__":
    for name, t in (("rooms", 120.0), ("concave", 60.0)):
        q = np.quantile(largest_per_tick(name, t), [0.5, 0.9, 0.95, 0.99])
        print(f"{name}: ticks' largest closing speed, quantiles 50/90/95/99 %: " + ", ".join(f"{x:.3f}" for x in q))
