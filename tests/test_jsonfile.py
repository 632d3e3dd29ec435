"""Strict JSON for the files the commands write: no NaN or Infinity."""

import json
import math
from types import SimpleNamespace

import pytest

from cekm_swarm import jsonfile
from world.outcome import write_outputs


def _strict(text: str):
    def refuse(name):
        raise ValueError(f"not JSON: {name}")
    return json.loads(text, parse_constant=refuse)


def test_non_finite_floats_are_written_as_null():
    doc = {"a": math.inf, "b": [1.5, math.nan, -math.inf], "c": {"d": (math.nan, 2)}, "e": "x", "f": None, "g": True}
    assert _strict(jsonfile.dumps(doc)) == {"a": None, "b": [1.5, None, None], "c": {"d": [None, 2]}, "e": "x",
                                            "f": None, "g": True}
    with pytest.raises(ValueError):
        _strict(json.dumps(doc))  # what the files were before


def test_the_world_servers_outcome_is_strict_json(tmp_path):
    write_outputs(tmp_path, {"robots": {"r1": {"min_clearance_m": math.inf}}}, SimpleNamespace(progress={}))
    assert _strict((tmp_path / "outcome.json").read_text()) == {"robots": {"r1": {"min_clearance_m": None}}}
