"""Import contracts checked by import-linter over the whole import graph (function-level
imports and indirect chains included), as CI's ``lint-imports`` runs pyproject's: a circle
between siblings is caught, and the command line's packages (experiments, launch, tune and
the CLI toolkit) hold none and stay below the ``cekm`` registry."""

from __future__ import annotations

from pathlib import Path

import pytest
from importlinter.cli import lint_imports


def _lint(tmp_path: Path, contracts: str, roots: tuple[str, ...] = ("cekm_swarm", "world")) -> int:
    config = tmp_path / "importlinter.ini"
    config.write_text("[importlinter]\nroot_packages =\n" + "".join(f"    {r}\n" for r in roots)
                      + "include_external_packages = True\n\n" + contracts)
    return lint_imports(config_filename=str(config), no_cache=True, no_logo=True)


def _package(root: Path, files: dict[str, str]) -> None:
    (root / "circled").mkdir()
    (root / "circled" / "__init__.py").write_text("")
    for name, text in files.items():
        (root / "circled" / f"{name}.py").write_text(text)


ACYCLIC = "[importlinter:contract:acyclic]\nname = no circles\ntype = acyclic_siblings\nancestors = circled\n"


@pytest.mark.parametrize("circle", [True, False])
def test_a_circle_held_by_a_function_level_import_is_caught(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                            circle: bool) -> None:
    _package(tmp_path, {"a": "from . import b\n",
                        "b": "def f():\n    from . import a  # the import that closes the circle\n" if circle
                             else "def f():\n    return 1\n"})
    monkeypatch.syspath_prepend(str(tmp_path))
    assert _lint(tmp_path, ACYCLIC, roots=("circled",)) == (1 if circle else 0)


def test_the_command_line_packages_hold_no_circle_and_stay_below_the_registry(tmp_path: Path) -> None:
    contracts = """
[importlinter:contract:acyclic]
name = No circle inside experiments, launch and tune
type = acyclic_siblings
ancestors =
    cekm_swarm.experiments
    cekm_swarm.launch
    cekm_swarm.tune

[importlinter:contract:registry]
name = Nothing imports the cekm registry (cli.py lists the command groups; they never import it)
type = forbidden
source_modules =
    cekm_swarm.experiments
    cekm_swarm.launch
    cekm_swarm.tune
    cekm_swarm.cli_support
    world
forbidden_modules =
    cekm_swarm.cli

[importlinter:contract:toolkit]
name = The CLI toolkit reaches no experiment, launch, tune or controller code
type = forbidden
source_modules =
    cekm_swarm.cli_support
forbidden_modules =
    cekm_swarm.experiments
    cekm_swarm.launch
    cekm_swarm.tune
    cekm_swarm.controller
    cekm_swarm.models
    cekm_swarm.node
"""
    assert _lint(tmp_path, contracts) == 0
