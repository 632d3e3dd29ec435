"""A long run: does anything drift? N minutes (default 60) of real time with 8 robots.

`cekm launch` runs an 8-robot tracking scenario (``tracking-crowd`` with two more robots:
tracking never ends early and keeps every robot moving) in real time for ``--minutes``.
Every ``--sample-every`` s the benchmark reads, from ``/proc``, the resident memory of every
process of the run (by kind: world server, launcher, fork server, and each kind of node),
the machine's stolen and idle time since the last sample, and the log's size on disk and
the age of its last write (the flush lag: the recorder writes a chunk out at least every
half second). At the end it reads the world's ``outcome.json`` (deadline misses, by
minute) and runs ``cekm log info`` and ``cekm log cat`` on the log, timed.

Baseline, measured in the same run: each kind's resident memory at the end of minute 1
(so the start-up's allocations and the first minute's caches are in it); the benchmark
prints each later minute as a ratio of it, with the host's steal beside it.
Goal: every kind's growth after minute 1 under 5 %, the world server included.

Run: python benchmarks/bench_soak.py [--minutes 60] [--robots 8] [--record full|lean]
     [--max-log-size 500M] [--out DIR] [--port 7481]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from cekm_swarm.launch.cpu import host_times, kind_of  # noqa: E402

EXTRA_ROBOTS = [(1.2, 0.9), (2.7, 0.8), (0.6, 1.2), (2.4, 1.2), (1.5, 1.4), (0.3, 1.5), (2.7, 1.6), (1.0, 1.6)]


def scenario_text(robots: int) -> str:
    """tracking-crowd (six robots) with ``robots - 6`` more, started north of its rows."""
    text = (ROOT / "world" / "scenarios" / "tracking-crowd.toml").read_text()
    if robots < 6:
        cut = [m.start() for m in re.finditer(r"^\[\[robots\]\]", text, re.M)][robots]
        first_target = text.index("[[targets]]")
        text = text[:cut] + text[first_target:]
    extra = "".join(f'[[robots]]\nid = "r{7 + i}"\nstart = [{x}, {y}, 1.5707963267948966]\n\n'
                    for i, (x, y) in enumerate(EXTRA_ROBOTS[:max(0, robots - 6)]))
    i = text.index("[[targets]]")
    text = text[:i] + extra + text[i:]
    return text.replace('name = "tracking-crowd"', f'name = "soak-{robots}"')


def rss_kb(pid: int) -> int | None:
    try:
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1])
    except OSError:
        return None
    return None


def log_files(out: Path) -> list[Path]:
    return sorted(out.glob("run*.mcap"), key=lambda p: (len(p.name), p.name))


def sample(out: Path, launcher_pid: int, host_prev) -> tuple[dict, tuple]:
    try:
        pids = json.loads((out / "pids.json").read_text())
    except (OSError, ValueError):
        pids = {}
    pids["launch/launcher"] = launcher_pid
    by_kind: dict[str, list[int]] = {}
    for label, pid in pids.items():
        kb = rss_kb(pid)
        if kb is not None:
            by_kind.setdefault(kind_of(label), []).append(kb)
    host = host_times()
    steal = idle = None
    if host is not None and host_prev is not None:
        total = host[0] - host_prev[0]
        if total > 0:
            idle, steal = (host[1] - host_prev[1]) / total, (host[2] - host_prev[2]) / total
    files = log_files(out)
    now = time.time()
    size = sum(p.stat().st_size for p in files if p.exists())
    lag = min((now - p.stat().st_mtime for p in files if p.exists()), default=None)
    return {"t": time.monotonic(), "rss_kb": by_kind, "steal": steal, "idle": idle, "log_bytes": size,
            "log_files": len(files), "flush_lag_s": lag}, host


def timed(cmd: list[str]) -> tuple[int, float, str]:
    t0 = time.perf_counter()
    p = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
    return p.returncode, time.perf_counter() - t0, p.stdout if p.returncode == 0 else p.stderr[-500:]


def pct(x: float) -> str:
    return f"{100 * x:+.1f} %"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, default=60.0)
    ap.add_argument("--robots", type=int, default=8)
    ap.add_argument("--sample-every", type=float, default=10.0, help="s between two samples")
    ap.add_argument("--record", choices=["full", "lean"], default="full")
    ap.add_argument("--max-log-size", default=None, help="split the log into a set (e.g. 500M)")
    ap.add_argument("--out", type=Path, default=None, help="the run's directory (default: a temporary one)")
    ap.add_argument("--port", type=int, default=7481)
    ap.add_argument("--json", type=Path, default=None, help="also write every sample and the summary here")
    args = ap.parse_args()
    tmp = None
    if args.out is None:
        tmp = tempfile.TemporaryDirectory()
        args.out = Path(tmp.name) / "out"
    work = args.out.parent
    work.mkdir(parents=True, exist_ok=True)
    sc = work / f"soak-{args.robots}.toml"
    sc.write_text(scenario_text(args.robots))
    sim = args.minutes * 60.0
    cmd = [sys.executable, "-m", "cekm_swarm", "launch", str(sc), "--mode", "realtime", "--max-time", str(sim),
           "--out", str(args.out), "--overwrite", "--no-plot", "--port", str(args.port)]
    if args.record != "full":
        cmd += ["--record", args.record]
    if args.max_log_size:
        cmd += ["--max-log-size", args.max_log_size]
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    launch_log = open(work / "soak-launch.out", "w")  # noqa: SIM115 -- the launch's output, closed once it ended
    proc = subprocess.Popen(cmd, stdout=launch_log, stderr=subprocess.STDOUT, cwd=ROOT, env=env,
                            start_new_session=True)
    samples: list[dict] = []
    started = None  # when the world started ticking
    host = host_times()
    try:
        while proc.poll() is None:
            time.sleep(1.0 if started is None else args.sample_every)
            if started is None:
                text = (work / "soak-launch.out").read_text(errors="replace")
                if "world started ticking" not in text:
                    continue
                started = time.monotonic()
                host = host_times()
                print(f"world ticking; sampling every {args.sample_every:g} s for {args.minutes:g} min", flush=True)
                continue
            s, host = sample(args.out, proc.pid, host)
            s["minute"] = (s["t"] - started) / 60.0
            samples.append(s)
    except KeyboardInterrupt:
        os.killpg(proc.pid, signal.SIGINT)
        proc.wait()
    code = proc.wait()
    launch_log.close()
    if code != 0 or not samples:
        print(f"the launch ended with code {code}; see {work / 'soak-launch.out'}")
        print((work / "soak-launch.out").read_text(errors="replace")[-3000:])
        sys.exit(1)
    outcome = json.loads((args.out / "outcome.json").read_text())
    report(args, samples, outcome)
    if tmp is not None:
        tmp.cleanup()


def report(args, samples: list[dict], outcome: dict) -> None:
    robots = args.robots
    samples = [s for s in samples if "world" in s["rss_kb"]]  # not the last ones, once the run ended
    # nor one taken while the world writes its outputs after its tick loop (trajectory.json and
    # the log's summary: its RSS jumps a few MB for those seconds); ``minute`` counts from when
    # the launcher's line was read, up to about a second late, hence the margin
    loop_end = (outcome.get("tick_loop_seconds") or float("inf")) / 60.0 - 2.0 / 60.0
    kept = [s for s in samples if s["minute"] <= loop_end]
    if kept and len(kept) < len(samples):
        print(f"left out {len(samples) - len(kept)} sample(s) taken after the world's tick loop (minute "
              f"{loop_end + 2 / 60:.2f}): world " + ", ".join(
                  f"{statistics.median(s['rss_kb']['world']) / 1024:.1f} MB" for s in samples[len(kept):]))
        samples = kept
    kinds = sorted({k for s in samples for k in s["rss_kb"]})
    base = min((s for s in samples if s["minute"] >= 1.0), key=lambda s: s["minute"], default=samples[0])
    minutes = int(samples[-1]["minute"])
    print(f"\n{robots} robots, {args.minutes:g} min of real time, record {args.record}; "
          f"baseline = the sample at minute {base['minute']:.2f}")
    print("\nresident memory per process, median over the processes of a kind (MB), and growth over the baseline")
    head = f"{'minute':>6} {'steal':>6} " + " ".join(f"{k:>18}" for k in kinds)
    print(head)
    rows = []
    picks = [base] + [min(samples, key=lambda s, m=m: abs(s["minute"] - m)) for m in range(2, minutes + 1)]
    picks.append(samples[-1])
    seen = set()
    for s in picks:
        if id(s) in seen:
            continue
        seen.add(id(s))
        cells = []
        for k in kinds:
            v, b = s["rss_kb"].get(k), base["rss_kb"].get(k)
            if not v or not b:
                cells.append(f"{'-':>18}")
                continue
            med, bmed = statistics.median(v) / 1024, statistics.median(b) / 1024
            cells.append(f"{med:8.1f} {pct(med / bmed - 1):>9}")
        steal = "-" if s["steal"] is None else f"{100 * s['steal']:.0f} %"
        rows.append(f"{s['minute']:6.1f} {steal:>6} " + " ".join(cells))
    print("\n".join(rows))
    worst = {}
    for k in kinds:
        b = base["rss_kb"].get(k)
        e = samples[-1]["rss_kb"].get(k)
        if b and e:
            worst[k] = max(e) / 1024, max(b) / 1024
    print("\nlargest process of each kind, baseline -> end (MB): " +
          ", ".join(f"{k} {b:.1f} -> {e:.1f} ({pct(e / b - 1)})" for k, (e, b) in worst.items()))
    growth = {k: statistics.median(samples[-1]["rss_kb"][k]) / statistics.median(base["rss_kb"][k]) - 1
              for k in kinds if base["rss_kb"].get(k) and samples[-1]["rss_kb"].get(k)}
    ok = all(g < 0.05 for g in growth.values())
    print(f"goal: growth after minute 1 under 5 % for every kind: {'met' if ok else 'NOT met'} "
          f"(world {pct(growth.get('world', float('nan')))})")
    # deadline misses, per minute
    ticks = outcome.get("ticks", 0)
    misses = outcome.get("deadline_misses", 0)
    per_min: dict[int, int] = {}
    for k, v in (outcome.get("deadline_miss_ticks") or {}).items():
        per_min[int(int(k) * 0.128 // 60)] = per_min.get(int(int(k) * 0.128 // 60), 0) + v
    lat = outcome.get("sense_to_command_ms") or {}
    host = (outcome.get("launcher", {}).get("cpu") or {}).get("host") or {}
    print(f"\ndeadline misses {misses} of {robots * ticks} robot-ticks ({100 * misses / max(1, robots * ticks):.3f} %)"
          f"; by minute (of the first {len(outcome.get('deadline_miss_ticks') or {})} ticks with one): "
          f"{dict(sorted(per_min.items())) or '-'}; latency p50 {lat.get('p50')} ms, p99 {lat.get('p99')} ms; "
          f"host stole {100 * host.get('steal', float('nan')):.0f} % of the machine's time over the run")
    # the log
    size = samples[-1]["log_bytes"]
    lags = sorted(s["flush_lag_s"] for s in samples if s["flush_lag_s"] is not None)
    b_rate = (size - base["log_bytes"]) / max(1e-9, (samples[-1]["t"] - base["t"]))
    print(f"\nlog: {size / 1e6:.1f} MB in {samples[-1]['log_files']} file(s) after {samples[-1]['minute']:.1f} min; "
          f"{b_rate * 3600 / 1e6:.0f} MB an hour after minute 1 (baseline), "
          f"{b_rate * 3600 / 1e6 / robots:.0f} MB per robot-hour; flush lag (age of the last write) "
          f"median {statistics.median(lags):.2f} s, max {lags[-1]:.2f} s")
    out = args.out
    target = str(out)
    code, secs, text = timed([sys.executable, "-m", "cekm_swarm", "log", "info", target, "--json"])
    info = json.loads(text) if code == 0 else {}
    print(f"cekm log info {target}: exit {code} in {secs:.1f} s; {info.get('messages')} messages, complete "
          f"{info.get('complete')}" + ("" if code == 0 else f": {text}"))
    code2, secs2, text2 = timed([sys.executable, "-m", "cekm_swarm", "log", "cat", target,
                                 "--topics", "cekm/world/clock"])
    n_clock = len(text2.splitlines()) if code2 == 0 else None
    print(f"cekm log cat {target} --topics cekm/world/clock: exit {code2} in {secs2:.1f} s; {n_clock} lines "
          f"(ticks {ticks + 1})" + ("" if code2 == 0 else f": {text2}"))
    if args.json is not None:
        args.json.write_text(json.dumps({"samples": samples, "growth": growth, "outcome_misses": misses,
                                         "log_bytes": size, "info_s": secs, "cat_s": secs2}, indent=1))


if __name__ == "__main__":
    main()
