"""Messages: round trips of every kind, and every validation failure names key and field."""

from __future__ import annotations

import logging
import math
import re
import warnings

import msgpack
import numpy as np
import pytest

from cekm_swarm.protocol import (
    DEFAULT_KEYS,
    SCHEMA_VERSION,
    Clock,
    Data,
    DropCounter,
    KeyKind,
    KeySpace,
    MessageArrayError,
    MessageError,
    MessageFieldError,
    MessageFormatError,
    MessageKindError,
    MessageVersionError,
    ObstacleField,
    RobotState,
    SenseRange,
    SenseTarget,
    Share,
    TargetField,
    TargetState,
    Unchanged,
    WheelCommand,
    WorldState,
    decode,
    encode,
    peek,
    summary,
    to_plain,
    to_wire,
)

K = DEFAULT_KEYS
RNG = np.random.default_rng(5)
A = RNG.random(225)

SAMPLES = [
    (K.sense_target("r1"), SenseTarget(1.024, "world", -0.5, 0.123, True)),
    (K.sense_target("r1"), SenseTarget(0.0, "world", 0.0, 0.0, False)),
    (K.sense_range("r1", 4), SenseRange(0.128, "world", 4, 2.094, 0.085)),
    (K.sense_range("r1", 11), SenseRange(0.128, "world", 11, -math.pi, None)),
    (K.field_target("r1"), TargetField(0.256, "r1/target", 112, A)),
    (K.field_target("r1"), TargetField(0.256, "r1/target", 112, A, alpha=0.3, d=1.2)),
    (K.field_target("r1"), TargetField(0.512, "r1/target", None, None, alpha=-1.0, d=0.0, at_goal=True)),
    (K.field_target("r1"), TargetField(0.768, "r1/target", None, None)),
    (K.field_obstacle("r1", 3), ObstacleField(0.128, "r1/obstacle-3", 3, 40, A * -1)),
    (K.field_obstacle("r1", 0), ObstacleField(0.128, "r1/obstacle-0", 0, None, None)),
    (K.cmd_wheels("r1"), WheelCommand(0.3, "r1/motor", 0.15625, -0.05, 17)),
    (K.share("r2"), Share(2.0, "r2/share", (0.1, -0.2, 3.0), {"t1": (1.0, 2.0), "t2": (0.0, -1.5)})),
    (K.share("r2"), Share(2.0, "r2/share", (0.1, -0.2, 3.0), {})),
    (K.world_state(), WorldState(5.0, "world",
                                 {"r1": {"x": 0.1, "y": 0.2, "theta": 0.3, "in_contact": False, "goal": [1.0, 2.0]}},
                                 {"t1": {"x": 1.0, "y": 2.0}}, {"box": {"x": 0.0, "y": 0.0, "theta": 0.0}})),
    (K.world_clock(), Clock(1.024, "world", 8)),
]


def wire(msg):
    return msgpack.unpackb(encode(msg), raw=False)


def pack(m):
    return msgpack.packb(m, use_bin_type=True)


@pytest.mark.parametrize("key, msg", SAMPLES, ids=[f"{k}-{i}" for i, (k, _) in enumerate(SAMPLES)])
def test_round_trip(key, msg):
    data = encode(msg)
    back = decode(key, data)
    assert type(back) is type(msg) and back == msg
    assert decode(msg.KIND, data) == msg
    assert wire(msg)["v"] == SCHEMA_VERSION and wire(msg)["kind"] == msg.KIND.value
    assert peek(data) == (msg.KIND.value, msg.stamp)
    assert summary(back).startswith(msg.KIND.value)
    assert to_plain(back)["sender"] == msg.sender


def test_arrays_travel_as_raw_little_endian_bytes_and_come_back_read_only():
    w = wire(TargetField(1.0, "r1/target", 0, A))
    assert w["a"]["dtype"] == "<f8" and w["a"]["shape"] == [225] and len(w["a"]["data"]) == 225 * 8
    assert np.array_equal(np.frombuffer(w["a"]["data"], "<f8"), A)
    back = decode(K.field_target("r1"), encode(TargetField(1.0, "r1/target", 0, A)))
    assert back.a.dtype == np.float64 and not back.a.flags.writeable
    # other numeric inputs are converted; numpy scalars accepted
    m = TargetField(np.float64(1.0), "r1/target", np.int64(3), [1, 2, 3, 4])
    assert m.a.dtype == np.float64 and m.winner == 3 and type(m.stamp) is float


