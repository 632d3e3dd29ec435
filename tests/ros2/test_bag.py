"""``cekm log export RUN.mcap --to ros2``: a ``crossing`` lockstep run's bag, read back by two
readers independent of the writer's code path (rosbags' rosbag2 reader; the mcap library
with Foxglove's ROS 2 decoder, which parses the bag's own ``ros2msg`` schemas), equals the
run's own log and outcome."""

import json
import math
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from ros2_helpers import cekm
from rosbags.rosbag2 import Reader
from ruamel.yaml import YAML

from cekm_swarm.protocol import SenseRange, Unchanged, WheelCommand, decode, with_stamp
from cekm_swarm.robot import KHEPERA
from cekm_swarm.ros2.bag import export_ros2, msgpack_message_count
from cekm_swarm.ros2.interfaces import JAZZY_TYPE_HASHES, interfaces
from cekm_swarm.ros2.mapping import TOPICS
from cekm_swarm.runtime.mcap_log import read_messages

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def bag(crossing_run, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("export") / "bag"
    r = cekm("log", "export", str(crossing_run / "run.mcap"), "--to", "ros2", "--out", str(out))
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith(f"wrote {out} (rosbag2, MCAP storage, ROS 2 jazzy)")
    return out


@pytest.fixture(scope="module")
def log(crossing_run) -> list:
    return [(m.topic, decode(m.topic, m.data)) for m in read_messages(crossing_run / "run.mcap", encodings=["msgpack"])]


@pytest.fixture(scope="module")
def bag_messages(bag) -> dict[str, list]:
    """{topic: [(bag time ns, message)]}, read with rosbags' reader and its Jazzy CDR decoder."""
    store = interfaces("jazzy").store
    out: dict[str, list] = {}
    with Reader(bag) as r:
        assert r.message_count == sum(c.msgcount for c in r.connections)
        for c, t, raw in r.messages():
            out.setdefault(c.topic, []).append((t, store.deserialize_cdr(raw, c.msgtype)))
    return out


def test_the_bag_is_a_rosbag2_mcap_bag_with_the_jazzy_hashes(bag):
    assert sorted(p.name for p in bag.iterdir()) == ["bag.mcap", "metadata.yaml"]
    meta = YAML(typ="safe").load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert meta["storage_identifier"] == "mcap" and meta["version"] == 9 and meta["relative_file_paths"] == ["bag.mcap"]
    assert meta["custom_data"]["cekm.scenario"] == "crossing" and meta["custom_data"]["cekm.mode"] == "lockstep"
    with Reader(bag) as r:
        assert r.message_count == meta["message_count"] > 10_000
        for c in r.connections:
            assert c.digest == JAZZY_TYPE_HASHES[c.msgtype]
            assert c.ext.serialization_format == "cdr"
            latched = c.topic == "/tf_static"
            assert [q.durability.name for q in c.ext.offered_qos_profiles] == [
                "TRANSIENT_LOCAL" if latched else "VOLATILE"
            ]
    with open(bag / "bag.mcap", "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        assert reader.get_header().profile == "ros2"
        summary = reader.get_summary()
        assert {s.encoding for s in summary.schemas.values()} == {"ros2msg"}
        assert {c.message_encoding for c in summary.channels.values()} == {"cdr"}
        assert {i.compression for i in summary.chunk_indexes} == {"zstd"}
        # Foxglove's decoder builds each type from the bag's own schema text and decodes every message
        decoded = Counter(c.topic for _, c, _, _ in reader.iter_decoded_messages())
    with Reader(bag) as r:
        assert decoded == Counter({c.topic: c.msgcount for c in r.connections})


def test_every_robots_last_pose_is_the_runs_final_pose(bag_messages, crossing_run):
    traj = json.loads((crossing_run / "trajectory.json").read_text())
    outcome = json.loads((crossing_run / "outcome.json").read_text())
    assert sorted(traj) == ["r1", "r2", "r3"]
    for rid, tr in traj.items():
        odom = bag_messages[f"/{rid}/odom"]
        assert len(odom) == len(tr["t"]) == outcome["ticks"] + 1  # one per tick
        t_ns, last = odom[-1]
        p = last.pose.pose
        assert t_ns == round(tr["t"][-1] * 1e9) == round(outcome["sim_seconds"] * 1e9)
        assert (p.position.x, p.position.y) == (tr["x"][-1], tr["y"][-1])  # bit for bit
        assert 2 * math.atan2(p.orientation.z, p.orientation.w) == pytest.approx(tr["theta"][-1], abs=1e-12)
        gx, gy = outcome["robots"][rid]["checkpoints"][-1]
        assert math.hypot(gx - p.position.x, gy - p.position.y) == outcome["robots"][rid]["final_distance_m"]
        assert [(m.pose.pose.position.x, m.pose.pose.position.y) for _, m in odom] == list(
            zip(tr["x"], tr["y"], strict=True)
        )


def held_readings(log, rid: str, j: int) -> list[SenseRange]:
    """Sensor j's reading at every tick: the logged one, or, in a tick where the world held
    it (named on sense/unchanged), the last one logged, restamped."""
    out: list[SenseRange] = []
    key, unchanged = f"cekm/{rid}/sense/range/{j}", f"cekm/{rid}/sense/unchanged"
    for k, m in log:
        if k == key and isinstance(m, SenseRange) and (not out or m.stamp > out[-1].stamp):
            out.append(m)
        elif k == unchanged and isinstance(m, Unchanged) and f"sense/range/{j}" in m.keys:
            out.append(with_stamp(out[-1], m.stamp))
    return out


def test_every_range_sensor_has_one_message_per_obstacle_tick_with_the_logged_reading(bag_messages, log, crossing_run):
    outcome = json.loads((crossing_run / "outcome.json").read_text())
    assert outcome["readings_left_out"] > 0  # the world held readings: the bag has them all the same
    radius = KHEPERA.body_radius  # the crossing robots'
    sensors = 0
    for rid in ("r1", "r2", "r3"):
        for j in range(12):
            readings = held_readings(log, rid, j)
            ranges = bag_messages[f"/{rid}/range_{j}"]
            assert len(ranges) == len(readings) == outcome["ticks"] + 1
            for (t, r), m in zip(ranges, readings, strict=True):
                assert t == round(m.stamp * 1e9) and r.header.frame_id == f"{rid}/range_{j}"
                expected = math.inf if m.d is None else np.float32(m.d - radius)
                assert r.range == expected and r.max_range == np.float32(0.17)
            sensors += 1
    assert sensors == 36
    seen = sum(1 for k, m in log if isinstance(m, SenseRange) and m.d is not None)
    assert seen > 0  # the check above compared real readings, not only +inf
    (_, static), *_ = reversed(bag_messages["/tf_static"])
    assert len(static.transforms) == 36  # the last latched message holds every sensor frame


def test_wheel_commands_and_fields_are_the_logs(bag_messages, log):
    for rid in ("r1", "r2", "r3"):
        cmds = [m for k, m in log if k == f"cekm/{rid}/cmd/wheels" and isinstance(m, WheelCommand)]
        speeds = bag_messages[f"/{rid}/wheel_speeds"]
        twists = bag_messages[f"/{rid}/cmd_vel_out"]
        assert len(speeds) == len(twists) == len(cmds) > 100
        for (t, s), (_, tw), c in zip(speeds, twists, cmds, strict=True):
            assert t == round(c.stamp * 1e9) and list(s.data) == [c.v_l, c.v_r]  # raw wheel speeds, exactly
            assert tw.linear.x == (c.v_l + c.v_r) / 2 and tw.angular.z == (c.v_r - c.v_l) / KHEPERA.axle
        assert len(bag_messages[f"/{rid}/ekm/motor_activity"]) == len(cmds)
        fields = []  # the logged target fields, and the last one again where the target reading was held
        for k, m in log:
            if k == f"cekm/{rid}/field/target":
                fields.append(m)
            elif k == f"cekm/{rid}/sense/unchanged" and "sense/target" in m.keys and fields:
                fields.append(fields[-1])
        arrays = bag_messages[f"/{rid}/ekm/target_field"]
        assert len(arrays) == len(fields)
        for (_, arr), f in zip(arrays, fields, strict=True):
            assert (f.a is None and len(arr.data) == 0) or np.array_equal(arr.data, f.a)
    names = {row.name.format(robot=r, j=j) for row in TOPICS for r in ("r1", "r2", "r3") for j in range(12)}
    assert set(bag_messages) <= names  # every exported topic is a row of the documented mapping


def test_export_reports_progress_and_refuses_bad_input_in_one_line(crossing_run, tmp_path):
    calls = []
    report = export_ros2(
        crossing_run / "run.mcap", tmp_path / "b", progress=lambda done, total: calls.append((done, total))
    )
    assert calls[-1] == (report.read, report.read) and len(calls) >= report.read // 2000
    assert all(total == report.read for _, total in calls) and [d for d, _ in calls] == sorted(d for d, _ in calls)
    not_mcap = tmp_path / "notes.mcap"
    not_mcap.write_text("hello")
    busy = tmp_path / "busy"
    busy.mkdir()
    (busy / "keep.txt").write_text("x")
    for args, expected in (([str(not_mcap)], f"{not_mcap}: not an MCAP file"),
                           ([str(tmp_path / "missing.mcap")], "no such file"),
                           ([str(crossing_run / "run.mcap")], f"--out {busy}: not empty")):
        out = busy if "run.mcap" in args[0] else tmp_path / "never"
        r = cekm("log", "export", *args, "--to", "ros2", "--out", str(out))
        assert r.returncode == 2 and r.stdout == ""
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("cekm: error:") and expected in lines[0], r.stderr
    assert not (tmp_path / "never").exists() and (busy / "keep.txt").exists()


def test_the_scene_comes_from_the_logs_geometry_also_when_the_log_was_cut(crossing_run, bag_messages, tmp_path):
    (_, first), *_ = bag_messages["/world/markers"]
    assert {m.ns for m in first.markers} == {"walls", "discs"}  # crossing: walls and two unforeseen discs
    data = (crossing_run / "run.mcap").read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) * 3 // 5])  # a world server killed mid-run
    report = export_ros2(cut, tmp_path / "b")
    assert not report.complete and 0 < report.read < msgpack_message_count(crossing_run / "run.mcap")
    with Reader(tmp_path / "b") as r:
        assert r.message_count == report.written
        first = next(raw for c, _, raw in r.messages() if c.topic == "/world/markers")
    assert {m.ns for m in interfaces().from_cdr(first, "visualization_msgs/msg/MarkerArray").markers} == {
        "walls",
        "discs",
    }


def test_a_log_under_another_key_root_exports_as_the_same_bag(crossing_run, bag, tmp_path):
    """A launch with ``--root run2`` logs every key under ``run2/``: the export reads the
    log's own root (its world keys, as `cekm log cat` does) instead of finding no message."""
    from cekm_swarm.protocol import KeySpace
    from cekm_swarm.runtime.mcap_log import McapRecorder

    moved = tmp_path / "run2.mcap"
    rec = McapRecorder(moved, keys=KeySpace("run2"))
    for m in read_messages(crossing_run / "run.mcap", encodings=["msgpack"]):
        rec.write("run2/" + m.topic.split("/", 1)[1], m.data, m.log_time / 1e9)
    rec.close()
    out = tmp_path / "bag"
    r = cekm("log", "export", str(moved), "--to", "ros2", "--out", str(out))
    assert r.returncode == 0, r.stderr

    def counts(path: Path) -> Counter:
        with Reader(path) as reader:
            return Counter(c.topic for c, _, _ in reader.messages() if c.topic != "/world/markers")

    assert counts(out) == counts(bag) and sum(counts(out).values()) > 0
