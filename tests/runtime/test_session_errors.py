"""What a client is told when it cannot open a Zenoh session: nothing listening, or
something listening that is no Zenoh router it may talk to (runtime.config.open_session)."""

from __future__ import annotations

import socket
import threading

import pytest

from cekm_swarm.runtime.config import client_config, free_port, open_session
from cekm_swarm.runtime.errors import RuntimeTransportError


def test_nothing_listening_is_named_as_such():
    with pytest.raises(RuntimeTransportError, match="nothing accepts connections there"):
        open_session(client_config(f"tcp/127.0.0.1:{free_port()}"), "client session")


def test_a_listener_that_is_no_zenoh_router_is_not_called_a_router_that_wants_credentials():
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen()
    port = srv.getsockname()[1]
    stop = threading.Event()

    def answer_like_http() -> None:  # accept, say something that is not Zenoh, close
        srv.settimeout(0.2)
        while not stop.is_set():
            try:
                conn, _ = srv.accept()
            except OSError:
                continue
            with conn:
                conn.sendall(b"HTTP/1.0 400 Bad Request\r\n\r\n")

    t = threading.Thread(target=answer_like_http, daemon=True)
    t.start()
    try:
        with pytest.raises(RuntimeTransportError) as err:
            open_session(client_config(f"tcp/127.0.0.1:{port}"), "client session")
    finally:
        stop.set()
        t.join(5)
        srv.close()
    assert "accepts connections but refused a Zenoh session" in str(err.value)
    assert "or not a Zenoh router at all" in str(err.value)