def test_huge_finite_values_are_accepted():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # numpy may note the overflow of the fast check
        m = TargetField(1.0, "s", 0, np.array([1e200, -1e300, 1.7e308]))  # sum of squares overflows
        assert decode(KeyKind.FIELD_TARGET, encode(m)) == m


def test_equality_compares_arrays():
    assert TargetField(1.0, "s", 0, A) == TargetField(1.0, "s", 0, A.copy())
    assert TargetField(1.0, "s", 0, A) != TargetField(1.0, "s", 0, A + 1)
    assert ObstacleField(1.0, "s", 0, None, None) != ObstacleField(1.0, "s", 0, 0, A)


# --------------------------------------------------------------------------- construction errors


@pytest.mark.parametrize("build, field, match", [
    (lambda: SenseTarget(-1.0, "world", 0, 0, True), "stamp", "below 0"),
    (lambda: SenseTarget(math.nan, "world", 0, 0, True), "stamp", "not finite"),
    (lambda: SenseTarget(1.0, "", 0, 0, True), "sender", "1..128 characters"),
    (lambda: SenseTarget(1.0, 5, 0, 0, True), "sender", "expected a string"),
    (lambda: SenseTarget(1.0, "w", 4.0, 0, True), "alpha", r"4.0 is not an angle in \[-pi, pi\]"),
    (lambda: SenseTarget(1.0, "w", 0, -0.1, True), "d", "below 0"),
    (lambda: SenseTarget(1.0, "w", 0, math.inf, True), "d", "not finite"),
    (lambda: SenseTarget(1.0, "w", 0, 0, 1), "visible", "expected a bool"),
    (lambda: SenseTarget(1.0, "w", "0", 0, True), "alpha", "expected a number"),
    (lambda: SenseTarget(1.0, "w", True, 0, True), "alpha", "expected a number"),
    (lambda: SenseRange(1.0, "w", -1, 0, None), "index", "out of range"),
    (lambda: SenseRange(1.0, "w", 1.5, 0, None), "index", "expected an integer"),
    (lambda: SenseRange(1.0, "w", 1, 0, math.nan), "d", "not finite"),
    (lambda: TargetField(1.0, "s", 225, A), "winner", r"out of range 0\.\.224"),
    (lambda: TargetField(1.0, "s", 0, np.zeros((15, 15))), "a", "1-D"),
    (lambda: TargetField(1.0, "s", 0, np.zeros(0)), "a", "length 0"),
    (lambda: TargetField(1.0, "s", 0, np.array([1.0, np.nan])), "a", "not finite at index 1"),
    (lambda: TargetField(1.0, "s", 0, np.array([1.0, -np.inf])), "a", "not finite at index 1"),
    (lambda: TargetField(1.0, "s", 0, ["x"]), "a", "float64"),
    (lambda: ObstacleField(1.0, "s", 0, 3, None), "b", "both be None"),
    (lambda: ObstacleField(1.0, "s", 0, None, A), "winner", "both be None"),
    (lambda: WheelCommand(1.0, "s", math.nan, 0, 0), "v_l", "not finite"),
    (lambda: WheelCommand(1.0, "s", 0, None, 0), "v_r", "expected a number"),
    (lambda: WheelCommand(1.0, "s", 0, 0, -1), "seq", "out of range"),
    (lambda: Share(1.0, "s", (0, 0), {}), "pose", "expected 3 values"),
    (lambda: Share(1.0, "s", (0, 0, 9.0), {}), "pose[2]", "not an angle"),
    (lambda: Share(1.0, "s", (0, 0, 0), {"t1": (0, math.nan)}), "targets.t1[1]", "not finite"),
    (lambda: Share(1.0, "s", (0, 0, 0), [("t1", 0, 0)]), "targets", "expected a map"),
    # a tuple's entries are checked under the tuple's name first, then named when one fails
    (lambda: Unchanged(1.0, "w", ("sense/range/1", "range 2"), (0.5, 0.6)), "keys[1]", "not matching"),
    (lambda: Unchanged(1.0, "w", ("sense/range/1", "sense/range/2", "sense/target"), (0.5, 0.6, math.nan)),
     "since[2]", "not finite"),
    (lambda: Unchanged(1.0, "w", ("sense/range/1",), ("0.5",)), "since[0]", "expected a number"),
    (lambda: Unchanged(1.0, "w", ("sense/range/1", 7), (0.5, 0.6)), "keys[1]", "expected a string"),
    (lambda: WorldState(1.0, "w", {"r1": {"x": math.nan, "y": 0, "theta": 0}}, {}, {}), "robots.r1.x", "not finite"),
    (lambda: WorldState(1.0, "w", {"r1": {"y": 0.5, "theta": 0}}, {}, {}), "robots.r1.x", "missing"),
    (lambda: WorldState(1.0, "w", {"r1": {"x": 0, "y": 0, "theta": 0, "z": 1}}, {}, {}), "robots.r1.z",
     "unexpected field"),
    (lambda: WorldState(1.0, "w", {"r1": {"x": 0, "y": 0, "theta": 0, "goal": [1.0]}}, {}, {}), "robots.r1.goal",
     "expected 2 values"),
    (lambda: WorldState(1.0, "w", {"r1": {"x": 0, "y": 0, "theta": 0, "in_contact": "yes"}}, {}, {}),
     "robots.r1.in_contact", "expected a bool"),
    (lambda: WorldState(1.0, "w", {"world": {"x": 0, "y": 0, "theta": 0}}, {}, {}), "robots.world", "reserved"),
    (lambda: WorldState(1.0, "w", {"r1": 3}, {}, {}), "robots.r1", "expected a map"),
    (lambda: WorldState(1.0, "w", {}, [], {}), "targets", "expected a map"),
    (lambda: WorldState(1.0, "w", {}, {"t": object()}, {}), "targets.t", "expected a map"),
    (lambda: WorldState(1.0, "w", {}, {"t": {"x": "left", "y": 0}}, {}), "targets.t.x", "expected a number"),
    (lambda: WorldState(1.0, "w", {}, {}, {1: 2}), "obstacles", "map key 1"),
    (lambda: Data(1.0, "w", {"a": [[[[[[[[[[[[[[[[[[1]]]]]]]]]]]]]]]]]]}), "values.a" + "[0]" * 17, "deeper"),
    (lambda: Data(1.0, "w", {"a": b"x"}), "values.a", "not plain data"),
    (lambda: Clock(1.0, "w", -3), "tick", "out of range"),
])
def test_construction_errors_name_the_field(build, field, match):
    with pytest.raises(MessageFieldError, match=match) as info:
        build()
    assert info.value.field == field and info.value.key is None
    assert f"field '{field}'" in str(info.value)


