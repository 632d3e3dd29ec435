"""The world server alone, past this machine's cores: N robots whose graphs are replaced by
one light process, the FAKE FLEET, that answers every robot's command.

For N = 32, 64, 128, 256, 512, 1024 (or --robots) robots in an open arena
(``bench_runtime_scale.scenario_text``: navigation, each robot with a goal), the world
server runs in real time exactly as ``cekm launch`` starts it (its run spec from the
default ``cekm`` graph, held readings, the embedded router with ``--listen``, the full
MCAP log with its Foxglove views). The fake fleet is one process with one Zenoh session:
a subscriber on every robot's readings (``<root>/*/sense/**``) whose ring channel Python
never reads (every reading leaves the world over TCP, none costs the fleet any Python), and a subscriber on the
world's clock that answers each tick with one wheel command per robot on the robot's
answer key (each robot its own constant speeds: the robots drive circles, so their
readings change and go out). So what it measures is the world server's own work per tick:
the simulation, the readings' encoding and held-readings bookkeeping, publishing through
its router, the commands' checks and the log. It leaves out what a real fleet adds: the
nodes' own messages (fields, shares) that the full log records too.

Per N it prints the world's CPU per tick (``time.process_time`` of every thread, from its
START and DONE lines) and per robot-tick, the share of one core, tick-to-command latency
(p50/p99: readings out to the robot's command in), deadline misses, the world process's
peak memory (the router embedded in it) and the log's bytes per sim second; and, measured
in the same run, the in-process world of the same N (the same episode stepped with the
same commands, no Zenoh, no log: ``cekm run --controller stay``'s world side) and the
ratio. Also the fake fleet's own CPU per tick, and the host's steal (compare rows at low
steal only: docs/performance.md, "Reading these numbers").

Run: python benchmarks/bench_world_fleet.py [--robots 32,64,128,256,512,1024] [--sim 10]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_runtime_scale import checkout_env, scenario_text  # noqa: E402

from cekm_swarm.launch.cpu import host_shares, host_times  # noqa: E402

TICK_S = 0.128


def wheel_speeds(i: int) -> tuple[float, float]:
    """Robot i's constant wheel speeds (m/s): a circle of its own radius."""
    return 0.06, 0.06 * (0.5 + 0.4 * ((i * 7) % 11) / 10)


# ------------------------------------------------------------------ the fake fleet


def fake_fleet(spec_path: str) -> None:
    """The FAKE FLEET process: answers every robot's command on the world's clock until
    SIGTERM, then prints its CPU seconds."""
    import zenoh

    from cekm_swarm.graph.runspec import RunSpec
    from cekm_swarm.protocol import Clock, WheelCommand, decode, encode
    from cekm_swarm.runtime.config import open_client

    spec = RunSpec.read(spec_path)
    keys, plan = spec.keys, spec.plan()
    session = open_client(spec.connect)
    answers = [(session.declare_publisher(plan.answer_key(r)), wheel_speeds(i)) for i, r in enumerate(spec.team)]
    seq = [0]
    cpu0: list[float] = []

    def on_clock(sample: zenoh.Sample) -> None:
        msg = decode(keys.world_clock(), sample.payload.to_bytes())
        if not isinstance(msg, Clock):
            return
        if not cpu0:
            cpu0.append(time.process_time())  # its CPU from tick 0 on, not its start-up's
        seq[0] += 1
        for pub, (v_l, v_r) in answers:
            pub.put(encode(WheelCommand(msg.stamp, "fake-fleet", v_l, v_r, seq[0])))

    clock = session.declare_subscriber(keys.world_clock(), on_clock)
    sink = session.declare_subscriber(f"{keys.root}/*/sense/**", zenoh.handlers.RingChannel(8))  # read by no one
    # every node's token, as the robots' nodes hold them: the world holds tick 0 for them
    # and starts its wall clock once tick 0 is answered, as in a launch
    tokens = [session.liveliness().declare_token(k) for k in sorted(plan.tokens(spec.team))]
    done = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: done.set())
    done.wait()
    for token in tokens:
        token.undeclare()
    clock.undeclare()
    sink.undeclare()
    session.close()
    print(json.dumps({"fleet_cpu_s": time.process_time() - (cpu0[0] if cpu0 else 0.0)}), flush=True)


# ------------------------------------------------------------------ one run


def write_spec(scenario: Path, port: int, out: Path) -> Path:
    """The run spec ``cekm launch`` would write for the default graph (held readings on)."""
    from cekm_swarm.launch.prepare import body_of, resolve, run_spec
    from world import load_scenario

    sc = load_scenario(str(scenario))
    checked, task = resolve(sc, None, None)
    team = tuple(r.id for r in sc.robots)
    spec = run_spec(checked, team, task, body_of(sc), mode="realtime", connect=f"tcp/127.0.0.1:{port}")
    return spec.write(out / "run-spec.json")


def _lines(proc: subprocess.Popen, into: list[str]) -> None:
    for line in proc.stdout:
        into.append(line)


def _peak_kb(pid: int) -> int | None:
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1])
    except OSError:
        return None
    return None


