"""``cekm tune``: train the field policy (``fields``) and judge it on held-out scenarios
(``evaluate``); docs/fields.md."""

from __future__ import annotations

from pathlib import Path

import click

from ..cli_support import Finite, seed_option, workers_option
from ..errors import ParameterError
from ..experiments.learning_commands import model_option
from ..jsonfile import dumps


def _text(path: Path | None) -> str | None:
    """A model path as the rollouts' jobs carry it (text, the key of their model cache)."""
    return None if path is None else str(path)


@click.group("tune")
def tune_group() -> None:
    """Field parameters learned, not hand-tuned (docs/fields.md)."""


def mix_option(help: str):
    """``--mix``, the generated geometry mix (the keys of scenarios.MIXES, which a test keeps
    equal; not imported here, as scenarios pulls in the world)."""
    mixes = ["default", "wide", "route", "movers", "turned", "discs", "lone-disc", "stalls"]
    return click.option("--mix", type=click.Choice(mixes), default="default", show_default=True, help=help)


@tune_group.command("fields")
@click.option("--task", type=click.Choice(["navigation", "tracking"]), default="navigation", show_default=True,
              help="Train the navigation policy (generated obstacle geometries) or the tracking one (grid cells).")
@click.option("--out", "out_dir", type=click.Path(file_okay=False, path_type=Path), required=True,
              help="Directory of the training; run the same command again to resume it after a kill.")
@seed_option(1, "CMA-ES seed.")
@click.option("--generations", type=click.IntRange(min=1), help="Generations (default 30 navigation, 15 tracking).")
@click.option("--popsize", type=click.IntRange(min=1),
              help="Candidates per generation (default 12 navigation, 8 tracking).")
@click.option("--sigma0", type=Finite(min=0.0, min_open=True), default=0.5, show_default=True,
              help="CMA-ES initial step size.")
@click.option("--batch", type=click.IntRange(min=1), help="Training scenarios per candidate per generation "
                                        "(default 24 navigation, 6 tracking).")
@click.option("--validation", type=click.IntRange(min=1),
              help="Validation scenarios (default 48 navigation, 12 tracking).")
@click.option("--validate-every", type=click.IntRange(min=1), default=5, show_default=True,
              help="Generations between validations.")
@click.option("--max-time", type=Finite(min=0.2), help="Sim seconds per run (default 90 navigation, 30 tracking).")
@mix_option("Navigation: the generated geometries trained and validated on (wide: also disc rows with "
            "narrow gaps, long walls and narrow deep U's; route: also a goal in a narrow alcove; "
            "movers: the wide mix with rooms with movers a third of the time; turned: the wide mix and U's "
            "turned any way a third of the time; discs: the route mix and a lone small disc head-on a fifth of "
            "the time; lone-disc: only those; stalls: the default mix, narrow deep U's a third and lone discs "
            "two ninths of the time).")
@click.option("--hold", multiple=True, help="An output held at today's value (its rows of W and V stay 0), e.g. "
                                          "sigma_b_d_near; repeat for more.")
@click.option("--per-field", is_flag=True, help="Also learn V: each obstacle field's widths from its own "
                                                "features (nearness, angle, nearest, lone ray, closing speed), not one "
                                                "set a tick.")
@click.option("--init", "init", type=click.Path(dir_okay=False, exists=True), default=None,
              help="A policy file the search starts from (default: today's constants); kept if it is the best "
                   "on validation.")
@click.option("--keep", multiple=True, help="An output whose rows of W and V stay at --init's weights (not "
                                          "searched), e.g. sigma_b_alpha; repeat for more.")
@model_option()
@workers_option("Worker processes.", default=2)
def fields_cmd(task, out_dir, seed, generations, popsize, sigma0, batch, validation, validate_every, max_time,
               mix, hold, per_field, init, keep, model_path, workers) -> None:
    """Train a field policy by CMA-ES into OUT (policy.json), seeded and resumable."""
    from .train import TuneConfig, tune  # noqa: PLC0415 -- lazy: pymunk, tqdm, world

    nav = task == "navigation"
    try:
        config = TuneConfig(task, seed, generations or (30 if nav else 15), popsize or (12 if nav else 8), sigma0,
                            batch or (24 if nav else 6), validation or (48 if nav else 12), validate_every,
                            max_time or (90.0 if nav else 30.0), mix, tuple(hold), per_field, str(init or ""),
                            tuple(keep))
        meta = tune(config, out_dir, _text(model_path), workers)
    except ParameterError as exc:
        raise click.UsageError(str(exc)) from None
    click.echo(f"kept generation {meta['kept_generation']}: validation score {meta['validation_score']:.3f} "
               f"(today's constants {meta['validation_score_of_constants']:.3f}); wrote {out_dir / 'policy.json'}")


