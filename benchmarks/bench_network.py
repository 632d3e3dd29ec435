"""How a real-time run degrades on a bad network: every robot on its own host (a network
namespace) behind a fault link (``cekm_swarm.runtime.faultlink``: one-way delay, loss as
TCP retransmission) to the world host's router, each robot host with its own router
joined to the world's (the shape docs/faults.md recommends for Wi-Fi).

Rows: ``tracking-crowd`` (6 robots) and ``crossing`` (3) at one-way delays 0, 10, 50, 100
and 200 ms without loss, 1 and 5 % loss at 50 ms (``--grid full``: every delay with every
loss), and one 5 s partition of r1 (no delay). Per row: Parker's A (tracking), goals
reached and contacts (crossing), deadline misses (robot-ticks whose command was not in
by the tick's end), dead-man stops, ticks missing from the world's log (must be 0), the
median sense-to-command latency, and the host's load and steal during the row (the
machine may be shared: read wall-clock figures beside them).

Baseline, measured in the same run: the 0 ms row of each scenario; A is printed as a
ratio of it. Goal: A at 50 ms at least 0.9 of A at 0 ms; no lost world message in any row.

``--soak MINUTES`` instead runs the bad-link hour: ``tracking`` (2 robots) behind 50 ms and
1 % loss, r1 cut for 5 s every 10 minutes, the log split every 600 s, the dead-man at the
1 s docs/faults.md recommends for a lossy link; every process's
memory at minute 1 and at the end, misses outside the partitions, dead-man stops, the log
set and ``cekm log info`` over it.

``--lockstep`` instead runs ``crossing`` in lockstep (10 s of sim time) through each delay:
wall time per tick against the round trip, and equality with ``cekm run``.

Run (as root, Linux): python benchmarks/bench_network.py [--grid reduced|full]
    [--tracking-time 30] [--crossing-time 90] [--out DIR] [--json FILE] [--plot FILE]
    python benchmarks/bench_network.py --lockstep [--loss 0.05]
    python benchmarks/bench_network.py --soak 60 --out DIR
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from cekm_swarm.experiments.default_model import default_model_path  # noqa: E402
from cekm_swarm.launch.cpu import host_times, kind_of  # noqa: E402
from cekm_swarm.runtime.faultlink import LinkSettings  # noqa: E402
from cekm_swarm.runtime.mcap_sets import log_files  # noqa: E402
from cekm_swarm.runtime.netns import Hosts, namespaces_unavailable  # noqa: E402
from cekm_swarm.runtime.netns_run import NetRun, world_log_gaps  # noqa: E402
from world.clocks import link_deadline_ticks  # noqa: E402
from world.deadman import DEADMAN_S  # noqa: E402

SEED = 1
DELAYS_MS = (0, 10, 50, 100, 200)
LOSSES = (0.0, 0.01, 0.05)
PARTITION_S = 5.0
PARTITION_AT = 5.0  # sim s
WIFI_DEADMAN_S = 1.0  # the dead-man limit docs/faults.md recommends on a lossy link
SOAK_LINK = {"delay": 0.05, "loss": 0.01}  # the bad-link hour's link (the issue's)
WIFI_DEADLINE_TICKS = link_deadline_ticks(SOAK_LINK["delay"])  # the rule of docs/faults.md: 5 at 50 ms with loss


def robots_of(scenario: str) -> tuple[str, ...]:
    from world import load_scenario

    return tuple(r.id for r in load_scenario(scenario).robots)


def steal_since(before) -> float | None:
    after = host_times()
    if before is None or after is None or after[0] == before[0]:
        return None
    return (after[2] - before[2]) / (after[0] - before[0])


def wait_sim(run: NetRun, t: float) -> None:
    while True:
        line = run.world.wait_line(" t=", timeout=120)
        if float(line.split(" t=")[1].split()[0]) >= t:
            return


def one_row(work: Path, scenario: str, max_time: float, delay_ms: float, loss: float, partition: bool,
            tag: str, deadman: float | None = None, host_routers: bool = True) -> dict:
    robots = robots_of(scenario)
    hosts = Hosts(robots, tag=tag)
    try:
        link = LinkSettings(delay=delay_ms / 1000, loss=loss)
        opts = ["--seed", str(SEED), "--max-time", str(max_time), "--model", str(default_model_path())]
        if deadman is not None:
            opts += ["--deadman", str(deadman)]
        run = NetRun(hosts, work, scenario, "realtime", opts, {r: link for r in robots}, host_routers=host_routers,
                     seed=SEED)
        before = host_times()
        run.start()
        if partition:
            wait_sim(run, PARTITION_AT)
            run.link(robots[0], "cut")
            time.sleep(PARTITION_S)  # the partition's length
            run.link(robots[0], "restore")
        out = run.finish(timeout=max_time * 4 + 300)
    finally:
        hosts.remove()
    gaps = world_log_gaps(work / "world-host" / "run.mcap", out, list(robots))
    row = {"scenario": scenario, "delay_ms": delay_ms, "loss": loss, "partition_s": PARTITION_S if partition else 0,
           "deadman_s": deadman or DEADMAN_S, "host_routers": host_routers,
           "ticks": out["ticks"], "robot_ticks": out["ticks"] * len(robots),
           "misses": out["deadline_misses"], "deadman_stops": sum(e["event"] == "deadman" for e in out["events"]),
           "lost_world_ticks": sum(v for k, v in gaps.items() if k != "recorded"),
           "unlogged": gaps["recorded"],
           "latency_p50_ms": (out.get("sense_to_command_ms") or {}).get("p50"),
           "command_age_ticks": out.get("command_age_ticks"),
           "steal": steal_since(before), "load": float(Path("/proc/loadavg").read_text().split()[0])}
    if "tracking" in out:
        row["A"] = out["tracking"]["A"]
    else:
        row["reached"] = sum(bool(r["reached"]) for r in out["robots"].values())
        row["contacts"] = sum(int(r.get("collisions", 0)) for r in out["robots"].values())
        row["sim_s"] = out["sim_seconds"]
    return row


def grid(args) -> list[tuple[float, float, bool, float | None]]:
    """(delay ms, loss, partition?, dead-man limit or None for the default) per row."""
    cells = [(d, 0.0, False, None) for d in DELAYS_MS]
    losses = [x for x in LOSSES if x]
    cells += [(d, x, False, None) for d in DELAYS_MS for x in losses] if args.grid == "full" else \
        [(50, x, False, None) for x in losses]
    # the setting docs/faults.md recommends for a lossy link, and the partition
    return cells + [(50, x, False, WIFI_DEADMAN_S) for x in losses] + [(0, 0.0, True, None)]


def lockstep_speed(work: Path, delays: list[float], loss: float, max_time: float) -> None:
    """Lockstep ``crossing`` through each delay (every robot behind its link, host routers):
    wall s per tick against the one-way delay, and whether the outcome still equals the
    one-process run bit for bit."""
    from cekm_swarm.experiments.default_model import default_model
    from cekm_swarm.experiments.navigation_run import run_scenario
    from world import load_scenario

    scenario, robots = "crossing", robots_of("crossing")
    ref = run_scenario(load_scenario(scenario), "cekm", default_model(progress=False), SEED, max_time=max_time)
    for i, d in enumerate(delays):
        hosts = Hosts(robots, tag=f"l{i}")
        try:
            opts = ["--seed", str(SEED), "--max-time", str(max_time), "--model", str(default_model_path())]
            run = NetRun(hosts, work / f"lockstep-{d}ms", scenario, "lockstep", opts,
                         {r: LinkSettings(delay=d / 1000, loss=loss) for r in robots}, host_routers=True, seed=SEED)
            before = host_times()
            run.start()
            t0 = time.monotonic()
            out = run.finish(timeout=max_time * 20 + 300)
            wall = time.monotonic() - t0
        finally:
            hosts.remove()
        traj = json.loads((work / f"lockstep-{d}ms" / "world-host" / "trajectory.json").read_text())
        equal = all(traj[r]["x"] == ref.logs[r].x and traj[r]["v_l"] == ref.logs[r].v_l for r in robots)
        steal = steal_since(before)
        per_tick = 1000 * wall / out["ticks"]
        ratio = f"{per_tick / (2 * d):.2f} x the round trip" if d else "no delay"
        print(
            f"lockstep crossing {d:4.0f} ms {100 * loss:3.0f} %: {out['ticks']} ticks, {per_tick:6.1f} ms per tick "
            f"({ratio}), "
            f"republished {out['republished']}, equals cekm run: {equal} | load "
            f"{Path('/proc/loadavg').read_text().split()[0]} steal {'?' if steal is None else f'{100 * steal:.1f} %'}",
            flush=True,
        )


def fmt(row: dict, base_a: float | None) -> str:
    what = (f"A {row['A']:.3f} ({row['A'] / base_a:.2f})" if "A" in row and base_a else
            f"A {row['A']:.3f}" if "A" in row else
            f"reached {row['reached']}, contacts {row['contacts']}, {row['sim_s']:.1f} s")
    cut = f", {row['partition_s']:.0f} s cut" if row["partition_s"] else ""
    cut += f", dead-man {row['deadman_s']} s" if row["deadman_s"] != DEADMAN_S else ""
    steal = "?" if row["steal"] is None else f"{100 * row['steal']:.1f} %"
    return (f"{row['scenario']:15s} {row['delay_ms']:4.0f} ms {100 * row['loss']:3.0f} %{cut:18s} | {what:32s} | "
            f"misses {row['misses']:4d}/{row['robot_ticks']:5d} | dead-man {row['deadman_stops']} | "
            f"lost {row['lost_world_ticks']}+{row['unlogged']} | p50 {row['latency_p50_ms']} ms | "
            f"load {row['load']:.1f} steal {steal}")


def plot(rows: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 3.6))
    for scen in sorted({r["scenario"] for r in rows}):
        line = [r for r in rows if r["scenario"] == scen and not r["loss"] and not r["partition_s"]
                and r["deadman_s"] == DEADMAN_S]
        xs = [r["delay_ms"] for r in line]
        if "A" in line[0]:
            ax1.plot(xs, [r["A"] / line[0]["A"] for r in line], "o-", label=f"{scen}: A / A(0 ms)")
        else:
            ax1.plot(xs, [r["reached"] / max(1, len(robots_of(scen))) for r in line], "s--",
                     label=f"{scen}: goals reached (fraction)")
        ax2.plot(xs, [100 * r["misses"] / r["robot_ticks"] for r in line], "o-", label=scen)
    ax1.set_xlabel("one-way delay (ms)")
    ax1.set_ylim(0, 1.15)
    ax1.legend(fontsize=8)
    ax2.set_xlabel("one-way delay (ms)")
    ax2.set_ylabel("deadline misses (% of robot-ticks)")
    ax2.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


MEMORY_FIELDS = {"VmRSS:": "rss", "RssAnon:": "anon", "RssFile:": "file"}
"""Resident memory in all (``rss``), the process's own (``anon``: heap, stacks, buffers) and
its mapped files' pages (``file``: mostly shared-library code paged in as it first runs)."""


