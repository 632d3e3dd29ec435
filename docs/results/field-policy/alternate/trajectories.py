"""Fig. 9's long shallow U (2.0 m wide, 0.12 m deep, sensing range 0.12 m) on validation seeds,
the robot's path with the policy's widths only (``alternate`` 0, the ninth round's motor) and
with the paper's widths in turn (the default): the ticks in the paper's turn drawn in red.

Run: python docs/results/field-policy/alternate/trajectories.py [--seeds 2000014,2000005]
     [--out docs/results/field-policy/alternate/trajectories.png]   (about 20 s)
"""

from __future__ import annotations

import argparse

from cekm_swarm.experiments.graph_run import GraphSession
from cekm_swarm.tune.motor import PAPER
from world import load_scenario

CELL = {"obstacles[0].width": 2.0, "obstacles[0].depth": 0.12, "sensors.range": 0.12}


def path(seed: int, alternate: float) -> tuple[list[tuple[float, float, bool]], dict]:
    """The robot's (x, y, paper's turn) each tick, and the run's outcome."""
    s = GraphSession(load_scenario("concave", overrides=CELL), "cekm", seed=seed, max_time=300.0,
                     params={"alternate": alternate})
    motor, out = s.executor.node("r1", "motor"), []
    done = False
    while not done:
        done = s.step()
        x, y = s.world.pose("r1")[:2]
        out.append((x, y, motor.last_choice is PAPER))
    o = s.episode.outcome()["r1"]
    s.executor.close()
    return out, o


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", default="2000014,2000005")
    ap.add_argument("--out", default="docs/results/field-policy/alternate/trajectories.png")
    a = ap.parse_args()
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    seeds = [int(s) for s in a.seeds.split(",")]
    sc = load_scenario("concave", overrides=CELL)
    fig, axes = plt.subplots(len(seeds), 2, figsize=(8, 5.2 * len(seeds)), squeeze=False)
    for row, seed in zip(axes, seeds, strict=True):
        for ax, (alternate, label) in zip(row, ((0.0, "policy's widths only (alternate 0)"),
                                                (20.0, "paper's widths in turn (default, 20 s)")), strict=True):
            pts, o = path(seed, alternate)
            ax.fill(*zip(*sc.obstacles[0].outline, strict=True), color="k")
            ax.plot(*sc.targets[0].position, "g*", ms=14)
            for paper in (False, True):
                xs = [p[0] for p in pts if p[2] == paper]
                ys = [p[1] for p in pts if p[2] == paper]
                ax.scatter(xs, ys, s=1, c="tab:red" if paper else "tab:blue",
                           label="paper's widths" if paper else "policy's widths")
            ax.set_aspect("equal")
            ax.set_xlim(0.6, 2.2)
            ax.set_ylim(0.2, 2.8)
            verdict = f"reached in {o['time_s']:.0f} s" if o["reached"] else "not reached in 300 s"
            ax.set_title(f"seed {seed:,}: {label}\n{verdict}, {o['collisions']} contacts", fontsize=9)
            ax.legend(loc="lower left", fontsize=7, markerscale=6)
    fig.suptitle("Fig. 9's U 2.0 m wide, 0.12 m deep, sensing range 0.12 m (validation seeds)")
    fig.tight_layout()
    fig.savefig(a.out, dpi=80)
    print(f"wrote {a.out}")


if __name__ == "__main__":
    main()
