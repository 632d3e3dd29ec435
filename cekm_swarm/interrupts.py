"""SIGINT for a process started ignoring it: the one home of that rule, which the ``cekm``
entry and ``cekm run``'s step watchdog both apply."""

from __future__ import annotations

import signal


def restore_sigint() -> bool:
    """Let SIGINT interrupt this process (Python's KeyboardInterrupt) if it was started
    ignoring it; True when it was. A shell script's background job (``cekm view ... &``)
    and everything it starts inherit SIGINT ignored: a supervisor's, a test's or a user's
    ``kill -INT`` would be lost and the command run on until killed. Main thread only."""
    if signal.getsignal(signal.SIGINT) is not signal.SIG_IGN:
        return False
    signal.signal(signal.SIGINT, signal.default_int_handler)
    return True
