"""The live view's state and its HTTP server, without Zenoh: fields combined as Eq. 9,
paths, malformed messages dropped and counted, the page and the event stream."""

from __future__ import annotations

import json
import threading
import urllib.request

import msgpack
import numpy as np
import pytest

from cekm_swarm.protocol import DEFAULT_KEYS as K
from cekm_swarm.protocol import ObstacleField, TargetField, WorldState, encode
from cekm_swarm.view.live import PATH_STEP, LiveView
from cekm_swarm.view.server import ViewServer

GEOMETRY = {"bounds": [0.0, 0.0, 2.0, 1.0], "body_radius": 0.03, "walls": [], "polygons": [], "discs": [],
            "moving_obstacles": [], "targets": [{"id": "g1", "position": [1.8, 0.5]}],
            "robots": [{"id": "r1", "start": [0.2, 0.5, 0.0], "goal": "g1"}, {"id": "r2", "start": [0.2, 0.2, 0.0]}]}


def _state(t: float, x: float) -> bytes:
    robots = {"r1": {"x": x, "y": 0.5, "theta": 0.1, "goal": [1.8, 0.5]}, "r2": {"x": 0.2, "y": 0.2, "theta": 0.0}}
    return encode(WorldState(t, "world", robots, {"g1": {"x": 1.8, "y": 0.5}}, {}))


def test_fields_of_the_chosen_robot_combine_as_eq_9():
    v = LiveView(GEOMETRY)
    assert v.robot == "r1" and v.fields() is None
    a = np.linspace(1.0, 0.0, 9)
    b3 = np.zeros(9)
    b3[0] = 0.7
    b5 = np.zeros(9)
    b5[1] = 0.4
    v.observe(
        K.field_target("r1"), encode(TargetField(0.25, "r1/target", 0, a, 0.0, 1.0))
    )  # the target sensor is slower
    v.observe(K.field_obstacle("r1", 3), encode(ObstacleField(0.5, "r1/obstacle-3", 3, 0, b3)))
    v.observe(K.field_obstacle("r1", 5), encode(ObstacleField(0.5, "r1/obstacle-5", 5, 1, b5)))
    v.observe(K.field_obstacle("r1", 7), encode(ObstacleField(0.5, "r1/obstacle-7", 7, None, None)))  # sees nothing
    v.observe(K.field_obstacle("r1", 9), encode(ObstacleField(0.25, "r1/obstacle-9", 9, 2, np.ones(9))))  # stale
    v.observe(K.field_target("r2"), encode(TargetField(0.5, "r2/target", 8, a[::-1].copy(), 0.0, 1.0)))  # other robot
    f = v.fields()
    e = a - b3 - b5
    assert f["seeing"] == [3, 5] and f["s"] == 0
    assert f["e"] == pytest.approx(list(e), abs=1e-4) and f["b"] == pytest.approx(list(b3 + b5), abs=1e-4)
    assert f["k"] == int(np.argmax(e)) == 2  # the obstacles push the motor winner off the target winner


def test_paths_accumulate_and_malformed_messages_are_dropped_and_counted():
    v = LiveView(GEOMETRY, robot="r2")
    for i in range(10):
        v.observe(K.world_state(), _state(0.1 * i, 0.2 + 0.001 * i))  # 1 mm steps: kept every PATH_STEP
    v.observe(K.world_state(), b"\x93garbage")
    v.observe(K.field_target("r2"), encode(ObstacleField(0.5, "r2/obstacle-3", 3, 0, np.ones(4))))  # wrong kind
    wire = msgpack.unpackb(_state(1.0, 0.3))
    wire["robots"]["r1"]["x"] = "far"
    v.observe(K.world_state(), msgpack.packb(wire))  # no numeric pose: the typed world state does not decode
    tick = v.tick()
    assert tick["dropped"] == 3
    assert tick["time"] == 0.9 and tick["robots"]["r1"]["x"] == pytest.approx(0.209)  # dropped whole
    p = v.init()["paths"]["r1"]
    assert len(p) == 1 + int(0.009 / PATH_STEP + 1e-9) and p[0] == [0.0, 0.2, 0.5]


