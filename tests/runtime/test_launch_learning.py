"""`cekm launch --learn --mode lockstep` equals `cekm run --learn` bit for bit (docs/learning.md):
every pose and command of every tick, the outcome, and every map version's digest, from
untrained maps with a team of three sharing their experience (an obstacle node of one SIGKILLed as the world starts
ticking: it catches up from the learner's next message) and from the trained map with one;
`cekm model extract` on the log gives the run's final map."""

from __future__ import annotations

import json
import os
import random
import re
import signal
import time

import numpy as np
import pytest
from scenario_gen import generated_scenario

from cekm_swarm.experiments.default_model import default_model, default_model_path
from cekm_swarm.experiments.graph_run import resolve_graph, with_params
from cekm_swarm.experiments.learning_run import LEARNER, learning_params, untrained_model
from cekm_swarm.experiments.navigation_run import run_scenario
from cekm_swarm.models.io import load_model
from cekm_swarm.models.learning import map_digest
from cekm_swarm.runtime.map_log import versions
from helpers.launch import LaunchProcess
from world import load_scenario

pytestmark = pytest.mark.slow  # starts real processes (tests/process_guard.py)


def in_process(scenario: str, model, choice, max_time: float, controller: str = "cekm-learning"):
    from cekm_swarm.experiments.graph_run import run_graph

    checked = with_params(resolve_graph(controller, None, "navigation"), learning_params(choice))
    ref = run_scenario(load_scenario(scenario), controller, model, None, max_time=max_time, graph=checked)
    graph = run_graph(load_scenario(scenario), graph=checked, model=model, max_time=max_time)
    history = {r: [(v, d) for v, _, d in graph.executor.node(r, LEARNER).history] for r in graph.world.robot_ids}
    return ref, history


def launched(tmp_path, scenario, max_time, *args, kill=None):
    run = LaunchProcess(scenario, tmp_path / "run", "--learn", "--mode", "lockstep", "--max-time", str(max_time), *args)
    try:
        if kill:
            run.wait_line("world started ticking", timeout=120)
            os.kill(run.pids()[kill], signal.SIGKILL)
        code = run.finish(timeout=180)
    finally:
        run.kill()
    assert code == 0, "\n".join(run.lines)
    return run


def assert_equal_runs(run, ref, history):
    outcome = run.outcome()
    assert outcome["reproducible"]["equals_cekm_run"] is True
    traj = json.loads((run.out / "trajectory.json").read_text())
    for r, log in ref.logs.items():
        assert traj[r]["t"] == log.t
        assert traj[r]["x"] == log.x and traj[r]["y"] == log.y and traj[r]["theta"] == log.theta
        assert traj[r]["v_l"] == log.v_l and traj[r]["v_r"] == log.v_r
    assert outcome["robots"] == json.loads(json.dumps(ref.outcome))
    assert versions(run.out / "run.mcap") == history  # every version, its digest, in order
    for r, block in ref.learning.items():
        got = outcome["learning"][r]
        assert got["final_digest"] == block["final_digest"] == history[r][-1][1]
        assert got["updates_applied"] == block["updates_applied"] > 0
        assert got["end"] == block["end"] and got["start"] == block["start"]


def replayed_maps(log, clients) -> list[tuple[str, bytes]]:
    """The map messages a subscriber receives while ``cekm replay`` republishes ``log``."""
    import threading

    from cekm_swarm.runtime.bridge import Publishers
    from cekm_swarm.runtime.mcap_read import read_messages
    from cekm_swarm.runtime.replay import replay_log

    want = [m.topic for m in read_messages(log) if m.topic.endswith("/model/update")]
    got: list[tuple[str, bytes]] = []
    done = threading.Event()

    def on(sample) -> None:
        got.append((str(sample.key_expr), sample.payload.to_bytes()))
        if len(got) == len(want):
            done.set()

    sub = clients().declare_subscriber("cekm/**/model/update", on)
    a = clients()
    pubs = Publishers(a, block=True)
    assert pubs.wait_matching(want[0], 30)  # the subscription known before the first message goes
    replay_log(a, log, rate=None, publishers=pubs, key_expr="cekm/**/model/update")
    assert done.wait(30), f"{len(got)} of {len(want)} map messages"
    pubs.close()
    sub.undeclare()
    return got


