"""The paper's widths in turn on validation seeds (docs/fields.md, "The tenth round"): the
navigation motor as it ships with its ``alternate`` period set to each value tried (0: the
ninth round's motor, the policy's widths only), on the two families where the policy's widths
and the paper's differ:

- Fig. 9's cell that the paper's constants negotiate and the ninth round's default did not:
  a U 2.0 m wide and 0.12 m deep, sensing range 0.12 m, the concave scenario's start and goal;
- generated U's (0.10-1.0 m wide, 0.06-0.30 m deep, ranges 0.12-0.25 m), where the paper's
  widths alone do worse: they hold the robot off a deep U's back wall, and it circles inside.

Both on validation seeds 2,000,000 onward (never reported as results), 300 s a run. For each
period: the runs reaching the goal without a contact, and against the period 0 the runs
only it / only the period 0 makes, with McNemar's exact two-sided p on those.

Run: python docs/results/field-policy/alternate/validate.py [--cell-runs 40] [--u-runs 300]
     [--periods 0,20,30,45,60]
(about four minutes on 2 cores)
"""

from __future__ import annotations

import argparse
import math
from concurrent.futures import ProcessPoolExecutor

from cekm_swarm.experiments.graph_run import run_graph
from cekm_swarm.tune.scenarios import navigation_raw, navigation_scenario
from world import load_scenario

FIRST = 2_000_000  # validation seeds: apart from the held-out seeds and the training seeds
CELL = {"obstacles[0].width": 2.0, "obstacles[0].depth": 0.12, "sensors.range": 0.12}


def one(job: tuple[str, int, float]) -> tuple[str, int, float, bool]:
    """One run: (family, seed, period, reached without a contact)."""
    family, seed, period = job
    if family == "cell":
        out = run_graph(load_scenario("concave", overrides=CELL), "cekm", seed=seed, max_time=300.0,
                        params={"alternate": period})
    else:
        out = run_graph(navigation_scenario(seed, kind="u"), "cekm", max_time=300.0, params={"alternate": period})
    o = out.episode.outcome()["r1"]
    return family, seed, period, bool(o["reached"]) and o["collisions"] == 0


def mcnemar(b: int, c: int) -> float:
    """Exact two-sided McNemar p for b and c discordant pairs."""
    n = b + c
    if n == 0:
        return 1.0
    tail = sum(math.comb(n, i) for i in range(min(b, c) + 1)) / 2 ** n
    return min(1.0, 2 * tail)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cell-runs", type=int, default=40)
    ap.add_argument("--u-runs", type=int, default=300)
    ap.add_argument("--periods", default="0,20,30,45,60")
    a = ap.parse_args()
    periods = [float(p) for p in a.periods.split(",")]
    if 0.0 not in periods:
        periods.insert(0, 0.0)
    runs = {"cell": a.cell_runs, "u": a.u_runs}
    jobs = [(fam, seed, p) for fam, n in runs.items() for p in periods for seed in range(FIRST, FIRST + n)]
    with ProcessPoolExecutor(2) as pool:
        ok = {(fam, seed, p): r for fam, seed, p, r in pool.map(one, jobs, chunksize=4)}
    print(f"| alternate (s) | U 2.0 x 0.12 m, range 0.12 m: contact-free /{a.cell_runs} | only this / only 0 | "
          f"generated U's: contact-free /{a.u_runs} | only this / only 0 (McNemar p) |")
    print("|---|---|---|---|---|")
    for p in periods:
        row = [f"{p:g}" + (" (the ninth round)" if p == 0 else "")]
        for fam, n in runs.items():
            seeds = range(FIRST, FIRST + n)
            mine = sum(ok[(fam, s, p)] for s in seeds)
            b = sum(ok[(fam, s, p)] and not ok[(fam, s, 0.0)] for s in seeds)
            c = sum(ok[(fam, s, 0.0)] and not ok[(fam, s, p)] for s in seeds)
            row += [str(mine), "-" if p == 0 else f"{b} / {c} (p {mcnemar(b, c):.2g})"]
        print("| " + " | ".join(row) + " |")
    fails = sorted(navigation_raw(s, kind="u")["name"] for s in range(FIRST, FIRST + a.u_runs)
                   if not ok[("u", s, 0.0)])
    print(f"\nGenerated U's the period 0 does not make: {', '.join(fails) or 'none'}")


if __name__ == "__main__":
    main()
