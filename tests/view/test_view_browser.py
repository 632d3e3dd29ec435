"""`cekm view` end to end in a real browser: a real-time `cekm launch` of the lone_obstacle
scenario (its goal moved further away) on a free port, `cekm view` attached to it, headless
Chromium loading the page at two moments of the run. The screenshots are not blank and differ where the robots
moved; a protocol-level client decodes the live event stream, whose poses equal the
run's MCAP log at the same sim time, and whose fields obey Eq. 9. The run's
trajectory.png (``cekm plot``'s drawing) has the shared picture style.

The run is in real time: the moments the test asks for are then late by the view's and
the test's latency only (tenths of a second of sim time; in lockstep, at some 40 times real
time, a loaded machine held them tens of seconds of sim time late, once with r1 already at
its goal). The run ends before r1 can reach its goal's star, which is drawn in r1's
colour (MAX_TIME at robot.KHEPERA's v_max)."""

from __future__ import annotations

import json
import os
import queue
import shutil
import subprocess
import sys
import threading
import time
import urllib.request
from pathlib import Path

import numpy as np
import pytest

from cekm_swarm.experiments.default_model import default_model_path
from cekm_swarm.launch.plot import plot_log, read_run
from cekm_swarm.robot import KHEPERA
from cekm_swarm.runtime.config import free_port
from helpers.foxglove import WsClient
from helpers.launch import LaunchProcess

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser") or shutil.which("google-chrome")
pytestmark = [
    pytest.mark.skipif(CHROMIUM is None, reason="needs headless Chromium (.ci/run installs Debian's chromium)"),
    pytest.mark.slow,
]  # starts a launch and a browser (tests/process_guard.py)
R1 = (0x1F, 0x77, 0xB4)  # world.draw.ROBOT_COLOURS[0], r1's colour on the page


class Stream:
    """A protocol-level client of the view's Server-Sent Events stream: every ``tick``
    event decoded from JSON, in order."""

    def __init__(self, url: str) -> None:
        self.ticks: list[dict] = []
        self._q: queue.Queue[dict] = queue.Queue()
        threading.Thread(target=self._read, args=(url,), daemon=True).start()

    def _read(self, url: str) -> None:
        with urllib.request.urlopen(url, timeout=120) as s:
            event = None
            for line in s:
                if line.startswith(b"event: "):
                    event = line[7:].strip().decode()
                elif line.startswith(b"data: ") and event == "tick":
                    tick = json.loads(line[6:])
                    self.ticks.append(tick)
                    self._q.put(tick)

    def wait(self, pred, timeout: float, what: str) -> dict:
        deadline = time.monotonic() + timeout
        while True:
            try:
                tick = self._q.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                raise AssertionError(f"no tick with {what} in {timeout} s (last: {self.ticks[-1:]})") from None
            if pred(tick):
                return tick


def _screenshot(url: str, path: Path):
    from PIL import Image

    subprocess.run([CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
                    "--window-size=1000,720", f"--screenshot={path}", url],
                   check=True, capture_output=True, timeout=120)
    return np.asarray(Image.open(path).convert("RGB")).astype(int)


def _front(mask) -> float:
    """The rightmost x of ``mask``'s pixels (r1 drives towards +x)."""
    _, xs = np.nonzero(mask)
    assert len(xs) >= 10, "too few of r1's pixels changed"
    return float(xs.max())


def _moved(img_a, img_b, rgb) -> float:
    """How far (px, along x) the front of r1's drawing moved from one screenshot to the
    other: the rightmost of its colour's pixels that appeared (its disc now, its path since)
    against the rightmost of those that vanished (its disc then); its start and goal markers,
    in both, count in neither (the run ends before r1 can reach its goal's star and cover
    some of it). The front, not the centroid: a page that drew no path yet in the first
    screenshot (it reloads once when it learns the run) shows the whole path in the second,
    whose centroid can lie behind the first disc although the robot drove on."""
    in_a, in_b = (np.all(np.abs(img - np.array(rgb)) <= 2, axis=2) for img in (img_a, img_b))
    return float(_front(in_b & ~in_a) - _front(in_a & ~in_b))


# lone_obstacle with the goal 3 m away instead of 1, and a run too short to reach it
LONG_LONE_OBSTACLE = """name = "long_lone_obstacle"
seed = 3
[arena]
bounds = [0.0, 0.0, 4.0, 2.0]
[[robots]]
id = "r1"
start = [0.5, 1.0, 0.0]
goal = "goal"
[[targets]]
id = "goal"
position = [3.5, 1.0]
[[obstacles]]
id = "disc"
shape = "disc"
center = [1.0, 1.0]
radius = 0.05
"""
MAX_TIME = 12.0


