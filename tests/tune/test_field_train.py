"""``cekm tune fields``: its settings are checked, a directory resumes only its own
training, and a training killed and resumed writes the uninterrupted run's policy, bit for bit."""

from __future__ import annotations

import json
import os
import pickle
import signal
import subprocess
import sys
import time
from dataclasses import asdict

import numpy as np
import pytest

from cekm_swarm.errors import ParameterError
from cekm_swarm.tune.policy import FieldPolicy
from cekm_swarm.tune.train import (
    STATE_VERSION,
    TuneConfig,
    _check_dir,
    command_of,
    full_weights,
    search_size,
    start_vector,
    where_of,
)

TINY = ["--task", "navigation", "--seed", "7", "--generations", "4", "--popsize", "3", "--batch", "2",
        "--validation", "2", "--validate-every", "1", "--max-time", "20", "--workers", "1",
        "--per-field", "--hold", "sigma_b_d_near"]


def test_settings_are_checked():
    with pytest.raises(ParameterError, match="--popsize"):
        TuneConfig(popsize=0)
    with pytest.raises(ParameterError, match="unknown task"):
        TuneConfig(task="juggling")
    with pytest.raises(ParameterError, match="--max-time"):
        TuneConfig(max_time=0.0)
    with pytest.raises(ParameterError, match="unknown geometry mix 'maze'"):
        TuneConfig(mix="maze")
    with pytest.raises(ParameterError, match="--mix goes with --task navigation"):
        TuneConfig(task="tracking", mix="wide")


def test_the_mix_chooses_the_jobs_scenarios_and_is_in_the_command():
    assert where_of(TuneConfig(), "train", 3) == 1_000_003  # the default mix: the seeds as before
    assert where_of(TuneConfig(mix="wide"), "validation", 3) == ("mix", "wide", 2_000_003)
    assert command_of(TuneConfig(mix="wide")).endswith("--mix wide") and "--mix" not in command_of(TuneConfig())


def test_held_outputs_keep_their_rows_of_w_at_zero():
    with pytest.raises(ParameterError, match="--hold: 'teammate_gain' is not an output of the navigation"):
        TuneConfig(hold=("teammate_gain",))
    with pytest.raises(ParameterError, match="at least one output must be free"):
        TuneConfig(hold=("sigma_b_alpha", "sigma_b_d_beyond", "sigma_b_d_near", "sigma_a_d", "sigma_a_alpha"))
    c = TuneConfig(hold=("sigma_b_d_near",))
    W = full_weights(c, np.arange(44.0) + 1).reshape(5, 11)
    assert np.array_equal(W[[0, 1, 3, 4]].ravel(), np.arange(44.0) + 1) and not W[2].any()
    assert np.array_equal(full_weights(TuneConfig(), np.arange(55.0)), np.arange(55.0))
    assert command_of(c).endswith("--hold sigma_b_d_near")


def test_per_field_training_searches_w_and_v_and_holds_both_rows():
    c = TuneConfig(per_field=True, hold=("sigma_b_d_near",))
    assert search_size(c) == 4 * 11 + 2 * 6 and search_size(TuneConfig()) == 55
    flat = full_weights(c, np.arange(56.0) + 1)
    W, V = flat[:55].reshape(5, 11), flat[55:].reshape(3, 6)
    assert np.array_equal(W[[0, 1, 3, 4]].ravel(), np.arange(44.0) + 1) and not W[2].any()
    assert np.array_equal(V[:2].ravel(), np.arange(44.0, 56.0) + 1) and not V[2].any()
    assert command_of(c).endswith("--hold sigma_b_d_near --per-field") and "--per-field" not in command_of(TuneConfig())
    trk = TuneConfig(task="tracking", per_field=True, hold=("teammate_gain",))
    assert search_size(trk) == 3 * 11 + 3 * 6 and full_weights(trk, np.ones(51)).size == 44 + 18


def test_a_search_starts_from_an_init_policy_or_refuses_it(tmp_path):
    W, V = np.zeros((5, 11)), np.zeros((3, 6))
    W[0], W[1, 2], V[1, 4] = 0.5, -1.0, 2.0
    FieldPolicy("navigation", W, field_weights=V).save(tmp_path / "start.json")
    c = TuneConfig(per_field=True, hold=("sigma_b_d_near",), init=str(tmp_path / "start.json"))
    x0 = start_vector(c)
    assert x0.size == search_size(c) and full_weights(c, x0).tolist() == list(FieldPolicy("navigation", W,
                                                                                          field_weights=V).flat())
    assert command_of(c).endswith(f"--per-field --init {tmp_path / 'start.json'}")
    assert not start_vector(TuneConfig()).any()
    with pytest.raises(ParameterError, match="start.json: it has per-field weights V; train it with --per-field"):
        start_vector(TuneConfig(init=str(tmp_path / "start.json")))
    with pytest.raises(ParameterError, match="its weights for sigma_b_d_beyond are not 0, but --hold"):
        start_vector(TuneConfig(per_field=True, hold=("sigma_b_d_beyond",), init=str(tmp_path / "start.json")))
    with pytest.raises(ParameterError, match="a navigation policy, not tracking"):
        start_vector(TuneConfig(task="tracking", per_field=True, init=str(tmp_path / "start.json")))


