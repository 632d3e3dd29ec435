"""The tick order of a robot's modules, shared by the in-process runner and the runtime's
lockstep mode (which must reproduce it exactly).

Time advances in ticks of 0.128 s (the obstacle modules' period; 4 world sub-steps of
0.032 s). At tick k, sim time t = k * 0.128 s:

1. the world takes the readings due at t: all 12 distance sensors every tick, the
   target sensor on even ticks (every 0.256 s);
2. the modules due at t compute from those readings: every obstacle localization module,
   and the target localization module on even ticks;
3. the motor module integrates the latest field of every module (Eqs. 9-11) and sends c;
4. the world applies c and advances 0.128 s.

Before the first target field arrives the motor module commands c = 0.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..ticks import SUBSTEP_S, TARGET_PERIOD_S, TICK_S


@dataclass(frozen=True)
class Schedule:
    substep_s: float = SUBSTEP_S
    obstacle_period_s: float = TICK_S
    target_period_s: float = TARGET_PERIOD_S

    @property
    def tick_s(self) -> float:
        return self.obstacle_period_s

    @property
    def substeps_per_tick(self) -> int:
        return round(self.tick_s / self.substep_s)

    @property
    def target_every(self) -> int:
        return round(self.target_period_s / self.obstacle_period_s)

    def time(self, tick: int) -> float:
        """Sim time of tick k (computed, not accumulated, so it never drifts)."""
        return round(tick * self.tick_s, 9)

    def target_due(self, tick: int) -> bool:
        return tick % self.target_every == 0


SCHEDULE = Schedule()
