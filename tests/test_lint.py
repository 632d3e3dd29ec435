"""The linter is part of the suite: ``ruff check .`` (pyproject's rules: pyflakes, import
order, pycodestyle, bugbear, pyupgrade, simplify, complexity, imports at the top) must be
clean. There is no rule on a file's length: one concept a module, however long.

The rules are in pyproject.toml's ``[tool.ruff]``; ruff is in the ``test`` extra, so this test
runs wherever the suite does. CI also runs ``ruff check .`` on its own, before the tests.
"""

from __future__ import annotations

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
