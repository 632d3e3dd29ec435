"""``cekm run --fields`` and ``cekm tune evaluate`` end to end, in process (small runs)."""

from __future__ import annotations

import json

import numpy as np
from click.testing import CliRunner

from cekm_swarm.cli import main, run_cli_args
from cekm_swarm.tune.features import N_FEATURES
from cekm_swarm.tune.policy import FieldPolicy
from cekm_swarm.tune.scenarios import navigation_raw


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


def test_evaluate_writes_every_variant_on_the_same_held_out_scenarios(tmp_path):
    W = np.zeros((3, N_FEATURES))
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
