"""A step that never returns in ``cekm run`` (one process): after ``step_timeout`` wall
seconds the run ends as failed with the line a lockstep launch says of a stalled tick,
naming the node, the tick, how long its step has run and the line of the node's code it
is at (``r1/drive: its step at t=0.512 s has run for 5.0 s, at File "mine.py", line 48
in step``), instead of hanging without a word."""

from __future__ import annotations

import signal
import sys
import threading
import time
import traceback
import weakref

from ..interrupts import restore_sigint
from . import runner
from .api import StepFailed

_RUNNER = runner.__file__


class StepTimeout(StepFailed):
    """A step ran past ``step_timeout``: the run failed (exit 1)."""


class Watchdog:
    """Watch the runner whose step runs on the thread that built this (the main thread, in
    ``cekm run``): :meth:`stepping` marks a step, :meth:`check` turns the interrupt the
    watchdog raised into the :class:`StepTimeout` naming it."""

    def __init__(self, timeout: float) -> None:
        self.timeout = timeout
        self.line: str | None = None
        self.runner: runner.Runner | None = None  # the Runner whose step runs now
        self.closed = False
        self._main = threading.get_ident()
        self._ignored = False  # SIGINT was ignored when the run began (a script's background job)
        if threading.current_thread() is threading.main_thread():  # only the main thread can be interrupted
            self._ignored = restore_sigint()  # `cekm run ... &` in a script: its interrupt would be lost
            threading.Thread(target=_watch, args=(weakref.ref(self), min(1.0, timeout / 4)),
                             name="cekm-step-watchdog", daemon=True).start()

    def _fired(self) -> bool:
        """True (and the interrupt raised) when the step running now has run too long."""
        runner = self.runner
        stepping = None if runner is None else runner.stepping
        if runner is None or stepping is None or time.monotonic() - stepping[1] < self.timeout:
            return False
        t, began = stepping
        self.line = (f"{runner.plan.label}: its step at t={t:.3f} s has run for {time.monotonic() - began:.1f} s"
                     f"{self._where()}; --step-timeout {self.timeout:g} s passed")
        signal.pthread_kill(self._main, signal.SIGINT)  # a real signal: it wakes a blocked wait too
        return True

    def _where(self) -> str:
        frame = sys._current_frames().get(self._main)
        if frame is None:
            return ""
        stack = traceback.extract_stack(frame)
        # the frame the runner called: the node's step, at the line it is at (as a launch names it)
        at = [i for i, f in enumerate(stack) if f.filename == _RUNNER and f.name == "run"]
        if not at or at[-1] + 1 >= len(stack):
            return ""
        f = stack[at[-1] + 1]
        return f', at File "{f.filename}", line {f.lineno} in {f.name}'

    def timed_out(self) -> StepTimeout | None:
        """The failure to raise in place of the KeyboardInterrupt the watchdog caused (None:
        the user's Ctrl-C)."""
        return None if self.line is None else StepTimeout(self.line)

    def close(self) -> None:
        self.closed = True
        if self._ignored and threading.get_ident() == self._main:
            signal.signal(signal.SIGINT, signal.SIG_IGN)  # as the run found it
            self._ignored = False


def _watch(ref: weakref.ref[Watchdog], every: float) -> None:
    """The watchdog's thread: it ends once its executor is closed or gone."""
    while True:
        time.sleep(every)
        dog = ref()
        if dog is None or dog.closed or dog._fired():
            return
        del dog
