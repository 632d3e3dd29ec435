"""How the launcher starts a node process: forked warm from its fork server
(:mod:`.forkserver`), or exec'd afresh (``cekm launch --cold-start``, and whenever the
fork server is not there). Both give a handle with what supervision uses of
:class:`asyncio.subprocess.Process`: ``pid``, ``returncode``, ``wait()``,
``send_signal()``, ``terminate()`` and ``kill()``."""

from __future__ import annotations

import asyncio
import contextlib
import json
import os
import signal
import socket
import sys
from pathlib import Path
from typing import Any

from cekm_swarm.runtime.lifetime import child_env

from .forkserver import FORK_SERVER_MODULE

FORK_SERVER_READY_TIMEOUT = 120.0  # s: its imports on a loaded machine


class ForkedProcess:
    """A node process the fork server forked (its parent is the fork server, so its end
    reaches us as the server's report)."""

    def __init__(self, pid: int) -> None:
        self.pid = pid
        self.returncode: int | None = None
        self._done = asyncio.Event()

    def _ended(self, code: int) -> None:
        if self.returncode is None:
            self.returncode = code
            self._done.set()

    async def wait(self) -> int:
        await self._done.wait()
        assert self.returncode is not None
        return self.returncode

    def send_signal(self, sig: int) -> None:
        if self.returncode is not None:
            raise ProcessLookupError(self.pid)
        os.kill(self.pid, sig)

    def terminate(self) -> None:
        self.send_signal(signal.SIGTERM)

    def kill(self) -> None:
        self.send_signal(signal.SIGKILL)


class ForkServer:
    """The launcher's side of its fork server: start it, ask it for children, follow them."""

    def __init__(self, proc: asyncio.subprocess.Process, sock: socket.socket, reader: asyncio.StreamReader,
                 writer: asyncio.StreamWriter) -> None:
        self.proc, self.sock, self.reader, self.writer = proc, sock, reader, writer
        self.children: dict[int, ForkedProcess] = {}
        self.pending: dict[int, asyncio.Future] = {}
        self.next_id = 0
        self.reading = asyncio.ensure_future(self._read())

    @property
    def pid(self) -> int:
        return self.proc.pid

    @property
    def alive(self) -> bool:
        return self.proc.returncode is None and not self.reading.done()

    @classmethod
    async def start(cls, specs: list[Path], log_path: Path, run_id: str | None = None) -> ForkServer:
        """Start the fork server (preloading ``specs``) and wait until it is ready."""
        ours, theirs = socket.socketpair(socket.AF_UNIX, socket.SOCK_STREAM)
        argv = [sys.executable, "-m", FORK_SERVER_MODULE, "--fd", str(theirs.fileno())]
        for s in specs:
            argv += ["--preload", str(s)]
        if run_id:
            argv += ["--run-id", run_id]
        with open(log_path, "ab") as log:
            proc = await asyncio.create_subprocess_exec(*argv, stdin=asyncio.subprocess.DEVNULL, stdout=log,
                                                        stderr=log, pass_fds=(theirs.fileno(),),
                                                        start_new_session=True, env=child_env())
        theirs.close()
        reader, writer = await asyncio.open_unix_connection(sock=ours)
        server = cls(proc, ours, reader, writer)
        await server._ready(log_path)
        return server

    async def _ready(self, log_path: Path) -> None:
        """Until the server logs its ready line (or ends: then its log says why)."""
        loop = asyncio.get_running_loop()
        deadline = loop.time() + FORK_SERVER_READY_TIMEOUT
        while loop.time() < deadline:
            if self.proc.returncode is not None:
                break
            if b" ready: " in log_path.read_bytes():
                return
            await asyncio.sleep(0.02)
        tail = log_path.read_text(errors="replace").strip().splitlines()[-3:]
        raise OSError(f"the fork server did not start ({'; '.join(tail) or 'no output'})")

    async def _read(self) -> None:
        try:
            while line := await self.reader.readline():
                doc = json.loads(line)
                if "id" in doc:
                    fut = self.pending.pop(doc["id"], None)
                    if fut is not None and not fut.done():
                        if "pid" in doc:
                            child = ForkedProcess(int(doc["pid"]))
                            self.children[child.pid] = child
                            fut.set_result(child)
                        else:
                            fut.set_exception(OSError(doc.get("error", "the fork server refused")))
                elif "pid" in doc:
                    pid = int(doc["pid"])
                    if pid in self.children:
                        self.children.pop(pid)._ended(int(doc["code"]))
        finally:
            await self._orphaned()

    async def _orphaned(self) -> None:
        """The fork server is gone: its children die with it (their parent-death signal);
        report each as ended by SIGTERM once its pid is gone."""
        for fut in self.pending.values():
            if not fut.done():
                fut.set_exception(OSError("the fork server ended"))
        self.pending.clear()
        while self.children:
            for pid in list(self.children):
                try:
                    os.kill(pid, 0)
                except ProcessLookupError:
                    self.children.pop(pid)._ended(-signal.SIGTERM)
            await asyncio.sleep(0.05)

    async def spawn(self, argv: list[str], log_path: Path, env: dict[str, str]) -> ForkedProcess:
        """Fork the process ``argv`` would start, with its output appended to ``log_path``."""
        if not self.alive:
            raise OSError("the fork server ended")
        self.next_id += 1
        fut = asyncio.get_running_loop().create_future()
        self.pending[self.next_id] = fut
        self.writer.write(json.dumps({"id": self.next_id, "argv": argv, "log": str(log_path), "env": env}).encode()
                          + b"\n")
        await self.writer.drain()
        return await fut

    async def close(self) -> None:
        """Close our end: the server exits (any child still alive dies with it)."""
        with contextlib.suppress(Exception):  # closing twice or after its end
            self.writer.close()
        try:
            await asyncio.wait_for(self.proc.wait(), 5.0)
        except TimeoutError:
            self.proc.kill()
            await self.proc.wait()
        self.reading.cancel()


async def exec_process(argv: list[str], log_path: Path, env: dict[str, str]) -> Any:
    """Start ``argv`` afresh (a cold start), its output appended to ``log_path``."""
    with open(log_path, "ab") as f:
        return await asyncio.create_subprocess_exec(*argv, stdout=f, stderr=asyncio.subprocess.STDOUT,
                                                    stdin=asyncio.subprocess.DEVNULL, start_new_session=True,
                                                    env=env)
