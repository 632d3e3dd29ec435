"""Key space: every key of docs/design.md section 6 builds, parses back, and bad parts fail clearly."""

from __future__ import annotations

import pytest

from cekm_swarm.errors import CekmError
from cekm_swarm.protocol import DEFAULT_KEYS, KeyKind, KeySpace, KeySpaceError, ParsedKey

K = DEFAULT_KEYS


def test_every_key_of_the_table():
    assert K.sense_target("r1") == "cekm/r1/sense/target"
    assert K.sense_range("r1", 0) == "cekm/r1/sense/range/0"
    assert K.sense_range("r1", 11) == "cekm/r1/sense/range/11"
    assert K.field_target("r1") == "cekm/r1/field/target"
    assert K.field_obstacle("r2", 3) == "cekm/r2/field/obstacle/3"
    assert K.cmd_wheels("r1") == "cekm/r1/cmd/wheels"
    assert K.share("r1") == "cekm/r1/share"
    assert K.world_state() == "cekm/world/state"
    assert K.world_clock() == "cekm/world/clock"
    assert K.alive("r1", "obstacle-3") == "cekm/r1/alive/obstacle-3"
    assert K.alive("world", "server") == "cekm/world/alive/server"


@pytest.mark.parametrize("key, parsed", [
    ("cekm/r1/sense/target", ParsedKey(KeyKind.SENSE_TARGET, "r1")),
    ("cekm/r1/sense/range/7", ParsedKey(KeyKind.SENSE_RANGE, "r1", 7)),
    ("cekm/robot_2/field/target", ParsedKey(KeyKind.FIELD_TARGET, "robot_2")),
    ("cekm/r1/field/obstacle/11", ParsedKey(KeyKind.FIELD_OBSTACLE, "r1", 11)),
    ("cekm/r1/cmd/wheels", ParsedKey(KeyKind.CMD_WHEELS, "r1")),
    ("cekm/r1/share", ParsedKey(KeyKind.SHARE, "r1")),
    ("cekm/world/state", ParsedKey(KeyKind.WORLD_STATE)),
    ("cekm/world/clock", ParsedKey(KeyKind.WORLD_CLOCK)),
    ("cekm/r1/alive/motor", ParsedKey(KeyKind.ALIVE, "r1", None, "motor")),
    ("cekm/world/alive/server", ParsedKey(KeyKind.ALIVE, "world", None, "server")),
])
def test_parse(key, parsed):
    assert K.parse(key) == parsed
    assert K.key(parsed.kind, parsed.robot, parsed.index, parsed.module) == key


def test_configurable_root_and_sensor_count():
    ks = KeySpace(root="lab/run-7", range_sensors=16)
    assert ks.sense_range("r1", 15) == "lab/run-7/r1/sense/range/15"
    assert ks.parse("lab/run-7/r1/field/obstacle/15").index == 15
    assert ks.everything() == "lab/run-7/**"
    assert ks.robot_keys("r3") == "lab/run-7/r3/**"
    assert ks.alive_all() == "lab/run-7/*/alive/**"  # tokens of any run
    with pytest.raises(KeySpaceError, match="not under the root"):
        ks.parse("cekm/r1/share")


@pytest.mark.parametrize("robot, match", [
    ("world", "reserved"), ("", "must start with a letter"), ("1r", "must start with a letter"),
    ("r/1", "must start with a letter"), ("r*", "must start"), ("r$1", "must start"), (3, "expected a string"),
    ("r" * 65, "at most 64"),
])
def test_bad_robot_ids(robot, match):
    with pytest.raises(KeySpaceError, match=match) as info:
        K.cmd_wheels(robot)
    assert isinstance(info.value, CekmError) and isinstance(info.value, ValueError)


@pytest.mark.parametrize("index, match", [(12, r"sensor index 12: out of range 0\.\.11"), (-1, "out of range"),
                                          (True, "got bool"), (1.0, "got float"), ("3", "got str")])
