"""A minimal WebSocket client speaking Foxglove's protocol, for the tests of ``cekm view --foxglove``."""

from __future__ import annotations

import base64
import json
import os
import socket
import struct


class WsClient:
    """Just enough RFC 6455 for the test: handshake, masked text frames out, frames in."""

    def __init__(self, port: int) -> None:
        self.s = socket.create_connection(("127.0.0.1", port), timeout=20)
        key = base64.b64encode(os.urandom(16)).decode()
        self.s.sendall((f"GET / HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                        f"Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n"
                        f"Sec-WebSocket-Protocol: foxglove.sdk.v1\r\n\r\n").encode())
        self.buf = b""
        while b"\r\n\r\n" not in self.buf:
            self._more()
        head, self.buf = self.buf.split(b"\r\n\r\n", 1)
        assert head.startswith(b"HTTP/1.1 101"), head

    def _more(self) -> None:
        chunk = self.s.recv(65536)
        assert chunk, "server closed the connection"
        self.buf += chunk

    def _need(self, n: int) -> None:
        while len(self.buf) < n:
            self._more()

    def frame_within(self, seconds: float) -> tuple[int, bytes] | None:
        """The next frame, or None when none is whole within ``seconds`` (a partial one stays
        buffered for the next call): for a test that must send again until an answer comes."""
        self.s.settimeout(seconds)
        try:
            return self.frame()
        except TimeoutError:
            return None
        finally:
            self.s.settimeout(20)

    def frame(self) -> tuple[int, bytes]:
        self._need(2)
        op, n, i = self.buf[0] & 15, self.buf[1] & 127, 2
        if n == 126:
            self._need(4)
            n, i = struct.unpack(">H", self.buf[2:4])[0], 4
        elif n == 127:
            self._need(10)
            n, i = struct.unpack(">Q", self.buf[2:10])[0], 10
        self._need(i + n)
        data, self.buf = self.buf[i:i + n], self.buf[i + n:]
        return op, data

    def send_json(self, obj: dict) -> None:
        data, mask = json.dumps(obj).encode(), os.urandom(4)
        assert len(data) < 126
        self.s.sendall(bytes([0x81, 0x80 | len(data)]) + mask + bytes(b ^ mask[i % 4] for i, b in enumerate(data)))
