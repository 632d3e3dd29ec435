"""Checks of the default switch (docs/fields.md, "The default") that the held-out set does
not make: a team (crossing's three robots, seeds 1-20) and a small disc head-on (the
two-robot scenario of tests/runtime/test_launch_realtime.py, r1's start moved by up to
1 cm and turned by up to 0.15 rad, at three sensing ranges). Each with the learned
widths (cekm, the default) and the constants (cekm-tuned).

Run: python docs/results/field-policy/default/checks.py [--out DIR] (about a minute on 2 cores)
"""

from __future__ import annotations

import argparse
import json
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from cekm_swarm.experiments.navigation_run import run_scenario
from world import load_scenario
from world.scenario import parse_scenario

PAIR = {"name": "pair", "seed": 1, "arena": {"bounds": [0.0, 0.0, 1.4, 1.2]},
        "robots": [{"id": "r1", "start": [0.2, 0.35, 0.0], "goal": "g1"},
                   {"id": "r2", "start": [0.2, 0.85, 0.0], "goal": "g2"}],
        "targets": [{"id": "g1", "position": [1.0, 0.35]}, {"id": "g2", "position": [0.75, 0.85]}],
        "obstacles": [{"id": "disc", "shape": "disc", "center": [0.6, 0.35], "radius": 0.04}]}
CONTROLLERS = ("cekm", "cekm-tuned")


def _run(job: tuple) -> dict:
    check, controller, where = job
    if check == "crossing":
        sc, seed = load_scenario("crossing"), where
    else:
        dy, th, rng = where
        doc = json.loads(json.dumps(PAIR))
        doc["robots"][0]["start"] = [0.2, 0.35 + dy, th]
        doc["sensors"] = {"range": rng}
        sc, seed = parse_scenario(doc, "pair"), 1
    out = run_scenario(sc, controller, None, seed, 60.0).outcome
    robots = out if check == "crossing" else {"r1": out["r1"]}
    return {"check": check, "controller": controller, "where": where,
            "robots": {r: {"reached": o["reached"], "collisions": o["collisions"]} for r, o in robots.items()}}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--out", type=Path, default=Path(__file__).parent)
    args = ap.parse_args()
    starts = [(round(float(dy), 4), round(float(th), 3), rng) for dy in np.linspace(-0.01, 0.01, 9)
              for th in np.linspace(-0.15, 0.15, 7) for rng in (0.12, 0.17, 0.25)]
    jobs = [("crossing", c, s) for c in CONTROLLERS for s in range(1, 21)] + \
           [("pair", c, w) for c in CONTROLLERS for w in starts]
    with ProcessPoolExecutor(2) as ex:
        rows = list(ex.map(_run, jobs))
    summary = {}
    for check in ("crossing", "pair"):
        for c in CONTROLLERS:
            rs = [o for r in rows if r["check"] == check and r["controller"] == c for o in r["robots"].values()]
            summary[f"{check} {c}"] = {"robot_runs": len(rs), "reached": sum(o["reached"] for o in rs),
                                       "contact_free": sum(o["reached"] and o["collisions"] == 0 for o in rs)}
            print(f"{check:9s} {c:11s}", summary[f"{check} {c}"])
    args.out.mkdir(parents=True, exist_ok=True)
    runs = ",\n  ".join(json.dumps(r) for r in rows)  # one run a line
    (args.out / "checks.json").write_text(f'{{"summary": {json.dumps(summary, indent=1)},\n "runs": [\n  {runs}\n]}}\n')
    print(f"wrote {args.out / 'checks.json'}")


if __name__ == "__main__":
    main()
