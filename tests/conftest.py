"""The suite's own rule: a test that starts a process is marked ``slow`` (tests/process_guard.py),
so that ``python3 -m pytest -q -m "not slow"`` stays the fast lane."""

from process_guard import pytest_configure, pytest_runtest_makereport, pytest_runtest_protocol

__all__ = ["pytest_configure", "pytest_runtest_makereport", "pytest_runtest_protocol"]
