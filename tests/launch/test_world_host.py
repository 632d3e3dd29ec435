"""The launcher's lines about the world server's run."""

from __future__ import annotations


def test_a_progress_line_names_a_dozen_robots_and_counts_the_rest():
    from cekm_swarm.launch.world_host import PROGRESS_ROBOTS, format_progress

    def doc(n: int) -> dict:
        return {"t": 1.0, "robots": {f"r{i}": {"x": 0.0, "y": 0.0, "reached": False} for i in range(1, n + 1)}}

    assert "more robots" not in format_progress(doc(PROGRESS_ROBOTS))
    line = format_progress(doc(200))
    assert f"r{PROGRESS_ROBOTS} (0.00, 0.00)" in line and f"r{PROGRESS_ROBOTS + 1} " not in line
    assert line.endswith(f"and {200 - PROGRESS_ROBOTS} more robots")


def test_world_events_read_as_sentences_without_dicts_or_epoch_stamps():
    from cekm_swarm.launch.world_host import format_event

    line = format_event({"event": "deadman", "t": 3.072, "robot": "r1", "silent_s": 0.5213, "limit_s": 0.5,
                         "wall": 1764800000.123})
    assert line == ("world event at t=3.07 s: deadman: r1 silent for 0.5213 s (limit 0.5 s), stopped until its "
                    "commands come again")
    assert format_event({"event": "republish", "t": 0.512, "waiting": ["r1", "r2"]}) == \
        "world event at t=0.51 s: republish: waiting for r1, r2, the tick's readings sent again"
    line = format_event({"event": "modules_missing", "t": 0.0, "after_s": 180, "missing": ["r1/motor"]})
    assert line == "world event at t=0.00 s: modules_missing: after_s 180, missing r1/motor"
    assert "{" not in line and "1764800000" not in line
    assert format_event({"event": "goal", "t": 1.024, "robot": "r1", "goal": [1.7, 1.0], "wall": 1764800000.1}) == \
        "world event at t=1.02 s: goal: r1's goal is now (1.70, 1.00)"