def test_bad_sensor_indices(index, match):
    with pytest.raises(KeySpaceError, match=match):
        K.sense_range("r1", index)
    with pytest.raises(KeySpaceError, match=match):
        K.field_obstacle("r1", index)


@pytest.mark.parametrize("key, match", [
    ("cekm/r1/sense/range/12", "out of range 0..11"),
    ("cekm/r1/sense/range/03", "not a plain non-negative integer"),
    ("cekm/r1/sense/range/x", "not a plain"),
    ("cekm/r1/sense/range/-1", "not a plain"),
    ("cekm/r1/sense/range", "not a key of the cekm key space"),
    ("cekm/r1/sense/bogus", "not a key"),
    ("cekm/r1/alive", "not a key"),
    ("cekm/world/other", "unknown world key"),
    ("cekm/1r/share", "bad robot id"),
    ("cekm/r1/alive/3x", "bad module name"),
    ("other/r1/share", "not under the root 'cekm'"),
    ("cekm", "not under the root"),
])
def test_parse_errors_name_the_key(key, match):
    with pytest.raises(KeySpaceError, match=match) as info:
        K.parse(key)
    assert key in str(info.value)


def test_bad_roots_and_builders():
    for root in ("", "a//b", "cekm/*", "cekm/**", "/cekm", "ce$km"):
        with pytest.raises(KeySpaceError, match="key root"):
            KeySpace(root=root)
    with pytest.raises(KeySpaceError, match="range_sensors"):
        KeySpace(range_sensors=0)
    with pytest.raises(KeySpaceError, match="needs a sensor index"):
        K.key(KeyKind.SENSE_RANGE, "r1")
    with pytest.raises(KeySpaceError, match="needs a robot id"):
        K.key(KeyKind.SHARE)
    with pytest.raises(KeySpaceError, match="needs a module name"):
        K.key(KeyKind.ALIVE, "r1")
    with pytest.raises(KeySpaceError, match="module name"):
        K.alive("r1", "bad/name")


def test_liveliness_tokens_carry_the_run_id_and_selectors_keep_runs_apart():
    ks = KeySpace(run="20261201-134500-a1b2c3")
    assert ks.alive("r1", "motor") == "cekm/r1/alive/motor/20261201-134500-a1b2c3"
    assert ks.alive("world", "server") == "cekm/world/alive/server/20261201-134500-a1b2c3"
    assert ks.alive_all() == "cekm/*/alive/*/20261201-134500-a1b2c3"
    parsed = ks.parse(ks.alive("r1", "obstacle-3"))
    assert (parsed.kind, parsed.robot, parsed.module, parsed.run) == (KeyKind.ALIVE, "r1", "obstacle-3",
                                                                      "20261201-134500-a1b2c3")
    assert ks.parse("cekm/r1/alive/motor").run is None
    other = ks.with_run("other-run")
    assert other.alive("r1", "motor") != ks.alive("r1", "motor")
    names = ("target", "obstacle-0", "motor")
    assert {ks.alive("r1", m) for m in names}.isdisjoint({other.alive("r1", m) for m in names})


@pytest.mark.parametrize("bad", ["", "a/b", "*", "-x", "a" * 65, 7])
def test_a_bad_run_id_is_refused_by_name(bad):
    with pytest.raises(KeySpaceError, match="run id"):
        KeySpace(run=bad)
    if isinstance(bad, str) and bad and "/" not in bad:  # one chunk of a key: refused when parsed too
        with pytest.raises(KeySpaceError, match="run id"):
            KeySpace().parse(f"cekm/r1/alive/motor/{bad}")


def test_a_graphs_own_keys_parse_as_node_keys_under_the_robot():
    """A graph may give its nodes keys of their own below the robot; sense/ and alive/ stay
    the world's and the tokens'."""
    ks = KeySpace()
    for path in ("fusion/avoid", "cmd/wheels/extra", "my_node/out.1"):
        p = ks.parse(f"cekm/r1/{path}")
        assert (p.kind, p.robot, p.path) == (KeyKind.NODE, "r1", path)
    assert ks.node_key("r2", "fusion/avoid") == "cekm/r2/fusion/avoid"
