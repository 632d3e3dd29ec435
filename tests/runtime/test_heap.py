"""The heap trimmer of long-running processes (runtime/heap.py)."""

from __future__ import annotations

import sys

import pytest

from cekm_swarm.runtime.heap import HeapTrimmer, hold_mmap_threshold, trim


def test_a_trim_is_due_once_a_period_and_never_at_the_start() -> None:
    h = HeapTrimmer(every_s=60.0)
    if not h.available:
        pytest.skip("this C library has no malloc_trim")
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
    assert not h.available and not h.due(0.0) and not h.due(1e9)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="mallopt is glibc's (Linux)")
def test_the_mmap_threshold_is_held_where_glibc_runs() -> None:
    if not HeapTrimmer().available:
        pytest.skip("this C library is not glibc")
    assert hold_mmap_threshold()
