"""Large messages from an outside client against a lockstep run (docs/robustness.md).

``cekm launch concave --mode lockstep --seed 4`` (313 ticks) while a client publishes ten
messages of zeros, one every 4 ticks from tick 20, on one key: a key only the world's
recorder hears (the baseline), the motor's key, an obstacle module's key. Prints, per
case, the re-published ticks (each a 1 s wait for a command), the run's wall seconds and
its ratio to the baseline's, and how many of the ten messages the module counted.

Run: python benchmarks/bench_large_messages.py [--size 1048576] [--port 7462]
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import zenoh

from cekm_swarm.protocol import DEFAULT_KEYS as K
from cekm_swarm.protocol import Clock, MessageError, decode
from cekm_swarm.runtime.config import open_client


def wait_tick(sub, past: int, timeout: float) -> int:
    """The world's tick once it is past ``past`` (from a ring channel: no callback)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        sample = sub.try_recv()
        if sample is None:
            time.sleep(0.005)
            continue
        try:
            msg = decode(K.world_clock(), sample.payload.to_bytes())
        except MessageError:
            continue
        if isinstance(msg, Clock) and msg.tick > past:
            return msg.tick
    raise TimeoutError(f"the world did not pass tick {past}")


def case(key: str, size: int, port: int, out: Path) -> dict:
    proc = subprocess.Popen([sys.executable, "-m", "cekm_swarm", "launch", "concave", "--mode", "lockstep", "--seed",
                             "4", "--max-time", "40", "--no-plot", "--port", str(port), "--out", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    started = threading.Event()

    def read() -> None:
        for line in proc.stdout:
            if "world started ticking" in line:
                started.set()

    threading.Thread(target=read, daemon=True).start()
    if not started.wait(120):
        proc.kill()
        raise RuntimeError("the launch did not start ticking")
    session = open_client(f"tcp/127.0.0.1:{port}")
    sub = session.declare_subscriber(K.world_clock(), zenoh.handlers.RingChannel(16))
    tick = wait_tick(sub, 19, 60)
    for _ in range(10):
        session.put(key, bytes(size), congestion_control=zenoh.CongestionControl.BLOCK)
        tick = wait_tick(sub, tick + 3, 120)
    session.close()
    proc.wait(300)
    o = json.loads((out / "outcome.json").read_text())
    counted = None
    m = re.match(r"cekm/r1/(field/obstacle/\d+|sense/range/(\d+))", key)
    if m:
        log = out / "logs" / ("r1-motor.log" if "field" in key else f"r1-obstacle-{m.group(2)}.log")
        doc = json.loads(re.findall(r"DROPS (\{.*\})", log.read_text())[0])
        counted = doc["dropped"].get(key, 0)
    return {"republished": o["republished"], "wall_s": o["wall_seconds"], "module_counted": counted}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--size", type=int, default=1 << 20)
    p.add_argument("--port", type=int, default=7462)
    args = p.parse_args()
    keys = ["cekm/fuzz/big", K.field_obstacle("r1", 3), K.sense_range("r1", 3)]
    results = {}
    with tempfile.TemporaryDirectory() as tmp:
        for i, key in enumerate(keys):
            results[key] = case(key, args.size, args.port, Path(tmp) / str(i))
    base = results[keys[0]]["wall_s"]
    print(f"10 messages of {args.size} bytes, lockstep concave seed 4 (313 ticks)")
    for key, r in results.items():
        print(f"{key:28s} re-published {r['republished']:3d}  wall {r['wall_s']:6.1f} s  "
              f"x{r['wall_s'] / base:5.1f} of the baseline  module counted {r['module_counted']}")


if __name__ == "__main__":
    main()
