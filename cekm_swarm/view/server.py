"""The live view's HTTP server (standard library only, loopback by default).

``/`` the page (with the current state inlined, so it draws on load), ``/state.json``
the same state as JSON, ``/events`` a Server-Sent Events stream: one ``tick`` event
(JSON of :meth:`LiveView.tick`) per change, at most ``rate`` per second.
"""

from __future__ import annotations

import json
import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from typing import Any

from .live import LiveView

PAGE = "page.html"


def _page(view: LiveView) -> bytes:
    html = resources.files(__package__).joinpath(PAGE).read_text(encoding="utf-8")
    state = json.dumps(view.init(), separators=(",", ":")).replace("</", "<\\/")
    return html.replace("/*INIT*/null", state).encode()


class ViewServer:
    """Serve ``view`` on ``host:port`` (port 0: any free one) in a background thread."""

    def __init__(self, view: LiveView, host: str = "127.0.0.1", port: int = 0, rate: float = 20.0) -> None:
        self.view = view
        self.rate = rate
        self.stopping = threading.Event()
        server = self

        class Handler(BaseHTTPRequestHandler):
            def log_message(self, *args: Any) -> None:  # quiet
                pass

            def _send(self, body: bytes, ctype: str) -> None:
                self.send_response(200)
                self.send_header("Content-Type", ctype)
                self.send_header("Content-Length", str(len(body)))
                self.send_header("Cache-Control", "no-store")
                self.end_headers()
                self.wfile.write(body)

            def do_GET(self) -> None:
                path = self.path.split("?")[0]
                if path == "/":
                    self._send(_page(server.view), "text/html; charset=utf-8")
                elif path == "/state.json":
                    self._send(json.dumps(server.view.init()).encode(), "application/json")
                elif path == "/events":
                    server._stream(self)
                else:
                    self.send_error(404, f"no such page: {path}")

        self.httpd = ThreadingHTTPServer((host, port), Handler)
        self.httpd.daemon_threads = True
        address = self.httpd.server_address  # an IP socket's: (host, port, ...)
        bound = address[0]
        self.host: str = bound if isinstance(bound, str) else bytes(bound).decode()
        self.port: int = int(address[1])
        self._thread = threading.Thread(target=self.httpd.serve_forever, name="view-http", daemon=True)
        self._thread.start()

    @property
    def url(self) -> str:
        return f"http://{self.host}:{self.port}/"

    def _stream(self, h: BaseHTTPRequestHandler) -> None:
        h.send_response(200)
        h.send_header("Content-Type", "text/event-stream")
        h.send_header("Cache-Control", "no-store")
        h.end_headers()
        version = -1
        try:
            while not self.stopping.is_set():
                if not self.view.wait_change(version, timeout=1.0):
                    h.wfile.write(b": keep-alive\n\n")
                    h.wfile.flush()
                    continue
                tick = self.view.tick()
                version = tick["version"]
                h.wfile.write(b"event: tick\ndata: " + json.dumps(tick, separators=(",", ":")).encode() + b"\n\n")
                h.wfile.flush()
                time.sleep(1.0 / self.rate)  # at most `rate` events a second; changes in between coalesce
        except (BrokenPipeError, ConnectionResetError):
            return

    def close(self) -> None:
        self.stopping.set()
        self.httpd.shutdown()
        self.httpd.server_close()
