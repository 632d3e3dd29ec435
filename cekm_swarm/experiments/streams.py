"""Random streams of a target-reaching trial, drawn up front so that two runners (the
reference and the fast one) consume exactly the same numbers.

Every stream is keyed by (seed, trial, what, chunk) through numpy's SeedSequence, so
every network sees the same targets and noise (common random numbers): differences
between networks are the networks', not the dice's.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..errors import ParameterError
from ..robot import KHEPERA
from .arena import Arena, draw_targets

_INIT, _TRAIN_TARGETS, _TRAIN_NOISE, _TEST = range(4)


@dataclass(frozen=True)
class Schedule:
    """How long a trial trains and how it is tested (section 4.1)."""

    steps: int = 100_000
    test_interval: int = 10_000
    test_targets: int = 50
    test_budget: int = 500  # steps per test target before it counts as ended by budget
    train_budget: int = 100  # steps per training target before the next one is presented

    def __post_init__(self) -> None:
        for name in ("steps", "test_interval", "test_targets", "test_budget", "train_budget"):
            value = getattr(self, name)
            if not isinstance(value, (int, np.integer)) or value <= 0:
                raise ParameterError(f"Schedule.{name} must be a positive integer, got {value!r}")
        if self.steps % self.test_interval:
            raise ParameterError(f"Schedule.steps ({self.steps}) must be a multiple of test_interval "
                                 f"({self.test_interval})")

    @property
    def test_points(self) -> list[int]:
        """Training steps at which the network is tested, 0 included."""
        return list(range(0, self.steps + 1, self.test_interval))


class TrialStreams:
    """The random numbers of one trial."""

    def __init__(self, seed: int, trial: int, arena: Arena, schedule: Schedule) -> None:
        self.seed, self.trial, self.arena, self.schedule = int(seed), int(trial), arena, schedule

    def rng(self, *key: int) -> np.random.Generator:
        return np.random.Generator(np.random.PCG64(np.random.SeedSequence(self.seed, spawn_key=(self.trial, *key))))

    def init_rng(self) -> np.random.Generator:
        """For the networks' initial random parameters."""
        return self.rng(_INIT)

    @cached_property
    def train_targets(self) -> np.ndarray:
        """Enough targets for the whole training run (at most one new target per step)."""
        return draw_targets(self.rng(_TRAIN_TARGETS), self.schedule.steps + 64, self.arena)

    def train_chunk(self, chunk: int, nsteps: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(wheel noise factors (n, substeps, 2), target-sensor noise factors (n, 2), exploration N(0,1) (n, 2))."""
        g = self.rng(_TRAIN_NOISE, chunk)
        wn, sn = KHEPERA.wheel_noise, KHEPERA.sensor_noise
        wheel = 1.0 + g.uniform(-wn, wn, size=(nsteps, self.arena.substeps, 2))
        sense = 1.0 + g.uniform(-sn, sn, size=(nsteps, 2))
        explore = g.standard_normal(size=(nsteps, 2))
        return wheel, sense, explore

    @cached_property
    def test_set(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The fixed testing procedure: (targets (m, 2), wheel noise (m, budget, substeps, 2),
        sensor noise (m, budget, 2))."""
        g = self.rng(_TEST)
        s = self.schedule
        wn, sn = KHEPERA.wheel_noise, KHEPERA.sensor_noise
        targets = draw_targets(g, s.test_targets, self.arena)
        wheel = 1.0 + g.uniform(-wn, wn, size=(s.test_targets, s.test_budget, self.arena.substeps, 2))
        sense = 1.0 + g.uniform(-sn, sn, size=(s.test_targets, s.test_budget, 2))
        return targets, wheel, sense


def batch_train_chunk(streams: list[TrialStreams], chunk: int,
                      nsteps: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every trial's training noise for one chunk, stacked (B, ...); drawn in threads
    (numpy's generators release the GIL), each trial from its own stream as before."""
    with ThreadPoolExecutor(max_workers=min(len(streams), os.cpu_count() or 1)) as ex:
        parts = list(ex.map(lambda st: st.train_chunk(chunk, nsteps), streams))
    wheel, sense, explore = (np.stack([p[q] for p in parts]) for q in range(3))
    return wheel, sense, explore
