"""The project's error hierarchy: every error names what is wrong and where."""

from __future__ import annotations


class CekmError(Exception):
    """Base class of every error this package raises on purpose."""


class ModelFormatError(CekmError):
    """A saved-model file is missing, damaged, of another version, or inconsistent."""

    def __init__(self, path: str, field: str | None, problem: str) -> None:
        self.path = str(path)
        self.field = field
        self.problem = problem
        where = f"{self.path}: field '{field}'" if field else self.path
        super().__init__(f"{where}: {problem}")


class ParameterError(CekmError, ValueError):
    """A model or experiment parameter is out of its valid range."""
