"""draw_world renders every shipped scenario with and without a state."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pytest  # noqa: E402
from matplotlib.colors import to_rgba  # noqa: E402

from world import World, load_scenario, scenario_names  # noqa: E402
from world.draw import KNOWN_FACE, UNKNOWN_FACE, draw_world  # noqa: E402


@pytest.mark.parametrize("name", scenario_names())
def test_draw_world(name, tmp_path):
    w = World(load_scenario(name))
    for rid in w.robot_ids:
        w.set_wheels(rid, 0.1, 0.1)
    w.advance(0.5)
    fig, (a1, a2) = plt.subplots(1, 2)
    draw_world(a1, w.static_geometry(), None)
    draw_world(a2, w.static_geometry(), w.state())
    geo = w.static_geometry()
    n_static = len(geo["walls"]) + len(geo["polygons"]) + len(geo["discs"])
    assert len(a1.patches) >= n_static
    faces = {p.get_facecolor() for p in a1.patches}
    assert to_rgba(KNOWN_FACE) in faces  # walls
    if geo["polygons"] or geo["discs"]:
        assert to_rgba(UNKNOWN_FACE) in faces  # unforeseen obstacles look different
    assert len(a2.patches) > len(a1.patches)  # robots drawn from the state
    x0, x1 = a1.get_xlim()
    assert x0 < geo["bounds"][0] and x1 > geo["bounds"][2]
    fig.savefig(tmp_path / f"{name}.png")
    plt.close(fig)
