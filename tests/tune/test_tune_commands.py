"""``cekm run --fields`` and ``cekm tune evaluate`` end to end, in process (small runs)."""

from __future__ import annotations

import json

import numpy as np
from click.testing import CliRunner

from cekm_swarm.cli import main, run_cli_args
from cekm_swarm.experiments.field_widths import policy_graph
from cekm_swarm.experiments.graph_run import run_graph
from cekm_swarm.node.graph_check import check_graph
from cekm_swarm.tune.features import N_FEATURES
from cekm_swarm.tune.motor import PLAIN
from cekm_swarm.tune.policy import FieldPolicy
from cekm_swarm.tune.scenarios import navigation_raw
from world import load_scenario


def _run(tmp_path, *args) -> dict:
    out = tmp_path / "-".join(args)
    r = CliRunner().invoke(main, ["run", "concave", *args, "--out", str(out)])
    assert r.exit_code == 0, r.output
    return json.loads((out / "outcome.json").read_text())["robots"]["r1"]


def test_run_fields_paper_differs_from_the_default(tmp_path, capsys):
    plain, paper = _run(tmp_path), _run(tmp_path, "--fields", "paper")
    assert paper != plain  # the paper's obstacle width drives another path round the U
    code = run_cli_args(["run", "concave", "--controller", "fusion", "--fields", "paper", "--out", str(tmp_path / "x")])
    assert code != 0 and "--fields goes with --controller cekm, not 'fusion'" in capsys.readouterr().err


def test_run_takes_a_policy_file_of_ones_own_with_fields_learned(tmp_path, capsys):
    """Zero weights are today's widths: the default graph's motor with them (its turns in place
    at speed), and with Eq. 11's turns as they are ``--fields tuned``, exactly; a policy that
    widens the target field runs another path; a policy without --fields learned, or for
    tracking, is refused before anything runs, naming the file."""
    pol = tmp_path / "policies"
    pol.mkdir()
    FieldPolicy("navigation").save(pol / "zero.json")
    W = np.zeros((5, N_FEATURES))
    W[3, 0] = 3.0  # sigma_a_d at twice today's
    FieldPolicy("navigation", W).save(pol / "wide.json")
    plain = _run(tmp_path, "--fields", "tuned", "--seed", "3")
    zero = _run(tmp_path, "--fields", "learned", "--policy", str(pol / "zero.json"), "--seed", "3")
    graph = check_graph(policy_graph("navigation"))
    weights = {"weights": (0.0,) * FieldPolicy.size("navigation")}
    for motor, expected in (({}, zero), (PLAIN, plain)):
        r1 = run_graph(load_scenario("concave"), graph=graph, seed=3, params={**weights, **motor})
        assert {k: v for k, v in r1.episode.outcome()["r1"].items() if k in expected} == expected
    assert _run(tmp_path, "--fields", "learned", "--policy", str(pol / "wide.json"), "--seed", "3") != plain
    code = run_cli_args(["run", "concave", "--policy", str(pol / "wide.json"), "--out", str(tmp_path / "x")])
    assert code != 0 and "wide.json goes with --fields learned, not no --fields" in capsys.readouterr().err
    FieldPolicy("tracking").save(pol / "trk.json")
    code = run_cli_args(["run", "concave", "--fields", "learned", "--policy", str(pol / "trk.json"),
                         "--out", str(tmp_path / "y")])
    assert code != 0 and "trk.json: a field policy for tracking, not navigation" in capsys.readouterr().err
    assert not (tmp_path / "x").exists() and not (tmp_path / "y").exists()


def test_evaluate_writes_every_variant_on_the_same_held_out_scenarios(tmp_path):
    W = np.zeros((5, N_FEATURES))
    W[0, 1] = 2.0
    FieldPolicy("navigation", W).save(tmp_path / "p.json")
    r = CliRunner().invoke(main, ["tune", "evaluate", "--task", "navigation", "--policy", str(tmp_path / "p.json"),
                                  "--tests", "3", "--only", "tuned,learned", "--max-time", "20", "--workers", "1",
                                  "--out", str(tmp_path / "ev")])
    assert r.exit_code == 0, r.output
    doc = json.loads((tmp_path / "ev" / "results.json").read_text())
    assert set(doc["runs"]) == {"tuned", "learned"} and doc["seeds"] == [3_000_000, 3_000_002]
    assert [x["where"] for x in doc["runs"]["tuned"]] == [x["where"] for x in doc["runs"]["learned"]]
    s = doc["summary"]["tuned"]["contact_free"]
    assert s["n"] == 3 and s["wilson95"][0] <= s["rate"] <= s["wilson95"][1]
    bad = CliRunner().invoke(main, ["tune", "evaluate", "--task", "navigation", "--only", "magic",
                                    "--out", str(tmp_path / "ev2")])
    assert bad.exit_code != 0 and "unknown variant 'magic'" in bad.output


