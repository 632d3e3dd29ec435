"""The runtime's process graph: sense-to-command latency, lockstep speed-up, module memory.

One robot's 14 module processes (target, obstacle 0..11, motor; lockstep mode, so the
motor answers each tick exactly once, when the tick's 13 fields are in) on loopback. This
process plays the world server as the launcher runs it: it hosts the embedded router
(Zenoh's threads as the world server sets them on loopback), steps ``lone_obstacle`` with
``world.episode.Episode``, publishes each tick's readings on the router's own session and
waits for the command.

* sense-to-command latency: from the tick's sensor readings in hand (before they are
  encoded and put on Zenoh, as the world server measures it) to the command for that
  tick arriving (in the Zenoh callback), paced at one tick per 128 ms
  as in real time (p50, p99); beside it, in the same run and with the same Zenoh
  router, the raw one-way latency of a 2 KB message between two processes with
  bench_zenoh's method: 1 hop (publisher in the router's process, the world's readings)
  and 2 hops through the router (a module's field to the motor);
* lockstep speed-up: ticks as fast as the graph answers, sim time / wall time, both for
  this bare loop and for full ``cekm launch lone_obstacle|concave --mode lockstep`` runs (the world
  server recording the MCAP log and Foxglove views): sim time over the world's tick loop
  (first tick's readings to the last tick), and beside it over the world server's run
  from the moment every module is alive (its ``wall_seconds``: the subscribers' matching
  wait, the tick loop, closing the log);
* memory: resident set (VmRSS) and proportional set (Pss, shared pages split among the
  processes sharing them) of one obstacle module process.

* CPU: the 14 module processes' CPU time per paced tick, and the share of the host's time
  stolen meanwhile (docs/performance.md: steal moves every number here).

``--module-runtime SPEC`` starts the modules with ``ZENOH_RUNTIME=SPEC`` instead of their
own choice (runtime.config.ONE_THREAD_RUNTIME, or LOCKSTEP_MODULE_RUNTIME in lockstep), to compare
Zenoh thread layouts.

Run: python benchmarks/bench_runtime.py [--ticks 400] [--no-launch] [--module-runtime SPEC]
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import platform
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from cekm_swarm.experiments.default_model import default_model, default_model_path  # noqa: E402
from cekm_swarm.launch.cpu import cpu_seconds, host_shares, host_times  # noqa: E402
from cekm_swarm.launch.prepare import body_of, run_spec  # noqa: E402
from cekm_swarm.launch.processes import node_argv  # noqa: E402
from cekm_swarm.node.graph_check import check_graph  # noqa: E402
from cekm_swarm.protocol import DEFAULT_KEYS as K  # noqa: E402
from cekm_swarm.protocol import WheelCommand, decode  # noqa: E402
from cekm_swarm.runtime.bridge import InlineSubscription, LivelinessWatcher, Publishers  # noqa: E402
from cekm_swarm.runtime.config import ROUTER_RUNTIME, free_port, open_embedded_router, use_zenoh_runtime  # noqa: E402
from world import World, load_scenario  # noqa: E402
from world.episode import TICK_S, Episode  # noqa: E402
from world.sense import SenseEncoder  # noqa: E402


def pct(xs: list[float], q: float) -> float:
    xs = sorted(xs)
    return xs[min(len(xs) - 1, int(round(q / 100 * (len(xs) - 1))))]


def memory(pid: int) -> dict[str, float]:
    out = {}
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            out["rss_mb"] = int(line.split()[1]) / 1024
    try:
        for line in Path(f"/proc/{pid}/smaps_rollup").read_text().splitlines():
            if line.startswith("Pss:"):
                out["pss_mb"] = int(line.split()[1]) / 1024
            elif line.startswith("Private_Clean:") or line.startswith("Private_Dirty:"):
                out["uss_mb"] = out.get("uss_mb", 0.0) + int(line.split()[1]) / 1024
    except OSError:
        pass
    return out


async def start_modules(session, endpoint: str, model: Path) -> tuple[list[subprocess.Popen], float]:
    """The cekm navigation graph's 14 node processes of robot r1, from a run spec as the launcher writes it."""
    checked = check_graph("cekm-navigation")
    spec = run_spec(checked, ("r1",), "navigation", body_of(load_scenario("lone_obstacle")), mode="lockstep",
                    connect=endpoint, model=str(model))
    path = spec.write(Path(tempfile.mkdtemp(prefix="bench-runtime-")) / "run-spec.json")
    names = checked.graph.node_names(12)
    procs = [subprocess.Popen(node_argv(str(path), "r1", n), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
             for n in names]
    t0 = time.monotonic()
    expected = {K.alive("r1", n) for n in names}
    with LivelinessWatcher(session, K.alive_all()) as w:
        while not expected <= w.alive:
            await w.next_event(timeout=120)
    return procs, time.monotonic() - t0


def graph_run(session, ticks: int, paced: bool, first_tick: int = 0) -> tuple[list[float], float, int]:
    """Step lone_obstacle through the module graph; latencies (ms), wall s, ticks run.
    Stamps start at ``first_tick`` (the motor ignores ticks older than its last answer)."""
    world = World(load_scenario("lone_obstacle"))
    ep = Episode(world)
    ep.tick = first_tick
    got: dict[float, float] = {}
    cv = threading.Condition()
    cmds: dict[float, WheelCommand] = {}

    def on_cmd(sample) -> None:
        at = time.perf_counter()
        msg = decode(K.cmd_wheels("r1"), sample.payload.to_bytes())
        with cv:
            if msg.stamp not in got:
                got[msg.stamp] = at
                cmds[msg.stamp] = msg
            cv.notify_all()

    sub = InlineSubscription(session, K.cmd_wheels("r1"), on_cmd, raw=True)  # as the world server takes commands
    lat = []
    pubs = Publishers(session, block=True, express=False)  # as the world server publishes
    for j in range(12):
        pubs.wait_matching(K.sense_range("r1", j), 20)
    pubs.wait_matching(K.sense_target("r1"), 20)
    sense = SenseEncoder(K, "r1", world.sensor_angles, world.body_radius)
    t_start = time.perf_counter()
    n = 0
    for k in range(first_tick, first_tick + ticks):
        if paced:
            time.sleep(max(0.0, t_start + (k - first_tick) * TICK_S - time.perf_counter()))
        (rd,) = ep.readings()
        t0 = time.perf_counter()
        for key, payload in sense(rd):  # as the world server publishes a tick's readings
            pubs.put(key, payload)
        t = rd.t
        with cv:
            if not cv.wait_for(lambda t=t: t in got, timeout=10):
                raise RuntimeError(f"no command for tick {k}")
        lat.append((got[t] - t0) * 1000)
        c = cmds[t]
        ep.apply({"r1": (c.v_l, c.v_r)})
        n += 1
        if ep.done:  # start over so the run is as long as asked
            world = World(load_scenario("lone_obstacle"))
            ep = Episode(world)
            ep.tick = k + 1  # keep stamps increasing for the motor
            continue
        ep.advance()
    wall = time.perf_counter() - t_start
    sub.close()
    pubs.close()
    return lat, wall, n


def launch_speedup(scenario: str) -> dict[str, float]:
    with tempfile.TemporaryDirectory() as d:
        port = free_port()
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "cekm_swarm", "launch", scenario, "--mode", "lockstep",
                        "--out", d, "--port", str(port), "--no-plot", "--model", str(default_model_path())],
                       check=True, stdout=subprocess.DEVNULL)
        total = time.perf_counter() - t0
        o = json.loads((Path(d) / "outcome.json").read_text())
    return {"sim_s": o["sim_seconds"], "world_wall_s": o["wall_seconds"], "tick_loop_s": o["tick_loop_seconds"],
            "speedup": o["sim_seconds"] / o["tick_loop_seconds"],
            "speedup_incl_world_start_and_log_close": o["sim_seconds"] / o["wall_seconds"],
            "startup_s": o["launcher"]["startup_s"],
            "total_wall_s": total, "p50_ms": o["sense_to_command_ms"]["p50"], "p99_ms": o["sense_to_command_ms"]["p99"]}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--ticks", type=int, default=400)
    ap.add_argument("--no-launch", action="store_true")
    ap.add_argument("--module-runtime", metavar="SPEC", help="the modules' ZENOH_RUNTIME (default: their own)")
    args = ap.parse_args()
    default_model(progress=False)
    model = default_model_path()
    use_zenoh_runtime(ROUTER_RUNTIME)  # as world.server does when it hosts the router on loopback
    port = free_port()
    router = open_embedded_router(port)
    if os.environ.get("ZENOH_RUNTIME") == ROUTER_RUNTIME:  # read once, at the router's opening:
        del os.environ["ZENOH_RUNTIME"]  # the children choose their own
    if args.module_runtime:
        os.environ["ZENOH_RUNTIME"] = args.module_runtime
    endpoint = f"tcp/127.0.0.1:{port}"
    session = router  # the world publishes on the router's own session
    procs, startup = asyncio.run(start_modules(session, endpoint, model))
    try:
        mem = memory(procs[1].pid)
        cpu0, host0 = [cpu_seconds(p.pid) or 0.0 for p in procs], host_times()
        paced_lat, _, _ = graph_run(session, args.ticks, paced=True)
        cpu1, host1 = [cpu_seconds(p.pid) or 0.0 for p in procs], host_times()
        fast_lat, wall, n = graph_run(session, args.ticks, paced=False, first_tick=args.ticks + args.ticks % 2)
    finally:
        for p in procs:
            p.terminate()
        for p in procs:
            p.wait(10)
        router.close()
    import bench_zenoh

    raw1 = bench_zenoh.latency("callback", 1, 1000, 0.002)
    raw = bench_zenoh.latency("asyncio", 2, 1000, 0.002)
    raw_cb = bench_zenoh.latency("callback", 2, 1000, 0.002)
    result = {
        "machine": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, Python "
        f"{platform.python_version()}",
        "module_startup_s_14_processes": round(startup, 2),
        "sense_to_command_ms_paced": {
            "p50": round(pct(paced_lat, 50), 3),
            "p99": round(pct(paced_lat, 99), 3),
            "n": len(paced_lat),
        },
        "sense_to_command_ms_flat_out": {"p50": round(pct(fast_lat, 50), 3), "p99": round(pct(fast_lat, 99), 3)},
        "raw_one_way_1_hop_ms": {
            "callback_p50": round(pct(raw1, 50) / 1000, 3),
            "callback_p99": round(pct(raw1, 99) / 1000, 3),
        },
        "raw_one_way_2_hops_ms": {
            "asyncio_p50": round(pct(raw, 50) / 1000, 3),
            "asyncio_p99": round(pct(raw, 99) / 1000, 3),
            "callback_p50": round(pct(raw_cb, 50) / 1000, 3),
            "callback_p99": round(pct(raw_cb, 99) / 1000, 3),
        },
        "module_cpu_ms_per_paced_tick": round(1000 * (sum(cpu1) - sum(cpu0)) / len(paced_lat), 2),
        "host_stolen_share_paced": host_shares(host0, host1).get("steal"),
        "lockstep_bare_loop": {"ticks": n, "wall_s": round(wall, 3), "speedup": round(n * TICK_S / wall, 1)},
        "module_memory_mb": {k: round(v, 1) for k, v in mem.items()},
    }
    if not args.no_launch:
        for scenario in ("lone_obstacle", "concave"):  # 100 and 203 ticks
            result[f"lockstep_cekm_launch_{scenario}"] = {k: round(v, 3) if isinstance(v, float) else v
                                                          for k, v in launch_speedup(scenario).items()}
    print(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
