"""Simulated world for cekm-swarm: Khepera-like robots, walls, obstacles and targets
in pymunk, built from TOML scenarios.

The world never imports the controller (``cekm_swarm``); the two meet through plain
data only.
"""

from .scenario import Scenario, ScenarioError, load_scenario, parse_scenario, scenario_names
from .sim import World

__all__ = ["Scenario", "ScenarioError", "World", "load_scenario", "parse_scenario", "scenario_names"]
