"""Faults: how much of a run a SIGKILLed world server loses, and how long clients take to
reconnect after their router is restarted.

* SIGKILL loss: the world server alone in real time (``lone_obstacle``; its readings go
  out whether or not a robot answers), joined to a router with a subscriber beside it.
  The world is SIGKILLed after K s of sim time (K = 3, 4.5, 6), its log recovered
  (``recover_log``); lost = the subscriber's last stamp minus the recovered log's last
  stamp (s of sim time = s of wall time in real time), and the messages the subscriber saw
  that the recovered log lacks.
* reconnect: two client sessions (a publisher at 100 Hz and a subscriber) on a router
  process; the router is SIGKILLed, started again on the same port after an outage of
  O s (O = 1, 3, 6), and the time from the new router being ready to the first message
  through it is measured, with the clients' retry settings
  (``runtime.config.RECONNECT_RETRY``) and, as the baseline in the same run, Zenoh's
  default retry (first after 1 s, doubling to 4 s).

Run: python benchmarks/bench_faults.py [--repeat 2]
"""

from __future__ import annotations

import argparse
import os
import platform
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import zenoh

from cekm_swarm.protocol import DEFAULT_KEYS as K
from cekm_swarm.protocol import peek
from cekm_swarm.runtime.config import client_config, free_port, open_session
from cekm_swarm.runtime.mcap_log import read_messages, recover_log

ROUTER = ("import sys, threading\n"
          "from cekm_swarm.runtime.config import open_embedded_router\n"
          "r = open_embedded_router(int(sys.argv[1]))\n"
          "print('READY', flush=True)\n"
          "threading.Event().wait()\n")


def start_router(port: int) -> tuple[subprocess.Popen, float]:
    """A router process on ``port``, and the monotonic time it said READY."""
    p = subprocess.Popen([sys.executable, "-c", ROUTER, str(port)], stdout=subprocess.PIPE, text=True)
    assert p.stdout is not None and p.stdout.readline().strip() == "READY"
    return p, time.monotonic()


def kill(p: subprocess.Popen) -> None:
    if p.poll() is None:
        p.send_signal(signal.SIGKILL)
    p.wait(timeout=10)


def default_retry_config(endpoint: str) -> zenoh.Config:
    """A client config like ours but with Zenoh's own (default) reconnect retry."""
    config = zenoh.Config()
    for key, value in (("mode", '"client"'), ("connect/endpoints", f'["{endpoint}"]'),
                       ("scouting/multicast/enabled", "false"), ("transport/shared_memory/enabled", "false")):
        config.insert_json5(key, value)
    return config


def reconnect_once(outage: float, ours: bool) -> float:
    port = free_port()
    endpoint = f"tcp/127.0.0.1:{port}"
    router, _ = start_router(port)
    make = (lambda: client_config(endpoint)) if ours else (lambda: default_retry_config(endpoint))
    pub_s, sub_s = open_session(make()), open_session(make())
    arrivals: list[float] = []
    sub = sub_s.declare_subscriber("bench/x", lambda s: arrivals.append(time.monotonic()))
    pub = pub_s.declare_publisher("bench/x")
    stop = threading.Event()

    def publish() -> None:
        while not stop.wait(0.01):
            pub.put(b"x")

    t = threading.Thread(target=publish, daemon=True)
    t.start()
    try:
        deadline = time.monotonic() + 10
        while not arrivals and time.monotonic() < deadline:
            time.sleep(0.01)
        kill(router)
        time.sleep(outage)
        router, ready = start_router(port)
        deadline = ready + 30
        while time.monotonic() < deadline and not any(a > ready for a in arrivals):
            time.sleep(0.005)
        after = [a for a in arrivals if a > ready]
        return after[0] - ready if after else float("inf")
    finally:
        stop.set()
        t.join()
        sub.undeclare()
        pub.undeclare()
        pub_s.close()
        sub_s.close()
        kill(router)


def sigkill_loss_once(kill_at: float) -> tuple[float, int, int]:
    """(s lost, messages the subscriber saw that the recovered log lacks, messages seen)."""
    port = free_port()
    endpoint = f"tcp/127.0.0.1:{port}"
    router, _ = start_router(port)
    session = open_session(client_config(endpoint))
    seen: list[tuple[str, int, bytes]] = []
    enough = threading.Event()

    def on_sample(sample: zenoh.Sample) -> None:
        payload = sample.payload.to_bytes()
        _, stamp = peek(payload)
        if stamp is not None:
            seen.append((str(sample.key_expr), round(stamp * 1e9), payload))
            if stamp >= kill_at:
                enough.set()

    sub = session.declare_subscriber(K.everything(), on_sample)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        world = subprocess.Popen([sys.executable, "-m", "world.server", "lone_obstacle", "--connect", endpoint,
                                  "--out", str(out), "--mode", "realtime", "--max-time", "120"],
                                 stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            if not enough.wait(60):
                raise SystemExit("the world server did not reach the kill time")
            world.send_signal(signal.SIGKILL)
            world.wait(timeout=10)
        finally:
            kill(world)
        sub.undeclare()
        session.close()
        kill(router)
        rep = recover_log(out / "run.mcap", out / "recovered.mcap")
        logged = {(m.topic, m.log_time, m.data) for m in read_messages(rep.output) if m.message_encoding == "msgpack"}
    last_seen = max(t for _, t, _ in seen)
    last_logged = max(t for _, t, _ in logged)
    missing = sum(1 for m in seen if m not in logged)
    return (last_seen - last_logged) / 1e9, missing, len(seen)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeat", type=int, default=2)
    args = ap.parse_args()
    print(f"{platform.node()}: {os.cpu_count()} cores, Python {platform.python_version()}")
    print("\nSIGKILL of the world server (real time), log recovered:")
    print(f"  {'killed at s':>11} {'lost s':>7} {'msgs lost':>9} {'msgs seen':>9}")
    losses = []
    for kill_at in (3.0, 4.5, 6.0):
        for _ in range(args.repeat):
            lost, missing, n = sigkill_loss_once(kill_at)
            losses.append(lost)
            print(f"  {kill_at:>11.1f} {lost:>7.3f} {missing:>9d} {n:>9d}")
    print(f"  worst {max(losses):.3f} s lost, mean {statistics.mean(losses):.3f} s")
    print("\nreconnect after a router restart: s from the new router ready to the first message")
    print(f"  {'outage s':>8} {'ours':>7} {'zenoh default':>13} {'default/ours':>12}")
    for outage in (1.0, 3.0, 6.0):
        ours = [reconnect_once(outage, True) for _ in range(args.repeat)]
        base = [reconnect_once(outage, False) for _ in range(args.repeat)]
        mo, mb = statistics.median(ours), statistics.median(base)
        print(f"  {outage:>8.1f} {mo:>7.3f} {mb:>13.3f} {mb / mo:>12.1f}")


if __name__ == "__main__":
    main()
