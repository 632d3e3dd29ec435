"""Section 4.1's target-reaching run defined (:class:`TargetReachingConfig`, everything that
makes its numbers) and one network's result (:class:`NetworkRun`): what the run
(:mod:`.reaching_run`), its statistics (:mod:`.reaching_stats`) and its report share."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

from ..errors import ParameterError
from ..models import fast
from ..models.networks import BFN_RULES, make_network, parse_network_name
from ..models.params import CompetitionParams, LearningParams, params_to_dict
from .arena import Arena
from .metrics import TestScore
from .stopping import GOAL_STOP, PAPER_STOP, StopRule
from .streams import Schedule
from .trial import NetworkBatch

PAPER_NETWORKS = ("B15", "D15", "G9", "G12", "G15", "R15")
DEFAULT_EPS_MM = tuple(float(e) for e in range(1, 31))  # Fig. 7's range, 1 mm steps


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