def served(n: int, sim: float, port: int, tmp: Path) -> dict:
    """The world server with N robots and the fake fleet, in real time for ``sim`` s."""
    sc = tmp / f"fleet{n}.toml"
    sc.write_text(scenario_text(n))
    spec = write_spec(sc, port, tmp)
    out = tmp / f"out{n}"
    env = checkout_env()
    world = subprocess.Popen([sys.executable, "-m", "world.server", str(sc), "--listen", f"tcp/127.0.0.1:{port}",
                              "--spec", str(spec), "--out", str(out), "--mode", "realtime", "--max-time", str(sim),
                              "--log-level", "WARNING", "--match-timeout", "60", "--wait-modules", "120"],
                             stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
    lines: list[str] = []
    reader = threading.Thread(target=_lines, args=(world, lines), daemon=True)
    reader.start()
    deadline = time.monotonic() + 120
    while not any(line.startswith("READY") for line in lines):
        if world.poll() is not None or time.monotonic() > deadline:
            world.kill()
            return {"robots": n, "error": "world server did not start: " + "".join(lines)[-1500:]}
        time.sleep(0.05)
    fleet = subprocess.Popen([sys.executable, __file__, "--fake-fleet", str(spec)], stdout=subprocess.PIPE, text=True,
                             env=env)
    t0 = time.monotonic()
    host0 = host_times()
    peak = None
    while world.poll() is None and time.monotonic() - t0 < sim + 300:
        peak = _peak_kb(world.pid) or peak
        time.sleep(0.2)
    host = host_shares(host0, host_times())
    if world.poll() is None:
        world.kill()
    world.wait()
    reader.join(timeout=10)
    fleet.send_signal(signal.SIGTERM)
    fleet_out, _ = fleet.communicate(timeout=30)
    fleet_cpu = next((json.loads(x)["fleet_cpu_s"] for x in fleet_out.splitlines() if x.startswith("{")), math.nan)
    doc_line = {k: json.loads(line.split(" ", 1)[1]) for line in lines for k in ("START", "DONE")
                if line.startswith(k + " ")}
    if "DONE" not in doc_line or not (out / "outcome.json").exists():
        return {"robots": n, "error": f"no DONE line or outcome.json ({sorted(doc_line)}, exit {world.returncode}): "
                + "".join(lines)[-1500:]}
    outcome = json.loads((out / "outcome.json").read_text())
    ticks = max(1, outcome["ticks"])
    cpu = doc_line["DONE"]["cpu_s"] - doc_line["START"]["cpu_s"]
    log_bytes = sum(p.stat().st_size for p in out.glob("run*.mcap"))
    return {
        "robots": n,
        "ticks": ticks,
        "world_cpu_ms_per_tick": 1000 * cpu / ticks,
        "deadline_misses": outcome["deadline_misses"],
        "latency_ms": outcome["sense_to_command_ms"],
        "world_peak_mb": None if peak is None else peak / 1024,
        "log_bytes_per_s": log_bytes / max(outcome["sim_seconds"], TICK_S),
        "fleet_cpu_ms_per_tick": 1000 * fleet_cpu / ticks,
        "steal": host.get("steal"),
        "left_out": outcome.get("readings_left_out"),
        "dropped": outcome.get("dropped_messages"),
    }


def in_process(n: int, ticks: int, tmp: Path) -> float:
    """CPU ms per tick of the same world stepped in this process with the same commands."""
    from world import World, load_scenario
    from world.run_episode import make_episode
    from world.tracking import run_kind

    sc = load_scenario(str(tmp / f"fleet{n}.toml"))
    world = World(sc, seed=None)
    ep = make_episode(world, run_kind(sc), None, ticks + 1)
    commands = {r: wheel_speeds(i) for i, r in enumerate(world.robot_ids)}
    t0 = time.process_time()
    for _ in range(ticks):
        ep.readings()
        ep.apply(commands)
        if ep.done:
            break
        ep.advance()
    return 1000 * (time.process_time() - t0) / ticks


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robots", default="32,64,128,256,512,1024")
    ap.add_argument("--sim", type=float, default=10.0, help="sim (= wall) seconds of each run")
    ap.add_argument("--port", type=int, default=7481)
    ap.add_argument("--fake-fleet", metavar="SPEC", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.fake_fleet:
        fake_fleet(args.fake_fleet)
        return
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for n in (int(x) for x in args.robots.split(",")):
            row = served(n, args.sim, args.port, Path(tmp))
            if "error" not in row:
                row["in_process_ms_per_tick"] = in_process(n, row["ticks"], Path(tmp))
            rows.append(row)
            print(f"  {n} robots done", file=sys.stderr, flush=True)
    print(f"load average {os.getloadavg()[0]:.1f}; the world server against a FAKE FLEET (one process answering "
          f"every robot's command); {args.sim:g} s of real time per row; a tick is {1000 * TICK_S:g} ms")
    print(
        "| robots | world CPU ms/tick | per robot-tick ms | one core | in-process ms/tick | x in-process "
        "| misses / robot-ticks | latency p50 / p99 ms | world peak MB | log KB/s | fake fleet CPU ms/tick | stolen |"
    )
    print("|---:|---:|---:|---:|---:|---:|---|---|---:|---:|---:|---:|")
    for r in rows:
        if "error" in r:
            print(f"| {r['robots']} | failed: {r['error'][-300:]!r} |")
            continue
        lat = r["latency_ms"] or {}
        w, ip = r["world_cpu_ms_per_tick"], r["in_process_ms_per_tick"]
        steal = "?" if r["steal"] is None else f"{100 * r['steal']:.0f} %"
        print(f"| {r['robots']} | {w:.1f} | {w / r['robots']:.3f} | {100 * w / (1000 * TICK_S):.0f} % | {ip:.1f} | "
              f"{w / ip:.1f}x | {r['deadline_misses']} / {r['robots'] * r['ticks']} | {lat.get('p50', math.nan)} / "
              f"{lat.get('p99', math.nan)} | {r['world_peak_mb'] or math.nan:.0f} | {r['log_bytes_per_s'] / 1024:.0f} "
              "| "
              f"{r['fleet_cpu_ms_per_tick']:.1f} | {steal} |")
    print(json.dumps(rows))


if __name__ == "__main__":
    main()
