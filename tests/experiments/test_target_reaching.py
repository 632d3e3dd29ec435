"""A reduced, seeded run of the section 4.1 experiment: the orderings it can support at this size."""

import json

import numpy as np
import pytest
from click.testing import CliRunner

from cekm_swarm.cli import main
from cekm_swarm.experiments.reaching_report import tables_markdown
from cekm_swarm.experiments.reaching_run import TargetReachingConfig, run_experiment
from cekm_swarm.experiments.reaching_stats import headline_orderings
from cekm_swarm.experiments.streams import Schedule


@pytest.fixture(scope="module")
def reduced():
    config = TargetReachingConfig(networks=("B15", "D15", "G12", "R15"), trials=3, seed=7,
                                  schedule=Schedule(steps=20_000, test_interval=10_000))
    return run_experiment(config, progress=False)


@pytest.mark.slow
def test_reduced_run_orderings(reduced):
    """At 20,000 steps (a fifth of the paper's), under the paper's stop rule, the orderings that
    have emerged by then: every indirect EKM below the direct EKM in E and T, and RLS (R15)
    converging fastest among the EKMs (lowest T), as in Fig. 5. Every network has learned to
    reach targets (P(5) rose from the untrained test's); whether B15 stays above the EKMs needs
    the full run over master seeds (docs/reproduction-4.1.md)."""
    results, _ = reduced
    n = results["networks"]
    assert results["settings"]["stop"]["rule"] == "command" and results["settings"]["bfn_rule"] == "paper"
    for ekm in ("G12", "R15"):
        for key in ("E_mm", "T_s_per_m"):
            assert n[ekm][key]["mean"] < n["D15"][key]["mean"], (ekm, key)
    for other in ("D15", "G12"):
        assert n["R15"]["T_s_per_m"]["mean"] < n[other]["T_s_per_m"]["mean"], other
    # learning happened: the share of targets reached within 5 mm rose from the untrained test's
    for name in ("G12", "R15", "D15", "B15"):
        curve = n[name]["learning_curves"]["P5"]["mean"]
        assert curve[-1] > curve[0] + 0.5, (name, curve)


@pytest.mark.slow
def test_results_document_shape(reduced):
    results, _ = reduced
    n = results["networks"]
    assert set(n) == {"B15", "D15", "G12", "R15"}
    for entry in n.values():
        for key in ("E_mm", "T_s_per_m", "D", "P5", "T5_s_per_m", "D5"):
            assert set(entry[key]) == {"mean", "std"}
        assert len(entry["learning_curves"]["E_mm"]["mean"]) == 3  # steps 0, 10k, 20k
    assert n["R15"]["parameters"] == 1350 and n["D15"]["parameters"] == 900
    assert set(results["t_tests"]) == {"E_mm", "T_s_per_m", "D", "P5", "T5_s_per_m", "D5"}
    assert "R15|D15" in results["t_tests"]["E_mm"] or "D15|R15" in results["t_tests"]["E_mm"]
    assert results["settings"]["seed"] == 7
    json.dumps(results)  # serializable
    assert "Table 1" in tables_markdown(results) and "Table 4" in tables_markdown(results)
    assert set(headline_orderings(results)) >= {"every indirect EKM below D15 in T_s_per_m"}


def test_same_seed_same_numbers():
    config = TargetReachingConfig(networks=("G9",), trials=2, seed=3,
                                  schedule=Schedule(steps=2_000, test_interval=1_000, test_targets=5))
    a, _ = run_experiment(config, progress=False)
    b, _ = run_experiment(config, progress=False)
    assert a["networks"]["G9"]["per_trial"] == b["networks"]["G9"]["per_trial"]


@pytest.mark.slow
def test_cli_writes_every_output(tmp_path):
    out = tmp_path / "run"
    result = CliRunner().invoke(main, ["experiment", "target-reaching", "--out", str(out), "--networks", "D9,R9",
                                       "--trials", "2", "--steps", "2000", "--test-interval", "1000", "--targets", "5",
                                       "--quiet"])
    assert result.exit_code == 0, result.output
    for name in (
        "results.json",
        "tables.md",
        "fig5_learning_curves.png",
        "fig6_input_weights.png",
        "fig7_eps_curves.png",
        "models/R9-trial1.npz",
        "models/D9-trial2.npz",
    ):
        assert (out / name).is_file(), name
    assert (out / "fig5_learning_curves.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    doc = json.loads((out / "results.json").read_text())
    assert doc["settings"]["schedule"]["steps"] == 2000


def test_cli_refuses_bad_input(tmp_path):
    r = CliRunner().invoke(main, ["experiment", "target-reaching", "--out", str(tmp_path), "--networks", "Q7"])
    assert r.exit_code != 0 and "unknown network 'Q7'" in r.output
    r = CliRunner().invoke(main, ["experiment", "target-reaching", "--out", str(tmp_path), "--steps", "1500",
                                  "--test-interval", "1000"])
    assert r.exit_code != 0 and "--steps (1500) must be a multiple of --test-interval (1000)" in r.output


def test_cli_train_saves_a_loadable_model(tmp_path):
    from cekm_swarm.models.io import load_model, model_provenance

    path = tmp_path / "m.npz"
    r = CliRunner().invoke(main, ["train", "--network", "R9", "--steps", "3000", "--out", str(path), "--quiet"])
    assert r.exit_code == 0, r.output
    net = load_model(path)
    assert net.kind == "indirect-rls" and net.lattice.size == 9
    assert model_provenance(path)["steps"] == 3000
    assert np.all(np.isfinite(net.M))


@pytest.mark.slow
def test_cli_protocol_options_reach_the_settings(tmp_path):
    out = tmp_path / "run"
    result = CliRunner().invoke(main, ["experiment", "target-reaching", "--out", str(out), "--networks", "B9,R9",
                                       "--trials", "1", "--steps", "1000", "--test-interval", "1000", "--targets", "3",
                                       "--stop", "goal", "--train-stop", "command", "--motor-resolution", "0.004",
                                       "--bfn", "trained-units", "--target-resolution", "0", "--quiet"])
    assert result.exit_code == 0, result.output
    s = json.loads((out / "results.json").read_text())["settings"]
    assert s["stop"] == {"rule": "goal", "motor_resolution": 0.004}
    assert s["train_stop"] == {"rule": "command", "motor_resolution": 0.004}
    assert s["bfn_rule"] == "trained-units" and s["arena"]["target_resolution"] == 0.0
    assert "Stop rule 'goal'" in (out / "tables.md").read_text()
    r = CliRunner().invoke(main, ["experiment", "target-reaching", "--out", str(tmp_path / "x"), "--stop", "sensor"])
    assert r.exit_code != 0 and "--stop" in r.output


def test_default_protocol_is_the_papers_and_training_keeps_the_goal_stop():
    from cekm_swarm.experiments.stopping import GOAL_STOP, PAPER_STOP

    c = TargetReachingConfig()
    assert c.stop == PAPER_STOP and c.train_stop == GOAL_STOP and c.bfn_rule == "paper"
    assert PAPER_STOP.rule == "command" and PAPER_STOP.motor_resolution == 0.008
