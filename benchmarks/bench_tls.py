"""What mutual TLS costs: opening a client session and a message's round trip through a
router on loopback, with the three router setups of deploy/:

- ``tcp``: the embedded router (plain TCP, no access control): the baseline;
- ``tcp+acl``: deploy/router.json5 (user/password, access control);
- ``tls+acl``: deploy/tls/router.json5 (mutual TLS, access control by certificate name).

The round trip: one session puts on a key, a second session's subscriber puts it back on
another key, the first waits for it (both log in as ``operator``, who may use any key).
Certificates come from deploy/make-certs.sh in a temporary directory. No speed goal: the
numbers are for the deployment notes (deploy/README.md).

Run: python benchmarks/bench_tls.py [--opens 20] [--pings 500]
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path

import zenoh

from cekm_swarm.runtime.config import client_config, embedded_router_config, free_port, load_config, open_session

DEPLOY = Path(__file__).resolve().parents[1] / "deploy"


def setups(tmp: Path) -> dict[str, tuple[zenoh.Config, Callable[[], zenoh.Config]]]:
    """name -> (router config, function making an operator client config for an endpoint)."""
    subprocess.run([str(DEPLOY / "make-certs.sh"), str(tmp / "certs")], check=True, capture_output=True,
                   env=dict(os.environ, HOSTS="operator"))
    creds = tmp / "credentials.txt"
    shutil.copy(DEPLOY / "credentials.example.txt", creds)
    out = {}
    port = free_port()
    out["tcp"] = (embedded_router_config(port), lambda: client_config(f"tcp/127.0.0.1:{port}"))
    port2 = free_port()
    out["tcp+acl"] = (load_config(DEPLOY / "router.json5", {"listen/endpoints": [f"tcp/127.0.0.1:{port2}"],
                                                           "transport/auth/usrpwd/dictionary_file": str(creds)}),
                      lambda: load_config(DEPLOY / "operator.json5", {"connect/endpoints": [f"tcp/127.0.0.1:{port2}"]}))
    port3 = free_port()
    out["tls+acl"] = (load_config(DEPLOY / "tls" / "router.json5", {"listen/endpoints": [f"tls/127.0.0.1:{port3}"]}),
                      lambda: load_config(DEPLOY / "tls" / "operator.json5",
                                          {"connect/endpoints": [f"tls/127.0.0.1:{port3}"]}))
    return out


def measure(
    router_config: zenoh.Config, client: Callable[[], zenoh.Config], opens: int, pings: int
) -> tuple[float, float, float]:
    """Median session-open time (ms), median and 99th-percentile round trip (us)."""
    router = open_session(router_config, "router")
    try:
        open_session(client(), "warm-up").close()  # the process's first session pays one-off costs
        open_ms = []
        for _ in range(opens):
            t = time.perf_counter()
            s = open_session(client(), "client")
            open_ms.append((time.perf_counter() - t) * 1e3)
            s.close()
        a, b = open_session(client(), "pinger"), open_session(client(), "echo")
        pong_pub = b.declare_publisher("cekm/bench/pong")
        b_sub = b.declare_subscriber("cekm/bench/ping", lambda s: pong_pub.put(s.payload))
        got = threading.Event()
        a_sub = a.declare_subscriber("cekm/bench/pong", lambda s: got.set())
        ping = a.declare_publisher("cekm/bench/ping")
        rtt = []
        for i in range(pings + 20):  # the first 20 warm up (and wait for the routes)
            got.clear()
            t = time.perf_counter()
            ping.put(b"x" * 64)
            if not got.wait(5.0):
                raise RuntimeError("no echo in 5 s")
            if i >= 20:
                rtt.append((time.perf_counter() - t) * 1e6)
        a_sub.undeclare(), b_sub.undeclare()
        a.close(), b.close()
    finally:
        router.close()
    rtt.sort()
    return statistics.median(open_ms), statistics.median(rtt), rtt[int(0.99 * (len(rtt) - 1))]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--opens", type=int, default=20)
    ap.add_argument("--pings", type=int, default=500)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as d:
        here = os.getcwd()
        os.chdir(d)  # the TLS configs name certs/ relative to the working directory
        try:
            results = {name: measure(r, c, args.opens, args.pings) for name, (r, c) in setups(Path(d)).items()}
        finally:
            os.chdir(here)
    base = results["tcp"]
    print(f"{'setup':8} {'open ms':>8} {'ratio':>6} {'rtt p50 us':>11} {'ratio':>6} {'rtt p99 us':>11}")
    for name, (o, p50, p99) in results.items():
        print(f"{name:8} {o:8.2f} {o / base[0]:6.2f} {p50:11.0f} {p50 / base[1]:6.2f} {p99:11.0f}")


if __name__ == "__main__":
    main()
