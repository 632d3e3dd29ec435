"""Fig. 9's sweep defined: the depths, widths and sensing ranges of the concave obstacle,
the seeds, and how many successes a width needs (:class:`SweepConfig`), shared by the
sweep's runs (:mod:`.concave_run`) and its statistics (:mod:`.concave_stats`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from world import ScenarioError, load_scenario

from ..errors import ParameterError
from .field_widths import REPRODUCTION, check_fields


@dataclass(frozen=True)
class SweepConfig:
    depths: tuple[float, ...] = (0.06, 0.12, 0.18, 0.24, 0.30)
    widths: tuple[float, ...] = (0.10, 0.20, 0.34, 0.50, 0.70, 1.00, 1.40, 2.00)
    ranges: tuple[float, ...] = (0.12, 0.17, 0.25)
    seeds: tuple[int, ...] = (1, 2, 3)
    need: int = 2  # successes out of len(seeds) for a width to count as negotiated
    max_time: float = 300.0
    scenario: str = "concave"
    fields: str = REPRODUCTION  # cekm's field widths (--fields, .field_widths): the paper's method's

    def __post_init__(self) -> None:
        for name in ("depths", "widths", "ranges"):
            values = getattr(self, name)
            if not values or not all(math.isfinite(v) and v > 0 for v in values):
                raise ParameterError(f"--{name}: sweep {name} must be positive numbers, got {list(values)}")
        if not self.seeds:
            raise ParameterError("--seeds: give at least one seed")
        check_fields(self.fields)
        if not 1 <= self.need <= len(self.seeds):
            raise ParameterError(f"--need: must be between 1 and the number of --seeds ({len(self.seeds)}), "
                                 f"got {self.need}")

    def check_scenarios(self) -> None:
        """Load the scenario with every (width, depth, range) the sweep will run, so that a
        value the scenario refuses is a :class:`ParameterError` naming its option before any
        worker starts (it was a ScenarioError traceback from a worker)."""
        options = {"obstacles[0].width": "--widths", "obstacles[0].depth": "--depths", "sensors.range": "--ranges"}
        for r in self.ranges:
            for d in self.depths:
                for w in self.widths:
                    try:
                        load_scenario(self.scenario, overrides={"obstacles[0].width": w, "obstacles[0].depth": d,
                                                                "sensors.range": r})
                    except ScenarioError as exc:
                        text = str(exc)
                        named = [o for field, o in options.items() if f"{field}:" in text]
                        where = named[0] if len(named) == 1 else "--depths/--widths/--ranges"
                        raise ParameterError(f"{where}: depth {d}, width {w}, range {r}: {text}") from None
