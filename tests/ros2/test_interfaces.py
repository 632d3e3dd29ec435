"""The ROS 2 message types: Jazzy's type hashes as stated, checked against two independent
computations, and the type store's helpers."""

import numpy as np
import pytest
from zenoh_ros2_sdk.message_registry import MessageRegistry
from zenoh_ros2_sdk.utils import get_type_hash, load_dependencies_recursive

from cekm_swarm.ros2.interfaces import (
    DISTROS,
    JAZZY_TYPE_HASHES,
    MESSAGE_TYPES,
    InterfaceError,
    dds_type_name,
    interfaces,
)

STRING_HASH_OF_REAL_ROS = "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18"
"""std_msgs/msg/String as a real ROS 2 talker announces it (rmw_zenoh's docs/design.md examples)."""


def test_the_stated_jazzy_hashes_are_what_rosbags_computes_from_its_jazzy_definitions():
    store = interfaces("jazzy").store
    assert {t: store.hash_rihs01(t) for t in MESSAGE_TYPES} == JAZZY_TYPE_HASHES
    assert store.hash_rihs01("std_msgs/msg/String") == STRING_HASH_OF_REAL_ROS


def test_the_independent_sdk_computes_the_same_hashes_from_the_message_definitions(msg_dir):
    """zenoh-ros2-sdk's own REP-2016 implementation, fed the .msg text of each type and its
    dependencies, gets every stated hash."""
    registry = MessageRegistry(str(msg_dir))
    for ros_type, expected in JAZZY_TYPE_HASHES.items():
        path = registry.get_msg_file_path(ros_type)
        definition = path.read_text()
        deps = load_dependencies_recursive(ros_type, definition, registry)
        assert get_type_hash(ros_type, msg_definition=definition, dependencies=deps) == expected, ros_type


def test_other_distributions_hash_from_their_own_definitions():
    kilted = interfaces("kilted")
    for t in MESSAGE_TYPES:
        assert kilted.hash(t) == kilted.store.hash_rihs01(t) == JAZZY_TYPE_HASHES[t]  # these types did not change
        assert kilted.hash(t).startswith("RIHS01_") and len(kilted.hash(t)) == 7 + 64
    assert set(DISTROS) == {"jazzy", "kilted"}
    with pytest.raises(InterfaceError, match="humble"):
        interfaces("humble")
    with pytest.raises(InterfaceError, match="not one the project uses"):
        interfaces("jazzy").hash("std_msgs/msg/String")


def test_dds_names_and_message_building():
    assert dds_type_name("geometry_msgs/msg/Twist") == "geometry_msgs::msg::dds_::Twist_"
    with pytest.raises(InterfaceError, match="package/msg/Name"):
        dds_type_name("Twist")
    ifc = interfaces()
    rng = ifc.make("sensor_msgs/msg/Range", range=0.1, not_a_field=3)
    assert rng.range == 0.1 and rng.variance == 0.0 and rng.header.frame_id == ""
    odom = ifc.make("nav_msgs/msg/Odometry")
    assert odom.pose.covariance.shape == (36,) and odom.pose.covariance.dtype == np.float64
    data = ifc.cdr(rng, "sensor_msgs/msg/Range")
    assert data[:4] == b"\x00\x01\x00\x00"
    assert ifc.from_cdr(data, "sensor_msgs/msg/Range").range == pytest.approx(0.1)
    with pytest.raises(InterfaceError, match="unknown"):
        ifc.make("nope_msgs/msg/Nope")
