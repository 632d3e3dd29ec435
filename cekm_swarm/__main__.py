"""``python -m cekm_swarm`` is the ``cekm`` command."""

from .cli import run

run()
