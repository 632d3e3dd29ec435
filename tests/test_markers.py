"""The fast lane's guard (tests/process_guard.py): a test that starts a process and is not
marked ``slow`` errors, so ``python3 -m pytest -q -m "not slow"`` stays fast."""

from __future__ import annotations

import process_guard
import pytest

pytest_plugins = ["pytester"]

INNER_ARGS = (
    "-p",
    "no:cacheprovider",
    "-p",
    "no:hypothesispytest",
)  # (hypothesis, if installed, ends a session in 2 s)
INNER_CONFTEST = "from process_guard import pytest_configure, pytest_runtest_makereport, pytest_runtest_protocol\n"


def test_every_way_python_starts_a_process_is_watched():
    watched = process_guard.installed()
    assert {"subprocess._fork_exec", "_posixsubprocess.fork_exec", "os.fork"} <= set(watched), watched
    assert all(watched.values()), watched


def test_a_start_is_recorded_with_its_command_line():
    calls = []
    fake = process_guard._wrap("fork_exec", lambda *a: calls.append(a) or 123)
    n = len(process_guard.started)
    assert fake(["prog", "--flag"], [b"prog"]) == 123 and calls  # the real function still runs
    assert process_guard.started[n:] == ["prog --flag"]
    assert process_guard._wrap("fork_exec", fake) is fake  # wrapped once only
    del process_guard.started[n:]


def test_an_unmarked_test_that_starts_a_process_errors_and_a_slow_one_passes(pytester):
    """Without a real process: the inner tests call a watched stand-in."""
    pytester.makeconftest(INNER_CONFTEST)
    pytester.makeini("[pytest]\nmarkers =\n    slow: slow\n")
    start = ("import process_guard, pytest\n"
             "start = process_guard._wrap('fork_exec', lambda *a: 0)\n")
    pytester.makepyfile(
        test_mixed=start + (
            "def test_unmarked():\n    start(['python', '-m', 'world.server', 'concave'])\n\n"
            "@pytest.mark.slow\ndef test_marked():\n    start(['python'])\n\n"
            "class TestGroup:\n    pytestmark = pytest.mark.slow\n    def test_in_class(self):\n        "
            "start(['x'])\n\n"
            "def test_plain():\n    assert True\n"),
        test_module=start + "pytestmark = pytest.mark.slow\n\ndef test_in_module():\n    start(['y'])\n")
    result = pytester.runpytest_inprocess(*INNER_ARGS)
    result.assert_outcomes(passed=5, errors=1)  # test_unmarked passes its call and errs at teardown
    result.stdout.fnmatch_lines(["*test_mixed.py::test_unmarked started 1 process(es) but is not marked slow*",
                                 "*python -m world.server concave*"])
    fast = pytester.runpytest_inprocess(*INNER_ARGS, "-m", "not slow")
    fast.assert_outcomes(passed=2, errors=1, deselected=3)  # the erring test also counts as passed (its call did)


@pytest.mark.slow  # it starts real processes itself
def test_real_processes_are_caught_however_they_are_started(pytester):
    pytester.makeconftest(INNER_CONFTEST)
    pytester.makeini("[pytest]\nmarkers =\n    slow: slow\n")
    pytester.makepyfile(test_real=(
        "import multiprocessing, os, subprocess, sys\n\n"
        "def test_subprocess():\n    subprocess.run([sys.executable, '-c', 'pass'], check=True)\n\n"
        "def test_fork():\n    pid = os.fork()\n    if pid == 0:\n        os._exit(0)\n    os.waitpid(pid, 0)\n\n"
        "def test_spawn():\n    p = multiprocessing.get_context('spawn').Process(target=print)\n"
        "    p.start()\n    p.join(30)\n    assert p.exitcode == 0\n\n"
        "def test_none():\n    assert subprocess.list2cmdline(['a']) == 'a'\n"))
    result = pytester.runpytest_inprocess(*INNER_ARGS)
    result.assert_outcomes(passed=4, errors=3)
    for name in ("test_subprocess", "test_fork", "test_spawn"):
        result.stdout.fnmatch_lines([f"*test_real.py::{name} started * process(es) but is not marked slow*"])
