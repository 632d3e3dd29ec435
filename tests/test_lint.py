"""The linter is part of the suite: ``ruff check .`` (pyflakes and import order) must be clean.

The rules are in pyproject.toml's ``[tool.ruff]``; ruff is in the ``test`` extra, so this test
runs wherever the suite does. CI also runs ``ruff check .`` on its own, before the tests.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_ruff_finds_nothing() -> None:
    done = subprocess.run([sys.executable, "-m", "ruff", "check", "--output-format", "concise", "."],
                          cwd=ROOT, capture_output=True, text=True)
    assert done.returncode == 0, f"ruff check . found problems (fix them, or `ruff check --fix .`):\n{done.stdout}{done.stderr}"
