"""Controllers of section 4.2 built on the model library; they see sensor readings, never the world.

* :mod:`.cooperative`: the cooperative EKMs (target localization, one obstacle
  localization per distance sensor, neural integration and motor control, Eqs. 5-11).
* :mod:`.fusion`: the command-fusion baseline (weighted sum of the target-reaching EKM
  and a Braitenberg avoider).
* :mod:`.schedule`: the tick order shared by the in-process runner and the runtime.
* :mod:`.planner`: checkpoints on the known walls for Fig. 12.
"""
