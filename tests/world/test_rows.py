"""The world's per-tick tables and the latency samples keep flat memory on long runs and
read back exactly what went in."""

from __future__ import annotations

import random
import tracemalloc

import pytest

from cekm_swarm.runtime.percentiles import Samples, percentile
from world.rows import BUFFER_ROWS, Rows


def test_rows_read_back_what_was_appended_across_spills():
    rng = random.Random(3)
    rows = [(rng.random(), rng.gauss(0, 1e6), -0.0, 1e-300) for _ in range(3 * BUFFER_ROWS + 17)]
    table = Rows(4, rows)
    assert len(table) == len(rows) and list(table) == rows and table == rows
    assert table[0] == rows[0] and table[-1] == rows[-1] and table[BUFFER_ROWS + 5] == rows[BUFFER_ROWS + 5]
    assert table[1:4] == rows[1:4] and table[-2:] == rows[-2:]
    assert table.column(2) == [r[2] for r in rows]
    with pytest.raises(IndexError):
        table[len(rows)]
    with pytest.raises(ValueError, match="row of 4"):
        table.append((1.0, 2.0))
    assert len(table) == len(rows) and not Rows(2)


def test_rows_memory_stays_flat():
    """Its buffer is allocated when the table is made and reused: once the spill file is open
    (the first BUFFER_ROWS rows), appending allocates nothing that stays."""
    table = Rows(4)
    for i in range(BUFFER_ROWS):
        table.append((i, i, i, i))
    tracemalloc.start()
    before = tracemalloc.get_traced_memory()[0]
    for i in range(20 * BUFFER_ROWS):  # a list of tuples grew about 5 MB here
        table.append((i * 0.128, 1.0, 2.0, 3.0))
    grown = tracemalloc.get_traced_memory()[0] - before
    tracemalloc.stop()
    assert grown < 1024, grown
    assert len(table) == 21 * BUFFER_ROWS
    with pytest.raises(TypeError):
        table.append((1.0, "x", 2.0, 3.0))
    assert len(table) == 21 * BUFFER_ROWS and table[-1] == ((21 * BUFFER_ROWS - 1 - BUFFER_ROWS) * 0.128, 1.0, 2.0, 3.0)


def test_samples_allocate_nothing_as_they_fill():
    s = Samples()
    tracemalloc.start()
    before = tracemalloc.get_traced_memory()[0]
    for i in range(Samples.exact_max + 1000):
        s.append(1e-3 * (1 + i % 97))
    grown = tracemalloc.get_traced_memory()[0] - before
    tracemalloc.stop()
    assert grown < 1024, grown
    assert len(s) == Samples.exact_max + 1000 and not s.exact


def test_samples_exact_then_within_the_histograms_resolution():
    rng = random.Random(5)
    values = [rng.lognormvariate(-4, 1) for _ in range(Samples.exact_max)]
    s = Samples()
    for v in values:
        s.append(v)
    assert s.exact and s.percentile(0.5) == percentile(values, 0.5) and s.percentile(0.99) == percentile(values, 0.99)
    more = values + [rng.lognormvariate(-4, 1) for _ in range(Samples.exact_max)]
    for v in more[len(values):]:
        s.append(v)
    assert not s.exact and len(s) == len(more)
    for q in (0.01, 0.5, 0.99):
        assert s.percentile(q) == pytest.approx(percentile(more, q), rel=Samples.resolution)
