"""The in-process step watchdog (node.watchdog) interrupts a hung step also in a process
that began with SIGINT ignored, as a shell script's background job does (`cekm run ... &`):
its interrupt is a SIGINT, which such a process would otherwise drop, hanging for ever."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

SCRIPT = textwrap.dedent("""
    import signal, time, types
    from cekm_swarm.node.watchdog import Watchdog

    assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN  # as a script's `cmd &` starts it
    dog = Watchdog(0.2)
    dog.runner = types.SimpleNamespace(stepping=(0.384, time.monotonic()), plan=types.SimpleNamespace(label="r1/x"))
    t0 = time.monotonic()
    try:
        time.sleep(20)  # the hung step
        print("not interrupted")
    except KeyboardInterrupt:
        print("interrupted after", round(time.monotonic() - t0, 1), "s:", dog.timed_out())
    dog.close()
    print("restored", signal.getsignal(signal.SIGINT) is signal.SIG_IGN)
""")


@pytest.mark.slow  # a process of its own (under a second)
@pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")
def test_a_hung_step_is_interrupted_where_sigint_was_ignored():
    import signal

    out = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, timeout=60,
                         preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    assert lines[0].startswith("interrupted after"), out.stdout
    assert "r1/x: its step at t=0.384 s has run for" in lines[0] and "--step-timeout 0.2 s passed" in lines[0]
    assert float(lines[0].split()[2]) < 10  # within the timeout's watch period, far below the 20 s sleep
    assert lines[1] == "restored True"  # the process's own choice comes back when the run ends
