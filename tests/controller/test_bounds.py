"""The controller parts' parameter check (cekm_swarm.controller.bounds)."""

import math
from dataclasses import dataclass

import pytest

from cekm_swarm.controller.bounds import check_bounds


@dataclass
class Part:
    n: int = 2
    width: float = 0.5
    gain: float = 0.0


@pytest.mark.parametrize("field,value,words", [("n", 0, "part n must be >= 1 tick, got 0"),
                                               ("width", 0.0, "part width must be > 0, got 0.0"),
                                               ("width", math.nan, "part width must be > 0, got nan"),
                                               ("gain", -1.0, "part gain must be >= 0, got -1.0")])
def test_the_first_field_out_of_range_is_named_with_its_value(field, value, words):
    with pytest.raises(ValueError, match=words):
        check_bounds("part", Part(**{field: value}), ticks=("n",), positive=("width",), nonnegative=("gain",))


def test_fields_in_range_pass():
    check_bounds("part", Part(), ticks=("n",), positive=("width",), nonnegative=("gain",))
