"""A bad network link in user space: a proxy between a robot's host and its Zenoh router
that adds one-way delay and jitter, loss, a bandwidth cap and a partition (cut, restore)
on command, and logs every change of its settings.

Why user space: the kernels this runs on have no ``netem`` queueing discipline (``tc
qdisc ... netem``: "Specified qdisc kind is unknown"); ``tbf`` and link up/down work but
give neither delay nor loss. The proxy runs beside the router (or in the robot's network
namespace); the robot's processes connect to it instead of the router.

What each setting means, per transport (both directions alike, so a round trip sees twice
the one-way delay):

- **delay, jitter**: each chunk of bytes (TCP) or datagram (UDP) is forwarded ``delay``
  s after it arrived, plus a uniform draw in [-jitter, +jitter] (never below 0). TCP
  keeps its order (a chunk never overtakes the one before); UDP datagrams may reorder.
- **loss**: UDP: the datagram is dropped (counted). TCP: a lost segment is retransmitted
  by the sender's kernel, so nothing is lost but the chunk (and everything behind it: TCP
  is in order) comes one retransmission timeout later, ``2 delay + 0.2`` s (Linux's RTO:
  the smoothed round trip plus at least 200 ms).
- **rate**: a bandwidth cap in bytes/s: a chunk leaves only once the ones before it have
  been serialised at that rate. UDP datagrams beyond :data:`UDP_QUEUE_S` s of backlog are
  dropped (tail drop, counted).
- **cut** (a partition): nothing crosses. TCP: bytes wait in the proxy, as they would in
  the sender's retransmission queue, and a new connection is not carried to the router,
  until ``restore``; the connection survives a cut shorter than Zenoh's lease (10 s), and
  one longer is closed by Zenoh itself. UDP: datagrams are dropped (counted).
- **reset**: every open TCP connection is closed at once (an interface gone, a router
  restarted); clients reconnect by themselves once a connection gets through.

``python -m cekm_swarm.runtime.faultlink --tcp 10.0.0.1:7448=127.0.0.1:7447 --delay 0.05``
runs one; it prints ``READY`` once listening and takes commands on stdin, one a line:
``cut``, ``restore``, ``reset``, ``set delay=0.1 jitter=0.01 loss=0.05 rate=125000``,
``stats``; each is answered, and logged, with one line."""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import dataclasses
import json
import random
import sys
import time
from collections.abc import Callable
from typing import IO, Any

CHUNK = 65536
"""Bytes read from a TCP socket at a time (a chunk is the unit of delay and loss)."""
MIN_RTO_S = 0.2
"""Linux's least retransmission timeout: a lost TCP segment comes this much plus a round trip late."""
UDP_QUEUE_S = 1.0
"""s of backlog a capped UDP direction holds before it drops (tail drop)."""


@dataclasses.dataclass
class LinkSettings:
    """The link's state; every field may be changed while it runs (:meth:`FaultLink.set`)."""

    delay: float = 0.0  # s, one way
    jitter: float = 0.0  # s, uniform +- around the delay
    loss: float = 0.0  # probability per chunk (TCP: retransmitted) or datagram (UDP: dropped)
    rate: float | None = None  # bytes/s, None: no cap
    cut: bool = False

    def check(self) -> None:
        """Refuse a setting no link can have, naming it."""
        for name in ("delay", "jitter"):
            if getattr(self, name) < 0:
                raise ValueError(f"fault link: {name} must be >= 0 s, got {getattr(self, name)}")
        if not 0.0 <= self.loss < 1.0:
            raise ValueError(f"fault link: loss must be in [0, 1), got {self.loss}")
        if self.rate is not None and self.rate <= 0:
            raise ValueError(f"fault link: rate must be > 0 bytes/s (or none), got {self.rate}")

    def retransmit_s(self) -> float:
        """How late a lost TCP segment arrives: one retransmission timeout."""
        return 2 * self.delay + MIN_RTO_S


@dataclasses.dataclass
class LinkStats:
    """What the link did, per direction: ``up`` is client to server, ``down`` back."""

    bytes: dict[str, int] = dataclasses.field(default_factory=lambda: {"up": 0, "down": 0})
    retransmitted: dict[str, int] = dataclasses.field(default_factory=lambda: {"up": 0, "down": 0})
    dropped: dict[str, int] = dataclasses.field(default_factory=lambda: {"up": 0, "down": 0})  # UDP datagrams
    held_during_cut: dict[str, int] = dataclasses.field(default_factory=lambda: {"up": 0, "down": 0})  # TCP bytes
    connections: int = 0
    resets: int = 0


