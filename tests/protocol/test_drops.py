"""Drop counting stays bounded whatever a peer invents."""

import logging

from cekm_swarm.protocol.drops import MAX_SOURCES, OTHER_SOURCES, DropCounter


def test_sources_beyond_the_cap_are_counted_together_and_logged_once(caplog):
    d = DropCounter("test", max_sources=10)
    with caplog.at_level(logging.WARNING):
        for i in range(1000):
            d.drop(f"cekm/fuzz/{i}", "bad")
            d.drop("cekm/r1/cmd/wheels", "bad")
    assert d.total == 2000
    by = d.by_source()
    assert len(by) == 11 and by[OTHER_SOURCES] == 991 and by["cekm/r1/cmd/wheels"] == 1000
    assert len(caplog.records) == 11  # one line per source told apart, one for the rest
    assert MAX_SOURCES >= 64
