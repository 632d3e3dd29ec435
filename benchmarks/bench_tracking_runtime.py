"""Tracking through the distributed runtime (docs/tracking.md): lockstep speed-up over
real time for 2 robots (``tracking.toml``, 28 processes) and 6 robots
(``tracking-crowd.toml``, 84 processes), and the in-process ``cekm run`` beside it.

Each lockstep run is a full ``cekm launch SCENARIO --mode lockstep`` (world server with
its MCAP log and Foxglove views, every robot's 14 module processes, teammates' shares
over Zenoh). Speed-up = sim seconds / wall seconds of the world's tick loop (first tick's
readings to the last tick); real time is 1x by definition. Also printed: the same over
the world server's whole run once every module is alive (``wall_seconds``).

Run: python benchmarks/bench_tracking_runtime.py [--sim 30] [--port 7470]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def launch(scenario: str, sim: float, port: int, out: Path) -> dict:
    cmd = [sys.executable, "-m", "cekm_swarm", "launch", scenario, "--mode", "lockstep", "--max-time", str(sim),
           "--port", str(port), "--out", str(out), "--no-plot"]
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT, timeout=1800)
    return json.loads((out / "outcome.json").read_text())


def in_process(scenario: str, sim: float) -> float:
    from cekm_swarm.experiments.default_model import default_model
    from cekm_swarm.experiments.tracking import run_tracking
    from world import load_scenario

    model = default_model(progress=False)
    t0 = time.perf_counter()
    run_tracking(load_scenario(scenario), "cekm", model, None, sim)
    return time.perf_counter() - t0


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sim", type=float, default=30.0, help="s of sim time per run")
    p.add_argument("--port", type=int, default=7470)
    args = p.parse_args()
    print(f"{platform.node()}: {os.cpu_count()} cores; load average {os.getloadavg()[0]:.1f}")
    print(f"| scenario | robots | processes | sim s | tick loop s | speed-up (tick loop) | speed-up (whole run) "
          f"| in-process s | in-process speed-up |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    with tempfile.TemporaryDirectory() as tmp:
        for scenario in ("tracking", "tracking-crowd"):
            doc = launch(scenario, args.sim, args.port, Path(tmp) / scenario)
            n = doc["tracking"]["robots"]
            loop, whole, sim = doc["tick_loop_seconds"], doc["wall_seconds"], doc["sim_seconds"]
            ip = in_process(scenario, args.sim)
            print(f"| {scenario} | {n} | {14 * n + 1} | {sim:.1f} | {loop:.1f} | {sim / loop:.1f}x | "
                  f"{sim / whole:.1f}x | {ip:.1f} | {args.sim / ip:.0f}x |", flush=True)
    print(f"load average after: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
