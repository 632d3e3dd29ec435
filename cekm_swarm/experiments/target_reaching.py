"""The target-reaching experiment of section 4.1 (Tables 1-4, Figures 5-7).

Each network is trained for ``steps`` steps in each of ``trials`` trials and tested every
``test_interval`` steps on the trial's fixed 50 targets. Trials run as one numba batch
per network. Every network of a trial sees the same targets and noise. Stop rules
(:mod:`.stopping`) end test targets (the paper's, by default) and training targets (the
goal state, by default, as before).
"""

from __future__ import annotations

import itertools
import time
import warnings
from dataclasses import asdict, dataclass, field
from typing import Callable, Sequence

import numpy as np

from ..errors import ParameterError
from ..models import fast
from ..models.networks import BFN_RULES, BFN_WIDTH_FLOOR, make_network, parameter_count, parse_network_name
from ..models.params import CompetitionParams, LearningParams, params_to_dict
from .arena import Arena
from .metrics import TestScore, mean_std, score, welch_p
from .stopping import GOAL_STOP, PAPER_STOP, StopRule
from .streams import Schedule, TrialStreams
from .trial import NetworkBatch, run_batch

PAPER_NETWORKS = ("B15", "D15", "G9", "G12", "G15", "R15")
DEFAULT_EPS_MM = tuple(float(e) for e in range(1, 31))  # Fig. 7's range, 1 mm steps
INDICES = ("E_mm", "T_s_per_m", "D", "P5", "T5_s_per_m", "D5")


@dataclass(frozen=True)
class TargetReachingConfig:
    """Everything that defines a run; the same config and seed give the same numbers.

    ``stop``: the test's stop rule (the paper's, ``command``, by default). ``train_stop``:
    training's (the goal state by default, so that every network is trained as before and
    only the test differs between the rules). ``bfn_rule``: the basis-function network's
    rule (:data:`BFN_RULES`).
    """

    networks: tuple[str, ...] = PAPER_NETWORKS
    trials: int = 5
    schedule: Schedule = field(default_factory=Schedule)
    seed: int = 2005
    eps_mm: tuple[float, ...] = DEFAULT_EPS_MM
    comp: CompetitionParams = field(default_factory=CompetitionParams)
    learn_p: LearningParams = field(default_factory=LearningParams)
    arena: Arena = field(default_factory=Arena)
    stop: StopRule = PAPER_STOP
    train_stop: StopRule = GOAL_STOP
    bfn_rule: str = "paper"

    def __post_init__(self) -> None:
        if self.bfn_rule not in BFN_RULES:
            raise ParameterError(f"bfn_rule must be one of {', '.join(BFN_RULES)}, got {self.bfn_rule!r}")
        for name in self.networks:
            parse_network_name(name)
        if len(set(self.networks)) != len(self.networks):
            raise ParameterError(f"networks must be distinct, got {list(self.networks)}")
        if not isinstance(self.trials, int) or self.trials < 1:
            raise ParameterError(f"trials must be a positive integer, got {self.trials!r}")
        if 5.0 not in self.eps_mm:
            raise ParameterError("eps_mm must include 5 (Tables 3-4 are at eps = 5 mm)")
        if list(self.eps_mm) != sorted(self.eps_mm) or self.eps_mm[0] <= 0:
            raise ParameterError("eps_mm must be positive and ascending")

    def settings(self) -> dict:
        return {
            "networks": list(self.networks), "trials": self.trials, "seed": self.seed, "eps_mm": list(self.eps_mm),
            "schedule": asdict(self.schedule), "arena": asdict(self.arena), "stop": asdict(self.stop),
            "train_stop": asdict(self.train_stop),
            "bfn_rule": self.bfn_rule, "params": params_to_dict(self.comp, self.learn_p),
        }


@dataclass
class NetworkRun:
    """One network's trained batch and its test scores: scores[trial][test point]."""

    name: str
    batch: NetworkBatch
    scores: list[list[TestScore]]
    seconds: float

    def trained(self, trial: int, config: TargetReachingConfig):
        """The trained network of one trial as a reference object (for saving and plotting)."""
        net = make_network(self.name, np.random.default_rng(0), config.comp, config.learn_p, config.bfn_rule)
        fast.load_arrays(net, self.batch.W[trial], self.batch.P[trial], self.batch.R[trial])
        return net


def run_network(name: str, config: TargetReachingConfig, on_progress: Callable[[int], None] | None = None) -> NetworkRun:
    """Train and test one network over all trials."""
    streams = [TrialStreams(config.seed, t, config.arena, config.schedule) for t in range(config.trials)]
    nets = [make_network(name, s.init_rng(), config.comp, config.learn_p, config.bfn_rule) for s in streams]
    arrays = [fast.network_arrays(n) for n in nets]
    kind, size = parse_network_name(name)
    params = fast.pack_params(config.comp, config.learn_p, config.arena.v_max, BFN_WIDTH_FLOOR, config.bfn_rule)
    batch = NetworkBatch(kind, size, *(np.ascontiguousarray(np.stack([a[q] for a in arrays])) for q in range(3)), params)
    eps = np.array(config.eps_mm) / 1000.0
    t0 = time.perf_counter()
    outcomes = run_batch(batch, streams, eps, on_progress, config.stop, config.train_stop)
    seconds = time.perf_counter() - t0
    scores = [[score(o, config.arena.step_s) for o in per_trial] for per_trial in outcomes]
    return NetworkRun(name, batch, scores, seconds)


