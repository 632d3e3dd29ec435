"""The section 4.2 commands end to end (outputs and errors), on a small quickly-trained model."""

import json

import pytest
from click.testing import CliRunner

from cekm_swarm.cli import main


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    path = tmp_path_factory.mktemp("model") / "r9.npz"
    r = CliRunner().invoke(main, ["train", "--network", "R9", "--steps", "20000", "--out", str(path), "--quiet"])
    assert r.exit_code == 0, r.output
    return path


@pytest.mark.slow
def test_run_writes_outcome_and_picture(tmp_path, model):
    import matplotlib.pyplot as plt

    plt.close("all")  # what earlier tests in this process left open
    out = tmp_path / "run"
    r = CliRunner().invoke(main, ["run", "lone_obstacle", "--model", str(model), "--seed", "3", "--max-time", "30",
                                  "--out", str(out)])
    assert r.exit_code == 0, r.output
    doc = json.loads((out / "outcome.json").read_text())
    assert doc["scenario"] == "lone_obstacle" and doc["seed"] == 3
    o = doc["robots"]["r1"]
    assert set(o) >= {"reached", "time_s", "path_length_m", "collisions", "min_clearance_m"}
    assert o["path_length_m"] > 0.05  # it moved
    assert (out / "trajectory.png").read_bytes()[:4] == b"\x89PNG"
    assert plt.get_fignums() == []  # the picture's figure is closed: a run in a long-lived process leaks none


@pytest.mark.slow
def test_same_seed_same_outcome(tmp_path, model):
    docs = []
    for i in range(2):
        out = tmp_path / f"r{i}"
        r = CliRunner().invoke(main, ["run", "doorway", "--model", str(model), "--seed", "5", "--max-time", "15",
                                      "--controller", "fusion", "--out", str(out)])
        assert r.exit_code == 0, r.output
        docs.append(json.loads((out / "outcome.json").read_text())["robots"])
    assert docs[0] == docs[1]


@pytest.mark.slow
def test_fields_picture(tmp_path, model):
    out = tmp_path / "f.png"
    r = CliRunner().invoke(main, ["fields", "concave", "--at", "5", "--model", str(model), "--out", str(out)])
    assert r.exit_code == 0, r.output
    assert out.read_bytes()[:4] == b"\x89PNG" and "motor winner" in r.output


@pytest.mark.slow
def test_sweep_writes_grid(tmp_path, model):
    out = tmp_path / "sweep"
    r = CliRunner().invoke(main, ["sweep", "concave", "--depths", "0.12", "--widths", "0.1,0.34", "--ranges", "0.17",
                                  "--seeds", "1", "--need", "1", "--max-time", "20", "--model", str(model),
                                  "--workers", "1", "--out", str(out)])
    assert r.exit_code == 0, r.output
    doc = json.loads((out / "fig9.json").read_text())
    assert len(doc["runs"]) == 2 and len(doc["grid"]) == 1
    assert {x["width"] for x in doc["runs"]} == {0.1, 0.34}
    # every (range, depth, width) cell with its success rate over the seeds
    assert [(c["range"], c["depth"], c["width"]) for c in doc["cells"]] == [(0.17, 0.12, 0.1), (0.17, 0.12, 0.34)]
    for c in doc["cells"]:
        assert set(c) == {"range", "depth", "width", "reached", "of", "rate"}
        run = next(x for x in doc["runs"] if x["width"] == c["width"])
        assert c["of"] == 1 and c["reached"] == int(run["reached"]) and c["rate"] == c["reached"] / c["of"]
    assert set(doc["grid"][0]) == {"range", "depth", "max_width", "negotiated_widths", "max_width_no_hole"}
    assert doc["settings"]["fields"] == "tuned"  # the paper's method (--fields learned: the policy)
    for name in ("fig9.png", "fig9_grid.png"):
        assert (out / name).read_bytes()[:4] == b"\x89PNG"


def test_bad_scenario_and_model_are_refused(tmp_path, model):
    bad = tmp_path / "bad.toml"
    bad.write_text(
        'name = "x"\nseed = 1\n[arena]\nbounds = [0, 0, 1]\n[[robots]]\nid = "r1"\nstart = [0.5, 0.5, 0.0]\n'
    )
    r = CliRunner().invoke(main, ["run", str(bad), "--out", str(tmp_path / "o")])
    assert r.exit_code != 0 and "bad.toml" in r.output and "bounds" in r.output
    assert not (tmp_path / "o").exists()  # refused before anything starts
    r = CliRunner().invoke(main, ["run", "no-such-scenario", "--out", str(tmp_path / "o")])
    assert r.exit_code != 0 and "no-such-scenario" in r.output
    d15 = tmp_path / "d.npz"
    assert (
        CliRunner()
        .invoke(main, ["train", "--network", "D9", "--steps", "1000", "--out", str(d15), "--quiet"])
        .exit_code
        == 0
    )
    r = CliRunner().invoke(main, ["run", "concave", "--model", str(d15), "--out", str(tmp_path / "o")])
    assert r.exit_code != 0 and "indirect-mapping" in r.output
    r = CliRunner().invoke(main, ["sweep", "concave", "--depths", "x", "--out", str(tmp_path / "s")])
    assert r.exit_code != 0 and "--depths" in r.output


def _strict(text: str):
    """json.loads that refuses NaN and Infinity (not JSON)."""
    def refuse(name):
        raise ValueError(f"not JSON: {name}")
    return json.loads(text, parse_constant=refuse)


def test_run_with_nothing_in_range_writes_strict_json(tmp_path):
    """A lone robot without walls never has anything within sensor range: its clearance is
    null in outcome.json (it was Infinity, which is not JSON) and said so on the terminal."""
    sc = tmp_path / "one.toml"
    sc.write_text('name = "one"\n[arena]\nbounds = [0.0, 0.0, 1.0, 1.0]\nboundary_walls = false\n'
                  '[[robots]]\nid = "solo"\nstart = [0.5, 0.5, 0.0]\ngoal = "g"\n'
                  '[[targets]]\nid = "g"\nposition = [0.9, 0.9]\n')
    out = tmp_path / "run"
    r = CliRunner().invoke(main, ["run", str(sc), "--max-time", "3", "--out", str(out)])
    assert r.exit_code == 0, r.output
    doc = _strict((out / "outcome.json").read_text())
    assert doc["robots"]["solo"]["min_clearance_m"] is None
    assert "min clearance nothing within sensor range" in r.output
