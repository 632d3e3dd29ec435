"""MCAP logs: channel layout, the independent ``mcap`` reader, crash recovery, summaries,
Foxglove view channels, and recording live Zenoh traffic."""

from __future__ import annotations

import asyncio
import os
import signal

import numpy as np
import pytest
from mcap.exceptions import McapError
from mcap.reader import make_reader
from runtime_samples import sample_traffic, write_log

from cekm_swarm.protocol import DEFAULT_KEYS, Clock, decode, encode
from cekm_swarm.runtime.bridge import Publishers, wait_matching_async
from cekm_swarm.runtime.errors import McapLogError
from cekm_swarm.runtime.mcap_log import (
    McapRecorder,
    format_log_info,
    is_complete,
    log_info,
    read_messages,
    record_zenoh,
    recover_log,
    sim_ns,
    stream_messages,
)

K = DEFAULT_KEYS


def test_channels_schemas_and_times_with_the_mcap_reader(tmp_path):
    path = tmp_path / "run.mcap"
    traffic = sample_traffic()
    write_log(path, traffic, chunk_size=8 * 1024)
    assert is_complete(path)
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None and summary.statistics.message_count == len(traffic)
        assert len(summary.chunk_indexes) > 1 and {c.compression for c in summary.chunk_indexes} == {"zstd"}
        channels = {c.topic: c for c in summary.channels.values()}
        assert set(channels) == {k for k, _, _ in traffic}
        for c in channels.values():
            assert c.message_encoding == "msgpack"
            schema = summary.schemas[c.schema_id]
            assert schema.encoding == "" and schema.data == b""
        assert summary.schemas[channels[K.field_target("r1")].schema_id].name == "cekm.field/target"
        got = [(ch.topic, msg.data, msg.log_time, msg.publish_time)
               for _, ch, msg in reader.iter_messages(log_time_order=True)]
    assert sorted(got, key=lambda g: g[2]) == got
    assert [(k, d) for k, d, _ in traffic] == [(k, d) for k, d, _, _ in got]  # stable order within a tick
    assert all(lt == pt == sim_ns(t) for (_, _, t), (_, _, lt, pt) in zip(traffic, got, strict=True))
    ours = list(read_messages(path))
    assert [(m.topic, m.data) for m in ours] == [(k, d) for k, d, _ in traffic]
    assert all(decode(m.topic, m.data) is not None for m in ours)
    assert [m.sequence for m in ours if m.topic == K.world_clock()] == list(range(1, 41))


def test_sim_ns_rounds_and_clamps():
    assert sim_ns(1.024) == 1_024_000_000 and sim_ns(-1.0) == 0 and sim_ns(float("nan")) == 0


def test_log_info_counts_rates_duration(tmp_path):
    path = tmp_path / "run.mcap"
    write_log(path, sample_traffic(40))
    info = log_info(path)
    assert info.complete and info.messages == 40 * 3 + 20
    assert info.start == 0.0 and info.duration == pytest.approx(39 * 0.128)
    by = {c.topic: c for c in info.channels}
    assert by[K.world_clock()].count == 40 and by[K.world_clock()].rate == pytest.approx(1 / 0.128)
    assert by[K.field_target("r1")].rate == pytest.approx(1 / 0.256)
    text = format_log_info(info)
    assert "complete" in text and K.cmd_wheels("r1") in text and "7.81" in text


def test_truncated_file_streams_to_the_cut_and_recovers(tmp_path):
    path = tmp_path / "run.mcap"
    traffic = sample_traffic(60)
    write_log(path, traffic, chunk_size=4 * 1024)
    data = path.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: int(len(data) * 0.6)])
    assert not is_complete(cut)
    with open(cut, "rb") as f, pytest.raises(McapError):
        make_reader(f).get_summary()  # the seeking reader needs the footer
    streamed = list(read_messages(cut))
    assert 0 < len(streamed) < len(traffic)
    assert [(m.topic, m.data) for m in streamed] == [(k, d) for k, d, _ in traffic[: len(streamed)]]
    info = log_info(cut)
    assert not info.complete and info.messages == len(streamed) and info.cut_reason
    assert "INCOMPLETE" in format_log_info(info)
    report = recover_log(cut)
    assert report.messages == len(streamed) and not report.input_complete and report.output.exists()
    assert is_complete(report.output)
    with open(report.output, "rb") as f:
        reader = make_reader(f)
        assert reader.get_summary().statistics.message_count == len(streamed)
        assert [(c.topic, m.data, m.log_time) for _, c, m in reader.iter_messages()] == \
            [(m.topic, m.data, m.log_time) for m in streamed]


