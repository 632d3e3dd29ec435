"""The world's deadline rule in real time: a robot's command for tick k is on time until the
end of tick k + ``deadline_ticks``; 0 (the default) asks for each tick's own command."""

from __future__ import annotations

import click
import pytest

from cekm_swarm.ticks import TICK_S
from world.clocks import RTO_MIN_S, late_ticks, link_deadline_ticks, missed_deadline
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


def test_a_links_allowance_covers_its_round_trip_and_one_retransmission_each_way():
    assert link_deadline_ticks(0.0, lossy=False) == 0  # one host: each tick's own command
    assert link_deadline_ticks(0.05, lossy=False) == 0  # 0.12 s of a 0.128 s tick
    assert link_deadline_ticks(0.1, lossy=False) == 1
    assert link_deadline_ticks(0.05) == 5  # the bad-link hour's link (docs/faults.md)
    for delay in (0.0, 0.01, 0.05, 0.1, 0.2):
        for jitter in (0.0, 0.005):
            n = link_deadline_ticks(delay, jitter)
            worst = 2 * (3 * delay + jitter + RTO_MIN_S) + 0.02  # readings down and command up, each retransmitted
            assert (n + 1) * TICK_S >= worst > n * TICK_S  # enough, and not a tick more
    with pytest.raises(ValueError, match="delay"):
        link_deadline_ticks(-0.01)


def test_the_rule_and_the_fault_link_assume_the_same_kernel():
    from cekm_swarm.runtime.faultlink import MIN_RTO_S, LinkSettings

    assert RTO_MIN_S == MIN_RTO_S
    assert LinkSettings(delay=0.05).retransmit_s() == 2 * 0.05 + RTO_MIN_S