def test_a_team_of_three_untrained_robots_learns_the_same_in_lockstep_as_in_process(tmp_path, clients):
    """Team sharing: each learner also learns from its teammates' (v, c) of the tick before.
    ``cekm replay`` of its log gives every map message, so every version, bit for bit."""
    run = launched(tmp_path, "crossing", 4, "--model", "untrained", "--controller", "cekm-learning-team",
                   kill="r2/obstacle-3")
    ref, history = in_process("crossing", untrained_model(), "untrained", 4, "cekm-learning-team")
    assert all(b["team_steps"] > 0 for b in ref.learning.values())
    for r in ("r1", "r2", "r3"):  # own and teammates' experience: never lost. The runtime's resend to a
        # restarted reader (LockstepGate.resend) sends a learner's recent outputs again, an old map version
        # and, with it, the experience of a run the others have already read: they drop such a copy as a
        # value no later run reads, and only so. That nothing was lost is the equality below: every map
        # version of every robot, bit for bit, which a teammate's experience never read would change
        text = (run.out / "logs" / f"{r}-learner.log").read_text()
        drops = [json.loads(line[len("DROPS "):]) for line in text.splitlines() if line.startswith("DROPS ")]
        assert drops, text
        for key in {key for d in drops for key in d["dropped"] if "experience" in key}:
            (why,) = re.findall(rf"dropped a message from {key} \(further drops from it are only counted\): (.*)", text)
            assert re.fullmatch(r"a value of t=[0-9.]+, which no run after t=[0-9.]+ reads", why), why
    assert run.outcome()["launcher"]["restarts"] == {"r2/obstacle-3": 1}
    assert all(len(h) > 2 for h in history.values())
    assert_equal_runs(run, ref, history)
    from cekm_swarm.cli import run_cli_args

    out = tmp_path / "r3.npz"
    assert run_cli_args(["model", "extract", str(run.out / "run.mcap"), "--robot", "r3", "--out", str(out)]) == 0
    m = load_model(out)  # a model file cekm run --model takes
    assert map_digest(m.w, m.M) == history["r3"][-1][1]
    from cekm_swarm.protocol import decode
    from cekm_swarm.runtime.mcap_read import read_messages

    recorded = [(m.topic, m.data) for m in read_messages(run.out / "run.mcap") if m.topic.endswith("/model/update")]
    replayed = replayed_maps(run.out / "run.mcap", clients)
    assert replayed == recorded  # every byte, in order
    last = {key.split("/")[1]: decode(key, data) for key, data in replayed}
    assert {r: msg.digest for r, msg in last.items()} == {r: h[-1][1] for r, h in history.items()}
    assert all(map_digest(msg.w, msg.M) == msg.digest for msg in last.values())


def learner_killed_at_version(tmp_path, mode: str, max_time: float, version: int) -> tuple[LaunchProcess, int]:
    """A launch of lone_obstacle with the trained map whose learner is SIGKILLed once its
    snapshot on disk holds ``version`` (waited for, bounded); the run, ended, and the
    version the snapshot held at the kill."""
    snapshot = tmp_path / "run" / "maps" / "r1.npy"
    run = LaunchProcess("lone_obstacle", tmp_path / "run", "--learn", "--mode", mode, "--max-time", str(max_time),
                        "--model", str(default_model_path()))
    try:
        run.wait_line("world started ticking", timeout=120)
        deadline = time.monotonic() + 60
        while not (snapshot.exists() and np.load(snapshot)[0] >= version):  # the version made and kept
            assert time.monotonic() < deadline, f"no map version {version} on disk"
            time.sleep(0.005)
        kept = int(np.load(snapshot)[0])
        os.kill(run.pids()["r1/learner"], signal.SIGKILL)
        code = run.finish(timeout=180)
    finally:
        run.kill()
    assert code == 0, "\n".join(run.lines)
    return run, kept


