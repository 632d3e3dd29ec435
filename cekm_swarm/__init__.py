"""cekm-swarm: cooperative Extended Kohonen Maps (Low, Leow & Ang, Neural Computation 2005).

The numerical core lives in :mod:`cekm_swarm.models` (pure numpy, no I/O); the
reproduction of the paper's experiments in :mod:`cekm_swarm.experiments`.
"""

__version__ = "0.1.0"
