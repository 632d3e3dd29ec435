"""The trail field in pictures (docs/fields.md, "The seventh round"): generated U's of the
validation seeds that the robot circles in without the trail (``trail_gain`` 0) and leaves
with it (the default), side by side.

Run: python docs/results/field-policy/trail/u_paths.py [--out FILE] (about half a minute)
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from cekm_swarm.experiments.navigation_figures import plot_run
from cekm_swarm.experiments.navigation_run import run_scenario
from cekm_swarm.graph.spec import graph_path
from cekm_swarm.tune.scenarios import navigation_raw, navigation_scenario

SEEDS = (2_000_079, 2_000_125, 2_000_195)  # validation seeds of the default mix: U's the sixth round never left
MAX_TIME = 300.0  # as the validation runs


def main() -> None:
    import matplotlib  # noqa: PLC0415 -- lazy, as the package's figures

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("u-paths.png"))
    out = ap.parse_args().out
    shipped = graph_path("cekm-navigation").read_text(encoding="utf-8")
    off = shipped.replace('outputs = { command = "cmd/wheels" }',
                          'outputs = { command = "cmd/wheels" }\nparams = { trail_gain = 0.0 }')
    assert off != shipped
    fig, axes = plt.subplots(2, len(SEEDS), figsize=(5.5 * len(SEEDS), 9))
    with tempfile.TemporaryDirectory() as tmp:
        no_trail = Path(tmp) / "no-trail.toml"
        no_trail.write_text(off, encoding="utf-8")
        for col, seed in enumerate(SEEDS):
            name = navigation_raw(seed)["name"]
            for row, (graph, label) in enumerate(((no_trail, "trail_gain 0"), (None, "the default, trail_gain 0.3"))):
                run = run_scenario(navigation_scenario(seed), max_time=MAX_TIME, graph=graph)
                log = run.logs["r1"]
                verdict = f"reached in {log.reached_time:.0f} s" if log.reached else f"not reached in {MAX_TIME:.0f} s"
                plot_run(run, ax=axes[row][col], title=f"{name}, seed {seed}\n{label}: {verdict}")
    fig.tight_layout()
    fig.savefig(out, dpi=80)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
