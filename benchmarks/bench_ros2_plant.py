"""Latency of the ROS 2 plant (``cekm launch --plant ros2``): from a LaserScan's arrival at
the plant to the Twist it causes, p50 and p99, against the simulated world's sense-to-command
latency (a tick's readings out to the robot's command in) in the same benchmark run.

Each repeat runs ``lone_obstacle`` twice with the cekm controller, in real time: once against
the project's world server (baseline), once through the plant against the differential-drive
simulator of the tests (``tests/ros2/diffdrive_sim.py``: Odometry and a 360-beam LaserScan at
15 Hz over ``zenoh-ros2-sdk``). From each run's ``outcome.json``: the world's
``sense_to_command_ms``; the plant's ``sense_to_command_ms`` (the same measure: its tick's
readings out to the command in) and ``scan_to_twist_ms`` (the scan's arrival to the Twist's
put: the wait for the tick that samples the scan, up to one 0.128 s tick, is part of it).

Run: python benchmarks/bench_ros2_plant.py [--repeat 3]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tests" / "ros2"))
from ros2_helpers import write_msg_files  # noqa: E402

from cekm_swarm.runtime.config import free_port  # noqa: E402

SIM_CONFIG = {"robots": {"r1": [0.5, 1.0, 0.0]}, "bounds": [0.0, 0.0, 2.0, 2.0], "disc": [1.0, 1.0, 0.05],
              "rate_hz": 15, "body_radius": 0.03, "beams": 360}


def launch(out: Path, port: int, plant: bool) -> subprocess.Popen:
    argv = [sys.executable, "-m", "cekm_swarm", "launch", "lone_obstacle", "--mode", "realtime", "--max-time", "40",
            "--out", str(out), "--overwrite", "--no-plot", "--port", str(port)] + (["--plant", "ros2"] if plant else [])
    return subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=REPO)


def run_world(tmp: Path) -> dict:
    proc = launch(tmp / "world", free_port(), plant=False)
    proc.communicate(timeout=300)
    return json.loads((tmp / "world" / "outcome.json").read_text())


def run_plant(tmp: Path, msg_dir: Path) -> dict:
    port = free_port()
    proc = launch(tmp / "plant", port, plant=True)
    assert proc.stdout is not None
    for line in proc.stdout:  # the router is up: the robot joins it
        if "hosts the embedded Zenoh router" in line:
            break
    sim = subprocess.Popen([sys.executable, str(REPO / "tests" / "ros2" / "diffdrive_sim.py"), f"127.0.0.1:{port}",
                            str(msg_dir), "0", json.dumps(SIM_CONFIG)], stdin=subprocess.PIPE,
                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, text=True)
    try:
        proc.communicate(timeout=300)
    finally:
        sim.communicate("quit\n", timeout=30)
    return json.loads((tmp / "plant" / "outcome.json").read_text())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    print(f"load average before: {Path('/proc/loadavg').read_text().split()[:3]}")
    rows = []
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        msg_dir = write_msg_files(tmp / "msg")
        for i in range(args.repeat):
            t0 = time.perf_counter()
            world = run_world(tmp)
            plant = run_plant(tmp, msg_dir)
            rows.append((world["sense_to_command_ms"], plant["sense_to_command_ms"], plant["scan_to_twist_ms"],
                         plant["robots"]["r1"]["reached"]))
            w, p, s, reached = rows[-1]
            print(f"repeat {i + 1}: world sense-to-command p50 {w['p50']} p99 {w['p99']} ms (n {w['n']}); plant "
                  f"sense-to-command p50 {p['p50']} p99 {p['p99']} ms; scan-to-Twist p50 {s['p50']} p99 {s['p99']} ms "
                  f"(n {s['n']}); reached {reached}; {time.perf_counter() - t0:.0f} s", flush=True)
    for what, k in (("plant sense-to-command", 1), ("plant scan-to-Twist", 2)):
        for q in ("p50", "p99"):
            ratios = [r[k][q] / r[0][q] for r in rows if r[0][q] and r[k][q]]
            print(f"{what} {q} / world sense-to-command {q}: " + ", ".join(f"{x:.2f}" for x in ratios))
    print(f"load average after: {Path('/proc/loadavg').read_text().split()[:3]}; cpus {os.cpu_count()}")


if __name__ == "__main__":
    main()
