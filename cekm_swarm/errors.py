"""The project's error hierarchy: every error names what is wrong and where.

Each class says which exit code ``cekm`` ends with when it reaches the command line:
``EXIT_USAGE`` for bad input (an argument, a file), ``EXIT_FAILED`` when a run could not
go on (a router unreachable, a process that did not come up)."""

from __future__ import annotations

import os

EXIT_OK = 0
EXIT_FAILED = 1
"""The run failed: ``cekm: failed: ...``."""
EXIT_USAGE = 2
"""Bad usage or input: ``cekm: error: ...``."""
EXIT_INTERRUPTED = 130
"""Stopped by the user (Ctrl-C, SIGINT)."""


class CekmError(Exception):
    """Base class of every error this package raises on purpose."""

    exit_code = EXIT_USAGE


class RunError(CekmError):
    """A run could not go on (exit code 1)."""

    exit_code = EXIT_FAILED


class OutputDirError(CekmError):
    """An output directory that cannot be used as given (not empty, not a directory)."""


class ModelFormatError(CekmError):
    """A saved-model file is missing, damaged, of another version, or inconsistent."""

    def __init__(self, path: str | os.PathLike[str], field: str | None, problem: str) -> None:
        self.path = str(path)
        self.field = field
        self.problem = problem
        where = f"{self.path}: field '{field}'" if field else self.path
        super().__init__(f"{where}: {problem}")


class ParameterError(CekmError, ValueError):
    """A model or experiment parameter is out of its valid range."""


class ResultsFileError(CekmError, ValueError):
    """An experiment's results file that does not hold what a command reads from it."""