@tune_group.command("evaluate")
@click.option("--task", type=click.Choice(["navigation", "tracking"]), default="navigation", show_default=True)
@click.option("--out", "out_dir", type=click.Path(file_okay=False, path_type=Path), required=True,
              help="Directory for results.json.")
@click.option("--policy", type=click.Path(dir_okay=False, exists=True, path_type=Path),
              help="The policy judged as `learned` (default: the one shipped for the task).")
@click.option("--tests", type=click.IntRange(min=1), default=100, show_default=True,
              help="Held-out generated scenarios.")
@click.option("--concave", is_flag=True, help="Navigation: Fig. 9's sweep cells instead of generated scenarios.")
@click.option("--suite", is_flag=True, help="Navigation: section 4.2's table (its five scenarios, --tests seeds "
                                            "from 1) instead of generated scenarios.")
@click.option("--only", help="Comma-separated variants to run (paper, tuned, learned; tracking also acmommt, "
                             "kmeans, kmeans-global).")
@click.option("--max-time", type=Finite(min=0.2), help="Sim seconds per run (default 300 navigation, 120 tracking).")
@model_option()
@workers_option("Worker processes.", default=2)
def evaluate_cmd(task, out_dir, policy, tests, concave, suite, only, max_time, model_path, workers) -> None:
    """Judge the learned field policy against the paper's and today's constants on held-out scenarios."""
    from .evaluate import evaluate, evaluate_concave, evaluate_suite, variants  # noqa: PLC0415 -- lazy: numba, pymunk, scipy, tqdm, world

    chosen = None if not only else tuple(x.strip() for x in only.split(","))
    known = variants(task, policy)
    for v in chosen or ():
        if v not in known:
            raise click.UsageError(f"--only: unknown variant {v!r} (known: {', '.join(known)})")
    if (concave or suite) and task != "navigation":
        raise click.UsageError("--concave and --suite go with --task navigation")
    out_dir.mkdir(parents=True, exist_ok=True)
    if suite:
        doc = evaluate_suite(tuple(range(1, tests + 1)), policy, _text(model_path), workers, max_time=max_time or 300.0,
                             only=chosen)
        for v in known:
            if v in doc:
                click.echo(f"{v:8s} " + "; ".join(f"{sc} {x['success']['k']}/{x['success']['n']} "
                                                  f"({x['collision_free']['k']} contact-free)"
                                                  for sc, x in doc[v].items() if sc != "runs"))
    elif concave:
        doc = evaluate_concave(policy, _text(model_path), workers, only=chosen)
        for v in known:
            if v in doc:
                widths = ", ".join("-" if g["max_width"] is None else f"{g['max_width']:.2f}" for g in doc[v]["grid"])
                click.echo(f"{v:8s} negotiated cells {doc[v]['negotiated_cells']}; widest per (range, depth): {widths}")
        _draw_fig9({v: doc[v]["cells"] for v in known if v in doc}, doc["need"], out_dir / "fig9_fields.png")
    else:
        doc = evaluate(task, tests, policy, max_time, _text(model_path), workers, only=chosen)
        for v, s in doc["summary"].items():
            if task == "navigation" and "contact_free" in s:
                c, r = s["contact_free"], s["reached"]
                click.echo(f"{v:8s} reached {r['k']}/{r['n']}, contact-free {c['k']}/{c['n']} "
                           f"[{c['wilson95'][0]:.3f}, {c['wilson95'][1]:.3f}]  by kind: "
                           + ", ".join(f"{k} {x['k']}/{x['n']}" for k, x in s["by_kind"].items()))
            elif task == "tracking" and "mean" in s:
                click.echo(f"{v:14s} A {s['mean']:.3f} [{s['ci95'][0]:.3f}, {s['ci95'][1]:.3f}] (n={s['n']})")
            else:
                click.echo(f"{v}: {s}")
    (out_dir / "results.json").write_text(dumps(doc))
    click.echo(f"wrote {out_dir / 'results.json'}")


