"""The fault link on loopback, in this process (no Zenoh): delay, order, loss per
transport, the bandwidth cap, a cut and a reset, and the log of every change."""

from __future__ import annotations

import asyncio
import json

import pytest

from cekm_swarm.runtime.faultlink import FaultLink, LinkSettings, _Direction, parse_command, parse_pair

WAIT = 10.0  # s any wait for something that must happen is bounded by (generous: shared machine)


async def echo_server() -> tuple[asyncio.AbstractServer, int]:
    async def echo(r: asyncio.StreamReader, w: asyncio.StreamWriter) -> None:
        while data := await r.read(65536):
            w.write(data)
            await w.drain()
        w.close()

    server = await asyncio.start_server(echo, "127.0.0.1", 0)
    return server, server.sockets[0].getsockname()[1]


async def tcp_link(**settings) -> tuple[FaultLink, asyncio.AbstractServer, int]:
    server, port = await echo_server()
    link = FaultLink(LinkSettings(**settings), seed=3)
    _, lport = await link.add_tcp(("127.0.0.1", 0), ("127.0.0.1", port))
    return link, server, lport


async def read_exactly(r: asyncio.StreamReader, n: int) -> bytes:
    return await asyncio.wait_for(r.readexactly(n), WAIT)


def test_tcp_round_trip_takes_twice_the_one_way_delay_and_keeps_every_byte_in_order_despite_loss():
    async def go():
        link, server, lport = await tcp_link(delay=0.05, jitter=0.02, loss=0.3)
        r, w = await asyncio.open_connection("127.0.0.1", lport)
        loop = asyncio.get_running_loop()
        t0 = loop.time()
        w.write(b"ping")
        assert await read_exactly(r, 4) == b"ping"
        assert loop.time() - t0 >= 2 * (0.05 - 0.02)  # at least the two one-way delays, less jitter
        sent = bytearray()
        for i in range(60):  # many chunks: jitter and retransmissions must not reorder them
            chunk = bytes([i]) * 100
            sent += chunk
            w.write(chunk)
            await w.drain()
            await asyncio.sleep(0.002)
        assert await read_exactly(r, len(sent)) == bytes(sent)
        assert link.stats.retransmitted["up"] + link.stats.retransmitted["down"] > 0  # loss happened: as delay
        assert link.stats.dropped == {"up": 0, "down": 0}
        w.close()
        await link.close()
        server.close()

    asyncio.run(go())


def test_a_cut_holds_tcp_bytes_and_new_connections_until_restore():
    async def go():
        link, server, lport = await tcp_link()
        r, w = await asyncio.open_connection("127.0.0.1", lport)
        w.write(b"a")
        assert await read_exactly(r, 1) == b"a"
        link.cut()
        w.write(b"held")
        r2, w2 = await asyncio.open_connection("127.0.0.1", lport)  # the proxy accepts; the router is not reached
        w2.write(b"new")
        with pytest.raises(asyncio.TimeoutError):
            await asyncio.wait_for(r.readexactly(4), 0.3)
        assert link.stats.connections == 1
        link.restore()
        assert await read_exactly(r, 4) == b"held"
        assert await read_exactly(r2, 3) == b"new"
        assert link.stats.held_during_cut["up"] >= 4 and link.stats.connections == 2
        link.reset()  # every connection closed at once
        assert await asyncio.wait_for(r.read(), WAIT) == b""
        assert await asyncio.wait_for(r2.read(), WAIT) == b""
        assert [h["event"] for h in link.history] == ["start", "listen", "cut", "restore", "reset"]
        assert link.history[-1]["connections"] == 4  # both ends of both connections
        await link.close()
        server.close()

    asyncio.run(go())


def test_the_bandwidth_cap_spreads_bytes_over_time():
    async def go():
        link, server, lport = await tcp_link(rate=100_000.0)
        r, w = await asyncio.open_connection("127.0.0.1", lport)
        loop = asyncio.get_running_loop()
        t0 = loop.time()
        w.write(b"x" * 30_000)
        assert await read_exactly(r, 30_000) == b"x" * 30_000
        assert loop.time() - t0 >= 2 * 30_000 / 100_000 * 0.95  # capped both ways
        await link.close()
        server.close()

    asyncio.run(go())