def _after_training(run: NetworkRun, i5: int) -> dict[str, list[float]]:
    """Per-trial values of every index at the last test point."""
    last = [s[-1] for s in run.scores]
    return {
        "E_mm": [s.E_mm for s in last],
        "T_s_per_m": [s.T_s_per_m for s in last],
        "D": [s.D for s in last],
        "P5": [float(s.P[i5]) for s in last],
        "T5_s_per_m": [float(s.T_eps[i5]) for s in last],
        "D5": [float(s.D_eps[i5]) for s in last],
        "ended_by_budget": [float(s.ended_by_budget) for s in last],
        "goal_stops": [float(s.goal_stops) for s in last],
    }


def summarize(runs: Sequence[NetworkRun], config: TargetReachingConfig) -> dict:
    """The results.json document."""
    i5 = list(config.eps_mm).index(5.0)
    per_trial = {r.name: _after_training(r, i5) for r in runs}
    networks = {}
    for r in runs:
        kind, size = parse_network_name(r.name)
        entry = {"kind": kind, "lattice": size, "parameters": parameter_count(kind, size)}
        entry.update({k: mean_std(v) for k, v in per_trial[r.name].items()})
        entry["per_trial"] = per_trial[r.name]
        curves = {"steps": config.schedule.test_points}
        pick = {"E_mm": lambda s: s.E_mm, "T_s_per_m": lambda s: s.T_s_per_m, "D": lambda s: s.D,
                "P5": lambda s: float(s.P[i5]), "T5_s_per_m": lambda s: float(s.T_eps[i5])}
        for key, get in pick.items():
            m = np.array([[get(s) for s in trial] for trial in r.scores])
            with warnings.catch_warnings():  # T5 is NaN at a test point where no target was reached
                warnings.simplefilter("ignore", RuntimeWarning)
                curves[key] = {"mean": np.nanmean(m, axis=0).tolist(),
                               "std": np.nanstd(m, axis=0, ddof=1).tolist() if len(m) > 1 else [0.0] * m.shape[1],
                               "per_trial": m.tolist()}
        curves["ended_by_budget"] = [[s.ended_by_budget for s in trial] for trial in r.scores]
        entry["learning_curves"] = curves
        last = [s[-1] for s in r.scores]
        entry["eps_curves"] = {
            "eps_mm": list(config.eps_mm),
            "P": _stack_mean_std([s.P for s in last]),
            "T_s_per_m": _stack_mean_std([s.T_eps for s in last]),
            "D": _stack_mean_std([s.D_eps for s in last]),
        }
        entry["seconds"] = round(r.seconds, 3)
        networks[r.name] = entry
    t_tests = {}
    for key in INDICES:
        t_tests[key] = {f"{a}|{b}": welch_p(per_trial[a][key], per_trial[b][key])
                        for a, b in itertools.combinations([r.name for r in runs], 2)}
    return {"experiment": "target-reaching", "paper_section": "4.1", "settings": config.settings(),
            "networks": networks, "t_tests": t_tests}


def _stack_mean_std(rows: list[np.ndarray]) -> dict:
    m = np.array(rows, dtype=np.float64)
    with np.errstate(all="ignore"):
        import warnings

        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            mean = np.nanmean(m, axis=0)
            std = np.nanstd(m, axis=0, ddof=1) if len(m) > 1 else np.zeros(m.shape[1])
    return {"mean": [None if not np.isfinite(x) else float(x) for x in mean],
            "std": [None if not np.isfinite(x) else float(x) for x in std]}


def run_experiment(config: TargetReachingConfig, progress: bool = True) -> tuple[dict, list[NetworkRun]]:
    """Run every network; returns (results document, runs)."""
    from tqdm import tqdm

    total = len(config.networks) * config.trials * config.schedule.steps
    runs = []
    t0 = time.perf_counter()
    with tqdm(total=total, unit="step", unit_scale=True, disable=not progress, desc="training",
              bar_format="{l_bar}{bar}| {n_fmt}/{total_fmt} robot-steps [{elapsed}<{remaining}, {rate_fmt}]") as bar:
        for name in config.networks:
            bar.set_description(f"{name} ({config.trials} trials)")
            runs.append(run_network(name, config, lambda n: bar.update(n * config.trials)))
    results = summarize(runs, config)
    results["wall_seconds"] = round(time.perf_counter() - t0, 3)
    return results, runs
