"""Import-linter's contracts, checked in process: ``lint(config)`` is its ``lint_imports``
without its side effect on the test session's logging (its ``dictConfig`` disables every
logger that exists, so a later test's ``caplog`` would see nothing)."""

from __future__ import annotations

import logging
from pathlib import Path

from importlinter.cli import lint_imports


def lint(config: Path) -> int:
    """0 if every contract in ``config`` (a pyproject.toml or an INI file) is kept, else 1."""
    loggers = [lg for lg in logging.root.manager.loggerDict.values() if isinstance(lg, logging.Logger)]
    disabled = {lg: lg.disabled for lg in loggers}
    try:
        return lint_imports(config_filename=str(config), no_cache=True, no_logo=True)
    finally:
        for lg, was in disabled.items():
            lg.disabled = was
