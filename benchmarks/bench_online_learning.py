"""Online learning through the runtime (docs/learning.md), in one run:

* learning steps per second (R15, RLS): the section 4.1 kernel's numba update
  (``models.fast.learn``, the baseline), the models' numpy rule the learner applies
  (``IndirectEKM.learn``), the learner node's run (v from the odometry record, then the
  rule), a whole learning graph in one process (``cekm run --learn``: one step per tick),
  and through the runtime in lockstep (``cekm launch --learn --mode lockstep``);
* a robot's CPU per tick in lockstep, the cekm graph with and without learning, on the
  same scenario and seed (the launcher's own measure, ``launcher.cpu``), launches of the
  two alternated and their medians compared; goal: within 1.5x. Both must run the same
  ticks (the default 15 s of concave ends before either robot reaches its goal): a run
  that stops early averages over another stretch of the path (in concave the first
  seconds, beside the U, cost most), so launches of unequal length are reported as such.

Wall-clock numbers on a shared host are inflated: the host's load and steal are printed.
Run: python benchmarks/bench_online_learning.py [--sim-seconds 15] [--pairs 5]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

GOAL_RATIO = 1.5


def rate(fn, n: int) -> float:
    t = time.perf_counter()
    for i in range(n):
        fn(i)
    return n / (time.perf_counter() - t)


def launch(scenario: str, out: Path, sim: float, learn: bool) -> dict:
    from cekm_swarm.runtime.config import free_port

    args = [sys.executable, "-m", "cekm_swarm", "launch", scenario, "--mode", "lockstep", "--seed", "1",
            "--max-time", str(sim), "--out", str(out), "--port", str(free_port()), "--no-plot"]
    t = time.perf_counter()
    subprocess.run(args + (["--learn"] if learn else []), check=True, capture_output=True)
    doc = json.loads((out / "outcome.json").read_text())
    doc["wall"] = time.perf_counter() - t
    return doc


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sim-seconds", type=float, default=15.0)
    ap.add_argument("--pairs", type=int, default=5, help="launches of each graph, alternated; the medians compared")
    a = ap.parse_args()
    from cekm_swarm.experiments.default_model import default_model
    from cekm_swarm.experiments.graph_run import resolve_graph, run_graph, with_params
    from cekm_swarm.experiments.learning_run import learning_params, untrained_model
    from cekm_swarm.models import fast
    from cekm_swarm.modules.learner import Learner, copy_model
    from cekm_swarm.node.api import Context, Inputs, start_node
    from cekm_swarm.protocol import SenseOdometry
    from cekm_swarm.ticks import TICK_S
    from world import load_scenario

    print("load:", Path("/proc/loadavg").read_text().strip())
    rng = np.random.default_rng(0)
    vs = np.stack([rng.uniform(-np.pi, np.pi, 4096), rng.uniform(0.0, 0.16, 4096)], axis=1)
    cs = rng.uniform(-0.08, 0.08, (4096, 2))
    net = copy_model(untrained_model())
    w, P, R = fast.network_arrays(net)
    p = fast.pack_params(net.comp, net.learn_p, net.v_max, 1e-3)
    idx, g = np.zeros(net.lattice.n, dtype=np.int64), np.zeros(net.lattice.n)
    fast.learn(fast.KIND_RLS, 0.1, 0.05, 0.01, 0.02, 0.0, w, P, R, 15, p, idx, g)  # compile
    kernel = rate(lambda i: fast.learn(fast.KIND_RLS, vs[i % 4096, 0], vs[i % 4096, 1], cs[i % 4096, 0],
                                       cs[i % 4096, 1], float(i), w, P, R, 15, p, idx, g), 20000)
    ref = rate(lambda i: net.learn(vs[i % 4096], cs[i % 4096], float(i)), 2000)
    node = start_node(Learner, Context("r1", "learner", None, ("r1",), model_source=untrained_model(),
                                       backend="numpy"), Learner.Params(start_step=0))

    def run(i):
        k = 8 * (i + 1)
        ticks = tuple(range(k - 7, k + 1))
        odo = SenseOdometry(k * TICK_S, "world", ticks, (0.05,) * 8, (0.06,) * 8, (0.0064,) * 8, (0.0077,) * 8,
                            (False,) * 8, TICK_S)
        node.step(k * TICK_S, Inputs({"odometry": odo}))

    node_rate = 8 * rate(run, 250)
    checked = with_params(resolve_graph("cekm-learning", None, "navigation"), learning_params("untrained"))
    t = time.perf_counter()
    g_run = run_graph(load_scenario("training"), graph=checked, model=untrained_model(), max_time=a.sim_seconds)
    graph_rate = g_run.executor.node("r1", "learner").counts.steps / (time.perf_counter() - t)
    default_model()
    plains, learns = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(a.pairs):  # alternated, so a change in the host's load falls on both
            plains.append(launch("concave", Path(tmp) / f"plain{i}", a.sim_seconds, False))
            learns.append(launch("concave", Path(tmp) / f"learn{i}", a.sim_seconds, True))
    plain = sorted(plains, key=lambda d: d["launcher"]["cpu"]["ms_per_robot_tick"])[len(plains) // 2]  # the median
    learn = sorted(learns, key=lambda d: d["launcher"]["cpu"]["ms_per_robot_tick"])[len(learns) // 2]
    lockstep_rate = learn["learning"]["r1"]["steps"] / learn["wall"]
    print(f"learning steps/s (R15, RLS): 4.1 kernel (numba) {kernel:,.0f} (baseline); models' numpy rule "
          f"{ref:,.0f} ({ref / kernel:.3f}x); learner node {node_rate:,.0f} ({node_rate / kernel:.3f}x); "
          f"learning graph in one process {graph_rate:,.0f} ({graph_rate / kernel:.4f}x); lockstep launch "
          f"(incl. start-up) {lockstep_rate:,.0f} ({lockstep_rate / kernel:.5f}x)")
    cp, cl = plain["launcher"]["cpu"], learn["launcher"]["cpu"]
    ratio = cl["ms_per_robot_tick"] / cp["ms_per_robot_tick"]
    every = [round(d["launcher"]["cpu"]["ms_per_robot_tick"], 2) for d in plains + learns]
    print(f"CPU per robot-tick, every launch (cekm x{a.pairs}, then cekm-learning x{a.pairs}): {every}")
    pairs = [round(lr["launcher"]["cpu"]["ms_per_robot_tick"] / pr["launcher"]["cpu"]["ms_per_robot_tick"], 2)
             for pr, lr in zip(plains, learns, strict=True)]
    ticks = sorted({d["launcher"]["cpu"]["ticks"] for d in plains + learns})
    print(f"each pair's ratio (launched one after the other): {pairs}; ticks measured: {ticks}"
          + ("" if len(ticks) == 1 else " - NOT the same stretch of the run: a robot reached its goal early"))
    for kind in sorted(learn["launcher"]["cpu"]["ms_per_tick"]):
        med = [float(np.median([d["launcher"]["cpu"]["ms_per_tick"].get(kind, 0.0) for d in ds]))
               for ds in (plains, learns)]
        print(f"  {kind}: {med[0]:.3f} -> {med[1]:.3f} ms per tick (medians)")
    print(f"CPU per robot-tick, lockstep, concave seed 1, {a.sim_seconds:g} s, medians: cekm "
          f"{cp['ms_per_robot_tick']:.2f} ms "
          f"{cp['ms_per_tick']}, cekm-learning {cl['ms_per_robot_tick']:.2f} ms {cl['ms_per_tick']}: "
          f"{ratio:.2f}x (goal <= {GOAL_RATIO}x: {'met' if ratio <= GOAL_RATIO else 'NOT met'}); steal "
          f"{cp['host']} / {cl['host']}")
    print("load:", Path("/proc/loadavg").read_text().strip())


if __name__ == "__main__":
    main()
