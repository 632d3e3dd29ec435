"""The ``cekm`` group: every command registered in one list (``cli.COMMANDS``), each option
that several commands take declared once, and start-up without the heavy libraries."""

from __future__ import annotations

import subprocess
import sys

import click
import pytest

from cekm_swarm import cli
from cekm_swarm.cli_support import SEED, WORLD_SEED_HELP
from cekm_swarm.experiments.learning_commands import MODEL_CHOICE
from cekm_swarm.runtime.log_commands import log_group


def _options(group: click.Group = cli.main) -> list[tuple[str, click.Option]]:
    out = []
    for name, cmd in group.commands.items():
        if isinstance(cmd, click.Group):
            out += [(f"{name} {path}", o) for path, o in _options(cmd)]
        else:
            out += [(name, p) for p in cmd.params if isinstance(p, click.Option)]
    return out


def test_the_group_holds_exactly_the_listed_commands_once_each():
    names = [c.name for c in cli.COMMANDS]
    assert len(names) == len(set(names))
    assert dict(cli.main.commands) == {c.name: c for c in cli.COMMANDS}


def test_cekm_log_holds_the_runtime_log_commands_and_the_ros2_export_leaving_the_runtime_group_alone():
    assert set(cli.main.commands["log"].commands) == set(log_group.commands) | {"export"}
    assert "export" not in log_group.commands  # the runtime's own group (its tests use it alone)


def test_every_seed_and_model_option_is_the_one_declaration():
    seeds = [(c, o) for c, o in _options() if "--seed" in o.opts]
    models = [(c, o) for c, o in _options() if "--model" in o.opts]
    assert len(seeds) >= 6 and len(models) >= 8
    assert all(o.type is SEED for _, o in seeds)
    assert all(o.help == WORLD_SEED_HELP for c, o in seeds if not isinstance(o.default, int)), seeds
    for c, o in models:
        assert o.name == "model_path", c
        assert o.type is MODEL_CHOICE or (isinstance(o.type, click.Path) and o.type.exists), c


@pytest.mark.slow
def test_cekm_help_starts_without_numba_scipy_matplotlib_or_the_world():
    code = ("import sys; from cekm_swarm.cli import run_cli_args; run_cli_args(['--help']); "
            "print(sorted(m for m in ('numba', 'scipy', 'matplotlib', 'world', 'pymunk') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=True)
    assert out.stdout.strip().splitlines()[-1] == "[]"