def test_server_inlines_the_state_and_streams_ticks():
    v = LiveView(GEOMETRY, w=np.array([[0.0, 0.1], [0.5, 0.2]]), ranges=[0.13], colours={"r1": "#123456"})
    v.observe(K.world_state(), _state(0.3, 0.4))
    server = ViewServer(v, port=0)
    try:
        page = urllib.request.urlopen(server.url, timeout=10).read().decode()
        assert "const S = {" in page and '"#123456"' in page and "/*INIT*/" not in page
        state = json.loads(urllib.request.urlopen(server.url + "state.json", timeout=10).read())
        assert state["lattice"] == [[0.0, 0.1], [0.5, 0.2]] and state["paths"]["r1"] == [[0.3, 0.4, 0.5]]
        events: list[dict] = []
        got_two = threading.Event()

        def read() -> None:
            with urllib.request.urlopen(server.url + "events", timeout=10) as stream:
                for line in stream:
                    if line.startswith(b"data: "):
                        events.append(json.loads(line[6:]))
                        if len(events) == 2:
                            got_two.set()
                            return

        threading.Thread(target=read, daemon=True).start()
        assert v.wait_change(-1, 0)  # the first event is the current state
        for _ in range(200):  # keep changing until the reader has seen a second tick
            if got_two.wait(0.05):
                break
            v.observe(K.world_state(), _state(0.6, 0.5))
        assert got_two.is_set()
        assert events[0]["time"] == 0.3 and events[1]["time"] == 0.6 and events[1]["robots"]["r1"]["x"] == 0.5
        with pytest.raises(urllib.error.HTTPError):
            urllib.request.urlopen(server.url + "nothing", timeout=10)
    finally:
        server.close()


def test_cli_errors_name_the_option():
    from click.testing import CliRunner

    from cekm_swarm.cli import main

    r = CliRunner().invoke(main, ["view", "crossing", "--log", __file__])
    assert r.exit_code == 2 and "give a SCENARIO (name or TOML file) or --log RUN.mcap, not both" in r.output
    r = CliRunner().invoke(main, ["view", "crossing", "--robot", "r9", "--wait", "0"])
    assert r.exit_code == 2 and "--robot" in r.output and "'r9' is not a robot of this arena (r1, r2, r3)" in r.output
    r = CliRunner().invoke(main, ["view", "no_such_scenario"])
    assert r.exit_code == 2 and "SCENARIO" in r.output and "no_such_scenario" in r.output


def test_the_fields_of_any_graph_are_drawn_tracking_and_a_users_own_keys():
    """A tracking module's fields (with its teammate fields) and obstacle fields on keys a
    graph of one's own gives them are the chosen robot's fields too (Eq. 9 as its motor sums them)."""
    from cekm_swarm.protocol import TrackingField

    v = LiveView(GEOMETRY)
    a = np.linspace(1.0, 0.0, 9)
    team = np.zeros(9)
    team[1] = 0.3
    b = np.zeros(9)
    b[0] = 0.5
    v.observe(K.field_tracking("r1"), encode(TrackingField(0.25, "r1/target", a, team, ((0, 0.1, 0.2, 1.0),),
                                                           {"t1": 1.0}, False)))
    v.observe("cekm/r1/avoid/nearest", encode(ObstacleField(0.25, "r1/nearest", 4, 0, b)))
    f = v.fields()
    assert f["teammates"] and f["seeing"] == [4] and f["s"] == 0
    assert f["e"] == pytest.approx(list(a - b - team), abs=1e-4)


