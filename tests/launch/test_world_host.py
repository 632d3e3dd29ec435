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
