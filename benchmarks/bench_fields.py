"""Field-policy training speed (docs/fields.md): environment steps per second of the
Gymnasium environment (:mod:`cekm_swarm.tune.env`) and ticks per second of a training's
run (the field-policy motor with a policy's weights W, and with per-field weights V too:
Eq. 8 per field with its own widths), against a plain ``cekm run`` of the same scenario
measured in the same run (the baseline: the shipped constant-width graph, ``cekm-tuned``
for navigation, in process), and the default ``cekm run`` (for navigation the shipped
field policy) beside it.

Every variant runs the same scenario to the same end; the best of ``--repeat`` timings
counts, the variants interleaved. The host's load and steal are printed beside: numbers taken on a shared machine
are inflated by its other work.

Run: python benchmarks/bench_fields.py [--scenario rooms] [--repeat 5]
"""

from __future__ import annotations

import argparse
import itertools
import subprocess
import time

import numpy as np


def best_of(fns: dict, repeat: int) -> dict[str, tuple[float, int]]:
    """The best time and the ticks of each variant, the variants interleaved round by round
    (so a burst of the host's other work does not fall on one of them only)."""
    best = {k: (np.inf, 0) for k in fns}
    for _ in range(repeat):
        for k, fn in fns.items():
            t0 = time.perf_counter()
            ticks = fn()
            best[k] = (min(best[k][0], time.perf_counter() - t0), ticks)
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="rooms")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--ticks-per-action", type=int, default=8)
    args = ap.parse_args()

    from cekm_swarm.experiments.default_model import default_model
    from cekm_swarm.experiments.field_widths import CONSTANT_GRAPH, policy_graph
    from cekm_swarm.experiments.graph_run import run_graph
    from cekm_swarm.node.graph_check import check_graph
    from cekm_swarm.tune.env import FieldEnv
    from cekm_swarm.tune.features import N_FEATURES, N_FIELD_FEATURES
    from world import load_scenario

    sc = load_scenario(args.scenario)
    model = default_model()
    task = "tracking" if sc.robots[0].goal is None else "navigation"
    max_time = 60.0 if task == "tracking" else 600.0
    env = FieldEnv(task, sc, ticks_per_action=args.ticks_per_action, max_time=max_time, model=model)
    zero = np.zeros(env.action_space.shape, dtype=np.float32)
    rng = np.random.default_rng(0)
    W = tuple(rng.normal(0, 0.3, len(env.policy.outputs) * N_FEATURES).tolist())
    WV = W + tuple(rng.normal(0, 0.3, 3 * N_FIELD_FEATURES).tolist())
    checked = check_graph(policy_graph(task))

    def plain():
        return run_graph(sc, CONSTANT_GRAPH[task], model=model, max_time=max_time).ticks

    def default():
        return run_graph(sc, "cekm", model=model, max_time=max_time).ticks

    def trained():
        return run_graph(sc, graph=checked, params={"weights": W}, model=model, max_time=max_time).ticks

    steps = {"n": 0}

    def per_field():
        return run_graph(sc, graph=checked, params={"weights": WV}, model=model, max_time=max_time).ticks

    def stepped():
        env.reset(seed=0)
        steps["n"] = 0
        for a in itertools.repeat(zero):
            _, _, term, trunc, _ = env.step(a)
            steps["n"] += 1
            if term or trunc:
                break
        return env.session.episode.tick

    plain()  # warm up (compile, caches)
    res = best_of({"plain": plain, "default": default, "env": stepped, "policy": trained, "per_field": per_field},
                  args.repeat)
    (base_s, base_ticks), (env_s, env_ticks), (pol_s, pol_ticks) = res["plain"], res["env"], res["policy"]
    pf_s, pf_ticks = res["per_field"]
    def_s, def_ticks = res["default"]
    print(f"scenario {args.scenario} ({task}), best of {args.repeat}")
    print(f"  cekm run, constant widths   {base_ticks:6d} ticks  {base_ticks / base_s:9.0f} ticks/s  (the baseline)")
    print(f"  cekm run, the default       {def_ticks:6d} ticks  {def_ticks / def_s:9.0f} ticks/s  "
          f"ratio {base_s / base_ticks / (def_s / def_ticks):.2f} of baseline ({task}: "
          f"{'the shipped policy' if task == 'navigation' else 'constant widths'})")
    print(f"  environment, {args.ticks_per_action} ticks/step   {env_ticks:6d} ticks  {env_ticks / env_s:9.0f} ticks/s "
          " "
          f"{steps['n'] / env_s:8.1f} steps/s  ratio {base_s / base_ticks / (env_s / env_ticks):.2f} of baseline")
    print(f"  training run (a policy)     {pol_ticks:6d} ticks  {pol_ticks / pol_s:9.0f} ticks/s  "
          f"ratio {base_s / base_ticks / (pol_s / pol_ticks):.2f} of baseline")
    print(f"  training run, per-field (V) {pf_ticks:6d} ticks  {pf_ticks / pf_s:9.0f} ticks/s  "
          f"ratio {base_s / base_ticks / (pf_s / pf_ticks):.2f} of baseline")
    with open("/proc/loadavg") as f:
        print(f"  host load: {f.read().strip()}")
    try:
        vm = subprocess.run(["vmstat", "1", "3"], capture_output=True, text=True, timeout=10).stdout.splitlines()
        print(f"  vmstat 1 3, last line: {dict(zip(vm[1].split()[-5:], vm[-1].split()[-5:], strict=False))}")
    except (OSError, subprocess.SubprocessError, IndexError):
        pass


if __name__ == "__main__":
    main()