def test_a_directory_from_before_the_mix_still_resumes(tmp_path):
    old = asdict(TuneConfig(seed=1))
    del old["mix"], old["hold"], old["per_field"], old["init"]
    (tmp_path / "config.json").write_text(json.dumps(old))
    assert _check_dir(tmp_path, TuneConfig(seed=1)) is None
    with pytest.raises(ParameterError, match="mix = 'default', not 'wide'"):
        _check_dir(tmp_path, TuneConfig(seed=1, mix="wide"))
    with pytest.raises(ParameterError, match="per_field = False, not True"):
        _check_dir(tmp_path, TuneConfig(seed=1, per_field=True))
    (tmp_path / "config.json").write_text(json.dumps(asdict(TuneConfig(seed=1, hold=("sigma_b_d_near",)))))
    assert _check_dir(tmp_path, TuneConfig(seed=1, hold=("sigma_b_d_near",))) is None  # a held output resumes


def test_a_directory_resumes_only_its_own_training(tmp_path):
    (tmp_path / "config.json").write_text(json.dumps(asdict(TuneConfig(seed=1))))
    assert _check_dir(tmp_path, TuneConfig(seed=1)) is None
    with pytest.raises(ParameterError, match="seed = 1, not 2"):
        _check_dir(tmp_path, TuneConfig(seed=2))
    (tmp_path / "state.pkl").write_bytes(b"junk")
    with pytest.raises(ParameterError, match="state.pkl: cannot read"):
        _check_dir(tmp_path, TuneConfig(seed=1))


def _tune(out, **kw):
    return subprocess.Popen([sys.executable, "-m", "cekm_swarm", "tune", "fields", "--out", str(out), *TINY],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, **kw)


def _generation(out) -> int:
    try:
        return pickle.loads((out / "state.pkl").read_bytes())["generation"]
    except (OSError, EOFError, pickle.UnpicklingError, KeyError):
        return -1


@pytest.mark.slow
def test_killed_and_resumed_gives_the_same_policy_bit_for_bit(tmp_path):
    whole = _tune(tmp_path / "whole")
    assert whole.wait(timeout=300) == 0, whole.stdout.read().decode()
    killed = _tune(tmp_path / "killed")
    deadline = time.monotonic() + 300
    while _generation(tmp_path / "killed") < 1:  # the first generation saved
        assert killed.poll() is None and time.monotonic() < deadline, "no generation saved"
        time.sleep(0.02)
    os.kill(killed.pid, signal.SIGKILL)
    killed.wait(timeout=60)
    stopped_at = _generation(tmp_path / "killed")
    assert 1 <= stopped_at < 4 and not (tmp_path / "killed" / "policy.json").exists()
    resumed = _tune(tmp_path / "killed")
    assert resumed.wait(timeout=300) == 0, resumed.stdout.read().decode()
    a = (tmp_path / "whole" / "policy.json").read_bytes()
    assert a == (tmp_path / "killed" / "policy.json").read_bytes()
    doc = json.loads(a)
    assert doc["meta"]["config"]["seed"] == 7 and doc["version"] == 6 and len(doc["field_weights"]) == 3
    history = (tmp_path / "killed" / "history.jsonl").read_text().splitlines()
    assert [json.loads(x)["generation"] for x in history] == [1, 2, 3, 4]


def test_a_state_of_another_policy_shape_is_refused_by_name(tmp_path):
    """A training directory whose saved search has another number of weights (made before
    the policy gained a feature or an output) is refused, naming the file, not resumed."""
    import cma  # noqa: PLC0415 -- as the training imports it

    config = TuneConfig(seed=1)
    (tmp_path / "config.json").write_text(json.dumps(asdict(config)))
    es = cma.CMAEvolutionStrategy(np.zeros(36), 0.3, {"seed": 1, "verbose": -9})
    (tmp_path / "state.pkl").write_bytes(pickle.dumps({"version": STATE_VERSION, "es": es}))
    with pytest.raises(ParameterError, match=r"state.pkl: a search over 36 weights, but this version's policy has 55"):
        _check_dir(tmp_path, config)


def test_kept_outputs_stay_at_the_init_policys_weights(tmp_path):
    """--keep searches the other rows only; the kept rows of W and V are --init's, exactly."""
    rng = np.random.default_rng(3)
    W, V = rng.normal(0, 1, (5, 11)), rng.normal(0, 1, (3, 6))
    W[2], V[2] = 0.0, 0.0  # sigma_b_d_near held
    FieldPolicy("navigation", W, field_weights=V).save(tmp_path / "start.json")
    c = TuneConfig(per_field=True, hold=("sigma_b_d_near",), init=str(tmp_path / "start.json"),
                   keep=("sigma_b_alpha", "sigma_b_d_beyond"))
    assert search_size(c) == 2 * 11  # sigma_a_d's and sigma_a_alpha's rows of W; no row of V
    x0 = start_vector(c)
    assert np.array_equal(full_weights(c, x0), np.concatenate([W.ravel(), V.ravel()]))  # the start is the init
    moved = FieldPolicy.from_flat("navigation", full_weights(c, x0 + 1.0))
    assert np.array_equal(moved.W[:3], W[:3]) and np.array_equal(moved.V, V)
    assert np.array_equal(moved.W[3:], W[3:] + 1.0)
    assert command_of(c).endswith("--keep sigma_b_alpha --keep sigma_b_d_beyond")
    with pytest.raises(ParameterError, match="--keep needs --init"):
        TuneConfig(keep=("sigma_b_alpha",))
    with pytest.raises(ParameterError, match="--keep sigma_a_d and --hold sigma_a_d"):
        TuneConfig(init="x.json", keep=("sigma_a_d",), hold=("sigma_a_d",))
    with pytest.raises(ParameterError, match="--keep: 'teammate_gain' is not an output of the navigation"):
        TuneConfig(init="x.json", keep=("teammate_gain",))
