"""The runtime's clock, one home for both sides of the protocol (world and controller;
plain constants, so the simulation may import it).

Time advances in ticks of 0.128 s (the obstacle modules' period), each 4 world sub-steps
of 0.032 s; the target sensor and module run every other tick (0.256 s). A tick's sim
time is computed, never accumulated, so every process derives the same stamp for tick k.
"""

from __future__ import annotations

SUBSTEP_S = 0.032  # Webots' basic time step; wheel slip noise is drawn this often
TICK_S = 0.128  # obstacle localization period (section 3.1)
TARGET_PERIOD_S = 0.256  # target localization period (section 3.1)
SUBSTEPS_PER_TICK = round(TICK_S / SUBSTEP_S)
TARGET_EVERY = round(TARGET_PERIOD_S / TICK_S)  # ticks
STEP_TIMEOUT = 60.0
"""Wall seconds a lockstep tick (``cekm launch --mode lockstep``) or a step of ``cekm run``
may wait on one node's step before the run ends as failed, naming the step's line
(``--step-timeout``)."""
ODOMETRY_EVERY = 8
"""Ticks between two odometry readings (``sense/odometry``, 1.024 s: one step of the map,
section 4.1); each holds the record of the last 16 ticks (docs/learning.md)."""


def tick_time(tick: int) -> float:
    """Sim time of tick k, as every process computes it: ``round(k * 0.128, 9)``."""
    return round(tick * TICK_S, 9)


def tick_of(stamp: float) -> int:
    """The tick whose sim time is nearest to ``stamp``."""
    return int(round(stamp / TICK_S))
