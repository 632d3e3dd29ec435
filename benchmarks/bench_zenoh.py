"""Zenoh transport costs: one-hop latency between two processes on loopback for a 2 KB
msgpack message (p50/p99), callback subscriber vs the asyncio bridge, plus the two-hop
path through a router process that the launcher's module processes use; and the cost of
encoding/decoding a 225-float field message.

Latency is one-way: the publisher stamps time.perf_counter_ns() (CLOCK_MONOTONIC, shared
by all processes of a machine) into the message; the subscriber process subtracts it
from its own clock on receipt, in the Zenoh callback (callback) or in the coroutine
after the bridge's queue (asyncio). Messages are sent at a steady rate (not a flood).

Run: python benchmarks/bench_zenoh.py [--messages 2000] [--period-ms 2]
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import platform
import statistics
import subprocess
import sys
import threading
import time
import timeit
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import msgpack  # noqa: E402
import numpy as np  # noqa: E402

from cekm_swarm.protocol import DEFAULT_KEYS, KeyKind, TargetField, decode, encode  # noqa: E402
from cekm_swarm.runtime.bridge import AsyncSubscription, Publishers  # noqa: E402
from cekm_swarm.runtime.config import free_port, open_client, open_embedded_router  # noqa: E402

KEY = "cekm/bench/latency"
PAYLOAD_BYTES = 2048
WARMUP = 200


def payload(seq: int, fill: int | None = None) -> bytes:
    """A 2 KB msgpack map carrying the send time (fixed-size ints, so every message is 2048 B)."""
    body = {"v": 1, "seq": np.uint64(seq).item() | (1 << 63), "t_ns": time.perf_counter_ns() | (1 << 63),
            "fill": b"\x00" * (_FILL if fill is None else fill)}
    return msgpack.packb(body, use_bin_type=True)


_FILL = PAYLOAD_BYTES - len(payload(0, 0)) - 1  # bin8 -> bin16 header once fill > 255 B


def pct(xs: list[float], q: float) -> float:
    xs = sorted(xs)
    return xs[min(len(xs) - 1, int(round(q / 100 * (len(xs) - 1))))]


# --------------------------------------------------------------------------- subscriber process


def child_sub(mode: str, endpoint: str, n: int) -> None:
    """Receive n messages on KEY; print the one-way latencies (us) as JSON."""
    session = open_client(endpoint)
    lat: list[float] = []
    if mode == "callback":
        done = threading.Event()

        def on_sample(sample) -> None:
            now = time.perf_counter_ns()
            m = msgpack.unpackb(sample.payload.to_bytes())
            lat.append((now - (m["t_ns"] & ~(1 << 63))) / 1e3)
            if len(lat) == n:
                done.set()

        sub = session.declare_subscriber(KEY, on_sample)
        print("READY", flush=True)
        done.wait(120)
        sub.undeclare()
    else:
        async def run() -> None:
            with AsyncSubscription(session, KEY) as sub:
                print("READY", flush=True)
                for _ in range(n):
                    rec = await sub.get()
                    now = time.perf_counter_ns()
                    m = msgpack.unpackb(rec.payload)
                    lat.append((now - (m["t_ns"] & ~(1 << 63))) / 1e3)

        asyncio.run(run())
    print(json.dumps(lat[WARMUP:]), flush=True)
    session.close()


def child_pub(endpoint: str, n: int, period: float) -> None:
    """Publish n messages on KEY every period seconds once the subscriber is there."""
    session = open_client(endpoint)
    print("READY", flush=True)
    run_pub(session, n, period)
    session.close()


def run_pub(session, n: int, period: float, express: bool = False) -> None:
    with Publishers(session, express=express) as pubs:
        if not pubs.wait_matching(KEY, 30):
            raise SystemExit("no subscriber")
        t0 = time.perf_counter()
        for i in range(n):
            due = t0 + i * period
            while (d := due - time.perf_counter()) > 0:
                time.sleep(d if d > 0.0005 else 0)
            pubs.put(KEY, payload(i))


def spawn(*args: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, __file__, *args], stdout=subprocess.PIPE, text=True)


def wait_ready(p: subprocess.Popen) -> None:
    line = p.stdout.readline()
    if not line.startswith("READY"):
        raise SystemExit(f"child failed: {line!r}")


def latency(mode: str, hops: int, n: int, period: float, express: bool = False) -> list[float]:
    """One-way latencies (us) for mode callback/asyncio over 1 hop (publisher in the
    router's process) or 2 hops (publisher process -> router process -> subscriber process)."""
    port = free_port()
    router = open_embedded_router(port)
    endpoint = f"tcp/127.0.0.1:{port}"
    sub = spawn("--child-sub", mode, endpoint, str(n + WARMUP))
    wait_ready(sub)
    try:
        if hops == 1:
            run_pub(router, n + WARMUP, period, express)
        else:
            pub = spawn("--child-pub", endpoint, str(n + WARMUP), str(period))
            wait_ready(pub)
            pub.wait(120)
        out = sub.stdout.readline()
        sub.wait(60)
        return json.loads(out)
    finally:
        for p in (sub,):
            if p.poll() is None:
                p.kill()
        router.close()


# --------------------------------------------------------------------------- codec


def codec(repeat: int = 7, number: int = 20000) -> dict[str, float]:
    """Best-of-repeat microseconds per call for the 225-float target field message."""
    a = np.random.default_rng(0).random(225)
    msg = TargetField(1.024, "r1/target", 112, a)
    data = encode(msg)
    key = DEFAULT_KEYS.field_target("r1")
    raw = {"a": a.tobytes()}
    raw_b = msgpack.packb(raw)
    cases = {
        "construct TargetField (validates)": lambda: TargetField(1.024, "r1/target", 112, a),
        "encode(TargetField 225)": lambda: encode(msg),
        "decode(key, bytes) -> TargetField": lambda: decode(key, data),
        "decode(KeyKind, bytes)": lambda: decode(KeyKind.FIELD_TARGET, data),
        "raw msgpack.packb of 1800 bytes": lambda: msgpack.packb(raw),
        "raw msgpack.unpackb + frombuffer": lambda: np.frombuffer(msgpack.unpackb(raw_b)["a"]),
    }
    out = {}
    for name, fn in cases.items():
        best = min(timeit.repeat(fn, number=number, repeat=repeat))
        out[name] = best / number * 1e6
    out["_message_bytes"] = float(len(data))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--messages", type=int, default=2000, help="Measured messages per case (after 200 warm-up).")
    ap.add_argument("--period-ms", type=float, default=2.0, help="Publishing period.")
    ap.add_argument("--child-sub", nargs=3, metavar=("MODE", "ENDPOINT", "N"), help=argparse.SUPPRESS)
    ap.add_argument("--child-pub", nargs=3, metavar=("ENDPOINT", "N", "PERIOD"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child_sub:
        child_sub(args.child_sub[0], args.child_sub[1], int(args.child_sub[2]))
        return
    if args.child_pub:
        child_pub(args.child_pub[0], int(args.child_pub[1]), float(args.child_pub[2]))
        return

    from importlib.metadata import version

    print(f"# bench_zenoh: Python {platform.python_version()}, {os.cpu_count()} CPUs, {platform.machine()}, "
          f"eclipse-zenoh {version('eclipse-zenoh')}, load average {os.getloadavg()[0]:.2f}")
    print(f"# {args.messages} messages of {len(payload(0))} B every {args.period_ms} ms per case, one-way latency")
    print(f"{'path':<44} {'p50 us':>8} {'p90 us':>8} {'p99 us':>8} {'max us':>8}")
    rows = {}
    for hops in (1, 2):
        for mode in ("callback", "asyncio"):
            lat = latency(mode, hops, args.messages, args.period_ms / 1e3)
            label = (f"{'1 hop (pub in router process)' if hops == 1 else '2 hops (pub -> router -> sub)'}, {mode}")
            rows[label] = lat
            print(f"{label:<44} {pct(lat, 50):>8.0f} {pct(lat, 90):>8.0f} {pct(lat, 99):>8.0f} {max(lat):>8.0f}")
    lat = latency("callback", 1, args.messages, args.period_ms / 1e3, express=True)
    label = "1 hop, callback, express publisher"
    print(f"{label:<44} {pct(lat, 50):>8.0f} {pct(lat, 90):>8.0f} {pct(lat, 99):>8.0f} {max(lat):>8.0f}")
    c1 = [statistics.median(v) for k, v in rows.items() if k.startswith("1 hop")]
    print(f"# asyncio bridge adds {c1[1] - c1[0]:.0f} us at p50 (1 hop)")
    print()
    res = codec()
    print(f"# codec, 225-float field message ({res.pop('_message_bytes'):.0f} B), best of 7 x 20000 calls")
    for name, us in res.items():
        print(f"{name:<44} {us:>8.2f} us")


if __name__ == "__main__":
    main()