def test_world_state_entries_are_typed_and_normalized():
    m = WorldState(1.0, "world", {"r1": {"x": 1, "y": np.float64(0.5), "theta": 0.0, "goal": (1, np.float64(2.5)),
                                         "in_contact": np.bool_(True)}}, {"t1": {"x": 1, "y": 2}}, {})
    r = m.robots["r1"]
    assert isinstance(r, RobotState) and isinstance(m.targets["t1"], TargetState)
    assert (r.x, r.y, r.goal, r.in_contact, r.v_l_exec) == (1.0, 0.5, (1.0, 2.5), True, 0.0)
    assert type(r.x) is float and type(r.goal[0]) is float and type(r.in_contact) is bool
    assert r["x"] == 1.0 and r.get("goal") == (1.0, 2.5) and r.get("nothing", 7) == 7 and "theta" in r
    back = decode(K.world_state(), encode(m))
    assert back == m and back.robots["r1"] == r
    # typed entries are taken as they are, and give the map World.state() gives
    again = WorldState(1.0, "world", {"r1": r}, m.targets, {})
    assert again.robots["r1"] is r
    assert to_plain(m)["robots"]["r1"] == {"x": 1.0, "y": 0.5, "theta": 0.0, "v_l": 0.0, "v_r": 0.0, "v_l_exec": 0.0,
                                            "v_r_exec": 0.0, "in_contact": True, "goal": [1.0, 2.5]}


