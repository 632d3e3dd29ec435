"""Section 4.1's tables and files: Tables 1-4 from a results document beside the paper's
values, and the summary over master seeds, as Markdown; results.json, tables.md and the
figures (:mod:`.reaching_figures`) of a run, summary.json and summary.md of several seeds."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from .. import jsonfile
from ..models.io import save_model
from .reaching_figures import plot_all

if TYPE_CHECKING:
    from .reaching_config import NetworkRun, TargetReachingConfig

# The paper's published numbers (Low, Leow & Ang 2005, Tables 1-4), for side-by-side tables.
PAPER_TABLE1 = {  # E (mm), T (s/m), D: mean, std
    "B15": ((10.02, 3.81), (166.40, 28.49), (0.11, 0.06)),
    "D15": ((8.37, 2.25), (36.78, 11.11), (0.18, 0.15)),
    "G9": ((3.40, 1.83), (15.31, 4.64), (0.10, 0.04)),
    "G12": ((3.89, 1.61), (19.31, 8.47), (0.06, 0.02)),
    "G15": ((3.23, 0.66), (18.96, 4.37), (0.07, 0.02)),
    "R15": ((1.29, 0.14), (17.00, 2.48), (0.04, 0.01)),
}
PAPER_TABLE3 = {  # P(5), T(5) (s/m), D(5)
    "B15": ((0.84, 0.05), (144.70, 20.16), (0.04, 0.03)),
    "D15": ((0.54, 0.07), (18.61, 1.66), (0.18, 0.08)),
    "G9": ((0.95, 0.08), (8.83, 0.96), (0.07, 0.02)),
    "G12": ((0.92, 0.09), (8.48, 0.74), (0.03, 0.02)),
    "G15": ((0.86, 0.04), (8.96, 0.47), (0.06, 0.01)),
    "R15": ((1.00, 0.01), (8.85, 0.35), (0.03, 0.01)),
}
_ROWS = ("R15", "G9", "G12", "G15", "D15")
_COLS = ("B15", "D15", "G15", "G12", "G9")
_P = {  # the paper's t-test tables, row -> values in _COLS order (None: blank cell)
    "E_mm": {"R15": (0.00, 0.00, 0.00, 0.00, 0.02), "G9": (0.00, 0.00, 0.42, 0.33), "G12": (0.01, 0.00, 0.21),
             "G15": (0.00, 0.00), "D15": (0.22,)},
    "D": {"R15": (0.01, 0.04, 0.01, 0.04, 0.00), "G9": (0.43, 0.16, 0.09, 0.02), "G12": (0.04, 0.06, 0.09),
          "G15": (0.12, 0.09), "D15": (0.19,)},
    "T_s_per_m": {"R15": (0.00, 0.00, 0.20, 0.29, 0.25), "G9": (0.00, 0.00, 0.12, 0.19), "G12": (0.00, 0.01, 0.47),
                  "G15": (0.00, 0.01), "D15": (0.00,)},
    "P5": {"R15": (0.00, 0.00, 0.00, 0.04, 0.12), "G9": (0.02, 0.00, 0.03, 0.29), "G12": (0.06, 0.00, 0.11),
           "G15": (0.26, 0.00), "D15": (0.00,)},
    "T5_s_per_m": {"R15": (0.00, 0.00, 0.35, 0.17, 0.48), "G9": (0.00, 0.00, 0.40, 0.27), "G12": (0.00, 0.00, 0.13),
                   "G15": (0.00, 0.00), "D15": (0.00,)},
    "D5": {"R15": (0.12, 0.00, 0.00, 0.19, 0.00), "G9": (0.09, 0.01, 0.14, 0.02), "G12": (0.31, 0.00, 0.03),
           "G15": (0.20, 0.01), "D15": (0.00,)},
}
_LABEL = {"E_mm": "E (mm)", "T_s_per_m": "T (s/m)", "D": "D", "P5": "P(5)", "T5_s_per_m": "T(5) (s/m)", "D5": "D(5)"}


def _ms(entry: dict, digits: int) -> str:
    if entry is None or entry.get("mean") is None:
        return "n/a"
    return f"{entry['mean']:.{digits}f} ± {entry['std']:.{digits}f}"


def _paper(pair, digits: int) -> str:
    return f"{pair[0]:.{digits}f} ± {pair[1]:.{digits}f}"


def _network_table(networks: dict, keys: tuple[str, str, str], paper: dict, title: str, cell,
                   parameters: bool) -> list[str]:
    """Ours beside the paper's, one row per network; ``cell`` formats our entry (mean ±
    std of one run's trials, or a mean with its interval over master seeds)."""
    lines = [f"### {title}", "",
             "| Network | " + ("Parameters | " if parameters else "")
             + " | ".join(f"{_LABEL[k]} ours | {_LABEL[k]} paper" for k in keys) + " |",
             "|---|" + ("---:|" if parameters else "") + "---:|---:|" * len(keys)]
    for name, e in networks.items():
        cells = [str(e["parameters"])] if parameters else []
        for j, k in enumerate(keys):
            cells.append(cell(e.get(k), 2))
            cells.append(_paper(paper[name][j], 2) if name in paper else "")
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return lines


