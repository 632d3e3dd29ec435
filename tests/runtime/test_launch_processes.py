"""The command lines the launcher builds parse back, through each process's own parser,
to the values it meant (both come from one declaration per process)."""

from __future__ import annotations

import argparse

import pytest

from cekm_swarm.launch.processes import module_argv, new_run_id, server_argv
from cekm_swarm.modules.shell import INDEX_PARAM, base_parser
from cekm_swarm.protocol import KeySpace
from cekm_swarm.runtime.process_args import Param, add_params, to_argv
from world.server import parser as world_parser


def test_a_module_command_line_parses_back_to_its_values():
    argv = module_argv("obstacle-7", robot="r2", model="m.npz", connect="tcp/10.0.0.1:7447", root="lab",
                       mode="lockstep", zenoh_config="c.json5", run_id="run-1")
    assert argv[1:3] == ["-m", "cekm_swarm.modules.obstacle"]
    args = add_params(base_parser("x"), (INDEX_PARAM,)).parse_args(argv[3:])
    assert (args.robot, args.model, args.connect, args.root, args.mode, args.zenoh_config, args.run_id, args.index) == (
        "r2", "m.npz", "tcp/10.0.0.1:7447", "lab", "lockstep", "c.json5", "run-1", 7)


def test_the_world_server_command_line_parses_back_to_its_values(tmp_path):
    argv = server_argv(scenario="concave", listen="tcp/0.0.0.0:7500", out=tmp_path, mode="lockstep", seed=3,
                       max_time=12.5, run_id="run-1", wait_modules=185, checkpoints=tmp_path / "c.json")
    args = world_parser().parse_args(argv[3:])
    assert (args.scenario, args.listen, args.out, args.mode, args.seed, args.max_time, args.run_id,
            args.wait_modules, args.checkpoints) == ("concave", "tcp/0.0.0.0:7500", str(tmp_path), "lockstep", 3,
                                                     12.5, "run-1", 185.0, str(tmp_path / "c.json"))


def test_an_undeclared_or_missing_parameter_fails_in_the_launcher_not_in_the_child():
    with pytest.raises(TypeError, match="wheels"):
        module_argv("motor", robot="r1", model="m", wheels=2)
    with pytest.raises(TypeError, match="--robot"):
        module_argv("motor", model="m")
    with pytest.raises(ValueError, match="obstacle-<j>"):
        module_argv("obstacle", robot="r1", model="m")
    with pytest.raises(TypeError, match="scenario"):
        to_argv((Param("scenario", positional=True),))


def test_a_bad_run_id_is_a_usage_error_of_the_process():
    with pytest.raises(SystemExit) as exc:
        world_parser().parse_args(["concave", "--out", "o", "--run-id", "a/b"])
    assert exc.value.code == 2


def test_run_ids_are_fresh_and_valid_key_chunks():
    ids = {new_run_id() for _ in range(50)}
    assert len(ids) == 50
    for r in ids:
        KeySpace(run=r)  # raises if not one plain chunk


def test_exclusive_parameters_exclude_each_other():
    p = add_params(argparse.ArgumentParser(), (Param("connect", exclusive="w"), Param("listen", exclusive="w")))
    with pytest.raises(SystemExit):
        p.parse_args(["--connect", "a", "--listen", "b"])
