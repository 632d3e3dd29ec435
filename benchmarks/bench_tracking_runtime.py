"""Tracking through the distributed runtime (docs/tracking.md): lockstep speed-up over
real time for 2 robots (``tracking.toml``, 28 processes) and 6 robots
(``tracking-crowd.toml``, 84 processes), and the in-process ``cekm run`` beside it.

Each lockstep run is a full ``cekm launch SCENARIO --mode lockstep`` (world server with
its MCAP log and Foxglove views, every robot's 14 module processes, teammates' shares
over Zenoh). Speed-up = sim seconds / wall seconds of the world's tick loop (first tick's
readings to the last tick); real time is 1x by definition. Also printed: the same over
the world server's whole run once every module is alive (``wall_seconds``).

Each scenario runs twice per round, alternating: as launched (the world holds unchanged
readings, docs/runtime.md) and, the baseline measured in the same run, with
``--send-every-reading`` (every reading every tick, as before held readings). Each row says
where the tick loop's CPU went by kind of process and how much of the machine's CPU time
the hypervisor stole meanwhile (``launcher.cpu.host`` in outcome.json): on a shared
virtual machine the same build's speed-up moves by a factor of two with it. The summary
gives the best and the median speed-up per scenario and variant, and the ratio.
Goal: tracking-crowd at 20x real time or more.

Run: python benchmarks/bench_tracking_runtime.py [--sim 30] [--repeats 3] [--port 7470]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

VARIANTS = {"held": (), "every reading": ("--send-every-reading",)}


def launch(scenario: str, sim: float, port: int, out: Path, extra: tuple[str, ...] = ()) -> dict:
    cmd = [sys.executable, "-m", "cekm_swarm", "launch", scenario, "--mode", "lockstep", "--max-time", str(sim),
           "--port", str(port), "--out", str(out), "--no-plot", *extra]
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT, timeout=1800)
    return json.loads((out / "outcome.json").read_text())


def in_process(scenario: str, sim: float) -> float:
    from cekm_swarm.experiments.default_model import default_model
    from cekm_swarm.experiments.tracking_run import run_tracking
    from world import load_scenario

    model = default_model(progress=False)
    t0 = time.perf_counter()
    run_tracking(load_scenario(scenario), "cekm", model, None, sim)
    return time.perf_counter() - t0


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sim", type=float, default=30.0, help="s of sim time per run")
    p.add_argument("--port", type=int, default=7470)
    p.add_argument("--repeats", type=int, default=3, help="runs of each scenario (alternating)")
    args = p.parse_args()
    print(f"{platform.node()}: {os.cpu_count()} cores; load average {os.getloadavg()[0]:.1f}")
    print("| scenario | variant | run | robots | processes | sim s | tick loop s | speed-up (tick loop) "
          "| speed-up (whole run) | CPU ms/tick (by kind) | host stolen | in-process s | in-process speed-up |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---|---:|---:|---:|")
    speedups: dict[tuple[str, str], list[tuple[float, float]]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(args.repeats):
            for scenario in ("tracking", "tracking-crowd"):
                ip = in_process(scenario, args.sim)
                for variant, extra in VARIANTS.items():
                    doc = launch(scenario, args.sim, args.port, Path(tmp) / f"{scenario}-{i}-{len(extra)}", extra)
                    n = doc["tracking"]["robots"]
                    loop, whole, sim = doc["tick_loop_seconds"], doc["wall_seconds"], doc["sim_seconds"]
                    cpu = doc.get("launcher", {}).get("cpu", {})
                    steal = cpu.get("host", {}).get("steal", float("nan"))
                    speedups.setdefault((scenario, variant), []).append((sim / loop, steal))
                    kinds = ", ".join(f"{k} {v:.1f}" for k, v in cpu.get("ms_per_tick", {}).items() if v >= 0.05)
                    print(f"| {scenario} | {variant} | {i + 1} | {n} | {doc['launcher']['modules'] + 1} | {sim:.1f} | "
                          f"{loop:.1f} | {sim / loop:.1f}x | {sim / whole:.1f}x | "
                          f"{cpu.get('total_ms_per_tick', float('nan')):.1f} ({kinds}) | {100 * steal:.0f} % | "
                          f"{ip:.1f} | {args.sim / ip:.0f}x |", flush=True)
    for (scenario, variant), runs in speedups.items():
        best = max(runs)
        print(f"{scenario}, {variant}: speed-up best {best[0]:.1f}x (host stole {100 * best[1]:.0f} %), median "
              f"{statistics.median(r[0] for r in runs):.1f}x over {len(runs)} runs")
    for scenario in ("tracking", "tracking-crowd"):
        held = statistics.median(r[0] for r in speedups[(scenario, "held")])
        every = statistics.median(r[0] for r in speedups[(scenario, "every reading")])
        print(f"{scenario}: held readings {held / every:.2f}x the speed-up of every reading (medians)")
    print(f"goal: tracking-crowd >= 20x. load average after: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