def _perf_table(results: dict, keys: tuple[str, str, str], paper: dict, title: str) -> list[str]:
    return _network_table(results["networks"], keys, paper, title, _ms, parameters=True)


def _p_table(results: dict, key: str) -> list[str]:
    """One t-test table in the paper's triangular layout: ours, with the paper's value in brackets."""
    names = set(results["networks"])
    rows = [r for r in _ROWS if r in names]
    cols = [c for c in _COLS if c in names]
    tt = results["t_tests"][key]
    lines = [f"**{_LABEL[key]}**: ours (paper)", "", "| | " + " | ".join(cols) + " |", "|---|" + "---:|" * len(cols)]
    for r in rows:
        paper_row = _P[key][r]
        cells = []
        for c in cols:
            ci = _COLS.index(c)
            if ci >= len(paper_row):
                cells.append("")
                continue
            p = tt.get(f"{r}|{c}", tt.get(f"{c}|{r}"))
            cells.append(("n/a" if p is None else f"{p:.2f}") + f" ({paper_row[ci]:.2f})")
        lines.append(f"| {r} | " + " | ".join(cells) + " |")
    return lines


def protocol_sentence(settings: dict) -> str:
    """One sentence on the stop rule, the plant and B15's rule of a run (from its settings)."""
    stop = settings.get("stop", {"rule": "goal"})
    unit = settings["arena"].get("speed_unit", 0.0)
    res = settings["arena"].get("target_resolution", 0.001)
    if stop["rule"] == "command":
        rule = (f"Stop rule 'command' (the paper's): a test target ends when the network's own command is 0 at the "
                f"motor's resolution, both wheels under {stop['motor_resolution'] * 500:g} mm/s (half the "
                f"{stop['motor_resolution'] * 1000:g} mm/s speed unit), or at the step budget")
    else:
        rule = ("Stop rule 'goal' (the project's earlier one): a test target ends at the goal state, where every "
                "network commands 0 (the sensed distance rounds to 0), or when the executed command is 0, or at the "
                "step budget")
    train = settings.get("train_stop", {"rule": "goal"})["rule"]
    plant = f"wheel speeds quantized to {unit * 1000:g} mm/s" if unit > 0 else "continuous wheel speeds"
    sensor = f"target sensor resolution {res * 1000:g} mm" if res > 0 else "target distances not rounded"
    return (f"{rule}; training targets end by the '{train}' rule; {plant}; {sensor}; "
            f"B15 rule '{settings.get('bfn_rule', 'trained-units')}' (docs/reproduction-4.1.md).")


def tables_markdown(results: dict) -> str:
    """Tables 1-4 as Markdown, ours beside the paper's."""
    s = results["settings"]
    sch = s["schedule"]
    out = ["# Target reaching (paper section 4.1): Tables 1-4", "",
           f"{s['trials']} trials x {sch['steps']:,} steps, tested every {sch['test_interval']:,} steps on "
           f"{sch['test_targets']} targets; seed {s['seed']}. Mean ± std over trials (ours) beside the paper's. "
           + protocol_sentence(s), ""]
    out += _perf_table(results, ("E_mm", "T_s_per_m", "D"), PAPER_TABLE1, "Table 1: performance after training")
    out += ["", "Targets that ended by the step budget rather than a stop (per trial, mean ± std): " + ", ".join(
        f"{n} {_ms(e.get('ended_by_budget'), 1)}" for n, e in results["networks"].items()) + ". Targets that ended "
        "by a stop at the goal state, the sensed distance rounding to 0: " + ", ".join(
        f"{n} {_ms(e.get('goal_stops'), 1)}" for n, e in results["networks"].items()), ""]
    out += ["### Table 2: Welch t-test p-values after training", ""]
    for key in ("E_mm", "D", "T_s_per_m"):
        out += _p_table(results, key) + [""]
    out += _perf_table(results, ("P5", "T5_s_per_m", "D5"), PAPER_TABLE3, "Table 3: performance at eps = 5 mm")
    out += ["", "### Table 4: Welch t-test p-values at eps = 5 mm", ""]
    for key in ("P5", "T5_s_per_m", "D5"):
        out += _p_table(results, key) + [""]
    return "\n".join(out)


