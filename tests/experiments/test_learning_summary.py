"""`cekm experiment learning`'s summary over seeds (cekm_swarm.experiments.learning_experiment):
means with Student-t 95 % intervals and the paired sharing-minus-not comparison, on hand-made curves."""

from __future__ import annotations

import math

import pytest

from cekm_swarm.experiments.learning_experiment import (
    Curve,
    LearningConfig,
    paired_difference,
    results_doc,
    seed_interval,
    summary_table,
)


def curve(team: int, share: bool, seed: int, E: list[float]) -> Curve:
    steps = [0, 10, 20, 40][: len(E)]
    return Curve(team, share, seed, steps=steps, updates=steps, E_mm=E, T_s_per_m=[100.0] * len(E), D=[1.0] * len(E))


def test_seed_interval_is_the_student_t_interval():
    s = seed_interval([10.0, 20.0, 30.0])  # mean 20, sd 10, t(0.975, 2) = 4.302653
    half = 4.302653 * 10.0 / math.sqrt(3)
    assert s["mean"] == pytest.approx(20.0) and s["n"] == 3 and s["of"] == 3
    assert s["lo"] == pytest.approx(20.0 - half, rel=1e-6) and s["hi"] == pytest.approx(20.0 + half, rel=1e-6)


def test_one_seed_has_no_interval_and_a_never_is_counted_not_averaged():
    assert seed_interval([7.0]) == {"mean": 7.0, "lo": None, "hi": None, "n": 1, "of": 1}
    s = seed_interval([None, 4.0, 6.0])
    assert s["mean"] == pytest.approx(5.0) and s["n"] == 2 and s["of"] == 3
    assert seed_interval([None]) == {"mean": None, "lo": None, "hi": None, "n": 0, "of": 1}


def test_paired_difference_pairs_by_seed():
    d = paired_difference([40.0, 20.0, 40.0, None], [20.0, 10.0, 10.0, 5.0])  # diffs -20, -10, -30; seed 4 left out
    half = 4.302653 * 10.0 / math.sqrt(3)
    assert d["n"] == 3 and d["mean_diff"] == pytest.approx(-20.0)
    assert d["lo"] == pytest.approx(-20.0 - half, rel=1e-6) and d["hi"] == pytest.approx(-20.0 + half, rel=1e-6)
    t = 20.0 / (10.0 / math.sqrt(3))  # |t| of the mean difference; with 2 df, two-sided p = 1 - |t| / sqrt(t^2 + 2)
    assert d["p"] == pytest.approx(1.0 - t / math.sqrt(t * t + 2.0), rel=1e-9)
    assert paired_difference([1.0], [2.0])["p"] is None


def test_results_doc_summarizes_each_team_and_compares_sharing():
    config = LearningConfig(teams=(1, 2), seeds=(1, 2), threshold_mm=5.0)
    curves = [curve(1, False, 1, [900.0, 50.0, 4.0, 1.0]), curve(1, False, 2, [900.0, 60.0, 8.0, 6.0]),
              curve(2, False, 1, [900.0, 9.0, 6.0, 3.0]), curve(2, False, 2, [900.0, 9.0, 4.0, 2.0]),
              curve(2, True, 1, [900.0, 3.0, 2.0, 1.0]), curve(2, True, 2, [900.0, 7.0, 3.0, 1.0])]
    doc = results_doc(config, curves)
    one = doc["summary"]["1"]["stats"]["steps_to_E"]
    assert doc["summary"]["1"]["steps_to_E"] == [20, None]
    assert (one["mean"], one["n"], one["of"], one["lo"]) == (20.0, 1, 2, None)
    assert doc["summary"]["2"]["stats"]["steps_to_E"]["mean"] == pytest.approx(30.0)  # 40, 20
    assert doc["summary"]["2-shared"]["stats"]["final_E_mm"]["mean"] == pytest.approx(1.0)
    share = doc["sharing"]["2"]["steps_to_E"]  # 10 - 40, 20 - 20
    assert share["mean_diff"] == pytest.approx(-15.0) and share["n"] == 2
    assert share["lo"] < -15.0 < share["hi"]
    assert "1" not in doc["sharing"]
    text = "\n".join(summary_table(doc))
    assert "(1 of 2 never)" in text and "sharing - not: steps_to_E -15" in text
