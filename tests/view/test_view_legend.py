"""The live view's page in headless Chromium at one still moment (``?still``: no live
stream, so ``--virtual-time-budget`` finishes): the legend names targets, sensing
circles, contact rims and who observes which target; every target is labelled; a run
whose world server is gone says so. Checked in the page's DOM and in its screenshot."""

from __future__ import annotations

import shutil
import subprocess

import numpy as np
import pytest

from cekm_swarm.protocol import DEFAULT_KEYS as K
from cekm_swarm.protocol import WorldState, encode
from cekm_swarm.view.command import _geometry
from cekm_swarm.view.live import LiveView
from cekm_swarm.view.server import ViewServer
from world.draw import robot_colours

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser") or shutil.which("google-chrome")
pytestmark = [
    pytest.mark.skipif(CHROMIUM is None, reason="needs headless Chromium (.ci/run installs Debian's chromium)"),
    pytest.mark.slow,
]  # starts a browser (tests/process_guard.py)
BANNER = (0xC0, 0x00, 0x00)  # the end notice's background
LABEL = (0x70, 0x30, 0xA0)  # targets and their labels


def chromium(url: str, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
                           "--window-size=1000,760", "--virtual-time-budget=3000", *args, url],
                          check=True, capture_output=True, text=True, timeout=120)


def test_legend_target_labels_and_the_end_notice(tmp_path):
    from PIL import Image

    geometry, ranges = _geometry("tracking", None, None)
    ids = [r["id"] for r in geometry["robots"]]
    view = LiveView(geometry, ranges=ranges, colours=robot_colours(sorted(ids)))
    view.run_seen("run-a")
    targets = {t["id"]: {"x": t["position"][0], "y": t["position"][1]} for t in geometry["targets"]}
    robots = {r["id"]: {"x": r["start"][0], "y": r["start"][1], "theta": r["start"][2]} for r in geometry["robots"]}
    first = next(iter(robots))
    robots[first]["in_contact"] = True
    t0 = geometry["targets"][0]["position"]  # the first robot observes the first target
    robots[first].update(x=t0[0] - 0.1, y=t0[1])
    view.observe(K.world_state(), encode(WorldState(12.8, "world", robots, targets, {})))
    view.run_ended("run-a")
    server = ViewServer(view, "127.0.0.1", 0)
    try:
        url = server.url + "?still"
        dom = chromium(url, "--dump-dom").stdout
        chromium(url, f"--screenshot={tmp_path / 'view.png'}")
    finally:
        server.close()
    legend = dom[dom.index('id="legend">'):]
    legend = legend[:legend.index("</div>")]
    for words in ("target", "sensing ranges (obstacles, targets)", "in contact", "observes"):
        assert f"</svg>{words}</span>" in legend, (words, legend)
    assert "goal</span>" not in legend  # a tracking run has no goals: no goal in its legend
    for tid in targets:
        assert f'class="target-label">{tid}</text>' in dom, tid
    assert 'class="observes"' in dom
    assert "run ended at sim time 12.80 s (its world server is gone)" in dom
    img = np.asarray(Image.open(tmp_path / "view.png").convert("RGB")).astype(int)
    banner = np.all(np.abs(img - BANNER) <= 8, axis=2)
    ys, _ = np.nonzero(banner)
    assert banner.sum() > 2000 and ys.max() < 80, "the end notice is not a red band at the top"
    purple = np.all(np.abs(img - LABEL) <= 40, axis=2)
    assert purple.sum() > 30 * len(targets), "targets and their labels are not drawn"
