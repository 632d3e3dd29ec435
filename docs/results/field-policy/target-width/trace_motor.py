"""The motor EKM tick by tick on one generated navigation scenario (docs/fields.md, "What the
corridor entrances say"), run from the repository's root:

  python docs/results/field-policy/target-width/trace_motor.py [SEED] [FROM_S] [TO_S] [POLICY]

Default: validation seed 2,000,116 from 3.4 s to 4.7 s with today's constants (W = 0). Each
line: the robot's pose, what each distance sensor's winner says (sensor, d in m, alpha in
degrees), the target input, its winner s and the motor winner k as (alpha, d) of their
neurons, e_k (Eq. 9) and the command (Eq. 11).
"""

from __future__ import annotations

import math
import sys

from cekm_swarm.experiments.graph_run import GraphSession
from cekm_swarm.node.graph_check import check_graph
from cekm_swarm.tune.graphs import policy_graph
from cekm_swarm.tune.policy import FieldPolicy
from cekm_swarm.tune.rollout import _model
from cekm_swarm.tune.scenarios import navigation_scenario


def trace(seed: int, t0: float, t1: float, policy: str | None) -> None:
    params = {"policy": policy} if policy else {"weights": (0.0,) * FieldPolicy.size("navigation")}
    s = GraphSession(navigation_scenario(seed), graph=check_graph(policy_graph("navigation")), model=_model(None),
                     max_time=t1, params=params)
    motor = s.executor.node("r1", "motor")
    w, integrate = motor.ekm.w, motor.ekm.integrate

    def deg(k: int) -> str:
        return f"({math.degrees(w[k, 0]):.0f} deg, {w[k, 1]:.3f} m)"

    def watched(target, obstacles):
        obstacles = list(obstacles)
        out = integrate(target, obstacles)
        if s.episode.t >= t0 and target is not None and target.a is not None:
            e = target.a.copy()
            for ob in obstacles:
                if ob.b is not None:
                    e -= ob.b
            seen = [(f.index, round(float(w[f.winner, 1]), 3), round(math.degrees(w[f.winner, 0])))
                    for f in obstacles if f.winner is not None]
            x, y, th = s.world.pose("r1")
            print(f"t={s.episode.t:.3f} pose=({x:.3f}, {y:.3f}, {th:.2f}) seen={seen} "
                  f"target=({math.degrees(target.alpha):.0f} deg, {target.d:.2f} m) s={deg(target.winner)} "
                  f"k={deg(out.k)} e_k={e[out.k]:.3f} c=({out.v_l:.3f}, {out.v_r:.3f})")
        return out

    motor.ekm.integrate = watched
    while not s.step():
        pass
    print(s.episode.outcome()["r1"]["collisions_with"])


if __name__ == "__main__":
    a = sys.argv[1:]
    trace(int(a[0]) if a else 2_000_116, float(a[1]) if len(a) > 1 else 3.4, float(a[2]) if len(a) > 2 else 4.7,
          a[3] if len(a) > 3 else None)
