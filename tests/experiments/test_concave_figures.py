"""Fig. 9's before-and-after picture: which cells a row gains and loses against another."""

from __future__ import annotations

import matplotlib.image as mpimg

from cekm_swarm.experiments.concave_figures import negotiated, plot_grid_rows, row_summary


def _cells(reached: dict[tuple[float, float], int]) -> list[dict]:
    return [{"range": 0.12, "depth": d, "width": w, "reached": k, "of": 3} for (d, w), k in reached.items()]


BEFORE = _cells({(0.06, 0.1): 3, (0.06, 0.2): 1, (0.3, 0.1): 2, (0.3, 0.2): 0})
AFTER = _cells({(0.06, 0.1): 3, (0.06, 0.2): 2, (0.3, 0.1): 1, (0.3, 0.2): 3})


def test_a_cell_is_negotiated_at_need_runs_and_rows_are_compared_cell_by_cell():
    assert negotiated(BEFORE, 2) == {(0.12, 0.06, 0.1), (0.12, 0.3, 0.1)}
    assert negotiated(BEFORE, 3) == {(0.12, 0.06, 0.1)}
    assert row_summary("tuned", BEFORE, 2) == "tuned: 2 cells negotiated"
    assert row_summary("learned", AFTER, 2, BEFORE, "tuned") == \
        "learned: 3 cells negotiated (2 gained, 1 lost against tuned)"


def test_the_picture_has_a_row_per_controller(tmp_path):
    one = plot_grid_rows({"tuned": BEFORE}, 2, tmp_path / "one.png")
    two = plot_grid_rows({"tuned": BEFORE, "learned": AFTER}, 2, tmp_path / "two.png", "tuned")
    h1, h2 = mpimg.imread(one).shape[0], mpimg.imread(two).shape[0]
    assert h2 > 1.6 * h1  # a second row of panels below the first
