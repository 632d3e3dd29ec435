"""The robot's module processes of the distributed runtime (docs/design.md section 6).

Each module is a thin asyncio shell (:mod:`.shell`) around a pure part that can be
tested without Zenoh:

* :mod:`.target`: target localization, on each ``sense/target`` (every 0.256 s);
* :mod:`.obstacle`: obstacle localization j, on each ``sense/range/<j>`` (every 0.128 s);
* :mod:`.motor`: motor integration, once per tick when the tick's fields are in (real
  time: those of live sources, or when the next tick begins; lockstep: every one).

They compute exactly what :meth:`cekm_swarm.experiments.navigation.RobotBrain.tick`
computes in one process, through :class:`cekm_swarm.controller.cooperative.CooperativeEKM`.
Started as ``python -m cekm_swarm.modules.<name> --robot r1 --model M.npz --connect ENDPOINT``.
Module processes never import the world.
"""
