"""free_port: a port outside the kernel's ephemeral range, free when returned."""

from __future__ import annotations

import socket

from cekm_swarm.runtime import config
from cekm_swarm.runtime.config import ephemeral_ports, free_port


def test_a_free_port_lies_outside_the_ephemeral_range_and_binds():
    first, last = ephemeral_ports()
    for _ in range(20):
        port = free_port()
        assert not first <= port <= last, (port, first, last)
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
            s.bind(("127.0.0.1", port))


def test_a_port_in_use_is_never_returned(monkeypatch):
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as held:
        held.bind(("127.0.0.1", 0))
        busy = held.getsockname()[1]
        monkeypatch.setattr(config.random.Random, "sample", lambda self, pool, k: [busy] * k)
        port = free_port()  # every draw is the busy port: the kernel's choice is the way out
        assert port != busy
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
            s.bind(("127.0.0.1", port))


def test_the_range_is_read_from_the_kernel_file_or_defaults(tmp_path):
    f = tmp_path / "ip_local_port_range"
    f.write_text("40000\t50000\n")
    assert ephemeral_ports(f) == (40000, 50000)
    f.write_text("garbage")
    assert ephemeral_ports(f) == (32768, 60999)
    assert ephemeral_ports(tmp_path / "missing") == (32768, 60999)
