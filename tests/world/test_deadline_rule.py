"""The world's deadline rule in real time: a robot's command for tick k is on time until the
end of tick k + ``deadline_ticks``; 0 (the default) asks for each tick's own command."""

from __future__ import annotations

import click
import pytest

from cekm_swarm.ticks import TICK_S
from world.clocks import late_ticks, missed_deadline
from world.config import parse_argv


@pytest.mark.parametrize("tick", [0, 1, 7, 1000, 28_125, 10**6])
def test_lag_in_ticks_is_exact_for_any_tick(tick: int) -> None:
    t = tick * TICK_S
    for lag in range(0, min(tick, 9) + 1):
        assert late_ticks(t, (tick - lag) * TICK_S) == lag


def test_the_default_rule_wants_the_ticks_own_command() -> None:
    t = 50 * TICK_S
    assert not missed_deadline(t, t)
    assert missed_deadline(t, t - TICK_S)
    assert missed_deadline(t, None)


def test_a_slow_link_allowance_counts_only_commands_older_than_it() -> None:
    t = 50 * TICK_S
    for allowance in range(0, 6):
        for lag in range(0, 10):
            assert missed_deadline(t, t - lag * TICK_S, allowance) == (lag > allowance)
        assert missed_deadline(t, None, allowance)  # no command at all is always a miss


def test_the_world_server_takes_the_allowance_from_its_command_line() -> None:
    base = ["tracking", "--out", "/nonexistent-out-dir-for-parse"]
    assert parse_argv(base).deadline_ticks == 0
    assert parse_argv(base + ["--deadline-ticks", "3"]).deadline_ticks == 3
    with pytest.raises(click.BadParameter, match="not in the range") as refused:
        parse_argv(base + ["--deadline-ticks", "-1"])
    assert refused.value.param is not None and "--deadline-ticks" in refused.value.param.opts