def test_contacts_counts_the_contacts_of_validation_runs(tmp_path):
    r = CliRunner().invoke(main, ["tune", "contacts", "--runs", "2", "--max-time", "60", "--out", str(tmp_path)])
    assert r.exit_code == 0, r.output
    doc = json.loads((tmp_path / "contacts.json").read_text())
    assert [x["seed"] for x in doc["runs"]] == [2_000_000, 2_000_001]
    assert sum(x["collisions"] for x in doc["runs"]) == len(doc["contacts"])
    assert f"contacts {len(doc['contacts'])}" in r.output
    r = CliRunner().invoke(main, ["tune", "contacts", "--runs", "4", "--max-time", "1", "--mix", "wide", "--out",
                                  str(tmp_path)])  # the wide mix's validation scenarios: its own kinds too
    assert r.exit_code == 0, r.output
    kinds = [x["kind"] for x in json.loads((tmp_path / "contacts.json").read_text())["runs"]]
    assert kinds == [navigation_raw(2_000_000 + i, mix="wide")["name"].split("-")[1] for i in range(4)]
    assert "wall" in kinds


def test_fig9_draws_rows_from_evaluate_documents_and_names_a_bad_one(tmp_path):
    def doc(**variants):
        return {"experiment": "field-policy-concave", "need": 2,
                **{v: {"cells": [{"range": 0.12, "depth": 0.3, "width": w, "reached": k, "of": 3}
                                 for w, k in zip((0.2, 0.34), ks, strict=True)]} for v, ks in variants.items()}}

    (tmp_path / "a.json").write_text(json.dumps(doc(tuned=(0, 3), learned=(2, 3))))
    (tmp_path / "b.json").write_text(json.dumps(doc(learned=(3, 1))))
    r = CliRunner().invoke(main, ["tune", "fig9", str(tmp_path / "a.json"), f"{tmp_path / 'b.json'}:learned=wide",
                                  "--out", str(tmp_path / "f.png")])
    assert r.exit_code == 0, r.output
    assert "learned: 2 cells negotiated (1 gained, 0 lost against tuned)" in r.output
    assert "wide: 1 cells negotiated (1 gained, 1 lost against tuned)" in r.output
    assert (tmp_path / "f.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    twice = CliRunner().invoke(main, ["tune", "fig9", str(tmp_path / "a.json"), str(tmp_path / "b.json"),
                                      "--out", str(tmp_path / "g.png")])
    assert twice.exit_code != 0 and "a second row named 'learned'" in twice.output
    (tmp_path / "c.json").write_text("{}")
    bad = CliRunner().invoke(main, ["tune", "fig9", str(tmp_path / "c.json"), "--out", str(tmp_path / "h.png")])
    assert bad.exit_code != 0 and "not the results of `cekm tune evaluate --concave`" in bad.output


def test_the_mix_option_offers_exactly_the_generator_s_mixes():
    from cekm_swarm.tune.commands import tune_group
    from cekm_swarm.tune.scenarios import MIXES

    for name in ("fields", "contacts"):
        (mix,) = [p for p in tune_group.commands[name].params if p.name == "mix"]
        assert list(mix.type.choices) == list(MIXES)


def test_tune_fields_refuses_keep_without_an_init_by_name(tmp_path, capsys):
    """--keep keeps --init's rows: without --init the command stops before training, saying so."""
    code = run_cli_args(["tune", "fields", "--out", str(tmp_path / "t"), "--keep", "sigma_b_alpha"])
    assert code != 0 and "--keep needs --init" in capsys.readouterr().err
    assert not (tmp_path / "t" / "state.pkl").exists()


def test_the_default_is_the_learned_policy_and_cekm_tuned_the_constants(tmp_path):
    """Navigation's ``cekm`` (the default controller) runs the shipped field policy, as
    ``--fields learned`` does; ``--controller cekm-tuned`` (a shipped graph, so launches
    and bridges take it) runs today's constants, as ``--fields tuned`` does; they differ."""
    default = _run(tmp_path)
    assert default == _run(tmp_path, "--fields", "learned")
    tuned = _run(tmp_path, "--controller", "cekm-tuned")
    assert tuned == _run(tmp_path, "--fields", "tuned") != default
    assert _run(tmp_path, "--controller", "cekm-tuned", "--fields", "learned") == default
