"""The built-in node programs of the shipped graphs (``cekm_swarm/graph/shipped``): each a
small :class:`cekm_swarm.node.Node` around the controller's pure functions.

* cooperative EKMs: :mod:`.target_localization`, :mod:`.obstacle_localization` (one per
  distance sensor), :mod:`.motor_integration`; for tracking :mod:`.tracking_localization`
  and :mod:`.tracking_motor`;
* the baselines: :mod:`.fusion` (command fusion), :mod:`.acmommt`, :mod:`.stay`.

Each runs as its own process (:mod:`cekm_swarm.node.process`) or, with the rest of its
graph, in one process (``cekm run``). They never import the world.
"""
