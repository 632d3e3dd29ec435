"""Fig. 9's files: ``fig9.json`` (the sweep's document, :func:`.concave_run.run_sweep`),
``fig9.png`` and ``fig9_grid.png`` (:mod:`.concave_figures`)."""

from __future__ import annotations

from pathlib import Path

from .. import jsonfile
from .concave_figures import plot_grid, plot_sweep


def write_sweep(doc: dict, out_dir: Path) -> list[Path]:
    """fig9.json, fig9.png and fig9_grid.png into out_dir."""
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / "fig9.json").write_text(jsonfile.dumps(doc))
    return [out_dir / "fig9.json", plot_sweep(doc, out_dir / "fig9.png"), plot_grid(doc, out_dir / "fig9_grid.png")]
