"""The one angle wrap: the numpy, scalar and numba forms agree bit for bit."""

import numpy as np

from cekm_swarm.angles import wrap, wrap_scalar
from cekm_swarm.models.fast import wrap as wrap_numba


def test_every_form_of_the_wrap_is_the_same_formula():
    a = np.random.default_rng(0).uniform(-40.0, 40.0, 2000)
    a = np.concatenate([a, [np.pi, -np.pi, 0.0, 3 * np.pi, -3 * np.pi]])
    ref = wrap(a)
    assert np.all((ref > -np.pi) & (ref <= np.pi))
    assert [wrap_scalar(float(x)) for x in a] == ref.tolist()
    assert [wrap_numba(float(x)) for x in a] == ref.tolist()