def write_report(results: dict, trained: dict, out_dir: Path) -> list[Path]:
    """results.json, tables.md and the figures into out_dir."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    written = [out_dir / "results.json", out_dir / "tables.md"]
    written[0].write_text(jsonfile.dumps(results))
    written[1].write_text(tables_markdown(results))
    return written + plot_all(results, trained, out_dir)


def _ci(entry: dict, digits: int) -> str:
    if entry is None or entry.get("mean") is None:
        return "n/a"
    if entry["n"] < 2:
        return f"{entry['mean']:.{digits}f}"
    return f"{entry['mean']:.{digits}f} [{entry['lo']:.{digits}f}, {entry['hi']:.{digits}f}]"


def _seeds_table(summary: dict, keys: tuple[str, str, str], paper: dict, title: str) -> list[str]:
    return _network_table(summary["networks"], keys, paper, title, _ci, parameters=False)


def seeds_markdown(summary: dict) -> str:
    """Tables 1 and 3 over master seeds (mean of the per-seed trial means, 95 % interval),
    how often each headline ordering holds, and every trial that ended targets by budget."""
    s = summary["settings"]
    sch = s["schedule"]
    seeds = s["master_seeds"]
    out = ["# Target reaching (paper section 4.1) over master seeds", "",
           f"Master seeds {', '.join(map(str, seeds))}; each: {s['trials']} trials x {sch['steps']:,} steps, "
           f"tested on {sch['test_targets']} targets. Ours: the mean over seeds of each seed's trial "
           "mean, with its 95 % interval (Student t, "
           f"{len(seeds) - 1} degrees of freedom); the paper's: mean ± std over its 5 trials. "
           + protocol_sentence(s), ""]
    out += _seeds_table(summary, ("E_mm", "T_s_per_m", "D"), PAPER_TABLE1, "Table 1: performance after training")
    out += ["", "Targets ended by the step budget (of the test's targets, per trial, mean over seeds): " + ", ".join(
        f"{n} {_ci(e.get('ended_by_budget'), 1)}" for n, e in summary["networks"].items()) + ". Ended by a stop at "
        "the goal state (the sensed distance rounding to 0): " + ", ".join(
        f"{n} {_ci(e.get('goal_stops'), 1)}" for n, e in summary["networks"].items()), ""]
    out += _seeds_table(summary, ("P5", "T5_s_per_m", "D5"), PAPER_TABLE3, "Table 3: performance at eps = 5 mm")
    out += ["", "### The paper's headline orderings", "", "| claim | holds in | fails with seeds |", "|---|---:|---|"]
    for claim, o in summary["orderings"].items():
        out.append(f"| {claim} | {o['holds']} of {o['seeds']} | {', '.join(map(str, o['fails_in'])) or '-'} |")
    out += ["", "### Trials that ended test targets by the step budget", ""]
    rows = [(seed, b) for seed, lst in summary["budget_ended"].items() for b in lst]
    if not rows:
        out.append("None.")
    else:
        out += ["| seed | network | trial | targets | E (mm) |", "|---:|---|---:|---:|---:|"]
        out += [f"| {seed} | {b['network']} | {b['trial']} | {b['targets']} | {b['E_mm']:.2f} |" for seed, b in rows]
    return "\n".join(out) + "\n"


def write_seeds_report(summary: dict, out_dir: Path) -> list[Path]:
    """summary.json and summary.md into out_dir."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = [out_dir / "summary.json", out_dir / "summary.md"]
    paths[0].write_text(jsonfile.dumps(summary))
    paths[1].write_text(seeds_markdown(summary))
    return paths


def write_seed(config: TargetReachingConfig, results: dict, runs: list[NetworkRun], out_dir: Path,
                models: bool) -> list[Path]:
    """One seed's report: with models, also the trained models and the figures (a single-seed
    run); without (one seed of several), results.json and tables.md only."""
    if not models:
        out_dir.mkdir(parents=True, exist_ok=True)
        (out_dir / "results.json").write_text(jsonfile.dumps(results))
        (out_dir / "tables.md").write_text(tables_markdown(results))
        return [out_dir / "results.json", out_dir / "tables.md"]
    if models:
        for r in runs:
            for t in range(config.trials):
                save_model(out_dir / "models" / f"{r.name}-trial{t + 1}.npz", r.trained(t, config),
                           {"network": r.name, "trial": t + 1, "steps": config.schedule.steps, "seed": config.seed,
                            "initial_M": "random", "experiment": "target-reaching"})
    return write_report(results, {r.name: r.trained(0, config) for r in runs}, out_dir)
