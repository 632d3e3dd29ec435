"""The guard on validation seeds (docs/fields.md, "The ninth round"): section 4.2's rooms and
checkpoints, seeds 2,000,000 onward, with the default motor as it ships and with its guard off
(``guard`` false: the eighth round's motor).

For each: the runs that reach the goal without a contact, and what the others touched (a
doorway jamb is a wall, a disc an obstacle); and the ticks the guard replaced the command.

Run: python docs/results/field-policy/guard/validate.py [--runs 200] [--scenarios rooms,checkpoints]
(about six minutes on 2 cores)
"""

from __future__ import annotations

import argparse
from collections import Counter
from concurrent.futures import ProcessPoolExecutor

from cekm_swarm.experiments.field_widths import policy_graph
from cekm_swarm.experiments.graph_run import GraphSession
from cekm_swarm.node.graph_check import check_graph
from cekm_swarm.tune.rollout import _model
from world import load_scenario

FIRST = 2_000_000  # validation seeds: apart from the held-out seeds 1-20 and the training seeds


def one(job: tuple[str, int, bool]) -> tuple[str, bool, int, bool, list[str], int]:
    """One run: (scenario, guard, seed, contact-free success, what was touched, guard replacements)."""
    scenario, seed, guard = job
    s = GraphSession(load_scenario(scenario), graph=check_graph(policy_graph("navigation")), model=_model(None),
                     seed=seed, max_time=300.0, params={"guard": guard})
    motor, replaced = s.executor.node("r1", "motor"), 0
    done = False
    while not done:
        done = s.step()
        replaced += motor.last_guarded
    o = s.episode.outcome()["r1"]
    s.executor.close()
    touched = ["disc" if name.startswith("obstacles") else "wall" for name in o["collisions_with"]]
    return scenario, guard, seed, bool(o["reached"]) and o["collisions"] == 0, touched, replaced


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=200)
    ap.add_argument("--scenarios", default="rooms,checkpoints")
    a = ap.parse_args()
    jobs = [(sc, seed, guard) for sc in a.scenarios.split(",") for guard in (False, True)
            for seed in range(FIRST, FIRST + a.runs)]
    with ProcessPoolExecutor(2) as pool:
        rows = list(pool.map(one, jobs, chunksize=4))
    print(f"| scenario (validation seeds {FIRST:,}-{FIRST + a.runs - 1:,}) | guard | contact-free | runs touching "
          "a wall | runs touching a disc | guard replacements |")
    print("|---|---|---|---|---|---|")
    for sc in a.scenarios.split(","):
        for guard in (False, True):
            mine = [r for r in rows if r[0] == sc and r[1] == guard]
            touched = Counter(kind for r in mine for kind in set(r[4]))
            print(f"| {sc} | {'on (the default)' if guard else 'off'} | {sum(r[3] for r in mine)}/{len(mine)} | "
                  f"{touched['wall']} | {touched['disc']} | {sum(r[5] for r in mine)} |")


if __name__ == "__main__":
    main()
