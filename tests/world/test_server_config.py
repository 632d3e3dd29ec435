"""The world server's typed config: one frozen field per declared option, built from the
parsed command line; the server sets every attribute it has in ``__init__``."""

from __future__ import annotations

import ast
import dataclasses
import inspect
import re
import subprocess
import sys
import textwrap

import pytest

from world import config as server
from world.config import WORLD_OPTIONS, WorldConfig, parse_argv, server_argv
from world.server import WorldServer


def test_the_config_has_one_field_per_declared_option_and_is_frozen(tmp_path):
    assert {f.name for f in dataclasses.fields(WorldConfig)} == {n for n, _ in WORLD_OPTIONS} | {"scenario"}
    argv = server_argv(scenario="concave", listen="tcp/127.0.0.1:7500", out=tmp_path, mode="lockstep", seed=3,
                       max_time=12.5, run_id="run-1", deadman=0.25)
    cfg = parse_argv(argv[3:])
    assert (cfg.scenario, cfg.listen, cfg.connect, cfg.out, cfg.mode, cfg.seed, cfg.max_time, cfg.run_id,
            cfg.deadman, cfg.republish) == ("concave", "tcp/127.0.0.1:7500", server.DEFAULT_ENDPOINT, str(tmp_path),
                                            "lockstep", 3, 12.5, "run-1", 0.25, server.REPUBLISH_S)
    with pytest.raises(dataclasses.FrozenInstanceError):
        cfg.seed = 4


def test_the_server_is_built_from_a_config_with_every_attribute_set_in_init(tmp_path):
    cfg = parse_argv(["lone_obstacle", "--out", str(tmp_path), "--mode", "lockstep"])
    ws = WorldServer(cfg)
    assert ws.config is cfg and ws.config.mode == "lockstep" and ws.robots == ["r1"]
    # every attribute assigned anywhere in the class already exists after __init__
    tree = ast.parse(textwrap.dedent(inspect.getsource(WorldServer)))
    assigned = {t.attr for node in ast.walk(tree) if isinstance(node, (ast.Assign, ast.AnnAssign, ast.AugAssign))
                for t in (node.targets if isinstance(node, ast.Assign) else [node.target])
                for t in ast.walk(t) if isinstance(t, ast.Attribute) and isinstance(t.value, ast.Name)
                and t.value.id == "self"}
    assert assigned and not assigned - set(vars(ws))


@pytest.mark.slow
@pytest.mark.parametrize("text,needle", [
    ('name = "x"\n[[robots]]\nid = "a"\nstart = [1.0, 1.0, 0.0]\n', "arena: missing"),
    ('name = "x"\n[arena]\nbounds = [0.0, 0.0, 2.0, 2.0]\n[[robots]]\nid = "a"\nstart = [1.0, 1.0, 0.0]\n',
     "robots[0].goal: robot 'a' has none"),
])
def test_a_bad_scenario_is_refused_in_one_line_before_anything_is_written(tmp_path, text, needle):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    r = subprocess.run([sys.executable, "-m", "world.server", str(path), "--out", str(tmp_path / "out")],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 2
    assert r.stderr.startswith(f"Error: {path}: {needle}") and r.stderr.count("\n") == 1, r.stderr
    assert not (tmp_path / "out").exists()


def test_checkpoints_are_parsed_or_refused_naming_what_is_wrong(tmp_path):
    from world.config import CheckpointsError, parse_checkpoints

    assert parse_checkpoints('{"r1": [[1, 2.5], [3.0, 4]]}', ["r1", "r2"]) == {"r1": [(1.0, 2.5), (3.0, 4.0)]}
    path = tmp_path / "cps.json"
    path.write_text('{"r2": [[0.5, 0.5]]}')
    assert parse_checkpoints(str(path), ["r1", "r2"]) == {"r2": [(0.5, 0.5)]}
    for value, needle in [('{"r1": [[1, 2]', "--checkpoints: not JSON"),
                          (str(tmp_path / "missing.json"), f"--checkpoints {tmp_path / 'missing.json'}: cannot read"),
                          ('{"r9": [[1, 2]]}', "no robot 'r9' in the scenario (robots: r1, r2)"),
                          ('{"r1": []}', "r1: must be a non-empty list"),
                          ('{"r1": [[1, 2], [1, NaN]]}', "r1[1]: must be [x, y] with finite numbers"),
                          ('{"r1": [[1, 2, 3]]}', "r1[0]: must be [x, y]"),
                          ('{"r1": [[true, 2]]}', "r1[0]: must be [x, y]")]:
        with pytest.raises(CheckpointsError, match=re.escape(needle)):
            parse_checkpoints(value, ["r1", "r2"])


@pytest.mark.slow
def test_bad_checkpoints_are_refused_in_one_line(tmp_path):
    r = subprocess.run([sys.executable, "-m", "world.server", "concave", "--out", str(tmp_path / "out"),
                        "--checkpoints", '{"r1": [[1, "x"]]}'], capture_output=True, text=True, timeout=60)
    assert r.returncode == 2
    assert r.stderr.startswith("Error: --checkpoints: r1[0]: must be [x, y]") and r.stderr.count("\n") == 1, r.stderr
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("argv,needle", [
    (["--seed", "-1"], "--seed"),
    (["--seed", "4294967296"], "--seed"),
    (["--max-time", "nan"], "--max-time"),
    (["--max-time", "0"], "--max-time"),
    (["--deadman", "-1"], "--deadman"),
    (["--republish", "inf"], "--republish"),
    (["--log-level", "chatty"], "--log-level"),
])
def test_a_bad_option_value_is_refused_naming_it(tmp_path, argv, needle):
    import click

    with pytest.raises(click.BadParameter) as err:
        parse_argv(["crossing", "--out", str(tmp_path / "o"), *argv])
    assert err.value.param.name == needle.lstrip("-").replace("-", "_")


def test_an_out_holding_an_earlier_run_is_refused_and_left_as_it_was(tmp_path):
    import click

    (tmp_path / "run.mcap").write_bytes(b"an earlier run's log")
    with pytest.raises(click.BadParameter, match=r"already holds a run \(run.mcap\)"):
        parse_argv(["crossing", "--out", str(tmp_path)])
    assert (tmp_path / "run.mcap").read_bytes() == b"an earlier run's log"
    (tmp_path / "launch.log").write_text("the launcher's own files are no run's outputs")
    (tmp_path / "run.mcap").unlink()
    assert parse_argv(["crossing", "--out", str(tmp_path)]).out == str(tmp_path)
