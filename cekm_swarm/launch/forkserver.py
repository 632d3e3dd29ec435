"""Warm start: node processes forked from a process that has already imported them.

Every node is its own OS process, but starting one afresh costs its interpreter about a
second of CPU importing numpy, Zenoh and the package before it does anything; 336 of them
(24 robots) take minutes on two cores. A launcher therefore starts one *fork server*
first (``python -m cekm_swarm.launch.forkserver``): it imports the node shell, the
graph's node programs and the run's model, freezes that heap (``gc.freeze``, so the
children's reference counting leaves the shared pages alone), and then forks one child
per request. A child is a node process like any other: its own session, its own pid,
signals, log and exit code; only the start is shared.

Rules that keep a fork safe:

* the fork server never opens a Zenoh session (Zenoh's runtime threads would not survive
  a fork): each child opens its own, after the fork;
* it runs no node's ``setup`` (a user's node may start threads): a child builds its node;
* it is single-threaded apart from numpy's idle BLAS pool, which handles fork itself.

The protocol, one JSON line per message on a socket pair the launcher made: a request
``{"id", "argv", "log", "env"}`` (``argv`` is ``[python, "-m", module, ...]``) gets
``{"id", "pid"}`` back (or ``{"id", "error"}``), and each child's end later gives
``{"pid", "code"}`` (the exit code, negative for a signal, as :mod:`subprocess`). The
child is a session leader with stdin on ``/dev/null``, stdout and stderr appended to its
log, the given environment, the command line it would have had (``ps`` shows it), and
dies with the fork server, which dies with the launcher (``PR_SET_PDEATHSIG``). When the
launcher closes its end, the fork server exits.
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import json
import os
import runpy
import select
import signal
import socket
import sys
import traceback
from collections.abc import Sequence
from typing import Any

from cekm_swarm.runtime.lifetime import PARENT_ENV, die_with_parent, signal_on_parent_death

FORK_SERVER_MODULE = "cekm_swarm.launch.forkserver"


# ---------------------------------------------------------------------- the server


def preload(spec_paths: Sequence[str]) -> list[str]:
    """Import what a node process imports, read each run spec and resolve its plan, import
    its node programs, load its model file and run one setup of each node kind that
    declares ``warm_setup`` (so a child finds all of it made); the names of what it
    loaded. What fails here is skipped: the nodes meet the error themselves and say it in
    their logs (a node that cannot start exits with its one line, as when exec'd)."""
    # importing is this function's job (the launcher imports this module for its name only)
    import zenoh  # noqa: F401, PLC0415 -- preload: imported, never opened here

    import cekm_swarm.node.process  # noqa: F401, PLC0415 -- preload: the node shell and what it imports
    import cekm_swarm.runtime.bridge  # noqa: F401, PLC0415 -- preload
    import cekm_swarm.runtime.config  # noqa: F401, PLC0415 -- preload
    import cekm_swarm.runtime.gc_tuning  # noqa: F401, PLC0415 -- preload
    from cekm_swarm.errors import CekmError  # noqa: PLC0415 -- preload
    from cekm_swarm.graph.runspec import RunSpec  # noqa: PLC0415 -- preload
    from cekm_swarm.node.graph_check import node_class  # noqa: PLC0415 -- preload
    from cekm_swarm.node.process import build_node  # noqa: PLC0415 -- preload
    from cekm_swarm.protocol.codec import warm  # noqa: PLC0415 -- preload

    warm()  # every message kind's decoder and check, made once for every child
    loaded = ["cekm_swarm.node"]
    for path in spec_paths:
        try:
            spec = RunSpec.read(path)
            plan = spec.plan()
        except CekmError as exc:
            sys.stderr.write(f"fork server: not preloading {path}: {exc}\n")
            continue
        for decl in spec.graph.nodes:
            try:
                cls = node_class(decl.program, spec.graph.source, decl.where)
                loaded.append(decl.program)
                first = next(((r, n.name) for r in plan.team for n in plan.nodes.get(r, ())
                              if n.decl.name == decl.name), None)
                model_here = isinstance(spec.model, str) and spec.model != "zenoh"
                if cls.warm_setup and first is not None and (model_here or not cls.uses_model):
                    _, runner = build_node(spec, plan, first[0], first[1], "numpy", spec.model)
                    runner.node.close()
            except Exception as exc:  # noqa: BLE001 - any failure is the node's own to report
                sys.stderr.write(f"fork server: not preloading {decl.where}: {type(exc).__name__}: {exc}\n")
    return loaded


class Server:
    """The fork server's loop: requests in, children out, their ends reported."""

    def __init__(self, sock: socket.socket) -> None:
        self.sock = sock
        self.children: set[int] = set()
        self.buf = b""

    def send(self, doc: dict[str, Any]) -> None:
        self.sock.sendall(json.dumps(doc).encode() + b"\n")

    def serve(self) -> int:
        wake_r, wake_w = os.pipe()
        os.set_blocking(wake_w, False)
        os.set_blocking(wake_r, False)
        signal.set_wakeup_fd(wake_w)
        signal.signal(signal.SIGCHLD, lambda *_: None)  # wakes select through the pipe
        self.wake = (wake_r, wake_w)
        while True:
            try:
                readers: list[Any] = [self.sock, wake_r]
                ready, _, _ = select.select(readers, [], [])
            except InterruptedError:  # pragma: no cover - PEP 475 retries
                continue
            if wake_r in ready:
                with contextlib.suppress(BlockingIOError):
                    os.read(wake_r, 4096)
                self.reap()
            if self.sock in ready:
                data = self.sock.recv(1 << 16)
                if not data:  # the launcher closed its end: done (children die with us)
                    return 0
                self.buf += data
                while b"\n" in self.buf:
                    line, self.buf = self.buf.split(b"\n", 1)
                    self.handle(json.loads(line))
                self.reap()

    def reap(self) -> None:
        while self.children:
            try:
                pid, status = os.waitpid(-1, os.WNOHANG)
            except ChildProcessError:
                return
            if pid == 0:
                return
            self.children.discard(pid)
            self.send({"pid": pid, "code": os.waitstatus_to_exitcode(status)})

    def handle(self, req: dict[str, Any]) -> None:
        argv = req.get("argv") or []
        if len(argv) < 3 or argv[1] != "-m":
            self.send({"id": req.get("id"), "error": f"not a 'python -m module' command line: {argv!r}"})
            return
        sys.stdout.flush()
        sys.stderr.flush()
        server = os.getpid()
        pid = os.fork()
        if pid == 0:
            run_child(argv, req["log"], req.get("env"), [self.sock.fileno(), *self.wake], server)
        self.children.add(pid)
        self.send({"id": req.get("id"), "pid": pid})


def run_child(argv: list[str], log: str, env: dict[str, str] | None, close: Sequence[int],
              server: int) -> None:
    """In the forked child: become the process ``argv`` describes, run it, exit with its code."""
    code = 1
    try:
        signal_on_parent_death(server)  # whatever it runs, it dies with the fork server
        signal.set_wakeup_fd(-1)
        for sig in (signal.SIGCHLD, signal.SIGTERM, signal.SIGINT, signal.SIGPIPE):
            signal.signal(sig, signal.SIG_DFL)
        for fd in close:
            os.close(fd)
        os.setsid()
        null = os.open(os.devnull, os.O_RDONLY)
        out = os.open(log, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
        os.dup2(null, 0)
        os.dup2(out, 1)
        os.dup2(out, 2)
        os.close(null)
        os.close(out)
        _set_title(argv)  # (before the environment changes: setproctitle moves it first)
        if env is not None:
            os.environ.clear()
            os.environ.update(env)
        os.environ[PARENT_ENV] = str(os.getppid())  # dies with the fork server (lifetime)
        sys.argv = [argv[2], *argv[3:]]
        try:
            runpy.run_module(argv[2], run_name="__main__", alter_sys=True)
            code = 0
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
            if not isinstance(exc.code, int) and exc.code is not None:
                sys.stderr.write(f"{exc.code}\n")
    except BaseException:  # noqa: BLE001 - whatever happens, the child must not return into the server
        traceback.print_exc()
        code = 1
    finally:
        try:
            sys.stdout.flush()
            sys.stderr.flush()
        finally:
            os._exit(code)


def _set_title(argv: Sequence[str]) -> None:
    """The command line ``ps`` shows: the one the process would have had when exec'd."""
    try:
        import setproctitle  # noqa: PLC0415 -- optional at run time: without it ps shows the fork server
    except ImportError:  # pragma: no cover - a declared dependency; ps then shows the fork server's
        return
    setproctitle.setproctitle(" ".join(argv))


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog=f"python -m {FORK_SERVER_MODULE}",
                                description="fork a launcher's node processes from one warm interpreter")
    p.add_argument("--fd", type=int, required=True, help="the launcher's end of the socket pair")
    p.add_argument("--preload", action="append", default=[], help="a run spec whose node programs and model to load")
    p.add_argument("--run-id", help="the run's id (so `ps` tells runs apart)")
    return p


def main(argv: list[str] | None = None) -> int:
    die_with_parent()
    args = parser().parse_args(argv)
    sock = socket.socket(fileno=args.fd)
    sock.setblocking(True)
    loaded = preload(args.preload)
    gc.collect()
    gc.freeze()  # what the children share is never touched by their collector
    sys.stderr.write(f"fork server {os.getpid()} ready: {', '.join(loaded)}\n")
    sys.stderr.flush()
    return Server(sock).serve()


if __name__ == "__main__":
    raise SystemExit(main())
