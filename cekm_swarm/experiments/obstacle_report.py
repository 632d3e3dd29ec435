"""The obstacle suite's files: ``outcomes.json``, ``table.md`` (the summary and every seed's
run, :func:`summary_markdown`, :func:`table_markdown`) and one picture per scenario
(:mod:`.obstacle_figures`)."""

from __future__ import annotations

from pathlib import Path

from .. import jsonfile
from .field_widths import REPRODUCTION
from .obstacle_figures import suite_figure
from .obstacle_run import FIGURE


def _pct(k: int, n: int, ci: list[float]) -> str:
    return f"{k}/{n} ({100 * ci[0]:.0f}-{100 * ci[1]:.0f} %)"


def _mm(metres: float | None) -> str:
    return "-" if metres is None else f"{1000 * metres:.1f}"


def _label(controller: str, doc: dict) -> str:
    """cekm's row names its field widths when they are not the paper's method's."""
    fields = doc.get("fields", REPRODUCTION)
    return f"cekm ({fields} widths)" if controller == "cekm" and fields != REPRODUCTION else controller


def summary_markdown(doc: dict) -> str:
    """One row per scenario and controller: success and collision-free success with their
    95 % intervals, contacts, runs with a contact, smallest clearance."""
    lines = ["| scenario | controller | success (95 % CI) | collision-free success (95 % CI) | contacts | "
             "runs with a contact | min clearance (mm) |", "|---|---|---|---|---:|---:|---:|"]
    for s, per in doc["summary"].items():
        fig = FIGURE.get(s)
        name = f"{s} (Fig. {fig})" if fig else s
        for c, t in per.items():
            lines.append(f"| {name} | {_label(c, doc)} | {_pct(t['success'], t['of'], t['success_ci95'])} | "
                         f"{_pct(t['collision_free'], t['of'], t['collision_free_ci95'])} | {t['contacts']} | "
                         f"{t['runs_with_contact']} | {_mm(t['min_clearance_m'])} |")
    return "\n".join(lines)


def table_markdown(doc: dict) -> str:
    """Per seed: success, sim time, contacts (and checkpoints passed)."""
    lines = ["| scenario | controller | " + " | ".join(f"seed {s}" for s in doc["seeds"]) + " | success |",
             "|---|---|" + "---|" * (len(doc["seeds"]) + 1)]
    for s, per in doc["summary"].items():
        for c, tally in per.items():
            cells = []
            for seed in doc["seeds"]:
                r = next(x for x in doc["runs"] if x["scenario"] == s and x["controller"] == c and x["seed"] == seed)
                mark = "yes" if r["success"] else "no"
                extra = f", {r['checkpoints_reached']}/{r['checkpoints']} cp" if s == "checkpoints" else ""
                cells.append(f"{mark} {r['time_s']:.0f} s, {r['collisions']} coll.{extra}")
            lines.append(f"| {s} | {_label(c, doc)} | " + " | ".join(cells) + f" | {tally['success']}/{tally['of']} |")
    return "\n".join(lines)


def write_suite(doc: dict, pictures: dict, out_dir: Path) -> list[Path]:
    """outcomes.json, table.md and one picture per scenario (controllers side by side)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir.mkdir(parents=True, exist_ok=True)
    written = [out_dir / "outcomes.json", out_dir / "table.md"]
    written[0].write_text(jsonfile.dumps(doc))
    written[1].write_text(summary_markdown(doc) + "\n\nPer seed:\n\n" + table_markdown(doc) + "\n")
    for s in doc["summary"]:
        runs = [pictures[(s, c)] for c in ("fusion", "cekm") if (s, c) in pictures]
        if not runs:
            continue
        fig = suite_figure(s, runs)
        fig_no = FIGURE[s]
        path = out_dir / (f"fig{fig_no}_{s}.png" if fig_no else f"{s}.png")
        fig.savefig(path, dpi=110)
        plt.close(fig)
        written.append(path)
    return written