class _Direction:
    """One direction of one connection: when each chunk may leave (delay, jitter, loss as
    retransmission, rate), in order for TCP."""

    def __init__(self, link: FaultLink, name: str, ordered: bool) -> None:
        self.link, self.name, self.ordered = link, name, ordered
        self.last_release = 0.0
        self.wire_free = 0.0  # when the capped wire has serialised what it holds

    def release_at(self, size: int, now: float) -> float | None:
        """When a chunk of ``size`` bytes that arrived ``now`` leaves; None if dropped (UDP)."""
        s, rng = self.link.settings, self.link.rng
        at = now + max(0.0, s.delay + (rng.uniform(-s.jitter, s.jitter) if s.jitter else 0.0))
        if s.loss and rng.random() < s.loss:
            if not self.ordered:
                self.link.stats.dropped[self.name] += 1
                return None
            self.link.stats.retransmitted[self.name] += 1
            at += s.retransmit_s()
        if s.rate is not None:
            self.wire_free = max(self.wire_free, now) + size / s.rate
            if not self.ordered and self.wire_free - now > UDP_QUEUE_S:
                self.wire_free -= size / s.rate
                self.link.stats.dropped[self.name] += 1
                return None
            at = max(at, self.wire_free + s.delay)
        if self.ordered:
            at = max(at, self.last_release)
            self.last_release = at
        return at


