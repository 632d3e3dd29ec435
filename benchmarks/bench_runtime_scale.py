"""How many robots (each with all 14 module processes) run in real time on this machine.

For N = 1, 2, 4, 8, 12, 16 (or --robots) robots in an open arena, each driving 1.5 m to
its own goal, `cekm launch --mode realtime` runs for --sim seconds; the world server
counts a deadline miss whenever a robot's latest command at a tick boundary is older
than that tick (its fields and command did not make it within 128 ms). Beside misses and
sense-to-command latency it prints where the tick loop's CPU went (the launcher's
``launcher.cpu`` in outcome.json: ms of CPU per tick by kind of process, from /proc):
2 cores give 256 ms of CPU per 128 ms tick, and the share of the machine's CPU time the
hypervisor stole meanwhile (a shared virtual machine's capacity moves with it). Baselines,
both measured in the same run: the same run with one robot, and the floor
(``benchmarks/floor.py``): as many bare Python processes as the run has modules, each woken
by one Zenoh message per tick and publishing one reply. Per kind of module (target,
obstacle, motor) it prints the CPU per process per tick and its ratio to the floor's.
Goals (issue 23): 32 robots, 448 module processes, with no deadline miss at low steal;
each module's CPU per tick within 1.5x of the floor.

Run: python benchmarks/bench_runtime_scale.py [--robots 1,2,4,8,16,24,32] [--sim 10] [--no-floor]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

FLOOR = Path(__file__).resolve().parent / "floor.py"


def checkout_env() -> dict[str, str]:
    """The environment of a child process: this checkout's package first (installed or not;
    a PYTHONPATH already set, as an A/B of two checkouts sets it, comes first)."""
    root = str(FLOOR.parent.parent)
    return {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in (os.environ.get("PYTHONPATH"), root) if p)}


def measure_floor(processes: int, seconds: float) -> dict:
    """The floor at this many processes, in a fresh process (it forks before any Zenoh session)."""
    done = subprocess.run([sys.executable, str(FLOOR), "--processes", str(processes), "--seconds", str(seconds)],
                          capture_output=True, text=True, env=checkout_env())
    if done.returncode != 0:
        return {"error": done.stderr[-500:]}
    return json.loads(done.stdout.strip().splitlines()[-1])


def scenario_text(n: int) -> str:
    cols = math.ceil(math.sqrt(n))
    size = 2.0 + 0.5 * cols
    lines = ['name = "scale"', f'description = "{n} robots in the open"', "seed = 1", "[arena]",
             f"bounds = [0.0, 0.0, {size + 1.5}, {size}]"]
    for i in range(n):
        x, y = 0.5 + 0.5 * (i % cols), 0.5 + 0.5 * (i // cols)
        lines += ["[[robots]]", f'id = "r{i + 1}"', f"start = [{x}, {y}, 0.0]", f'goal = "g{i + 1}"']
        lines += ["[[targets]]", f'id = "g{i + 1}"', f"position = [{x + 1.5}, {y}]"]
    return "\n".join(lines) + "\n"


def run(n: int, sim: float, port: int) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        sc = Path(tmp) / f"scale{n}.toml"
        sc.write_text(scenario_text(n))
        t0 = time.perf_counter()
        proc = subprocess.run([sys.executable, "-m", "cekm_swarm", "launch", str(sc), "--mode", "realtime",
                               "--max-time", str(sim), "--out", str(Path(tmp) / "out"), "--no-plot", "--port",
                               str(port)], capture_output=True, text=True, env=checkout_env())
        wall = time.perf_counter() - t0
        if proc.returncode != 0:
            return {"robots": n, "error": proc.stdout[-2000:] + proc.stderr[-2000:]}
        outcome = json.loads((Path(tmp) / "out" / "outcome.json").read_text())
    ticks = round(outcome.get("sim_time_s", sim) / 0.128) if "sim_time_s" in outcome else round(sim / 0.128)
    return {"robots": n, "modules": n * 14, "deadline_misses": outcome.get("deadline_misses"),
            "robot_ticks": n * ticks, "latency_ms": outcome.get("sense_to_command_ms"),
            "startup_s": outcome.get("launcher", {}).get("startup_s"), "wall_s": round(wall, 1),
            "cpu": outcome.get("launcher", {}).get("cpu", {})}


KINDS = ("target", "obstacle", "motor")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robots", default="1,2,4,8,16,24,32")
    ap.add_argument("--sim", type=float, default=10.0, help="sim (= wall) seconds of each run")
    ap.add_argument("--port", type=int, default=7461)
    ap.add_argument("--no-floor", action="store_true", help="skip the floor processes' measurement")
    args = ap.parse_args()
    rows = []
    for n in (int(x) for x in args.robots.split(",")):
        row = run(n, args.sim, args.port)
        if not args.no_floor and "error" not in row:
            row["floor"] = measure_floor(n * 14, args.sim)
        rows.append(row)
        print(f"  {n} robots done", file=sys.stderr, flush=True)
    base = rows[0]
    print(f"load average {os.getloadavg()[0]:.1f} (2 cores: 256 ms of CPU per 128 ms tick)")
    print(f"{'robots':>6} {'modules':>8} {'misses':>7} {'robot-ticks':>12} {'miss %':>7} {'lat p50 ms':>11} "
          f"{'lat p99 ms':>11} {'startup s':>10} {'CPU ms/tick':>12} {'per robot':>10} {'x 1 robot':>9} {'stolen':>7}  "
          f"split (ms/tick)")
    base_cpu = (base.get("cpu") or {}).get("ms_per_robot_tick")
    for r in rows:
        if "error" in r:
            print(f"{r['robots']:>6} failed: {r['error'][-300:]}")
            continue
        lat = r["latency_ms"] or {}
        cpu = r.get("cpu") or {}
        pct = 100.0 * r["deadline_misses"] / max(1, r["robot_ticks"])
        per = cpu.get("ms_per_robot_tick", math.nan)
        ratio = per / base_cpu if base_cpu else math.nan
        split = ", ".join(f"{k} {v:.1f}" for k, v in cpu.get("ms_per_tick", {}).items())
        stolen = cpu.get("host", {}).get("steal")
        steal = "?" if stolen is None else f"{100 * stolen:.0f}%"
        print(f"{r['robots']:>6} {r['modules']:>8} {r['deadline_misses']:>7} {r['robot_ticks']:>12} {pct:>6.1f}% "
              f"{lat.get('p50', math.nan):>11} {lat.get('p99', math.nan):>11} {r['startup_s']:>10} "
              f"{cpu.get('total_ms_per_tick', math.nan):>12} {per:>10} {ratio:>9.2f} {steal:>7}  {split}")
    if not args.no_floor:
        print()
        print("CPU per process per tick (ms) by kind, against the floor's (a bare process woken by one message per "
              "tick)")
        print(f"{'robots':>6} {'floor':>7} {'stolen':>7} " + " ".join(f"{k:>16}" for k in KINDS))
        for r in rows:
            if "error" in r or "ms_per_process_tick" not in r.get("floor", {}):
                continue
            f = r["floor"]["ms_per_process_tick"]
            per = (r.get("cpu") or {}).get("ms_per_process_tick", {})
            stolen = r["floor"].get("host", {}).get("steal")
            cells = [f"{per[k]:>7.3f} ({per[k] / f:>4.1f}x)" if k in per and f > 0 else f"{'-':>16}" for k in KINDS]
            steal = "?" if stolen is None else f"{100 * stolen:.0f}%"
            print(f"{r['robots']:>6} {f:>7.3f} {steal:>7} " + " ".join(cells))
    ok = [r["robots"] for r in rows if "error" not in r and r["deadline_misses"] == 0]
    print(f"baseline (1 robot): {base.get('deadline_misses')} misses; largest N with no deadline miss: "
          f"{max(ok) if ok else 'none'} (goal: 32)")
    print(json.dumps(rows))


if __name__ == "__main__":
    main()
