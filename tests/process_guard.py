"""The fast lane stays fast: a test that starts a process must be marked ``slow``.

``python3 -m pytest -q -m "not slow"`` is the fast lane (unit tests, well under a minute);
the default ``python3 -m pytest -q`` runs everything. What makes a test slow here is nearly
always a process: ``cekm launch``, a world server, a node, a helper, a fresh interpreter,
a command-line tool. So this plugin (loaded by tests/conftest.py) wraps every way Python
starts one -- ``subprocess`` (and so asyncio's subprocesses), ``multiprocessing``'s spawn
and fork, ``os.fork``, ``os.posix_spawn[p]`` -- and notes each start during a test's setup,
call and teardown (a shared fixture's processes count for the first test that asks for it).
A test not marked ``slow`` (itself, its class or its module's ``pytestmark``) that started
one gets an error at teardown naming the test and the command, whatever lane runs it.

Embedded Zenoh routers and sessions run in-process; they are left to the durations
(``--durations=0``): a file whose tests open them is marked slow when they take time.
"""

from __future__ import annotations

import _posixsubprocess
import functools
import os
import subprocess
from collections.abc import Callable
from typing import Any

import pytest

started: list[str] = []
"""What the running test has started (one description per process), reset before each test."""


def _describe(name: str, args: tuple[Any, ...]) -> str:
    if name in ("fork_exec", "_fork_exec") and args:
        argv = args[0]  # fork_exec(args, executable_list, ...)
        return " ".join(os.fsdecode(a) for a in argv) if isinstance(argv, (list, tuple)) else repr(argv)
    if name in ("posix_spawn", "posix_spawnp") and len(args) > 1:
        return " ".join(os.fsdecode(a) for a in args[1])
    return f"os.{name}()"


def _wrap(name: str, fn: Callable[..., Any]) -> Callable[..., Any]:
    if getattr(fn, "__process_guard__", False):
        return fn

    @functools.wraps(fn)
    def wrapper(*args: Any, **kw: Any) -> Any:
        started.append(_describe(name, args))
        return fn(*args, **kw)

    wrapper.__process_guard__ = True  # type: ignore[attr-defined]
    return wrapper


def install() -> None:
    """Wrap every entry point that starts a process (idempotent)."""
    for mod, name in ((subprocess, "_fork_exec"), (_posixsubprocess, "fork_exec"), (os, "fork"),
                      (os, "posix_spawn"), (os, "posix_spawnp")):
        fn = getattr(mod, name, None)
        if fn is not None:
            setattr(mod, name, _wrap(name, fn))


def installed() -> dict[str, bool]:
    """{entry point: wrapped} (tests/test_markers.py holds every one wrapped)."""
    return {f"{mod.__name__}.{name}": getattr(getattr(mod, name, None), "__process_guard__", False)
            for mod, name in ((subprocess, "_fork_exec"), (_posixsubprocess, "fork_exec"), (os, "fork"),
                              (os, "posix_spawn"), (os, "posix_spawnp")) if hasattr(mod, name)}


def pytest_configure(config: pytest.Config) -> None:
    install()


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item: pytest.Item, nextitem: pytest.Item | None):
    started.clear()
    yield
    started.clear()


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo):
    outcome = yield
    report = outcome.get_result()
    if call.when != "teardown" or not started or item.get_closest_marker("slow") is not None:
        return
    shown = "\n  ".join(s[:200] for s in started[:5]) + (f"\n  ... {len(started) - 5} more" if len(started) > 5 else "")
    report.outcome = "failed"
    report.longrepr = (f"{item.nodeid} started {len(started)} process(es) but is not marked slow: mark it "
                       f"@pytest.mark.slow, or its module with pytestmark = pytest.mark.slow, so that "
                       f"`pytest -m \"not slow\"` stays the fast lane (tests/process_guard.py).\n  {shown}")
