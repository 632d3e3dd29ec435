"""The heap trimmer of long-running processes (runtime/heap.py)."""

from __future__ import annotations

import sys

import pytest

from cekm_swarm.runtime.heap import HeapTrimmer, trim


def test_a_tidy_is_due_once_a_period_and_never_at_the_start() -> None:
    h = HeapTrimmer(every_s=60.0)
    assert not h.due(1000.0)  # the start
    assert not h.due(1059.9)
    assert h.due(1060.0)
    assert not h.due(1061.0)
    assert h.due(1120.0)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="malloc_trim is glibc's (Linux)")
def test_trim_gives_back_what_was_freed() -> None:
    import ctypes

    if not HeapTrimmer().available:
        pytest.skip("this C library has no malloc_trim")
    libc = ctypes.CDLL(None)
    libc.malloc.restype = ctypes.c_void_p
    libc.free.argtypes = [ctypes.c_void_p]
    blocks = [libc.malloc(4096) for _ in range(30000)]  # 120 MB on the heap, below mmap's threshold
    kept = blocks[2::3]  # holes of two blocks (whole pages) between kept ones: nothing freed at the top
    for i, b in enumerate(blocks):
        if i % 3 != 2:
            libc.free(b)
    try:
        assert trim()  # glibc gave the holes' pages back: 1
    finally:
        for b in kept:
            libc.free(b)


def test_no_trim_where_the_c_library_has_none(monkeypatch: pytest.MonkeyPatch) -> None:
    import cekm_swarm.runtime.heap as heap

    monkeypatch.setattr(heap, "_TRIM", None)
    assert heap.trim() is False
    h = heap.HeapTrimmer()
    assert not h.available and not h.due(0.0) and h.due(1e9)  # the collection still runs
    assert h.summary()["trim"] is False


def test_the_full_collection_frees_cycles_the_young_ones_left() -> None:
    import gc

    from cekm_swarm.runtime.gc_tuning import freeze_startup_heap

    class Node:
        pass

    old = gc.get_threshold()
    try:
        freeze_startup_heap()  # as the world server runs: start-up frozen, young collections rare
        a, b = Node(), Node()
        a.other, b.other = b, a  # a cycle
        gc.collect(0)
        gc.collect(1)  # it survived a young and a middle collection while alive
        del a, b  # now garbage, in the oldest generation
        h = HeapTrimmer()
        h.collect()
        summary = h.summary()
        assert summary["collections"] == 1 and summary["collected"] >= 2 and summary["collect_ms_max"] >= 0
    finally:
        gc.unfreeze()
        gc.set_threshold(*old)
