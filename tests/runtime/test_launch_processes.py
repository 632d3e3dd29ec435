"""The command lines the launcher builds parse back, through each process's own parser,
to the values it meant (both come from one declaration per process)."""

from __future__ import annotations

import pytest

from cekm_swarm.launch.processes import new_run_id, node_argv, server_argv
from cekm_swarm.node.process import parser as node_parser
from cekm_swarm.protocol import KeySpace
from world.config import parse_argv


def test_a_node_command_line_parses_back_to_its_values(tmp_path):
    """A node takes the run spec (every setting of the run, declared once) and which node it is."""
    argv = node_argv(str(tmp_path / "run-spec.json"), "r2", "obstacle-7")
    assert argv[1:3] == ["-m", "cekm_swarm.node"]
    args = node_parser().parse_args(argv[3:])
    assert (args.spec, args.robot, args.node) == (str(tmp_path / "run-spec.json"), "r2", "obstacle-7")


def test_the_world_server_command_line_parses_back_to_its_values(tmp_path):
    argv = server_argv(scenario="concave", listen="tcp/0.0.0.0:7500", out=tmp_path, mode="lockstep", seed=3,
                       max_time=12.5, run_id="run-1", wait_modules=185, checkpoints=tmp_path / "c.json")
    args = parse_argv(argv[3:])
    assert (args.scenario, args.listen, args.out, args.mode, args.seed, args.max_time, args.run_id,
            args.wait_modules, args.checkpoints) == ("concave", "tcp/0.0.0.0:7500", str(tmp_path), "lockstep", 3,
                                                     12.5, "run-1", 185.0, str(tmp_path / "c.json"))


def test_an_undeclared_or_missing_parameter_fails_in_the_launcher_not_in_the_child():
    with pytest.raises(TypeError, match="wheels"):
        server_argv(scenario="concave", out="o", wheels=2)
    with pytest.raises(TypeError, match="scenario"):
        server_argv(out="o")


def test_a_bad_run_id_is_a_usage_error_of_the_process():
    import click

    with pytest.raises(click.BadParameter, match="run id"):
        parse_argv(["concave", "--out", "o", "--run-id", "a/b"])


def test_run_ids_are_fresh_and_valid_key_chunks():
    ids = {new_run_id() for _ in range(50)}
    assert len(ids) == 50
    for r in ids:
        KeySpace(run=r)  # raises if not one plain chunk



