"""The package's boundaries, as import-linter's contracts in pyproject.toml ``[tool.importlinter]``:
no import circle at any depth; the controller and the world meet only through plain data and
the message protocol; the numerical core does no I/O; a graph as data reaches no node code;
the runtime (which the world server imports) reaches no controller code; the command line's
registry is on top. The contracts see every import, function-level ones and indirect chains
included (a hand-written walker of direct imports once let the world reach the controller
through a helper's function-level import). CI runs ``lint-imports`` too.

Heavy libraries at module level (matplotlib in the experiments' figures, scipy, ...) are
ruff's rule TID253 (pyproject's ``banned-module-level-imports``), checked by tests/test_lint.py.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

from helpers.contracts import lint

ROOT = Path(__file__).resolve().parents[1]


def _contracts() -> list[dict]:
    with open(ROOT / "pyproject.toml", "rb") as f:
        return tomllib.load(f)["tool"]["importlinter"]["contracts"]


def test_every_import_contract_is_kept(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.chdir(ROOT)
    monkeypatch.syspath_prepend(str(ROOT))
    code = lint(ROOT / "pyproject.toml")
    assert code == 0, "an import contract is broken (pyproject.toml [tool.importlinter]):\n" + capsys.readouterr().out


def test_the_contracts_hold_the_boundaries_the_architecture_names() -> None:
    """The contracts are the architecture: none of its rules may go missing from pyproject."""
    contracts = _contracts()
    kinds = {c["type"] for c in contracts}
    assert "acyclic_siblings" in kinds
    acyclic = next(c for c in contracts if c["type"] == "acyclic_siblings")
    assert set(acyclic["ancestors"]) == {"cekm_swarm", "world"}
    forbidden = {(src, bad) for c in contracts if c["type"] == "forbidden"
                 for src in c["source_modules"] for bad in c["forbidden_modules"]}
    for rule in [("world", "cekm_swarm.controller"), ("world", "cekm_swarm.models"), ("world", "cekm_swarm.node"),
                 ("world", "cekm_swarm.modules"), ("world", "cekm_swarm.experiments"),
                 ("cekm_swarm.controller", "world"), ("cekm_swarm.controller", "cekm_swarm.protocol"),
                 ("cekm_swarm.controller", "zenoh"), ("cekm_swarm.node", "world"), ("cekm_swarm.modules", "world"),
                 ("cekm_swarm.graph", "world"), ("cekm_swarm.runtime", "cekm_swarm.controller"),
                 ("cekm_swarm.models.networks", "os"), ("cekm_swarm.graph.runspec", "cekm_swarm.node"),
                 ("cekm_swarm.ros2.plant_server", "world"), ("cekm_swarm.experiments", "click")]:
        assert rule in forbidden, f"no contract forbids {rule[0]} -> {rule[1]}"
    for c in contracts:  # an ignored import names a real module pair, never a blanket wildcard
        for ignored in c.get("ignore_imports", []):
            assert "*" not in ignored, (c["name"], ignored)


def _lint(tmp_path: Path, roots: list[str], contracts: str) -> int:
    config = tmp_path / "contracts.toml"
    config.write_text(f"[tool.importlinter]\nroot_packages = {roots!r}\n"
                      f"include_external_packages = true\n\n{contracts}")
    return lint(config)


@pytest.mark.parametrize("leak", [True, False])
def test_a_forbidden_import_hidden_in_a_function_two_steps_away_is_caught(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, leak: bool) -> None:
    """The fault the old walker missed: the world imports a helper whose function imports the
    controller. The forbidden contract follows the chain through the function-level import."""
    for name, files in {"fakeworld": {"config": "from fakecli import helper\n"},
                        "fakecli": {"helper": "def refuse():\n    from fakectl import planner\n" if leak
                                    else "def refuse():\n    return None\n"},
                        "fakectl": {"planner": "X = 1\n"}}.items():
        (tmp_path / name).mkdir()
        (tmp_path / name / "__init__.py").write_text("")
        for module, text in files.items():
            (tmp_path / name / f"{module}.py").write_text(text)
    monkeypatch.syspath_prepend(str(tmp_path))
    contract = ('[[tool.importlinter.contracts]]\nname = "world never reaches the controller"\ntype = "forbidden"\n'
                'source_modules = ["fakeworld"]\nforbidden_modules = ["fakectl"]\n')
    assert _lint(tmp_path, ["fakeworld", "fakecli", "fakectl"], contract) == (1 if leak else 0)


@pytest.mark.parametrize("circle", [True, False])
def test_a_circle_held_by_a_function_level_import_is_caught(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                            circle: bool) -> None:
    """The acyclic contract sees a circle closed by an import inside a function (how the
    tree's circles hid before)."""
    (tmp_path / "circled").mkdir()
    (tmp_path / "circled" / "__init__.py").write_text("")
    (tmp_path / "circled" / "a.py").write_text("from . import b\n")
    (tmp_path / "circled" / "b.py").write_text("def f():\n    from . import a  # closes the circle\n" if circle
                                               else "def f():\n    return 1\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    contract = ('[[tool.importlinter.contracts]]\nname = "no circles"\ntype = "acyclic_siblings"\n'
                'ancestors = ["circled"]\n')
    assert _lint(tmp_path, ["circled"], contract) == (1 if circle else 0)