def _draw_fig9(rows: dict[str, list[dict]], need: int, path: Path, reference: str = "tuned") -> None:
    from ..experiments.concave_figures import plot_grid_rows, row_summary  # noqa: PLC0415 -- lazy: matplotlib

    ref = reference if reference in rows else None
    for label, cells in rows.items():
        click.echo(row_summary(label, cells, need, rows[ref] if ref and ref != label else None, ref))
    plot_grid_rows(rows, need, path, ref)
    click.echo(f"wrote {path}")


@tune_group.command("fig9")
@click.argument("results", nargs=-1, required=True)
@click.option("--out", "out_path", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="The picture (PNG).")
@click.option("--reference", default="tuned", show_default=True,
              help="The row the others are compared with (cells gained and lost are framed).")
def fig9_cmd(results, out_path, reference) -> None:
    """Fig. 9's cells before and after: one row per variant of `tune evaluate --concave` documents.

    Each RESULTS is FILE (every variant in it), FILE:VARIANT or FILE:VARIANT=LABEL.
    """
    from .evaluate import concave_rows  # noqa: PLC0415 -- lazy: numba, pymunk, scipy, tqdm, world

    try:
        rows, need = concave_rows(list(results))
    except ParameterError as exc:
        raise click.UsageError(str(exc)) from None
    if reference not in rows:
        raise click.UsageError(f"--reference: no row {reference!r} (rows: {', '.join(rows)})")
    _draw_fig9(rows, need, out_path, reference)


@tune_group.command("contacts")
@click.option("--out", "out_dir", type=click.Path(file_okay=False, path_type=Path), required=True,
              help="Directory for contacts.json (every run and every contact).")
@click.option("--purpose", type=click.Choice(["train", "validation"]), default="validation", show_default=True,
              help="Whose seeds: training's or validation's (never the held-out tests').")
@click.option("--runs", type=click.IntRange(min=1), default=200, show_default=True, help="Generated scenarios.")
@click.option("--policy", type=click.Path(dir_okay=False, exists=True, path_type=Path),
              help="A navigation field policy (default: today's constants, W = 0).")
@click.option("--max-time", type=Finite(min=0.2), default=300.0, show_default=True, help="Sim seconds per run.")
@mix_option("The generated geometries (as cekm tune fields --mix).")
@model_option()
def contacts_cmd(out_dir, purpose, runs, policy, max_time, mix, model_path) -> None:
    """Why contacts happen: every contact of generated navigation runs, classified (docs/fields.md)."""
    from tqdm import tqdm  # noqa: PLC0415 -- lazy

    from .contacts import diagnose  # noqa: PLC0415 -- lazy: pymunk, world
    from .policy import FieldPolicy  # noqa: PLC0415
    from .scenarios import seed_of  # noqa: PLC0415

    try:
        weights = None if policy is None else FieldPolicy.load(policy).flat()
    except ParameterError as exc:
        raise click.UsageError(str(exc)) from None
    seeds = [seed_of(purpose, i) for i in range(runs)]
    with tqdm(total=runs, desc="contacts", unit="run") as bar:
        doc = diagnose(seeds, max_time, _text(model_path), weights, bar.update, mix)
    out_dir.mkdir(parents=True, exist_ok=True)
    for k, x in doc["by_kind"].items():
        click.echo(f"{k:9s} runs {x['runs']:3d}  reached {x['reached']:3d}  contact-free {x['contact_free']:3d}")
    click.echo(f"contacts {len(doc['contacts'])}")
    for what, counts in doc["tally"].items():
        click.echo(f"  by {what}: " + ", ".join(f"{k} {v}" for k, v in sorted(counts.items(), key=lambda x: -x[1])))
    (out_dir / "contacts.json").write_text(dumps(doc))
    click.echo(f"wrote {out_dir / 'contacts.json'}")


COMMANDS = (tune_group,)
