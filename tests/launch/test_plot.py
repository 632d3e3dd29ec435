"""``cekm plot`` (cekm_swarm.launch.plot.plot_log) on a log written as the world server
writes it: geometry metadata and world/state messages of a real (in-process) world. The
figure has the shared style: one colour per robot for path, start and goal, time marks,
units, the legend outside the axes, limits fitted to the content."""

from __future__ import annotations

import json

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from click.testing import CliRunner  # noqa: E402

from cekm_swarm.launch.plot import plot_log  # noqa: E402
from cekm_swarm.protocol import DEFAULT_KEYS as K  # noqa: E402
from cekm_swarm.protocol import WorldState, encode  # noqa: E402
from cekm_swarm.runtime.mcap_log import McapRecorder  # noqa: E402
from world import World, load_scenario  # noqa: E402


def _log(path, scenario: str = "crossing") -> dict:
    w = World(load_scenario(scenario), seed=1)
    geometry = w.static_geometry()
    rec = McapRecorder(path)
    rec.add_metadata("geometry", {"json": json.dumps(geometry)})
    for rid, (vl, vr) in zip(w.robot_ids, [(0.05, 0.06), (0.06, 0.05), (0.05, 0.05)], strict=False):
        w.set_wheels(rid, vl, vr)
    for _ in range(60):  # 6 s
        st = w.state()
        rec.write(K.world_state(), encode(WorldState(st["time"], "world", st["robots"], st["targets"],
                                                     st["obstacles"])), st["time"])
        w.advance(0.1)
    rec.close()
    return geometry


def test_plot_log_has_the_shared_style(tmp_path):
    geometry = _log(tmp_path / "run.mcap")
    fig = plot_log(tmp_path / "run.mcap", outcome={"robots": {"r1": {"reached": False}}})
    fig.canvas.draw()
    ax = fig.axes[0]
    gids = {a.get_gid(): a for a in ax.lines + ax.patches if a.get_gid()}
    colours = set()
    for rid in ("r1", "r2", "r3"):
        c = gids[f"path:{rid}"].get_color()
        assert gids[f"start:{rid}"].get_color() == gids[f"goal:{rid}"].get_color() == c
        assert len(gids[f"time:{rid}"].get_xdata()) >= 5  # 6 s: a mark every 0.5 s
        colours.add(c)
    assert len(colours) == 3
    assert ax.get_xlabel() == "x (m)" and ax.get_ylabel() == "y (m)"
    legend = ax.get_legend()
    assert legend.get_window_extent().x0 >= ax.get_window_extent().x1
    assert "r1 (not reached)" in [t.get_text() for t in legend.get_texts()]
    # fitted, and never beyond the arena plus its walls
    bx0, by0, bx1, by1 = geometry["bounds"]
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    assert bx0 - 0.1 < x0 and x1 < bx1 + 0.1 and by0 - 0.1 < y0 and y1 < by1 + 0.1
    plt.close(fig)


def test_a_tracking_log_is_drawn_like_fig_13(tmp_path):
    """The targets' paths from world/state, and sensing circles of the range the geometry
    carries, as `cekm run tracking` draws them; the limits take in every target's path."""
    geometry = _log(tmp_path / "run.mcap", "tracking")
    fig = plot_log(tmp_path / "run.mcap")
    ax = fig.axes[0]
    target_lines = {a.get_gid(): a for a in ax.lines if (a.get_gid() or "").startswith("target:")}
    assert set(target_lines) == {f"target:{t['id']}" for t in geometry["targets"]}
    for t in geometry["targets"]:
        xs, ys = target_lines[f"target:{t['id']}"].get_data()
        assert (xs[0], ys[0]) == tuple(t["position"]) and len(xs) == 60
        (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
        assert x0 <= min(xs) and max(xs) <= x1 and y0 <= min(ys) and max(ys) <= y1
    circles = [a for a in ax.patches if (a.get_gid() or "").startswith("sensing:")]
    assert {c.get_gid() for c in circles} == {"sensing:r1", "sensing:r2"}
    assert {c.get_radius() for c in circles} == {geometry["target_range"]} == {0.5}
    plt.close(fig)


def test_cekm_plot_writes_the_png(tmp_path):
    from cekm_swarm.cli import main

    _log(tmp_path / "run.mcap")
    r = CliRunner().invoke(main, ["plot", str(tmp_path / "run.mcap"), "--out", str(tmp_path / "t.png")])
    assert r.exit_code == 0, r.output
    assert (tmp_path / "t.png").stat().st_size > 10_000


def test_a_broken_outcome_beside_the_log_is_passed_over_with_a_note(tmp_path):
    """The user named only the log: an ``outcome.json`` beside it that is empty or not an
    object is an extra to pass over (said once), not a traceback."""
    from cekm_swarm.cli import main

    _log(tmp_path / "run.mcap")
    for bad in ("", "[1, 2]"):
        (tmp_path / "outcome.json").write_text(bad)
        res = CliRunner().invoke(main, ["plot", str(tmp_path / "run.mcap"), "--out", str(tmp_path / "p.png")])
        assert res.exit_code == 0, res.output
        assert "outcome.json" in res.output and "drawing the log alone" in res.output
        assert (tmp_path / "p.png").stat().st_size > 0
