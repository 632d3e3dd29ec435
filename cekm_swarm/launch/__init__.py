"""``cekm launch``: the world server and every robot's module processes as separate OS
processes on one Zenoh network, supervised; ``cekm plot``: a run drawn from its MCAP log."""
