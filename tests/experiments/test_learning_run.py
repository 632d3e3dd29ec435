"""--learn's choices (cekm_swarm.experiments.learning_run): the learning graph of a
controller, the model it starts from, refusals that name what is wrong."""

from __future__ import annotations

import pytest

from cekm_swarm.cli import run_cli_args
from cekm_swarm.errors import ParameterError
from cekm_swarm.experiments.learning_run import learning_controller, learning_params, untrained_model


def test_the_learning_graph_of_a_controller():
    assert learning_controller("cekm", None) == "cekm-learning"
    assert learning_controller("cekm-learning-team", None) == "cekm-learning-team"
    with pytest.raises(ParameterError, match="'fusion' has no learning graph"):
        learning_controller("fusion", None)
    with pytest.raises(ParameterError, match="with --graph"):
        learning_controller("cekm", "mine.toml")
    assert learning_params("untrained") == {"start_step": 0} and learning_params(None) == {}


def test_untrained_maps_are_the_same_every_time():
    a, b = untrained_model(), untrained_model()
    assert a.kind == "indirect-rls" and a.lattice.size == 15
    assert (a.M == b.M).all() and (a.w == b.w).all()


def test_bad_model_choice_is_refused_in_one_line(tmp_path, capsys):
    code = run_cli_args(["run", "lone_obstacle", "--learn", "--model", str(tmp_path / "none.npz"),
                         "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code != 0 and "no such file (give a model .npz, or 'untrained')" in err
