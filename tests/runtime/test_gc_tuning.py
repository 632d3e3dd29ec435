"""freeze_startup_heap: what is alive is frozen, young collections are rarer, cycles made later are still freed."""

from __future__ import annotations

import gc
import weakref

from cekm_swarm.runtime.gc_tuning import YOUNG_THRESHOLD, freeze_startup_heap


def test_freeze_moves_survivors_out_of_sight_and_raises_the_young_threshold():
    before = gc.get_threshold()
    try:
        keep = [[i] for i in range(1000)]
        freeze_startup_heap()
        assert gc.get_freeze_count() >= 1000
        assert gc.get_threshold()[0] == YOUNG_THRESHOLD and gc.get_threshold()[1:] == before[1:]

        class Node:
            pass

        a, b = Node(), Node()
        a.other, b.other = b, a  # a cycle made after the freeze is still collected
        ref = weakref.ref(a)
        del a, b
        gc.collect()
        assert ref() is None
        assert keep[999] == [999]
    finally:
        gc.unfreeze()
        gc.set_threshold(*before)