def rss_by_process(hosts_dirs: list[Path]) -> dict[str, dict[str, int]]:
    """Resident memory (kB, :data:`MEMORY_FIELDS`) of every process of the run, by its
    launcher label (pids.json of each host's out directory)."""
    out: dict[str, dict[str, int]] = {}
    for d in hosts_dirs:
        try:
            pids = json.loads((d / "pids.json").read_text())
        except (OSError, ValueError):
            continue
        for label, pid in pids.items():
            try:
                with open(f"/proc/{pid}/status") as f:
                    for line in f:
                        name = MEMORY_FIELDS.get(line.split(maxsplit=1)[0] if line.strip() else "")
                        if name:
                            out.setdefault(label, {})[name] = int(line.split()[1])
            except OSError:
                pass
    return out


def soak(args, work: Path) -> None:
    scenario, robots = "tracking", robots_of("tracking")
    hosts = Hosts(robots, tag="s")
    minutes = args.soak
    cuts: list[tuple[float, float]] = []
    mem: dict[str, dict[str, int]] = {}
    series: list[dict[str, int]] = []  # minute m+1's memory, by process
    try:
        link = LinkSettings(**SOAK_LINK)
        opts = ["--seed", str(SEED), "--max-time", str(minutes * 60), "--model", str(default_model_path()),
                "--max-log-duration", "600", "--deadman", str(WIFI_DEADMAN_S),
                "--deadline-ticks", str(args.deadline_ticks)]
        run = NetRun(hosts, work, scenario, "realtime", opts, {r: link for r in robots}, host_routers=True, seed=SEED)
        before = host_times()
        run.start()
        t0 = time.monotonic()
        dirs = [work / "world-host", *(work / f"host-{r}" for r in robots)]
        next_cut = args.cut_every - 30
        while time.monotonic() - t0 < minutes * 60 - 20:
            el = time.monotonic() - t0
            if el >= 60 * (len(series) + 1):  # every process's memory, every minute
                series.append(rss_by_process(dirs))
                mem.setdefault("minute 1", series[0])
            if el >= next_cut:
                line = run.world.lines[-1] if run.world.lines else ""
                cut = run.link(robots[0], "cut")
                time.sleep(PARTITION_S)
                restore = run.link(robots[0], "restore")
                cuts.append((cut["wall"], restore["wall"]))
                print(f"cut r1 at {el / 60:.1f} min ({line[:40]})", flush=True)
                next_cut += args.cut_every
            mem["end"] = rss_by_process(dirs)
            time.sleep(5)
        out = run.finish(timeout=600)
        steal = steal_since(before)
    finally:
        hosts.remove()
    first = work / "world-host" / "run_0.mcap"
    files = log_files(first if first.is_file() else work / "world-host" / "run.mcap")
    gaps = world_log_gaps(files[0], out, list(robots))  # the first file of a set reads the whole set
    info = subprocess.run([sys.executable, "-m", "cekm_swarm", "log", "info", str(files[0])], capture_output=True,
                          text=True, timeout=600)
    stops = [e for e in out["events"] if e["event"] == "deadman"]
    walls = [e["wall"] for e in stops]
    outside = [w for w in walls if not any(a <= w <= b + 1.0 for a, b in cuts)]
    print(f"\nbad-link soak: {minutes} min, tracking (2 robots) behind 50 ms + 1 % loss, r1 cut {PARTITION_S:.0f} s "
          f"every {args.cut_every / 60:.0f} min ({len(cuts)} cuts); load "
          f"{Path('/proc/loadavg').read_text().split()[0]}, "
          "steal "
          f"{'?' if steal is None else f'{100 * steal:.1f} %'}")
    ages = {int(k): v for k, v in out["command_age_ticks"].items()}
    strict = out["deadline_misses"] + sum(v for k, v in ages.items() if 0 < k <= out.get("deadline_ticks", 0))
    print(f"ticks {out['ticks']}, deadline misses {out['deadline_misses']} of {out['ticks'] * len(robots)} robot-ticks "
          f"with --deadline-ticks {out.get('deadline_ticks', 0)} ({strict} by the tick's-own-command rule, 0); "
          f"applied commands by age in ticks {dict(sorted(ages.items()))}; "
          f"dead-man stops {len(stops)} ({len(outside)} outside a partition)")
    # sim time of a wall instant: real time runs on the wall clock (any event carries both)
    offset = statistics.median([e["wall"] - e["t"] for e in out["events"] if "wall" in e] or [0.0])
    windows = [(a - offset - 0.5, b - offset + 2.0) for a, b in cuts]
    listed = {int(k): v for k, v in out["deadline_miss_ticks"].items()}
    off_cut = {k: v for k, v in listed.items() if not any(lo <= k * 0.128 <= hi for lo, hi in windows)}
    print(f"misses listed by tick: {sum(listed.values())} (of {out['deadline_misses']}), outside the partitions "
          f"(from 0.5 s before a cut to 2 s after it): {sum(off_cut.values())} at ticks {sorted(off_cut)[:40]}")
    growth: dict[str, dict[str, float]] = {}
    for label, now in sorted(mem.get("end", {}).items()):
        first = mem.get("minute 1", {}).get(label, {})
        growth[label] = {k: now[k] / first[k] - 1 for k in now if first.get(k)}
    for field in ("rss", "anon"):
        by_kind: dict[str, list[float]] = {}
        for label, g in growth.items():
            if field in g:
                by_kind.setdefault(kind_of(label), []).append(g[field])
        for kind, gs in sorted(by_kind.items()):
            print(f"  memory ({field}) {kind:12s} minute 1 -> end: max {100 * max(gs):+.1f} %, median "
                  f"{100 * statistics.median(gs):+.1f} % ({len(gs)} processes)")
    print(f"log set: {len(files)} files, {sum(f.stat().st_size for f in files) / 1e6:.1f} MB; gaps {gaps}")
    print(info.stdout[-3000:] or info.stderr[-2000:])
    (work / "soak.json").write_text(json.dumps({"outcome_events": out["events"], "cuts": cuts, "memory": mem,
                                                "memory_by_minute": series, "command_age_ticks": ages,
                                                "deadline_misses": out["deadline_misses"], "strict_misses": strict,
                                                "misses_outside_partitions": sum(off_cut.values()),
                                                "growth": growth, "gaps": gaps, "steal": steal}, indent=1))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--grid", choices=["reduced", "full"], default="reduced")
    p.add_argument("--scenarios", default="tracking-crowd,crossing")
    p.add_argument("--tracking-time", type=float, default=30.0)
    p.add_argument("--crossing-time", type=float, default=90.0)
    p.add_argument("--out", type=Path, default=None)
    p.add_argument("--json", type=Path, default=None)
    p.add_argument("--plot", type=Path, default=None)
    p.add_argument("--soak", type=float, default=None, metavar="MINUTES")
    p.add_argument("--no-host-routers", action="store_true", help="every process a client of the world's router")
    p.add_argument("--lockstep", action="store_true", help="instead: lockstep speed against the delay")
    p.add_argument("--loss", type=float, default=0.0, help="--lockstep: the links' loss")
    p.add_argument("--cut-every", type=float, default=600.0, metavar="S", help="soak: s between two partitions")
    p.add_argument("--deadline-ticks", type=int, default=WIFI_DEADLINE_TICKS, metavar="N",
                   help="soak: the world's deadline allowance (docs/faults.md)")
    args = p.parse_args()
    why = namespaces_unavailable()
    if why:
        sys.exit(f"bench_network: {why}")
    work = args.out or Path(tempfile.mkdtemp(prefix="bench-network-"))
    if args.soak:
        soak(args, work / "soak")
        return
    if args.lockstep:
        lockstep_speed(work, list(DELAYS_MS), args.loss, 10.0)
        return
    rows: list[dict] = []
    for scen in args.scenarios.split(","):
        base_a = None
        for i, (d, loss, cut, deadman) in enumerate(grid(args)):
            t = args.tracking_time if scen.startswith("tracking") else args.crossing_time
            row = one_row(work / f"{scen}-{d}ms-{loss}-{int(cut)}-{deadman}", scen, t, d, loss, cut, str(i % 10),
                          deadman, host_routers=not args.no_host_routers)
            if d == 0 and not loss and not cut:
                base_a = row.get("A")
            rows.append(row)
            print(fmt(row, base_a), flush=True)
            if args.json:
                args.json.write_text(json.dumps(rows, indent=1))
    if args.plot:
        plot(rows, args.plot)
        print(f"wrote {args.plot}")


if __name__ == "__main__":
    main()