@pytest.mark.slow
def test_killed_writer_loses_only_the_open_chunk(tmp_path, helpers):
    path = tmp_path / "killed.mcap"
    writer = helpers("mcap", str(path), "300")
    writer.expect("FLUSHED 300")
    os.kill(writer.proc.pid, signal.SIGKILL)
    writer.proc.wait(timeout=10)
    assert not is_complete(path)
    report = recover_log(path, tmp_path / "fixed.mcap")
    assert report.messages == 300 and not report.input_complete  # everything up to the last flush
    msgs = list(read_messages(report.output))
    assert [decode(m.topic, m.data).tick for m in msgs] == list(range(300))


def test_periodic_flush_bounds_loss(tmp_path):
    path = tmp_path / "run.mcap"
    rec = McapRecorder(path, chunk_size=1 << 20, flush_interval=0.0)  # flush on every write
    traffic = sample_traffic(10)
    for key, data, t in traffic:
        rec.write(key, data, t)
    # the process "dies" here: nothing closed; everything written is already in the file
    assert len(list(stream_messages(path))) == len(traffic)
    rec.close()
    assert is_complete(path)


def test_errors_name_the_file(tmp_path):
    with pytest.raises(McapLogError, match="no such file"):
        log_info(tmp_path / "missing.mcap")
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(b"not an mcap file at all")
    with pytest.raises(McapLogError, match="bad.mcap: not an MCAP file"):
        list(read_messages(bad))
    with pytest.raises(McapLogError, match="compression"):
        McapRecorder(tmp_path / "x.mcap", compression="gzip")
    with McapRecorder(tmp_path / "y.mcap") as rec:
        rec.write(K.world_clock(), b"x", 0.0)
        with pytest.raises(McapLogError, match="already has message encoding 'msgpack'"):
            rec.write_encoded(K.world_clock(), "json", rec._msgpack_schema(K.world_clock()), b"{}", 0.0)
    with pytest.raises(McapLogError, match="closed"):
        rec.write(K.world_clock(), b"x", 0.0)