def test_live_view_in_headless_chromium(tmp_path):
    assert 0.5 + MAX_TIME * KHEPERA.v_max < 3.5 - 0.3  # r1 (from x = 0.5) stays clear of its goal's star
    port = free_port()
    scenario = tmp_path / "long_lone_obstacle.toml"
    scenario.write_text(LONG_LONE_OBSTACLE)
    # the view first: it waits for the launch's router and subscribes as soon as it is up,
    # seconds before the 14 modules are alive and the world ticks
    view = subprocess.Popen([sys.executable, "-m", "cekm_swarm", "view", str(scenario), "--http", "0",
                             "--foxglove", "0", "--connect", f"tcp/127.0.0.1:{port}",
                             "--model", str(default_model_path())],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, start_new_session=True,
                            env=dict(os.environ, PYTHONUNBUFFERED="1"))
    run = LaunchProcess(str(scenario), tmp_path / "run", "--mode", "realtime", "--max-time", str(MAX_TIME),
                        "--model", str(default_model_path()), port=port)
    try:
        said = [view.stderr.readline() for _ in range(2)]
        if said[0].startswith("waiting"):  # for the router
            said = said[1:] + [view.stderr.readline()]
        assert said[0].startswith("foxglove WebSocket server on ws://127.0.0.1:"), said
        assert said[1].startswith("live view on http://"), said
        fox_port = int(said[0].split(":")[-1])
        url = said[1].split()[3]
        stream = Stream(url + "events")
        run.wait_line("world started ticking", timeout=120)

        def moment(after: float) -> dict:
            """The state the view serves once the run has passed sim time ``after``."""
            stream.wait(lambda t: (t["time"] or 0) >= after, 120, f"time >= {after}")
            return json.loads(urllib.request.urlopen(url + "state.json", timeout=30).read())

        a = moment(1.0)
        # the page keeps r1's path (t, x, y) of this run from the first state the view got,
        # however late it learned the run's graph (it once started afresh only then)
        first = min(t["time"] for t in stream.ticks if t["time"] is not None and "r1" in t["robots"])
        assert a["paths"]["r1"][0][0] <= first, (a["paths"]["r1"][:3], first)
        ws = WsClient(fox_port)  # the Foxglove server of the same view advertises the scene
        while True:
            op, data = ws.frame()
            if op == 1 and any(c["topic"] == "/view/scene" for c in json.loads(data).get("channels", [])):
                break
        img_a = _screenshot(url, tmp_path / "a.png")
        # 3 s of sim time after the first screenshot ended: r1 has driven on since it was taken
        b = moment(max(t["time"] for t in stream.ticks if t["time"] is not None) + 3.0)
        img_b = _screenshot(url, tmp_path / "b.png")
        assert run.finish(timeout=300) == 0, "\n".join(run.lines[-20:])
    finally:
        view.terminate()
        view.wait(10)
        run.kill()

    # not blank: a white page with some grey would pass neither
    for img in (img_a, img_b):
        assert (img.sum(axis=2) < 600).mean() > 0.02
        assert len(np.unique(img.reshape(-1, 3), axis=0)) > 30
    # they differ, and r1's pixels moved the way r1 moved (it drives towards +x)
    assert (np.abs(img_a - img_b).sum(axis=2) > 30).sum() > 500
    ra, rb = a["robots"]["r1"], b["robots"]["r1"]
    assert rb["x"] > ra["x"] + 0.05
    assert _moved(img_a, img_b, R1) > 5

    # the stream: every tick's poses equal the log's at that sim time; fields obey Eq. 9
    logged = {round(t, 3): (x, y) for rid, poses in read_run(tmp_path / "run" / "run.mcap")["paths"].items()
              if rid == "r1" for t, x, y, _ in poses}
    with_time = [t for t in stream.ticks if t["time"] is not None and "r1" in t["robots"]]
    assert len(with_time) >= 5
    for t in with_time:
        if t["time"] in logged:
            assert (t["robots"]["r1"]["x"], t["robots"]["r1"]["y"]) == pytest.approx(logged[t["time"]], abs=1e-4)
    assert sum(t["time"] in logged for t in with_time) >= len(with_time) // 2
    fields = [t["fields"] for t in stream.ticks if t["fields"] and "e" in t["fields"]]
    assert fields, "no target field of r1 in the stream"
    for f in fields:
        assert f["n"] == 225 and len(f["a"]) == len(f["b"]) == len(f["e"]) == 225
        assert np.allclose(np.array(f["a"]) - np.array(f["b"]), f["e"], atol=2e-4)
        assert f["k"] == int(np.argmax(f["e"]))
    assert b["dropped"] == 0
    assert b["fields"] is not None and "e" in b["fields"]  # the held page shows r1's three fields

    # cekm plot's drawing of this run: one colour per robot, time marks, units, legend outside
    assert (tmp_path / "run" / "trajectory.png").is_file()
    fig = plot_log(tmp_path / "run" / "run.mcap")
    fig.canvas.draw()
    ax = fig.axes[0]
    gids = {a.get_gid(): a for a in ax.lines + ax.patches if a.get_gid()}
    for rid in ("r1",):
        assert gids[f"path:{rid}"].get_color() == gids[f"start:{rid}"].get_color() == gids[f"goal:{rid}"].get_color()
        assert len(gids[f"time:{rid}"].get_xdata()) >= 2
    assert ax.get_xlabel() == "x (m)" and ax.get_legend().get_window_extent().x0 >= ax.get_window_extent().x1