def test_world_state_entries_on_the_wire_are_checked_like_the_fields():
    good = to_wire(WorldState(1.0, "world", {"r1": {"x": 0.0, "y": 0.0, "theta": 0.0}}, {}, {}))
    for robot, field, match in [({"x": "left", "y": 0.0, "theta": 0.0}, "robots.r1.x", "expected a number"),
                                ({"y": 0.0, "theta": 0.0}, "robots.r1.x", "missing"),
                                ({"x": 0.0, "y": 0.0, "theta": 0.0, "extra": 1}, "robots.r1.extra", "unexpected"),
                                ({"x": 0.0, "y": 0.0, "theta": 4.0}, "robots.r1.theta", "angle"),
                                (3, "robots.r1", "expected a map")]:
        raises(MessageFieldError, K.world_state(), pack({**good, "robots": {"r1": robot}}), field, match)
    raises(MessageFieldError, K.world_state(), pack({**good, "robots": {"world": good["robots"]["r1"]}}),
           "robots.world", "reserved")


# --------------------------------------------------------------------------- decoding errors


def tampered(msg, **changes):
    w = wire(msg)
    for k, v in changes.items():
        if v is KeyError:
            del w[k]
        else:
            w[k] = v
    return pack(w)


FIELD = TargetField(1.0, "r1/target", 2, A)
FKEY = K.field_target("r1")


def raises(exc_type, key, data, field=None, match=None):
    with pytest.raises(exc_type, match=match) as info:
        decode(key, data)
    err = info.value
    assert err.key == (key.value if isinstance(key, KeyKind) else key)
    assert f"key '{err.key}'" in str(err)
    if field is not None:
        assert err.field == field and f"field '{field}'" in str(err)
    return err


def test_wrong_version():
    raises(MessageVersionError, FKEY, tampered(FIELD, v=2), "v", "schema version 2")
    raises(MessageVersionError, FKEY, tampered(FIELD, v="1"), "v")
    raises(MessageVersionError, FKEY, tampered(FIELD, v=KeyError), "v", "missing")


