"""Controller step cost: one tick of the cooperative EKM for one robot, i.e. the target
localization, 12 obstacle localizations (all sensors seeing something: the worst case)
and the motor EKM's integration and Eq. 11.

Baseline, measured in the same run: the same tick with the readable numpy reference
functions (models.competition.winner, models.fields.*). Goal (issue 3): at most 50 us.

Run: python benchmarks/bench_controller.py
"""

from __future__ import annotations

import time

import numpy as np

GOAL_US = 50.0


def main() -> None:
    from cekm_swarm.controller.cooperative import CooperativeEKM
    from cekm_swarm.controller.readings import RangeReading, TargetReading
    from cekm_swarm.experiments.default_model import default_model
    from cekm_swarm.models.competition import winner
    from cekm_swarm.models.fields import integrate, motor_control, motor_winner, obstacle_field, target_field
    from cekm_swarm.models.params import FieldParams

    model = default_model()
    ekm = CooperativeEKM(model)
    rng = np.random.default_rng(0)
    angles = np.array([np.angle(np.exp(2j * np.pi * j / 12)) for j in range(12)])
    cases = []
    for _ in range(200):
        target = TargetReading(float(rng.uniform(-np.pi, np.pi)), float(rng.uniform(0.01, 2.0)))
        ranges = [RangeReading(j, float(angles[j]), float(rng.uniform(0.03, 0.2))) for j in range(12)]
        cases.append((target, ranges))

    def fast_tick(target, ranges):
        t = ekm.localize_target(target, 0.0)
        obs = ekm.localize_obstacles(ranges, 0.0)
        return ekm.integrate(t, obs)

    fp = FieldParams()

    def reference_tick(target, ranges):
        u = np.array([target.alpha, target.d])
        s = winner(u, model.w, model.comp)
        a = target_field(model.w, s, fp)
        bs = [obstacle_field(model.w, winner(np.array([r.alpha, r.d]), model.w, model.comp), fp) for r in ranges]
        e = integrate(a, bs)
        k = motor_winner(np.where(ekm.eligible, e, -np.inf))  # the same motor candidates
        return motor_control(model.M, model.w, u, k, s, model.v_max, model.learn_p.d_scale)

    for target, ranges in cases[:5]:  # compile / warm up, and check the two agree
        f = fast_tick(target, ranges)
        r = np.clip(reference_tick(target, ranges), -model.v_max, model.v_max)
        assert np.allclose([f.v_l, f.v_r], r), "fast and reference ticks disagree"

    def per_tick(fn, repeat=5):
        best = np.inf
        for _ in range(repeat):
            t0 = time.perf_counter()
            for target, ranges in cases:
                fn(target, ranges)
            best = min(best, (time.perf_counter() - t0) / len(cases))
        return best * 1e6

    ref = per_tick(reference_tick)
    fst = per_tick(fast_tick)
    print(f"controller tick, 12 sensors all seeing, {model.w.shape[0]} neurons (best of 5 x {len(cases)} ticks)")
    print(f"  baseline (numpy reference): {ref:8.1f} us")
    print(f"  controller (numba modules): {fst:8.1f} us   x{ref / fst:.1f} faster; goal <= {GOAL_US:.0f} us: "
          f"{'met' if fst <= GOAL_US else 'NOT met'}")


if __name__ == "__main__":
    main()
