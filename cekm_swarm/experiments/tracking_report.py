"""The tracking experiment's files: ``results.json``, ``tables.md`` (:func:`table_markdown`),
``tracking.png`` and one Fig.-13 picture per controller (:mod:`.tracking_figures`)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from .. import jsonfile
from .tracking_figures import plot_team_sizes, plot_tracking
from .tracking_run import CONTROLLERS, TrackingRun


def write_experiment(doc: dict[str, Any], pictures: dict[str, TrackingRun], out_dir) -> list:
    """results.json, tables.md, tracking.png, one Fig.-13 picture per controller."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    (out / "results.json").write_text(jsonfile.dumps(doc))
    written.append(out / "results.json")
    (out / "tables.md").write_text(table_markdown(doc))
    written.append(out / "tables.md")
    fig = plot_team_sizes(doc)
    fig.savefig(out / "tracking.png", dpi=120)
    plt.close(fig)
    written.append(out / "tracking.png")
    for ctl, run in pictures.items():
        fig = plot_tracking(run)
        fig.savefig(out / f"fig13_{ctl}.png", dpi=120)
        plt.close(fig)
        written.append(out / f"fig13_{ctl}.png")
    return written


COMPARED = ("acmommt", "kmeans", "kmeans-global")
"""The controllers cekm is compared with in tables.md (Welch's p over the seeds)."""


def table_markdown(doc: dict[str, Any]) -> str:
    """tables.md: per team size, every controller's A with its 95 % interval, and cekm
    against each baseline: Welch's two-sided p over the seeds, and on how many seeds
    (the same scenario for every controller) cekm's A is the higher."""
    compared = [c for c in COMPARED if c in CONTROLLERS]
    lines = ["| robots | targets | " + " | ".join(f"A {c}" for c in CONTROLLERS) + " | "
             + " | ".join(f"cekm vs {c} (Welch p; seeds cekm higher)" for c in compared) + " |",
             "|---:|---:|" + "---:|" * len(CONTROLLERS) + "---|" * len(compared)]
    for c in doc["configs"]:
        cells = []
        for ctl in CONTROLLERS:
            a = c["controllers"][ctl]["A"]
            cells.append(f"{a['mean']:.3f} [{a['ci95'][0]:.3f}, {a['ci95'][1]:.3f}]")
        cells += [_versus(c["controllers"]["cekm"]["per_seed"], c["controllers"][b]["per_seed"]) for b in compared]
        lines.append(f"| {c['robots']} | {c['targets']} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def _versus(cekm: list[float], other: list[float]) -> str:
    from .metrics import welch_p  # noqa: PLC0415 -- lazy: scipy

    p = welch_p(cekm, other)
    higher = sum(1 for a, b in zip(cekm, other, strict=False) if a > b)
    return f"p = {'n/a' if p is None else f'{p:.2g}'}; {higher} of {min(len(cekm), len(other))}"
