"""The shared picture style of world.draw: a colour per robot shared by its path, start
and goal; time marks along the paths; units on the axes; the legend outside the axes;
limits fitted to the content. Checked on the figure of a real (in-process) run."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.colors as mcolors  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import pytest  # noqa: E402

from cekm_swarm.experiments.default_model import default_model  # noqa: E402
from cekm_swarm.experiments.navigation_figures import plot_run  # noqa: E402
from cekm_swarm.experiments.navigation_run import run_scenario  # noqa: E402
from world import load_scenario  # noqa: E402
from world.draw import draw_paths, figure_size, fit_bounds, legend_outside, nice_step, robot_colours  # noqa: E402


def _by_gid(ax, prefix):
    return {
        a.get_gid().split(":", 1)[1]: a for a in ax.get_children() + ax.lines if (a.get_gid() or "").startswith(prefix)
    }


@pytest.fixture(scope="module")
def crossing_figure():
    run = run_scenario(load_scenario("crossing"), "cekm", default_model(progress=False), 1, max_time=12)
    fig = plot_run(run)
    fig.canvas.draw()
    yield run, fig
    plt.close(fig)


def test_each_robot_has_one_colour_for_path_start_and_goal(crossing_figure):
    run, fig = crossing_figure
    ax = fig.axes[0]
    paths, starts, goals = _by_gid(ax, "path:"), _by_gid(ax, "start:"), _by_gid(ax, "goal:")
    assert set(paths) == set(starts) == set(goals) == set(run.logs) == {"r1", "r2", "r3"}
    colours = set()
    for rid in run.logs:
        c = mcolors.to_hex(paths[rid].get_color())
        assert mcolors.to_hex(starts[rid].get_color()) == c
        assert mcolors.to_hex(goals[rid].get_color()) == c
        colours.add(c)
    assert len(colours) == 3  # and the robots differ


def test_time_marks_lie_on_the_path_at_the_same_instants_for_every_robot(crossing_figure):
    run, fig = crossing_figure
    marks = _by_gid(fig.axes[0], "time:")
    step = nice_step(max(log.t[-1] for log in run.logs.values()))
    for rid, log in run.logs.items():
        xs, ys = marks[rid].get_data()
        assert len(xs) >= 3
        for n, (x, y) in enumerate(
            zip(xs, ys, strict=True), start=1
        ):  # the pose at the first tick at or after n * step
            i = next(i for i, t in enumerate(log.t) if t >= n * step)
            assert (x, y) == (log.x[i], log.y[i])


def test_axes_carry_units_and_the_legend_sits_outside_the_axes(crossing_figure):
    _, fig = crossing_figure
    ax = fig.axes[0]
    assert ax.get_xlabel() == "x (m)" and ax.get_ylabel() == "y (m)"
    legend = ax.get_legend()
    assert legend is not None
    lb, ab = legend.get_window_extent(), ax.get_window_extent()
    assert lb.x0 >= ab.x1  # entirely to the right of the arena
    texts = [t.get_text() for t in legend.get_texts()]
    assert any(t.startswith("dot every") for t in texts) and any(t.startswith("r1 (") for t in texts)


def test_limits_fit_the_content_with_a_small_margin():
    geometry = {"bounds": [0.0, 0.0, 4.0, 4.0], "walls": [{"thickness": 0.02}], "discs": [
        {"center": [1.0, 1.2], "radius": 0.1}], "targets": [{"id": "g", "position": [1.5, 1.0]}]}
    fig, ax = plt.subplots()
    x0, x1, y0, y1 = fit_bounds(ax, geometry, [(0.5, 1.0), (1.4, 0.9)], margin=0.1)
    assert (x0, x1, y0, y1) == pytest.approx((0.4, 1.6, 0.8, 1.4))  # path, disc and target, plus 0.1 m
    assert ax.get_xlim() == pytest.approx((0.4, 1.6))
    # a path reaching the arena's edge: the limits stop at the walls
    x0, x1, y0, y1 = fit_bounds(ax, geometry, [(0.01, 0.01), (3.99, 3.99)], margin=0.3)
    assert x0 == pytest.approx(-0.04) and x1 == pytest.approx(4.04)
    w, h = figure_size(x0, x1, y0, y1)
    assert 5 < w < 9 and h == 5.5
    # content near a side (within the margin) shows that side's wall whole
    x0, x1, y0, y1 = fit_bounds(ax, geometry, [(0.15, 1.0), (1.4, 0.9)], margin=0.15)
    assert x0 == pytest.approx(-0.04) and x1 == pytest.approx(1.5 + 0.15)  # the target at 1.5
    # a robot that left an arena without boundary walls: the limits follow it out
    x0, x1, y0, y1 = fit_bounds(ax, geometry | {"walls": []}, [(1.0, 1.0), (5.3, 1.9)], margin=0.1)
    margin = 0.03 * (5.3 - 0.9)  # at least 3 % of the map: a marker's size on a larger one
    assert x1 == pytest.approx(5.3 + margin) and x0 == pytest.approx(0.9 - margin)  # the disc at 0.9
    plt.close(fig)


def test_draw_paths_widens_the_limits_to_a_path_that_leaves_them():
    fig, ax = plt.subplots()
    ax.set_xlim(0.0, 4.0)
    ax.set_ylim(0.0, 4.0)  # the arena, as draw_world sets it
    draw_paths(ax, {"a": ([0.0, 1.0, 2.0], [1.0, 3.0, 5.25], [1.0, 1.0, 1.5])}, robot_colours(["a"]))
    assert ax.get_xlim() == pytest.approx((0.0, 5.35)) and ax.get_ylim() == pytest.approx((0.0, 4.0))
    plt.close(fig)


def test_paths_without_a_fixed_step_use_a_round_one_and_the_legend_says_so():
    fig, ax = plt.subplots()
    t = [0.1 * i for i in range(301)]  # 30 s
    step = draw_paths(ax, {"a": (t, [0.01 * i for i in range(301)], [0.0] * 301)}, robot_colours(["a"]))
    assert step == 5.0 and nice_step(30.0) == 5.0 and nice_step(0.7) == 0.1 and nice_step(120.0) == 10.0
    leg = legend_outside(ax, time_step=step)
    assert "dot every 5 s" in [x.get_text() for x in leg.get_texts()]
    assert len(_by_gid(ax, "time:")["a"].get_data()[0]) == 6
    plt.close(fig)


def test_a_large_team_gets_one_legend_entry_for_its_paths():
    from world.draw import LEGEND_ROWS

    fig, ax = plt.subplots()
    for n in (LEGEND_ROWS, LEGEND_ROWS + 1):
        ax.clear()
        ids = [f"r{i}" for i in range(n)]
        draw_paths(ax, {r: ([0.0, 1.0], [0.0, 0.1 * i], [0.0, 0.1]) for i, r in enumerate(ids)}, robot_colours(ids))
        texts = [t.get_text() for t in legend_outside(ax, time_step=1.0).get_texts()]
        assert texts == (ids if n == LEGEND_ROWS else [f"{n} robots' paths"]) + ["dot every 1 s"]
    plt.close(fig)
