"""Log sets: a log split by size or by sim time into numbered files, each a complete MCAP
of its own, read back (``cekm log info``, ``cekm log cat``, replay) as one log in time order."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
from mcap.reader import make_reader
from runtime_samples import sample_traffic

from cekm_swarm.protocol import DEFAULT_KEYS as K
from cekm_swarm.runtime.errors import McapLogError
from cekm_swarm.runtime.mcap_log import MSGPACK, McapRecorder, SchemaSpec, is_complete, log_info, read_messages
from cekm_swarm.runtime.mcap_sets import SplitRecorder, log_files
from cekm_swarm.runtime.replay import log_span, replay_log


def _summary(path):
    with open(path, "rb") as f:
        reader = make_reader(f)
        return reader.get_summary(), {m.name: dict(m.metadata) for m in reader.iter_metadata()}


def _split_log(tmp_path, **limits):
    """120 ticks of sample traffic, with the command of each tick logged 0.1 s late (its
    stamp lags: a message may land in the next file with a time before that file's first)."""
    traffic = sample_traffic(120)
    late = [(k, d, t + (0.1 if k == K.cmd_wheels("r1") else 0.0)) for k, d, t in traffic]
    with SplitRecorder(tmp_path / "run.mcap", metadata={"scenario": "s"}, **limits) as rec:
        rec.add_metadata("geometry", {"json": "{}"})
        rec.write_encoded("/view/scene", "protobuf", SchemaSpec("foxglove.SceneUpdate"), b"walls", 0.0, sticky=True)
        for key, data, t in sorted(late, key=lambda e: e[2] if e[0] != K.cmd_wheels("r1") else e[2] - 0.1):
            rec.write(key, data, t)
    return rec, late


def test_a_set_split_by_sim_time_reads_back_as_one_log_in_time_order(tmp_path):
    rec, traffic = _split_log(tmp_path, max_seconds=3.0)
    files = rec.files
    assert [p.name for p in files] == [f"run_{k}.mcap" for k in range(len(files))] and len(files) == 6
    assert not (tmp_path / "run.mcap").exists()
    for k, p in enumerate(files):  # each file a complete MCAP with its own channels and every metadata record
        assert is_complete(p)
        summary, meta = _summary(p)
        assert summary.channels and summary.statistics.message_count > 0
        assert meta["cekm"] == {"scenario": "s"} and meta["geometry"] == {"json": "{}"}
        assert meta["log_set"]["name"] == "run.mcap" and meta["log_set"]["index"] == str(k)
        assert "/view/scene" in {c.topic for c in summary.channels.values()}  # the sticky scene, again
        first, last = summary.statistics.message_start_time / 1e9, summary.statistics.message_end_time / 1e9
        assert last - first < 3.0 + 0.2
    assert log_files(tmp_path) == files == log_files(files[0])
    assert log_files(files[2]) == [files[2]]  # a later file alone is itself
    msgs = [m for m in read_messages(tmp_path, encodings=(MSGPACK,))]
    times = [m.log_time for m in msgs]
    assert times == sorted(times)
    assert sorted((m.topic, m.data) for m in msgs) == sorted((k, d) for k, d, _ in traffic)
    assert [m.topic for m in read_messages(files[0], topics=["/view/scene"])] == ["/view/scene"] * 6
    info = log_info(tmp_path)
    assert info.complete and info.files == tuple(str(p) for p in files)
    assert info.messages == len(traffic) + 6 and info.size_bytes == sum(p.stat().st_size for p in files)
    assert log_span(files[0]) == pytest.approx((0.0, traffic[-1][2]))


def test_a_set_split_by_size_keeps_each_file_near_the_limit(tmp_path):
    rec, traffic = _split_log(tmp_path, max_bytes=20_000)
    assert len(rec.files) >= 3
    for p in rec.files[:-1]:
        assert 20_000 <= p.stat().st_size < 20_000 + 70_000  # closed at the first message past the limit
    assert sum(1 for _ in read_messages(rec.files[0], encodings=(MSGPACK,))) == len(traffic)


def test_a_directory_with_two_logs_is_refused_by_name(tmp_path):
    _split_log(tmp_path, max_seconds=5.0)
    with McapRecorder(tmp_path / "other.mcap") as r:
        r.write(K.world_clock(), sample_traffic(1)[0][1], 0.0)
    with pytest.raises(McapLogError, match=r"holds several logs \(other.mcap, run_\*.mcap\): name one"):
        log_files(tmp_path)
    assert log_files(tmp_path / "other.mcap") == [tmp_path / "other.mcap"]
    with pytest.raises(McapLogError, match="no .mcap log"):
        log_files(tmp_path / "logs" if (tmp_path / "logs").mkdir() is None else tmp_path)


def test_replay_publishes_a_set_in_time_order(tmp_path):
    _, traffic = _split_log(tmp_path, max_seconds=2.0)

    class Pubs:
        sent: list = []

        def put(self, key, data):
            self.sent.append((key, data))

        def close(self):
            pass

    pubs = Pubs()
    res = replay_log(None, tmp_path / "run_0.mcap", rate=None, publishers=pubs)
    assert res.published == len(traffic)
    want = [(k, d) for k, d, _ in sorted(traffic, key=lambda e: e[2])]
    assert sorted(pubs.sent) == sorted(want)
    assert [k for k, _ in pubs.sent].index(K.cmd_wheels("r1")) > 0


def _cekm(*args):
    return subprocess.run([sys.executable, "-m", "cekm_swarm", *args], capture_output=True, text=True, timeout=120)


@pytest.mark.slow  # runs the cekm command
def test_cekm_log_info_and_cat_take_the_set(tmp_path):
    rec, traffic = _split_log(tmp_path, max_seconds=4.0)
    info = _cekm("log", "info", str(tmp_path), "--json")
    assert info.returncode == 0, info.stderr
    doc = json.loads(info.stdout)
    assert doc["messages"] == len(traffic) + len(rec.files) and len(doc["files"]) == len(rec.files)
    text = _cekm("log", "info", str(rec.files[0]))
    assert f"a log set of {len(rec.files)} files: run_0.mcap .. run_{len(rec.files) - 1}.mcap" in text.stdout
    cat = _cekm("log", "cat", str(rec.files[0]), "--json", "--topics", "cekm/world/clock")
    times = [json.loads(line)["log_time"] for line in cat.stdout.splitlines()]
    assert len(times) == 120 and times == sorted(times)



def test_cekm_plot_takes_the_set_by_its_directory(tmp_path, capsys):
    """docs/runtime.md: cekm plot takes the run's directory (it was refused: 'is a directory')."""
    from cekm_swarm.cli import main
    from cekm_swarm.cli_support import run_cli
    from world import World, load_scenario

    run = tmp_path / "run"
    run.mkdir()
    geometry = World(load_scenario("crossing")).static_geometry()
    with SplitRecorder(run / "run.mcap", metadata={"scenario": "crossing"}, max_seconds=3.0) as rec:
        rec.add_metadata("geometry", {"json": json.dumps(geometry)})
        for key, data, t in sample_traffic(60):
            rec.write(key, data, t)
    assert len(rec.files) > 1
    from cekm_swarm.runtime.mcap_read import read_geometry

    assert read_geometry(run) == read_geometry(rec.files[0]) == json.loads(json.dumps(geometry))  # the arena too
    (run / "outcome.json").write_text(json.dumps({"robots": {"r1": {"reached": True}}}))
    assert run_cli(main, ["plot", str(run), "--out", str(tmp_path / "p.png")]) == 0, capsys.readouterr()
    assert (tmp_path / "p.png").stat().st_size > 0