def test_a_new_run_starts_the_view_afresh():
    """A new run id, or sim time going back (a replay from its start): no path of the last
    run is joined to the next."""
    v = LiveView(GEOMETRY)
    for i in range(5):
        v.observe(K.world_state(), _state(1.0 + i, 0.2 + 0.01 * i))
    assert len(v.init()["paths"]["r1"]) == 5
    v.new_run("run-2", "cekm-navigation (cekm)")
    tick = v.tick()
    assert tick["run"] == "run-2" and tick["graph"] == "cekm-navigation (cekm)" and tick["time"] is None
    assert v.init()["paths"] == {} and v.fields() is None
    v.observe(K.world_state(), _state(5.0, 1.0))
    v.observe(K.world_state(), _state(0.0, 0.2))  # back to the start
    assert v.init()["paths"]["r1"] == [[0.0, 0.2, 0.5]] and v.tick()["run"] == "run-2"


def test_the_first_run_id_names_the_run_joined_and_another_starts_afresh():
    """A view that joins a run mid-way learns its id from the world's token after some of
    its states: those stay; a later run's id starts the view afresh; the same id again
    changes nothing."""
    v = LiveView(GEOMETRY)
    for i in range(3):
        v.observe(K.world_state(), _state(1.0 + i, 0.2 + 0.01 * i))
    v.run_seen("run-1")
    assert v.tick()["run"] == "run-1" and len(v.init()["paths"]["r1"]) == 3
    v.run_seen("run-1")
    assert len(v.init()["paths"]["r1"]) == 3
    v.run_seen("run-2")
    assert v.tick()["run"] == "run-2" and v.init()["paths"] == {} and v.tick()["time"] is None


def test_a_logs_arena_gives_the_same_sensing_circles_as_its_scenario(tmp_path):
    """``cekm view --log`` drew no sensing circles: the log's geometry carries the ranges."""
    import json

    from mcap.writer import Writer

    from cekm_swarm.view.command import _geometry
    from world import load_scenario
    from world.sim import World

    sc = load_scenario("tracking")
    path = tmp_path / "run.mcap"
    with open(path, "wb") as f:
        w = Writer(f)
        w.start()
        w.add_metadata("geometry", {"json": json.dumps(World(sc, seed=sc.seed).static_geometry())})
        w.finish()
    from_log, from_scenario = _geometry(None, path, None)[1], _geometry("tracking", None, None)[1]
    assert from_log == from_scenario and len(from_log) == 2


def test_a_learning_robots_map_shows_its_version_updates_error_and_lattice():
    """The chosen robot's MapVersion: its version, updates so far, running error and each
    neuron's input weight as the displacement it stands for (Fig. 6); another robot's, or an
    older version, changes nothing."""
    from cekm_swarm.models.learning import map_digest
    from cekm_swarm.protocol import MapVersion

    def version(robot, k, alpha):
        w = np.array([alpha, 0.1, 0.0, 0.05, -alpha, 0.1, 3.0, 0.02])  # 2 x 2 neurons: (alpha_i, d_i)
        M = np.arange(16, dtype=np.float64)
        return K.root + f"/{robot}/model/update", encode(MapVersion(k * 1.024, f"{robot}/learner", k, 10 * k, 9 * k, k,
                                                                     map_digest(w, M), w, M, 0.002 * k))

    v = LiveView(GEOMETRY)
    assert v.learning() is None and v.tick()["learning"] is None
    v.observe(*version("r1", 2, 0.5))
    v.observe(*version("r2", 3, 0.9))  # not the chosen robot
    v.observe(*version("r1", 1, 0.7))  # older than the one it shows
    got = v.tick()["learning"]
    assert (got["version"], got["updates"], got["steps"], got["skipped"], got["error"], got["size"]) == (2, 18, 20, 2,
                                                                                                       0.004, 2)
    assert got["points"][0] == pytest.approx([0.1 * np.cos(0.5), 0.1 * np.sin(0.5)], abs=1e-5)
    assert got["points"][2] == pytest.approx([0.1 * np.cos(0.5), -0.1 * np.sin(0.5)], abs=1e-5)
    assert got["points"][3] == pytest.approx([0.02 * np.cos(3.0), 0.02 * np.sin(3.0)], abs=1e-5)
    v.new_run("another")
    assert v.learning() is None
