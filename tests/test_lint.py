"""The linter is part of the suite: ``ruff check .`` (pyflakes and import order) must be clean,
and no product file is over 500 lines unless its docstring says why.

The rules are in pyproject.toml's ``[tool.ruff]``; ruff is in the ``test`` extra, so this test
runs wherever the suite does. CI also runs ``ruff check .`` on its own, before the tests.
"""

from __future__ import annotations

import ast
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_ruff_finds_nothing() -> None:
    done = subprocess.run([sys.executable, "-m", "ruff", "check", "--output-format", "concise", "."],
                          cwd=ROOT, capture_output=True, text=True)
    assert done.returncode == 0, (
        f"ruff check . found problems (fix them, or `ruff check --fix .`):\n{done.stdout}{done.stderr}"
    )


MAX_LINES = 500
WHY = "longer than 500 lines because"
"""A product file over :data:`MAX_LINES` lines must say why in its module docstring, with these words."""


def long_files_without_a_reason(root: Path = ROOT) -> list[str]:
    """The product files (``cekm_swarm/``, ``world/``) over :data:`MAX_LINES` lines whose
    module docstring does not contain :data:`WHY`, each as ``path: N lines``."""
    bad = []
    for path in sorted(p for pkg in ("cekm_swarm", "world") for p in (root / pkg).rglob("*.py")):
        text = path.read_text(encoding="utf-8")
        n = len(text.splitlines())
        if n > MAX_LINES and WHY not in " ".join((ast.get_docstring(ast.parse(text)) or "").split()):
            bad.append(f"{path.relative_to(root)}: {n} lines")
    return bad


def test_no_product_file_is_over_500_lines_without_saying_why() -> None:
    bad = long_files_without_a_reason()
    assert not bad, (f"split these by concept into smaller modules, or say in the module docstring "
                     f"'{WHY} ...': " + "; ".join(bad))


def test_the_length_rule_sees_a_long_file_and_its_reason(tmp_path: Path) -> None:
    pkg = tmp_path / "world"
    pkg.mkdir()
    (tmp_path / "cekm_swarm").mkdir()
    body = "x = 1\n" * MAX_LINES
    (pkg / "short.py").write_text('"""Short."""\n' + "x = 1\n" * (MAX_LINES - 1))
    (pkg / "long.py").write_text('"""Long."""\n' + body)
    (pkg / "why.py").write_text(f'"""Long, but one concept: {WHY.replace(" 500", chr(10) + "500")} it is."""\n' + body)
    assert long_files_without_a_reason(tmp_path) == [f"world{os.sep}long.py: {MAX_LINES + 1} lines"]
