"""``--learn`` for ``cekm run`` and ``cekm launch`` (docs/learning.md): the controller's
learning graph, the model it starts from (a trained file, or ``untrained`` maps), and the
``learning`` block of ``outcome.json``: per robot what its learner did, its final map's
digest, and the map's E and T on the section 4.1 test targets at the start and the end.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ParameterError
from ..graph.spec import shipped_graphs
from ..models.io import load_model, save_model
from ..models.networks import make_network
from ..modules.learner import MapFollower, copy_model

UNTRAINED = "untrained"
"""``--model untrained``: R15 with regular input weights and uninformed random M_i
(docs/design.md section 3, item 7), drawn from :data:`UNTRAINED_SEED`."""
UNTRAINED_SEED = 0
UNTRAINED_NAME = "R15"
LEARNER = "learner"
"""The learner node's name in a learning graph."""
TEST_SEED = 2005
"""The seed of the section 4.1 test targets a map is scored on (``cekm experiment target-reaching``'s default)."""


def untrained_model():
    """The untrained map ``--model untrained`` gives (the same in ``cekm run`` and ``cekm launch``)."""

    return make_network(UNTRAINED_NAME, np.random.default_rng(UNTRAINED_SEED))


def model_of_choice(choice):
    """The model of ``--model``: a file, ``untrained`` maps, or (None) the default R15."""
    from .default_model import default_model  # noqa: PLC0415 -- lazy: numba, scipy, tqdm

    return untrained_model() if choice == UNTRAINED else load_model(choice) if choice else default_model()


def learning_controller(controller: str, graph_file) -> str:
    """The controller whose learning graph ``--learn`` runs: ``cekm`` -> ``cekm-learning``."""
    if graph_file is not None:
        raise ParameterError("--learn runs a controller's learning graph; with --graph, give a graph with a "
                             "learner node instead (docs/learning.md)")
    name = controller if controller.endswith(("-learning", "-learning-team")) else f"{controller}-learning"

    learning = sorted({g.rsplit("-", 1)[0] for g in shipped_graphs() if "-learning" in g})
    if name not in learning:
        raise ParameterError(f"--learn: controller {controller!r} has no learning graph (learning controllers: "
                             f"{', '.join(learning)}; docs/learning.md)")
    return name


def learning_params(model_choice) -> dict[str, Any]:
    """The learner's parameters for the model it starts from: untrained maps start the
    neighbourhood schedule at step 0, a trained one at its final width."""
    return {"start_step": 0} if model_choice == UNTRAINED else {}


def model_file_for_launch(model_choice, out_dir: Path) -> Path | None:
    """A model file the launched nodes can read: ``untrained`` is written into ``out_dir``."""
    if model_choice != UNTRAINED:
        return model_choice

    return save_model(Path(out_dir) / "untrained-R15.npz", untrained_model(),
                      {"untrained": True, "seed": UNTRAINED_SEED})


def test_score(model) -> dict[str, float]:
    """The map's E (mm), T (s/m) and D on the section 4.1 test targets (50, from the arena's
    centre, no learning; :func:`cekm_swarm.experiments.trial.test_reference`)."""
    from .arena import Arena  # noqa: PLC0415 -- lazy: numba, scipy
    from .metrics import score  # noqa: PLC0415 -- lazy: numba, scipy
    from .stopping import GOAL_STOP  # noqa: PLC0415 -- lazy: numba, scipy
    from .streams import Schedule, TrialStreams  # noqa: PLC0415 -- lazy: numba, scipy
    from .trial import network_command, test_reference  # noqa: PLC0415 -- lazy: numba, scipy

    arena = Arena()
    streams = TrialStreams(TEST_SEED, 0, arena, Schedule(steps=10, test_interval=10))
    s = score(test_reference(network_command(model, GOAL_STOP), streams, np.array([0.005])), arena.step_s)
    return {"E_mm": round(s.E_mm, 3), "T_s_per_m": round(s.T_s_per_m, 3), "D": round(s.D, 4),
            "ended_by_budget": s.ended_by_budget}


def learner_summary(learner, dropped: int = 0, start=None) -> dict[str, Any]:
    """One robot's ``learning`` block from its learner node (and the start map's score): the
    map of its last version (steps learned since are in no version yet)."""
    c = learner.counts
    out = {"versions": learner.version, "steps": c.steps, "updates_applied": c.learned, "own_steps": c.applied,
           "team_steps": c.team, "skipped_stopped": c.stopped,
           "skipped_blocked": c.blocked, "updates_dropped": dropped, "final_digest": learner.digest,
           "start": start, "end": test_score(copy_model(learner.net, *learner.arrays))}  # the last version's map
    return out


def learning_outcome(executor, team, base_model) -> dict[str, dict]:
    """The ``learning`` block of an in-process run: per robot with a learner."""
    out = {}
    start = None
    for robot in team:
        try:
            node = executor.node(robot, LEARNER)
        except KeyError:
            continue
        if start is None:
            start = test_score(base_model)

        dropped = sum(r.node.dropped for r in executor.runners
                      if r.plan.robot == robot and isinstance(r.node, MapFollower))  # versions its nodes dropped
        out[robot] = learner_summary(node, dropped, start)
    return out


def check_learning_model(model) -> None:
    """A model a learner can start from: an indirect-mapping EKM."""
    if not str(getattr(model, "kind", "")).startswith("indirect"):
        raise ParameterError(f"--learn needs an indirect-mapping EKM (G or R), not {getattr(model, 'kind', model)!r}")
