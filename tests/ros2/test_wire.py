"""rmw_zenoh's wire format: key expressions and liveliness tokens against the examples of
its design document, the attachment against zenoh-ext's own serializer."""

import pytest
import xxhash
import zenoh.ext as ze

from cekm_swarm.ros2.wire import (
    ATTACHMENT_SIZE,
    PUBLISHER,
    SUBSCRIPTION,
    Attachment,
    Node,
    Qos,
    WireError,
    check_topic,
    gid,
    mangle,
    topic_key,
)

STRING = "std_msgs/msg/String"
STRING_HASH = "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18"


def test_topic_key_expressions_as_in_the_design_document():
    assert topic_key(0, "/chatter", STRING, STRING_HASH) == f"0/chatter/std_msgs::msg::dds_::String_/{STRING_HASH}"
    assert topic_key(0, "/robot1/chatter", STRING, STRING_HASH) == \
        f"0/robot1/chatter/std_msgs::msg::dds_::String_/{STRING_HASH}"
    with pytest.raises(WireError, match="domain"):
        topic_key(233, "/chatter", STRING, STRING_HASH)


def test_liveliness_tokens_as_in_the_design_document():
    listener = Node(2, "aac3178e146ba6f1fc6e6a4085e77f21", 0, "listener")
    assert listener.token() == "@ros2_lv/2/aac3178e146ba6f1fc6e6a4085e77f21/0/0/NN/%/%/listener"
    assert listener.entity_token(10, SUBSCRIPTION, "/chatter", STRING, STRING_HASH, Qos(depth=10)) == (
        "@ros2_lv/2/aac3178e146ba6f1fc6e6a4085e77f21/0/10/MS/%/%/listener/%chatter/std_msgs::msg::dds_::String_/"
        f"{STRING_HASH}/::,10:,:,:,,")
    talker = Node(2, "8b20917502ee955ac4476e0266340d5c", 0, "talker")
    assert talker.entity_token(10, PUBLISHER, "/chatter", STRING, STRING_HASH, Qos(depth=7)).endswith(
        f"/10/MP/%/%/talker/%chatter/std_msgs::msg::dds_::String_/{STRING_HASH}/::,7:,:,:,,")
    with pytest.raises(WireError, match="entity kind"):
        talker.entity_token(1, "NN", "/chatter", STRING, STRING_HASH, Qos())


def test_qos_text_and_names():
    assert Qos().keyexpr() == "::,10:,:,:,,"
    assert Qos(reliable=False, transient_local=True, depth=1).keyexpr() == "2:1:,1:,:,:,,"
    assert mangle("/r1/odom") == "%r1%odom" and mangle("/") == "%" and mangle("") == "%"
    assert check_topic("/r1/range_0") == "/r1/range_0"
    for bad in ("r1/odom", "/r1//odom", "/r1/range/0", "/r1/odom/", "/r-1/odom", "/"):
        with pytest.raises(WireError, match="fully qualified"):
            check_topic(bad)


def test_the_attachment_is_what_zenoh_ext_serializes_for_two_int64_and_the_gid():
    a = Attachment(7, 1_700_000_000_123_456_789, bytes(range(16)))
    data = a.encode()
    assert len(data) == ATTACHMENT_SIZE == 33
    assert data == ze.z_serialize((ze.Int64(7), ze.Int64(1_700_000_000_123_456_789), bytes(range(16)))).to_bytes()
    assert Attachment.decode(data) == a
    for bad, why in ((data[:-1], "32 bytes"), (data[:16] + b"\x0f" + data[17:], "GID length 15")):
        with pytest.raises(WireError, match=why):
            Attachment.decode(bad)
    with pytest.raises(WireError, match="GID of 3 bytes"):
        Attachment(1, 2, b"abc").encode()


def test_gid_is_the_xxh3_128_of_the_token_low_half_first():
    token = "@ros2_lv/0/abc/0/1/MP/%/%/cekm_bridge/%r1%odom/nav_msgs::msg::dds_::Odometry_/RIHS01_x/::,10:,:,:,,"
    h = xxhash.xxh3_128_intdigest(token.encode())
    g = gid(token)
    assert (
        len(g) == 16
        and int.from_bytes(g[:8], "little") == h & (2**64 - 1)
        and int.from_bytes(g[8:], "little") == h >> 64
    )
    assert gid(token + "x") != g