def test_foxglove_view_channels_decode_with_foxglove_schemas_protobuf(tmp_path):
    pytest.importorskip("foxglove", reason="foxglove-sdk not installed")
    pytest.importorskip("foxglove_schemas_protobuf", reason="foxglove-schemas-protobuf not installed")
    from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
    from foxglove_schemas_protobuf.PosesInFrame_pb2 import PosesInFrame
    from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate

    from cekm_swarm.runtime.foxglove_view import PATH_TOPIC, SCENE_TOPIC, TF_TOPIC, FoxgloveViews

    geometry = {
        "body_radius": 0.03,
        "walls": [{"a": [0.0, 0.0], "b": [1.0, 0.0], "thickness": 0.02, "known": True}],
        "polygons": [{"id": "box", "vertices": [[0.2, 0.2], [0.4, 0.2], [0.4, 0.4], [0.2, 0.4]],
                      "parts": [[[0.2, 0.2], [0.4, 0.2], [0.4, 0.4], [0.2, 0.4]]], "known": False}],
        "discs": [{"id": "post", "center": [0.7, 0.5], "radius": 0.05, "known": True}],
        "moving_obstacles": [{"id": "mover", "radius": 0.04, "vertices": None}],
    }
    path = tmp_path / "view.mcap"
    with McapRecorder(path) as rec:
        views = FoxgloveViews(rec)
        views.write_geometry(0.0, geometry)
        for i in range(5):
            t = 0.128 * i
            rec.write(K.world_clock(), encode(Clock(t, "world", i)), t)  # raw channels beside the views
            views.write_state(t, {"robots": {"r1": {"x": 0.1 * i, "y": 0.2, "theta": 0.3},
                                             "r2": {"x": 0.5, "y": 0.1 * i, "theta": -1.0}},
                                  "targets": {"t1": {"x": 0.9, "y": 0.9}},
                                  "obstacles": {"mover": {"x": 0.6, "y": 0.6, "theta": 0.0}}})
    decoders = {"foxglove.SceneUpdate": SceneUpdate, "foxglove.FrameTransforms": FrameTransforms,
                "foxglove.PosesInFrame": PosesInFrame}
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
        for ch in summary.channels.values():
            if ch.topic.startswith("/view"):
                schema = summary.schemas[ch.schema_id]
                assert ch.message_encoding == "protobuf" and schema.encoding == "protobuf"
                assert schema.name in decoders and len(schema.data) > 100
    decoded: dict[str, list] = {}
    for m in read_messages(path):
        if m.message_encoding == "protobuf":
            decoded.setdefault(m.topic, []).append(decoders[m.schema_name].FromString(m.data))
    static = decoded[SCENE_TOPIC][0]
    assert {e.id for e in static.entities} == {"wall/0", "obstacle/box", "obstacle/post"}
    wall = next(e for e in static.entities if e.id == "wall/0")
    assert wall.cubes[0].size.x == pytest.approx(1.02) and wall.frame_id == "world"
    last = decoded[SCENE_TOPIC][-1]
    assert {e.id for e in last.entities} == {"robot/r1", "robot/r2", "target/t1", "obstacle/mover"}
    r1 = next(e for e in last.entities if e.id == "robot/r1")
    assert r1.cylinders[0].pose.position.x == pytest.approx(0.4) and r1.texts[0].text == "r1"
    assert last.entities[0].timestamp.nanos == 512_000_000
    tf = decoded[TF_TOPIC][-1].transforms
    assert {t.child_frame_id for t in tf} == {"r1", "r2"} and tf[0].parent_frame_id == "world"
    assert tf[0].rotation.z == pytest.approx(np.sin(0.15))
    for rid in ("r1", "r2"):  # one path message (at t = 0: the next is due 1 s later); the trail has the rest
        assert len(decoded[PATH_TOPIC.format(robot=rid)]) == 1
        trail = next(e for e in last.entities if e.id == f"robot/{rid}").lines[0].points
        assert len(trail) == 6 and (trail[-1].x, trail[-1].y) == (trail[-2].x, trail[-2].y)
    assert [round(p.x, 6) for p in r1.lines[0].points[:5]] == [0.0, 0.1, 0.2, 0.3, 0.4]


def test_record_zenoh_files_live_traffic_at_sim_time(clients, tmp_path):
    a, b = clients(), clients()
    path = tmp_path / "live.mcap"
    traffic = sample_traffic(10)

    async def run():
        stop = asyncio.Event()
        with McapRecorder(path) as rec:
            task = asyncio.create_task(record_zenoh(b, rec, stop=stop))
            with Publishers(a, block=True) as pubs:
                assert await wait_matching_async(pubs.publisher(traffic[0][0]), 10)
                for key, data, _ in traffic:
                    pubs.put(key, data)
                pubs.put(K.cmd_wheels("r9"), b"\xc1 not msgpack")  # malformed: still recorded
                loop = asyncio.get_running_loop()
                deadline = loop.time() + 10
                while rec.messages < len(traffic) + 1:
                    assert loop.time() < deadline
                    await asyncio.sleep(0.005)
            stop.set()
            return await asyncio.wait_for(task, 10)

    n = asyncio.run(run())
    assert n == len(traffic) + 1
    msgs = list(read_messages(path))
    assert [(m.topic, m.data) for m in msgs if m.topic != K.cmd_wheels("r9")] == [(k, d) for k, d, _ in traffic]
    bad = [m for m in msgs if m.topic == K.cmd_wheels("r9")]
    assert len(bad) == 1 and bad[0].log_time == sim_ns(traffic[-1][2])  # filed at the latest sim time seen


def test_times_no_writer_can_hold_are_clamped_and_the_channel_table_is_bounded(tmp_path, monkeypatch):
    """A peer's stamp of 1e18 or 1e300 overflowed the mcap writer and killed the world
    server; keys invented without end grew the channel table (16-bit ids)."""
    import cekm_swarm.runtime.mcap_record as ml

    assert sim_ns(1e300) == sim_ns(1e18) == sim_ns(float("inf")) == ml.MAX_NS
    assert sim_ns(float("nan")) == sim_ns(-1.0) == 0 and sim_ns(0.128) == 128_000_000
    monkeypatch.setattr(ml, "MAX_CHANNELS", 5)
    path = tmp_path / "bounded.mcap"
    payload = encode(Clock(0.128, "world", 1))
    with McapRecorder(path) as rec:
        rec.write(DEFAULT_KEYS.world_clock(), payload, 1e300, 1e18)
        written = [rec.write(f"cekm/fuzz/{i}", payload, 0.128) for i in range(20)]
        assert rec.write(DEFAULT_KEYS.world_clock(), payload, 0.256)  # a known channel still takes messages
    assert written == [True] * 4 + [False] * 16 and rec.refused == 16
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    assert len(summary.channels) == 5 and summary.statistics.message_count == 6


