"""The tracking experiment's files: ``results.json``, ``tables.md`` (:func:`table_markdown`),
``tracking.png`` and one Fig.-13 picture per controller (:mod:`.tracking_figures`)."""

from __future__ import annotations

from typing import Any

from .. import jsonfile
from .tracking_run import CONTROLLERS, TrackingRun


def write_experiment(doc: dict[str, Any], pictures: dict[str, TrackingRun], out_dir) -> list:
    """results.json, tables.md, tracking.png, one Fig.-13 picture per controller."""
    from pathlib import Path

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .tracking_figures import plot_team_sizes, plot_tracking

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


def table_markdown(doc: dict[str, Any]) -> str:
    """tables.md: per team size, every controller's A with its 95 % interval."""
    lines = ["| robots | targets | " + " | ".join(f"A {c}" for c in CONTROLLERS) + " |",
             "|---:|---:|" + "---:|" * len(CONTROLLERS)]
    for c in doc["configs"]:
        cells = []
        for ctl in CONTROLLERS:
            a = c["controllers"][ctl]["A"]
            cells.append(f"{a['mean']:.3f} [{a['ci95'][0]:.3f}, {a['ci95'][1]:.3f}]")
        lines.append(f"| {c['robots']} | {c['targets']} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"
