"""Start-up of a launch: every node process alive, warm (forked from the fork server)
against cold (each exec'd afresh, ``--cold-start``), and each node's memory.

For N robots (default 24: 336 node processes) in an open arena, ``cekm launch --mode
realtime`` runs a few ticks, alternately cold and warm (``--repeat`` pairs); each run's
start-up is the launcher's ``startup_s`` (from the world server's start until every node's
liveliness token is up), with the share of the machine's time the hypervisor stole
meanwhile. When the world starts ticking, every node's memory is read from
``/proc/<pid>/smaps_rollup``: unique (USS: private pages, what the process alone costs)
and proportional (PSS: shared pages split among their users). Baseline: the cold start,
measured in the same run. Goal: 336 processes alive in under 10 s on 2 cores.

Run: python benchmarks/bench_startup.py [--robots 24] [--repeat 1]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from bench_runtime_scale import scenario_text  # noqa: E402 - the same arena

from cekm_swarm.launch.cpu import host_shares, host_times, kind_of  # noqa: E402


def memory_kb(pid: int) -> tuple[int, int] | None:
    """(USS, PSS) of ``pid`` in kB, from ``smaps_rollup`` (None if it is gone)."""
    try:
        text = Path(f"/proc/{pid}/smaps_rollup").read_text()
    except OSError:
        return None
    f = {}
    for line in text.splitlines()[1:]:
        name, _, rest = line.partition(":")
        parts = rest.split()
        if parts and parts[0].isdigit():
            f[name.strip()] = int(parts[0])
    return f.get("Private_Clean", 0) + f.get("Private_Dirty", 0), f.get("Pss", 0)


def launch(n: int, warm: bool, port: int, tmp: Path) -> dict:
    sc = tmp / f"scale{n}.toml"
    sc.write_text(scenario_text(n))
    out = tmp / ("warm" if warm else "cold")
    argv = [sys.executable, "-m", "cekm_swarm", "launch", str(sc), "--mode", "realtime", "--max-time", "1.5",
            "--out", str(out), "--overwrite", "--no-plot", "--port", str(port)] + ([] if warm else ["--cold-start"])
    h0 = host_times()
    t0 = time.perf_counter()
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    mem: dict[str, tuple[int, int]] = {}
    h1 = None
    lines = []
    assert proc.stdout is not None
    for line in proc.stdout:
        lines.append(line)
        if "world started ticking" in line and not mem:
            h1 = host_times()
            pids = json.loads((out / "pids.json").read_text())
            for label, pid in pids.items():
                m = memory_kb(pid)
                if m is not None and "/" in label and not label.startswith(("world/", "launch/")):
                    mem[label] = m
    code = proc.wait()
    wall = time.perf_counter() - t0
    if code != 0:
        return {"warm": warm, "error": "".join(lines[-20:])}
    outcome = json.loads((out / "outcome.json").read_text())
    by_kind: dict[str, list[tuple[int, int]]] = {}
    for label, m in mem.items():
        by_kind.setdefault(kind_of(label), []).append(m)
    return {"warm": warm, "processes": outcome["launcher"]["modules"], "startup_s": outcome["launcher"]["startup_s"],
            "wall_s": round(wall, 1), "steal": host_shares(h0, h1).get("steal"),
            "memory_kb": {k: {"uss": statistics.median(u for u, _ in v), "pss": statistics.median(p for _, p in v)}
                          for k, v in sorted(by_kind.items())},
            "pss_total_mb": round(sum(p for _, p in mem.values()) / 1024, 1)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robots", type=int, default=24)
    ap.add_argument("--repeat", type=int, default=1, help="cold/warm pairs")
    ap.add_argument("--port", type=int, default=7471)
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(args.repeat):
            for warm in (False, True):
                r = launch(args.robots, warm, args.port, Path(tmp))
                rows.append(r)
                what = "warm" if warm else "cold"
                if "error" in r:
                    print(f"{what}: failed\n{r['error']}")
                    continue
                steal = "?" if r["steal"] is None else f"{100 * r['steal']:.0f}%"
                mem = ", ".join(f"{k} USS {v['uss'] / 1024:.1f} / PSS {v['pss'] / 1024:.1f} MB"
                                for k, v in r["memory_kb"].items())
                print(f"[{i + 1}] {what}: {r['processes']} processes alive after {r['startup_s']:.1f} s "
                      f"(stolen {steal}); per node (median) {mem}; all nodes' PSS {r['pss_total_mb']} MB", flush=True)
    ok = [r for r in rows if "error" not in r]
    cold = [r["startup_s"] for r in ok if not r["warm"]]
    warm = [r["startup_s"] for r in ok if r["warm"]]
    print(f"load average {os.getloadavg()[0]:.1f}")
    if cold and warm:
        c, w = statistics.median(cold), statistics.median(warm)
        pc = statistics.median(r["pss_total_mb"] for r in ok if not r["warm"])
        pw = statistics.median(r["pss_total_mb"] for r in ok if r["warm"])
        print(f"{args.robots} robots: cold {c:.1f} s, warm {w:.1f} s: {c / w:.1f}x faster (goal: 336 processes "
              f"alive in < 10 s); nodes' total PSS {pc:.0f} MB cold, {pw:.0f} MB warm ({pw / pc:.2f}x)")
    print(json.dumps(rows))


if __name__ == "__main__":
    main()