def test_without_resends_leaves_out_a_message_equal_to_the_one_before_it_on_its_topic():
    """The log holds what was sent, a stalled tick's re-sends too; readers that want one
    sample a tick leave out a byte-equal repeat on the same topic, and nothing else."""
    from cekm_swarm.runtime.mcap_log import LoggedMessage, without_resends

    def m(topic: str, data: bytes, t: int) -> LoggedMessage:
        return LoggedMessage(topic, t, t, 0, data, "msgpack", None, None)

    log = [m("a", b"1", 0), m("b", b"1", 0), m("a", b"1", 1), m("a", b"2", 2), m("b", b"1", 3), m("a", b"1", 4)]
    assert [(x.topic, x.data, x.log_time) for x in without_resends(log)] == [
        ("a", b"1", 0), ("b", b"1", 0), ("a", b"2", 2), ("a", b"1", 4)]


def _root_log(path, root: str, metadata: dict | None, close: bool = True):
    """A log of a run under key root ``root``: its world clock, with ``metadata`` as its ``cekm`` record."""
    from cekm_swarm.protocol import KeySpace

    keys = KeySpace(root)
    rec = McapRecorder(path, keys=keys, metadata=metadata)
    for k in range(3):
        rec.write(keys.world_clock(), encode(Clock(k * 0.128, "world", k)), k * 0.128)
    if close:
        rec.close()
    else:
        rec.flush()
    return rec


def test_a_logs_root_is_its_metadata_else_that_of_its_world_keys(tmp_path):
    from cekm_swarm.runtime.mcap_log import log_root

    _root_log(tmp_path / "meta.mcap", "run2", {"root": "run2"})
    _root_log(tmp_path / "old.mcap", "run3/a", {"scenario": "concave"})  # a log from before the root was written
    _root_log(tmp_path / "cut.mcap", "run4", None, close=False)  # truncated: no summary
    rec = McapRecorder(tmp_path / "nothing.mcap")
    rec.write(K.cmd_wheels("r1"), b"x", 0.0)
    rec.close()
    (tmp_path / "text.mcap").write_text("hello")
    assert [log_root(tmp_path / f"{n}.mcap") for n in ("meta", "old", "cut", "nothing", "text", "absent")] == [
        "run2", "run3/a", "run4", None, None, None]


@pytest.mark.parametrize("metadata", [{"root": "run2"}, None])
def test_log_cat_decodes_a_log_under_its_own_root(tmp_path, capsys, metadata):
    """A log of `cekm launch --root run2` was printed all MALFORMED without --root run2 (QA item 18)."""
    from cekm_swarm.cli import main
    from cekm_swarm.cli_support import run_cli

    _root_log(tmp_path / "run.mcap", "run2", metadata)
    assert run_cli(main, ["log", "cat", str(tmp_path / "run.mcap")]) == 0
    out, err = capsys.readouterr()
    assert "MALFORMED" not in out and "malformed" not in err
    assert out.splitlines()[-1].split() == ["0.256", "run2/world/clock:", "world/clock", "t=0.256", "from=world",
                                            "tick=2"]
    assert run_cli(main, ["log", "cat", str(tmp_path / "run.mcap"), "--root", "cekm"]) == 0  # told otherwise
    assert "3 malformed message(s)" in capsys.readouterr().err


def test_the_world_log_writes_its_root(tmp_path):
    from cekm_swarm.protocol import KeySpace
    from world.recorder import open_run_log

    recorder, views = open_run_log(tmp_path / "run.mcap", "concave", 8, "lockstep", {"bounds": [0, 0, 1, 1]}, 0.03,
                                   keys=KeySpace("run2"))
    recorder.close()
    with open(tmp_path / "run.mcap", "rb") as f:
        meta = {m.name: dict(m.metadata) for m in make_reader(f).iter_metadata()}
    assert meta["cekm"]["root"] == "run2"