def test_truncated_and_garbage_bytes():
    data = encode(FIELD)
    for cut in (1, 10, len(data) // 2, len(data) - 1):
        raises(MessageFormatError, FKEY, data[:cut], None, "not valid msgpack")
    raises(MessageFormatError, FKEY, b"", None)
    raises(MessageFormatError, FKEY, data + b"\x00", None, re.escape("trailing bytes after the msgpack map (1 more "
                                                                     "byte)"))
    raises(MessageFormatError, FKEY, pack([1, 2, 3]), None, "not a msgpack map: a msgpack array")
    # garbage whose first byte is a whole msgpack object: not a map, whatever follows
    for junk, what in ((b"\x00\xff\x13\x37", "a msgpack integer followed by 3 more bytes"),
                       (b"\xff\xff", "a msgpack integer followed by 1 more byte"),
                       (b"abc", "a msgpack integer followed by 2 more bytes"),
                       (b"\xa3abcxyz", "a msgpack string followed by 3 more bytes"),
                       (pack([1, 2]) + b"\x00", "a msgpack array followed by 1 more byte"),
                       (b"\xc0\x00", "a msgpack nil followed by 1 more byte")):
        err = raises(MessageFormatError, FKEY, junk, None, "not a msgpack map: " + what)
        assert "trailing bytes" not in str(err)
    raises(MessageFormatError, FKEY, b"\xc1", None)  # never-used msgpack byte
    raises(MessageFormatError, FKEY, pack({1: 2}), None)  # non-string map key


def test_kind_must_match_the_key():
    raises(MessageKindError, K.cmd_wheels("r1"), encode(FIELD), "kind", "does not match")
    raises(MessageKindError, FKEY, tampered(FIELD, kind=KeyError), "kind")
    raises(MessageKindError, "cekm/r1/sense/nonsense", encode(FIELD), None, "not a key of the cekm key space")
    raises(MessageKindError, K.alive("r1", "motor"), encode(FIELD), None, "carry no message")


def test_a_graphs_own_key_carries_the_kind_its_node_declares():
    """On a node's own key (a graph declares it) the payload says its kind; a receiver that
    knows the graph expects one and refuses any other."""
    assert decode("cekm/r1/my/field", encode(FIELD)) == FIELD
    assert decode("cekm/r1/my/field", encode(FIELD), expect=KeyKind.FIELD_TARGET) == FIELD
    with pytest.raises(MessageKindError, match="does not match"):
        decode("cekm/r1/my/field", encode(FIELD), expect=KeyKind.CMD_WHEELS)
    with pytest.raises(MessageKindError, match="not a kind of the protocol"):
        decode("cekm/r1/my/field", msgpack.packb({"v": 1, "kind": "bogus", "stamp": 0.0, "sender": "x"}))
    data = Data(0.128, "r1/mine", {"d": 0.25, "seen": [1, 2], "ok": True, "none": None})
    assert decode("cekm/r1/mine/out", encode(data)) == data
    with pytest.raises(MessageFieldError, match="not finite"):
        Data(0.0, "x", {"d": float("nan")})
    with pytest.raises(MessageFieldError, match="not plain data"):
        Data(0.0, "x", {"a": object()})


def test_missing_and_unexpected_fields():
    raises(MessageFieldError, FKEY, tampered(FIELD, winner=KeyError), "winner", "missing")
    raises(MessageFieldError, FKEY, tampered(FIELD, stamp=KeyError), "stamp", "missing")
    raises(MessageFieldError, FKEY, tampered(FIELD, extra=1), "extra", "unexpected field")


def test_nan_and_types_on_the_wire():
    raises(MessageFieldError, FKEY, tampered(FIELD, stamp=math.nan), "stamp", "not finite")
    raises(MessageFieldError, FKEY, tampered(FIELD, winner="2"), "winner", "expected an integer")
    bad = A.copy()
    bad[17] = np.nan
    raises(MessageFieldError, FKEY, tampered(FIELD, a={"dtype": "<f8", "shape": [225], "data": bad.tobytes()}), "a",
           "not finite at index 17")
    cmd = WheelCommand(1.0, "r1/motor", 0.1, 0.1, 1)
    raises(MessageFieldError, K.cmd_wheels("r1"), tampered(cmd, v_l=math.inf), "v_l", "not finite")
    raises(MessageFieldError, K.cmd_wheels("r1"), tampered(cmd, v_r=True), "v_r", "expected a number")
    st = SenseTarget(1.0, "world", 0.1, 0.1, True)
    raises(MessageFieldError, K.sense_target("r1"), tampered(st, visible=1), "visible", "expected a bool")


@pytest.mark.parametrize("array, match", [
    ({"dtype": "<f4", "shape": [225], "data": A.astype("<f4").tobytes()}, "dtype '<f4'"),
    ({"dtype": ">f8", "shape": [225], "data": A.astype(">f8").tobytes()}, "dtype '>f8'"),
    ({"dtype": "<f8", "shape": [15, 15], "data": A.tobytes()}, r"shape \[15, 15\]"),
    ({"dtype": "<f8", "shape": [0], "data": b""}, r"shape \[0\]"),
    ({"dtype": "<f8", "shape": [224], "data": A.tobytes()}, "holds 1800 bytes, shape \\[224\\] needs 1792"),
    ({"dtype": "<f8", "shape": [225], "data": A.tobytes()[:-3]}, "holds 1797 bytes"),
    ({"dtype": "<f8", "shape": [225], "data": list(A)}, "data must be bytes"),
    ({"dtype": "<f8", "shape": [225]}, "exactly dtype, shape, data"),
    (A.tolist(), "expected an array map"),
])
def test_array_layout_errors(array, match):
    raises(MessageArrayError, FKEY, tampered(FIELD, a=array), "a", match)


def test_winner_out_of_range_on_the_wire():
    raises(MessageFieldError, FKEY, tampered(FIELD, winner=225), "winner", "out of range")


def test_sensor_index_checked_against_the_key():
    msg = SenseRange(1.0, "world", 3, 0.5, 0.1)
    raises(MessageFieldError, K.sense_range("r1", 4), encode(msg), "index", "differs from the key's sensor index 4")
    far = SenseRange(1.0, "world", 12, 0.5, 0.1)  # buildable, but not a sensor of a 12-sensor robot
    raises(MessageFieldError, KeyKind.SENSE_RANGE, encode(far), "index", r"out of range 0\.\.11")
    assert decode(KeyKind.SENSE_RANGE, encode(far), keys=KeySpace(range_sensors=16)).index == 12
    obs = ObstacleField(1.0, "r1/obstacle-3", 3, None, None)
    raises(MessageFieldError, K.field_obstacle("r1", 5), encode(obs), "index")


def test_obstacle_field_consistency_on_the_wire():
    obs = ObstacleField(1.0, "r1/obstacle-3", 3, None, None)
    raises(MessageFieldError, K.field_obstacle("r1", 3), tampered(obs, winner=4), "b", "both be None")


def test_peek_on_garbage():
    assert peek(b"\xc1") == (None, None)
    assert peek(pack([1])) == (None, None)
    assert peek(pack({"kind": 3, "stamp": "x"})) == (None, None)


def test_errors_are_cekm_errors():
    from cekm_swarm.errors import CekmError

    with pytest.raises(CekmError):
        decode(FKEY, b"")
    assert issubclass(MessageArrayError, MessageFieldError) and issubclass(MessageFieldError, MessageError)


def test_encode_rejects_non_messages():
    with pytest.raises(MessageKindError, match="not a protocol message"):
        encode({"v": 1})  # type: ignore[arg-type]


# --------------------------------------------------------------------------- drops


def test_drop_counter_counts_and_logs_once_per_source(caplog):
    drops = DropCounter("motor r1")
    good = encode(FIELD)
    with caplog.at_level(logging.WARNING, logger="cekm_swarm.protocol"):
        assert drops.decode(FKEY, good) == FIELD
        assert drops.decode(FKEY, tampered(FIELD, v=99)) is None
        assert drops.decode(FKEY, b"\x00garbage") is None
        assert drops.decode(K.field_obstacle("r1", 2), b"") is None
        assert drops.decode(FKEY, good) == FIELD  # keeps working after drops
    assert drops.total == 3 and drops.count(FKEY) == 2 and drops.count(K.field_obstacle("r1", 2)) == 1
    warnings = [r.getMessage() for r in caplog.records]
    assert len(warnings) == 2  # first drop per source only
    assert "schema version 99" in warnings[0] and FKEY in warnings[0]
    rec = drops.records()
    assert [r.source for r in rec] == sorted([FKEY, K.field_obstacle("r1", 2)])
    assert "schema version 99" in [r for r in rec if r.source == FKEY][0].first_reason


@pytest.mark.parametrize("kwargs,field", [
    (dict(winner=None, a=A, alpha=0.1, d=0.5), "winner"),
    (dict(winner=3, a=None, alpha=0.1, d=0.5), "a"),
    (dict(winner=3, a=A, alpha=0.1, d=None), "d"),
    (dict(winner=3, a=A, alpha=0.1, d=0.0, at_goal=True), "at_goal"),
    (dict(winner=None, a=None, at_goal=True), "at_goal"),
])
def test_target_field_states_are_consistent(kwargs, field):
    """A target field is one of: a field with the input u, the goal state (u, no field), no target."""
    with pytest.raises(MessageFieldError) as err:
        TargetField(1.0, "r1/target", **kwargs)
    assert err.value.field == field


def test_tracking_sense_messages_round_trip_and_reject_bad_fields():
    from cekm_swarm.protocol.messages import SensePose, SenseTargets

    K = KeySpace()
    p = SensePose(0.256, "world", (1.0, 2.0, -0.5))
    assert decode(K.sense_pose("r1"), encode(p)) == p
    t = SenseTargets(0.256, "world", {"t1": (0.3, 0.2), "t2": (-3.0, 0.0)})
    assert decode(K.sense_targets("r1"), encode(t)) == t
    assert decode(K.sense_targets("r1"), encode(SenseTargets(0.0, "world", {}))).targets == {}
    with pytest.raises(MessageFieldError, match="pose"):
        SensePose(0.0, "world", (1.0, 2.0, 4.0))  # heading outside [-pi, pi]
    with pytest.raises(MessageFieldError, match="targets.t1"):
        SenseTargets(0.0, "world", {"t1": (0.3, -0.1)})  # negative distance
    with pytest.raises(MessageFieldError, match="targets.t1"):
        SenseTargets(0.0, "world", {"t1": (4.0, 0.1)})  # angle outside [-pi, pi]
    with pytest.raises(MessageFieldError, match="targets"):
        SenseTargets(0.0, "world", [("t1", 0.3, 0.1)])
    with pytest.raises(MessageKindError):
        decode(K.sense_pose("r1"), encode(t))  # a targets message on the pose key
