"""A full disk while logging: the recorder closes the file with what it wrote out whole,
says so in one line, and the file is complete and readable. The disk is a file-size limit
(RLIMIT_FSIZE, with SIGXFSZ ignored, so the write fails with EFBIG) in a child process,
which works unprivileged; ``test_launch_log_full.py`` fills a small tmpfs under a launch."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from cekm_swarm.runtime.mcap_log import is_complete, log_info, read_messages, stream_messages

ROOT = Path(__file__).resolve().parents[2]

CHILD = textwrap.dedent("""
    import json, resource, signal, sys
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    limit, path, chunk = int(sys.argv[1]), sys.argv[2], int(sys.argv[3])
    from cekm_swarm.protocol import DEFAULT_KEYS as K, Clock, encode
    from cekm_swarm.runtime.mcap_record import LogFull, McapRecorder
    import random
    rng = random.Random(1)
    rec = McapRecorder(path, chunk_size=chunk, flush_interval=None, metadata={"scenario": "x"})
    resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
    n = 0
    try:
        for tick in range(100000):
            for r in range(8):
                rec.write(K.cmd_wheels(f"r{r}"), encode(Clock(0.128 * tick, "w", tick)) + rng.randbytes(40),
                          0.128 * tick)
                n += 1
            if tick % 50 == 0:
                rec.flush()
        rec.close()
        print(json.dumps({"full": None}))
    except LogFull as exc:
        again = None
        try:
            rec.write(K.world_clock(), b"", 1.0)
        except LogFull as exc2:
            again = str(exc2)
        rec.close()
        print(json.dumps({"full": str(exc), "closed": exc.closed, "messages": exc.messages, "size": exc.size,
                          "tried": n, "again": again}))
""")


def _fill(tmp_path: Path, limit: int, chunk: int = 8 * 1024) -> tuple[dict, Path]:
    path = tmp_path / "run.mcap"
    out = subprocess.run(
        [sys.executable, "-c", CHILD, str(limit), str(path), str(chunk)],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=ROOT,
        env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"},
    )
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.strip().splitlines()[-1]), path


pytestmark = pytest.mark.slow  # launches and child processes


@pytest.mark.parametrize("limit", [200_000, 1_000_003])
def test_a_full_disk_closes_the_log_with_its_summary(tmp_path, limit):
    """Chunks of 256 KB (of random bytes: zstd keeps their size): the chunk that did not
    fit leaves room for the summary of the ones before."""
    doc, path = _fill(tmp_path, limit, chunk=256 * 1024)
    assert doc["full"] is not None, "the limit was never reached"
    assert "File too large" in doc["full"] and "the log stops here, closed with its summary" in doc["full"]
    assert str(path) in doc["full"] and doc["again"] == doc["full"]  # every later call: the same one line
    assert doc["closed"] == "summary" and path.stat().st_size <= limit
    assert is_complete(path)
    info = log_info(path)
    assert info.complete and info.messages == doc["messages"] > 0 and info.messages < doc["tried"]
    in_order = list(read_messages(path))  # through the summary's chunk indexes
    assert len(in_order) == doc["messages"] == sum(1 for _ in stream_messages(path))
    times = [m.log_time for m in in_order]
    assert times == sorted(times)


def test_no_room_for_the_summary_leaves_a_footer_or_the_last_whole_chunk(tmp_path):
    """A limit just past a chunk: the summary does not fit, the 45-byte footer may; either
    way every message written out whole reads back."""
    doc, path = _fill(tmp_path, 9_000, chunk=4 * 1024)
    assert doc["closed"] in ("footer", "cut"), doc
    info = log_info(path)
    assert info.messages == doc["messages"] > 0
    assert info.complete == (doc["closed"] == "footer")
    assert sum(1 for _ in read_messages(path)) == doc["messages"]
