"""LineReader.drain: what a stream said so far, without waiting, and the end kept."""

from __future__ import annotations

import io
import time

from cekm_swarm.runtime.lines import LineReader


def test_drain_hands_out_what_was_read_and_keeps_the_end():
    reader = LineReader(io.StringIO("one\ntwo\nthree\n"))
    reader._thread.join(5)  # the whole stream read (a StringIO ends at once)
    assert reader.next(time.monotonic() + 1, "a line") == "one"
    assert reader.drain() == ["two", "three"]
    assert reader.seen == ["one", "two", "three"]
    assert reader.drain() == []
    assert reader.next(time.monotonic() + 1, "a line") is None  # the end is still there
