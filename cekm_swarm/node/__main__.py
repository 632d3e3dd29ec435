"""``python -m cekm_swarm.node RUN-SPEC.json --robot r1 --node obstacle-3``: one node as its own process."""

from .process import main

if __name__ == "__main__":
    raise SystemExit(main())
