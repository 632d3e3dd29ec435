"""``cekm sweep concave``: the widest concave obstacle negotiated per depth and sensing range
(Fig. 9), its runs on the experiment engine."""

from __future__ import annotations

from pathlib import Path

import click

from ..cli_support import Finite, check_seeds, out_dir_options, prepare_out_dir
from ..errors import CekmError
from .commands import engine_options, fields_option, parse_floats, seeds_of, seeds_option
from .concave_report import write_sweep
from .field_widths import REPRODUCTION
from .learning_commands import controller_model, model_option


@click.group()
def sweep() -> None:
    """Parameter sweeps of section 4.2."""


@sweep.command("concave")
@click.option("--depths", default="0.06,0.12,0.18,0.24,0.3", show_default=True, help="U depths (m), comma-separated.")
@click.option("--widths", default="0.1,0.2,0.34,0.5,0.7,1.0,1.4,2.0", show_default=True, help="U widths (m) to try.")
@click.option("--ranges", default="0.12,0.17,0.25", show_default=True, help="Sensing ranges (m).")
@seeds_option("1,2,3")
@click.option("--need", default=2, show_default=True, type=click.IntRange(1), help="Successes a width needs.")
@click.option("--max-time", default=300.0, show_default=True, type=Finite(min=1.0))
@fields_option(REPRODUCTION, "the paper's method has constant ones")
@model_option()
@engine_options
@out_dir_options("Directory for fig9.json, fig9.png and fig9_grid.png.")
def sweep_concave(depths: str, widths: str, ranges: str, seeds: str, need: int, max_time: float, fields: str,
                  model_path: Path | None, workers: int | None, out_dir: Path, overwrite: bool) -> None:
    """Find the widest concave obstacle negotiated, per depth and sensing range (Fig. 9)."""
    from .concave_config import SweepConfig  # noqa: PLC0415 -- lazy: pymunk, world
    from .concave_run import run_sweep  # noqa: PLC0415 -- lazy: pymunk, world
    from .default_model import default_model, default_model_path  # noqa: PLC0415 -- lazy: numba, scipy, tqdm

    try:
        config = SweepConfig(depths=parse_floats(depths, "depths"),
                             widths=tuple(sorted(parse_floats(widths, "widths"))),
                             ranges=parse_floats(ranges, "ranges"), seeds=tuple(seeds_of(seeds)), need=need,
                             max_time=max_time, fields=fields)
        config.check_scenarios()
    except CekmError as exc:
        raise click.UsageError(str(exc)) from None
    check_seeds(config.seeds)
    controller_model(model_path)
    prepare_out_dir(out_dir, overwrite)
    if model_path is None:
        default_model()
        model_path = default_model_path()
    doc = run_sweep(config, model_path, workers)
    paths = write_sweep(doc, out_dir)
    for c in doc["grid"]:
        w = "none" if c["max_width"] is None else f"{c['max_width']:.2f} m"
        click.echo(f"range {c['range']:.2f} m, depth {c['depth']:.2f} m: widest negotiated {w}")
    click.echo("wrote " + ", ".join(str(p) for p in paths))
