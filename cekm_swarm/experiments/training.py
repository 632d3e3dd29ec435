"""Train one network for use elsewhere (``cekm train``, the controller's default model)."""

from __future__ import annotations

from .streams import Schedule
from .target_reaching import TargetReachingConfig, run_network


def train_network(name: str, steps: int, seed: int, progress: bool = True):
    """Self-organized learning of one network in the obstacle-free arena from untrained maps.

    Returns (trained network, its scores on the fixed test after training).
    """
    from tqdm import tqdm

    interval = 10_000 if steps % 10_000 == 0 else steps
    config = TargetReachingConfig(networks=(name,), trials=1, seed=seed,
                                  schedule=Schedule(steps=steps, test_interval=interval))
    with tqdm(total=steps, unit="step", unit_scale=True, disable=not progress, desc=f"training {name}") as bar:
        run = run_network(name, config, bar.update)
    last = run.scores[0][-1]
    i5 = list(config.eps_mm).index(5.0)
    score = {"E_mm": last.E_mm, "T_s_per_m": last.T_s_per_m, "D": last.D, "P5": float(last.P[i5]),
             "ended_by_budget": last.ended_by_budget}
    return run.trained(0, config), score