def test_one_trained_robot_learns_the_same_in_lockstep_as_in_process_its_learner_killed(tmp_path):
    """The learner SIGKILLed once it has made a version: it goes on from its snapshot."""
    run, _ = learner_killed_at_version(tmp_path, "lockstep", 6, 1)
    ref, history = in_process("lone_obstacle", default_model(progress=False), None, 6)
    assert run.outcome()["launcher"]["restarts"] == {"r1/learner": 1}
    assert "restarted from map version" in (run.out / "logs" / "r1-learner.log").read_text()
    assert_equal_runs(run, ref, history)
    from cekm_swarm.runtime.mcap_read import read_messages

    views = [m for m in read_messages(run.out / "run.mcap") if m.topic.startswith("/view/lattice/")]
    assert not (run.out / "lattice.mcap").exists()  # a Foxglove view of every version's lattice, in run.mcap
    assert [m.topic for m in views] == ["/view/lattice/r1"] * len(history["r1"])
    assert {m.schema_name for m in views} == {"foxglove.SceneUpdate"}


@pytest.mark.parametrize("seed", [711, 714])
def test_a_generated_scenario_learns_the_same_in_lockstep_with_a_node_killed(tmp_path, seed):
    """Seeded (the seed names the failure): 2 robots of a generated navigation scenario, the
    learning graph with or without sharing, untrained or trained maps, one node SIGKILLed."""
    rng = random.Random(seed)
    path = str(generated_scenario(tmp_path, seed, 2, "navigation"))
    controller = rng.choice(["cekm-learning", "cekm-learning-team"])
    untrained = rng.random() < 0.5
    kill = f"r{rng.randint(1, 2)}/{rng.choice(['motor', 'target', 'learner', 'obstacle-5'])}"
    print(f"seed {seed}: {controller}, {'untrained' if untrained else 'trained'}, kill {kill}")
    model = ("untrained",) if untrained else (str(default_model_path()),)
    run = launched(tmp_path, path, 4, "--model", *model, "--controller", controller, kill=kill)
    ref, history = in_process(path, untrained_model() if untrained else default_model(progress=False),
                              "untrained" if untrained else None, 4, controller)
    assert run.outcome()["launcher"]["restarts"].get(kill) == 1
    assert_equal_runs(run, ref, history)


RETARGET = """name = "retarget"
seed = 4
retarget = true
explore = true
[arena]
bounds = [-1.0, -1.0, 1.0, 1.0]
[[robots]]
id = "r1"
start = [0.0, 0.0, 0.0]
goal = "t1"
[[targets]]
id = "t1"
position = [0.06, 0.0]
"""


def test_section_4_1_training_through_the_world_server_equals_cekm_run(tmp_path):
    """A retarget scenario: the world gives the robot a new target at each stop, with
    training exploration noise on its executed wheel speeds (the learner learns from them)."""
    path = tmp_path / "retarget.toml"
    path.write_text(RETARGET)
    run = launched(tmp_path, str(path), 8, "--model", str(default_model_path()))
    ref, history = in_process(str(path), default_model(progress=False), None, 8)
    assert run.outcome()["robots"]["r1"]["targets_reached"] >= 1
    assert_equal_runs(run, ref, history)


def test_a_learner_sigkilled_in_real_time_goes_on_from_its_last_version_and_says_what_it_lost(tmp_path):
    """Real time: the learner SIGKILLed once its version 2 is on disk; it restarts from the
    version it kept (not from the run's model), its log says how many steps the restart
    lost, and the map versions on the bus go on without a gap or a version made twice
    (but the one it was killed before sending)."""
    import re

    run, kept = learner_killed_at_version(tmp_path, "realtime", 10, 2)
    assert run.outcome()["launcher"]["restarts"] == {"r1/learner": 1}
    log = (run.out / "logs" / "r1-learner.log").read_text()
    resumed = re.search(r"restarted from map version (\d+) \(", log)
    assert resumed and int(resumed.group(1)) >= kept, log  # from its snapshot, not from the model (version 0)
    lost = re.search(r"restarted from map version \d+; (\d+) steps", log)
    assert lost, log  # the log says how many steps were lost, 0 included
    got = versions(run.out / "run.mcap")["r1"]
    numbers = [v for v, _ in got]
    assert numbers == sorted(set(numbers)) and numbers[-1] > kept  # none made twice
    # none missing, but the one the learner kept on disk and was killed before sending (it is
    # written before it is sent): its successor holds every step of it
    missing = sorted(set(range(numbers[0], numbers[-1] + 1)) - set(numbers))
    assert missing in ([], [int(resumed.group(1))]), (numbers, resumed.group(1))
    print(f"kept version {kept}, resumed from {resumed.group(1)}, {lost.group(1)} steps lost, {numbers[-1]} versions")