class FaultLink:
    """The proxy: :meth:`add_tcp` and :meth:`add_udp` listen, then :meth:`set`, :meth:`cut`,
    :meth:`restore`, :meth:`reset` change it while it runs. ``log`` gets one line per
    change (also kept in :attr:`history`)."""

    def __init__(self, settings: LinkSettings | None = None, seed: int = 0,
                 log: Callable[[str], None] | None = None) -> None:
        self.settings = settings or LinkSettings()
        self.settings.check()
        self.rng = random.Random(seed)
        self.stats = LinkStats()
        self.history: list[dict[str, Any]] = []
        self._log = log or (lambda line: None)
        self._restored = asyncio.Event()
        self._restored.set()
        self._servers: list[Any] = []
        self._conns: set[asyncio.StreamWriter] = set()
        self._tasks: set[asyncio.Task[None]] = set()
        self._note("start", dataclasses.asdict(self.settings))

    # -- settings -------------------------------------------------------------------------
    def _note(self, what: str, doc: dict[str, Any]) -> str:
        entry = {"wall": round(time.time(), 4), "event": what, **doc}
        self.history.append(entry)
        line = json.dumps(entry)
        self._log(line)
        return line

    def set(self, **changes: Any) -> str:
        """Change settings (delay, jitter, loss, rate); logged. Bad values are refused whole."""
        if "cut" in changes:
            raise ValueError("fault link: cut with cut() and restore(), not set()")
        new = dataclasses.replace(self.settings, **changes)
        new.check()
        self.settings = new
        return self._note("set", changes)

    def cut(self) -> str:
        """Partition: nothing crosses until :meth:`restore` (see the module docstring)."""
        self.settings.cut = True
        self._restored.clear()
        return self._note("cut", {})

    def restore(self) -> str:
        self.settings.cut = False
        self._restored.set()
        return self._note("restore", {})

    def reset(self) -> str:
        """Close every open TCP connection at once."""
        n = len(self._conns)
        for w in list(self._conns):
            w.transport.abort()
        self._conns.clear()
        self.stats.resets += n
        return self._note("reset", {"connections": n})

    def stats_line(self) -> str:
        return self._note("stats", dataclasses.asdict(self.stats))

    # -- TCP ------------------------------------------------------------------------------
    async def add_tcp(self, listen: tuple[str, int], target: tuple[str, int]) -> tuple[str, int]:
        """Listen on ``listen`` (port 0: any free one) and carry each connection to
        ``target``; returns the address listened on."""
        async def accepted(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
            self._spawn(self._tcp_connection(reader, writer, target))

        server = await asyncio.start_server(accepted, *listen)
        self._servers.append(server)
        addr = server.sockets[0].getsockname()[:2]
        self._note("listen", {"transport": "tcp", "listen": list(addr), "target": list(target)})
        return addr

    def _spawn(self, coro: Any) -> None:
        task = asyncio.ensure_future(coro)
        self._tasks.add(task)
        task.add_done_callback(self._tasks.discard)

    async def _tcp_connection(self, c_reader: asyncio.StreamReader, c_writer: asyncio.StreamWriter,
                              target: tuple[str, int]) -> None:
        self._conns.add(c_writer)
        queue_up: asyncio.Queue[tuple[float | None, bytes]] = asyncio.Queue()
        pump_up = asyncio.ensure_future(self._tcp_read(c_reader, _Direction(self, "up", True), queue_up))
        try:
            await self._restored.wait()  # a cut link carries no new connection (its SYNs are lost)
            s_reader, s_writer = await asyncio.open_connection(*target)
        except OSError:
            pump_up.cancel()
            self._close(c_writer)
            return
        if c_writer not in self._conns:  # reset meanwhile
            pump_up.cancel()
            self._close(s_writer)
            return
        self._conns.add(s_writer)
        self.stats.connections += 1
        queue_down: asyncio.Queue[tuple[float | None, bytes]] = asyncio.Queue()
        parts = [pump_up, asyncio.ensure_future(self._tcp_write(queue_up, s_writer)),
                 asyncio.ensure_future(self._tcp_read(s_reader, _Direction(self, "down", True), queue_down)),
                 asyncio.ensure_future(self._tcp_write(queue_down, c_writer))]
        try:
            await asyncio.wait(parts, return_when=asyncio.FIRST_COMPLETED)
            # One side ended: its close crosses no cut either; then deliver what the other
            # may still be owed, and close both.
            await self._restored.wait()
            await asyncio.wait([parts[1], parts[3]], timeout=self.settings.delay + 1.0)
        finally:
            for p in parts:
                p.cancel()
            for w in (c_writer, s_writer):
                self._close(w)

    async def _tcp_read(self, reader: asyncio.StreamReader, d: _Direction,
                        out: asyncio.Queue[tuple[float | None, bytes]]) -> None:
        loop = asyncio.get_running_loop()
        try:
            while data := await reader.read(CHUNK):
                if self.settings.cut:
                    self.stats.held_during_cut[d.name] += len(data)
                self.stats.bytes[d.name] += len(data)
                out.put_nowait((d.release_at(len(data), loop.time()), data))
        except (ConnectionError, OSError):
            pass
        out.put_nowait((None, b""))

    async def _tcp_write(self, inq: asyncio.Queue[tuple[float | None, bytes]], writer: asyncio.StreamWriter) -> None:
        loop = asyncio.get_running_loop()
        try:
            while True:
                at, data = await inq.get()
                if at is None:
                    return
                if (wait := at - loop.time()) > 0:
                    await asyncio.sleep(wait)
                await self._restored.wait()
                writer.write(data)
                await writer.drain()
        except (ConnectionError, OSError):
            pass

    def _close(self, writer: asyncio.StreamWriter) -> None:
        self._conns.discard(writer)
        with contextlib.suppress(ConnectionError, OSError, RuntimeError):
            writer.close()

    # -- UDP ------------------------------------------------------------------------------
    async def add_udp(self, listen: tuple[str, int], target: tuple[str, int]) -> tuple[str, int]:
        """Listen for datagrams on ``listen``; each client address gets its own socket
        towards ``target`` (as a NAT would), whose answers go back to that client."""
        loop = asyncio.get_running_loop()
        link = self

        class Front(asyncio.DatagramProtocol):
            def __init__(self) -> None:
                self.peers: dict[tuple[Any, ...], tuple[Any, _Direction, _Direction]] = {}

            def connection_made(self, transport: Any) -> None:
                self.transport = transport

            def datagram_received(self, data: bytes, addr: tuple[Any, ...]) -> None:
                if addr not in self.peers:
                    link._spawn(self._open(addr, data))
                    return
                back, up, _ = self.peers[addr]
                if back is not None:
                    link._send_udp(up, data, back.sendto)

            async def _open(self, addr: tuple[Any, ...], first: bytes) -> None:
                down = _Direction(link, "down", False)
                self.peers[addr] = (None, _Direction(link, "up", False), down)
                front = self.transport

                class Back(asyncio.DatagramProtocol):
                    def datagram_received(self, data: bytes, _addr: tuple[Any, ...]) -> None:
                        link._send_udp(down, data, lambda d: front.sendto(d, addr))

                back, _ = await loop.create_datagram_endpoint(Back, remote_addr=target)
                self.peers[addr] = (back, self.peers[addr][1], down)
                link._send_udp(self.peers[addr][1], first, back.sendto)

        transport, _ = await loop.create_datagram_endpoint(Front, local_addr=listen)
        self._servers.append(transport)
        addr = transport.get_extra_info("sockname")[:2]
        self._note("listen", {"transport": "udp", "listen": list(addr), "target": list(target)})
        return addr

    def _send_udp(self, d: _Direction, data: bytes, send: Callable[[bytes], Any]) -> None:
        self.stats.bytes[d.name] += len(data)
        if self.settings.cut:
            self.stats.dropped[d.name] += 1
            return
        loop = asyncio.get_running_loop()
        at = d.release_at(len(data), loop.time())
        if at is not None:
            loop.call_at(at, lambda: None if self.settings.cut else send(data))

    async def close(self) -> None:
        for s in self._servers:
            s.close()
        self.reset()
        for t in list(self._tasks):
            t.cancel()


def parse_pair(text: str) -> tuple[tuple[str, int], tuple[str, int]]:
    """``HOST:PORT=HOST:PORT`` (listen=target) as two addresses; a clear error otherwise."""
    try:
        listen, target = text.split("=")
        (lh, lp), (th, tp) = listen.rsplit(":", 1), target.rsplit(":", 1)
        return (lh, int(lp)), (th, int(tp))
    except ValueError:
        raise ValueError(f"fault link: {text!r} is not LISTEN_HOST:PORT=TARGET_HOST:PORT") from None


def parse_command(link: FaultLink, line: str) -> str:
    """Carry out one command line (see the module docstring); the answer line."""
    words = line.split()
    if not words:
        return ""
    verb, args = words[0], words[1:]
    if verb in ("cut", "restore", "reset", "stats") and not args:
        return {"cut": link.cut, "restore": link.restore, "reset": link.reset, "stats": link.stats_line}[verb]()
    if verb == "set" and args:
        changes: dict[str, Any] = {}
        for a in args:
            key, _, value = a.partition("=")
            if key not in ("delay", "jitter", "loss", "rate") or not value:
                raise ValueError(f"fault link: unknown setting {a!r} (delay=S jitter=S loss=P rate=BYTES_PER_S|none)")
            try:
                changes[key] = None if key == "rate" and value == "none" else float(value)
            except ValueError:
                raise ValueError(f"fault link: {key} must be a number, got {value!r}") from None
        return link.set(**changes)
    raise ValueError(f"fault link: unknown command {line.strip()!r} (cut, restore, reset, set K=V ..., stats)")


async def serve(args: argparse.Namespace) -> None:
    """Run the link of ``args`` until stdin closes, appending setting changes to ``--log``."""
    if not args.log:
        await _serve(args, None)
        return
    with open(args.log, "a") as log_file:
        await _serve(args, log_file)


async def _serve(args: argparse.Namespace, log_file: IO[str] | None) -> None:
    def log(line: str) -> None:
        if log_file is not None:
            log_file.write(line + "\n")
            log_file.flush()

    link = FaultLink(LinkSettings(args.delay, args.jitter, args.loss, args.rate), args.seed, log)
    for pair in args.tcp:
        await link.add_tcp(*parse_pair(pair))
    for pair in args.udp:
        await link.add_udp(*parse_pair(pair))
    print("READY", flush=True)
    loop = asyncio.get_running_loop()
    reader = asyncio.StreamReader()
    await loop.connect_read_pipe(lambda: asyncio.StreamReaderProtocol(reader), sys.stdin)
    while line := (await reader.readline()).decode():
        try:
            answer = parse_command(link, line)
        except (ValueError, TypeError) as exc:
            answer = f"error: {exc}"
        if answer:
            print(answer, flush=True)
    print(link.stats_line(), flush=True)
    await link.close()


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m cekm_swarm.runtime.faultlink", description=__doc__.split("\n\n")[0])
    p.add_argument("--tcp", action="append", default=[], metavar="LISTEN=TARGET", help="HOST:PORT=HOST:PORT")
    p.add_argument("--udp", action="append", default=[], metavar="LISTEN=TARGET", help="HOST:PORT=HOST:PORT")
    p.add_argument("--delay", type=float, default=0.0, help="one-way delay, s")
    p.add_argument("--jitter", type=float, default=0.0, help="+- s around the delay")
    p.add_argument("--loss", type=float, default=0.0, help="probability per chunk/datagram")
    p.add_argument("--rate", type=float, default=None, help="bandwidth cap, bytes/s")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--log", default=None, help="append every setting change here (JSON lines)")
    args = p.parse_args(argv)
    if not args.tcp and not args.udp:
        p.error("give at least one --tcp or --udp LISTEN=TARGET")
    try:
        LinkSettings(args.delay, args.jitter, args.loss, args.rate).check()
        for pair in args.tcp + args.udp:
            parse_pair(pair)
    except ValueError as exc:
        p.error(str(exc))
    try:
        asyncio.run(serve(args))
    except KeyboardInterrupt:
        return 130
    return 0


if __name__ == "__main__":
    sys.exit(main())