class Sink(asyncio.DatagramProtocol):
    def __init__(self, echo: bool = False) -> None:
        self.got: list[bytes] = []
        self.echo = echo
        self.changed = asyncio.Event()

    def connection_made(self, transport) -> None:
        self.transport = transport

    def datagram_received(self, data: bytes, addr) -> None:
        self.got.append(data)
        if self.echo:
            self.transport.sendto(data, addr)
        self.changed.set()


async def until(cond, what: str) -> None:
    loop = asyncio.get_running_loop()
    deadline = loop.time() + WAIT
    while not cond():
        assert loop.time() < deadline, what
        await asyncio.sleep(0.01)


def test_udp_loss_drops_and_counts_datagrams_and_a_cut_drops_all():
    async def go():
        loop = asyncio.get_running_loop()
        server_t, server = await loop.create_datagram_endpoint(lambda: Sink(echo=True), local_addr=("127.0.0.1", 0))
        link = FaultLink(LinkSettings(delay=0.01, loss=0.2), seed=7)
        _, lport = await link.add_udp(("127.0.0.1", 0), server_t.get_extra_info("sockname")[:2])
        client_t, client = await loop.create_datagram_endpoint(Sink, remote_addr=("127.0.0.1", lport))
        for i in range(200):
            client_t.sendto(i.to_bytes(2, "big"))
            await asyncio.sleep(0.001)
        up_dropped = lambda: link.stats.dropped["up"]  # noqa: E731
        await until(lambda: len(server.got) == 200 - up_dropped(), f"{len(server.got)} + {up_dropped()} != 200")
        await until(lambda: len(client.got) == len(server.got) - link.stats.dropped["down"], "echoes")
        assert 10 < up_dropped() < 80  # 20 % of 200, seeded
        link.cut()
        before, dropped = len(server.got), up_dropped()
        for _ in range(20):
            client_t.sendto(b"cut")
        await until(lambda: up_dropped() == dropped + 20, "every datagram into the cut dropped and counted")
        await asyncio.sleep(0.05)
        assert len(server.got) == before
        link.restore()
        link.set(loss=0.0)  # so the one datagram after the cut is not the 20 % that is lost
        client_t.sendto(b"back")
        await until(lambda: server.got[-1:] == [b"back"], "after restore")
        client_t.close()
        server_t.close()
        await link.close()

    asyncio.run(go())


def test_tcp_chunks_never_overtake_and_lost_ones_come_one_retransmission_timeout_late():
    link = FaultLink(LinkSettings(delay=0.1, jitter=0.05, loss=0.5), seed=1)
    d = _Direction(link, "up", ordered=True)
    times = [d.release_at(100, now=i * 0.01) for i in range(200)]
    assert times == sorted(times)
    assert max(t - i * 0.01 for i, t in enumerate(times)) >= 0.05 + link.settings.retransmit_s()
    assert link.settings.retransmit_s() == pytest.approx(0.4)
    u = _Direction(link, "up", ordered=False)
    assert sum(u.release_at(100, now=0.0) is None for _ in range(200)) == link.stats.dropped["up"] > 50


def test_every_change_is_logged_and_a_bad_setting_or_command_is_refused_by_name():
    lines: list[str] = []
    link = FaultLink(seed=0, log=lines.append)
    assert json.loads(parse_command(link, "set delay=0.1 loss=0.05 rate=none"))["delay"] == 0.1
    assert link.settings.delay == 0.1 and link.settings.loss == 0.05 and link.settings.rate is None
    parse_command(link, "cut")
    parse_command(link, "restore")
    assert [json.loads(x)["event"] for x in lines] == ["start", "set", "cut", "restore"]
    assert all("wall" in json.loads(x) for x in lines)
    for bad, needle in [("set loss=1.5", "loss must be in"), ("set delay=-1", "delay must be >= 0"),
                        ("set speed=3", "unknown setting 'speed=3'"), ("set delay=fast", "delay must be a number"),
                        ("jump", "unknown command 'jump'")]:
        with pytest.raises(ValueError, match=needle):
            parse_command(link, bad)
    assert link.settings.delay == 0.1  # a refused change leaves the link as it was
    with pytest.raises(ValueError, match="not LISTEN_HOST:PORT=TARGET_HOST:PORT"):
        parse_pair("127.0.0.1:7447")
    assert parse_pair("10.0.0.1:7448=127.0.0.1:7447") == (("10.0.0.1", 7448), ("127.0.0.1", 7447))
