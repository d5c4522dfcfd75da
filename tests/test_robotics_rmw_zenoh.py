"""Golden tests of rmw_zenoh's wire format (no ROS 2 here): the oracles are values rmw_zenoh
publishes in its own documentation and sources (the std_msgs/msg/String key of its design
notes, its liveliness token layout and QoS string), zenoh-ext's serializer for the
attachment, and CDR bytes worked out by hand."""

from __future__ import annotations

import numpy as np
import pytest
import zenoh.ext

from deploy.robotics import rmw_zenoh as rz
from deploy.robotics import ros

# rmw_zenoh's design notes: the key of topic /chatter (std_msgs/msg/String) in domain 0.
STRING_HASH = "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18"
CHATTER_KEY = f"0/chatter/std_msgs::msg::dds_::String_/{STRING_HASH}"


def test_type_hash_of_string_is_rmw_zenohs() -> None:
    assert rz.type_hash("std_msgs/msg/String") == STRING_HASH


@pytest.mark.parametrize(("typename", "digest"), [
    # Regression anchors: computed by rosbags from the Jazzy definitions.
    ("nav_msgs/msg/Path", "1957a5bb3cee5da65c4e52e52b65a93df227efce4c20f8458b36e73066ca334b"),
    ("geometry_msgs/msg/PoseStamped",
     "10f3786d7d40fd2b54367835614bff85d4ad3b5dab62bf8bca0cc232d73b4cd8"),
    ("nav_msgs/msg/OccupancyGrid",
     "8d348150c12913a31ee0ec170fbf25089e4745d17035792a1ba94d6f0bc0cfc7"),
])
def test_type_hashes_of_the_bridges_types(typename: str, digest: str) -> None:
    assert rz.type_hash(typename) == f"RIHS01_{digest}"


def test_topic_keys() -> None:
    assert rz.topic_key(0, "/chatter", "std_msgs/msg/String") == CHATTER_KEY
    assert rz.topic_key(2, "/robot1/chatter", "std_msgs/msg/String") == \
        f"2/robot1/chatter/std_msgs::msg::dds_::String_/{STRING_HASH}"
    assert rz.dds_type_name("nav_msgs/msg/OccupancyGrid") == "nav_msgs::msg::dds_::OccupancyGrid_"


def test_qos_strings_leave_defaults_empty() -> None:
    assert rz.qos_key(rz.Qos(depth=10)) == "::,10:,:,:,,"
    assert rz.qos_key(rz.DEFAULT_QOS) == "::,:,:,:,,"
    assert rz.qos_key(rz.LATCHED) == ":1:,1:,:,:,,"
    assert rz.qos_key(rz.Qos(reliability=rz.BEST_EFFORT, history=rz.KEEP_ALL)) == \
        "2::2,:,:,:,,"


def test_liveliness_tokens() -> None:
    zid = "b89f34a8f6a786788926e9c41d11be8e"
    node = rz.NodeName(0, zid, 1, "/", "talker")
    assert rz.node_token(node) == f"@ros2_lv/0/{zid}/1/1/NN/%/%/talker"
    assert rz.publisher_token(node, 5, "/chatter", "std_msgs/msg/String", rz.Qos(depth=10)) == \
        f"@ros2_lv/0/{zid}/1/5/MP/%/%/talker/%chatter/std_msgs::msg::dds_::String_/" \
        f"{STRING_HASH}/::,10:,:,:,,"
    nested = rz.NodeName(3, zid, 2, "/fleet/a", "bridge")
    assert rz.node_token(nested) == f"@ros2_lv/3/{zid}/2/2/NN/%/%fleet%a/bridge"
    # Every token is a valid Zenoh key expression (no empty chunk, no '//').
    for token in (rz.node_token(node), rz.node_token(nested)):
        zenoh.KeyExpr(token)


def test_attachment_is_zenoh_exts_serialization_in_33_bytes() -> None:
    gid = bytes(range(16))
    data = rz.attachment(5, 1_795_000_000_123_456_789, gid)
    oracle = zenoh.ext.z_serialize((zenoh.ext.Int64(5), zenoh.ext.Int64(1_795_000_000_123_456_789),
                                    [zenoh.ext.UInt8(b) for b in gid])).to_bytes()
    assert data == oracle and len(data) == rz.ATTACHMENT_SIZE == 33
    assert rz.parse_attachment(data) == (5, 1_795_000_000_123_456_789, gid)
    with pytest.raises(ValueError):
        rz.attachment(1, 2, b"short")
    with pytest.raises(ValueError):
        rz.parse_attachment(data[:-1])


def test_gids_are_stable_and_distinct() -> None:
    a, b = rz.gid("@ros2_lv/0/x/1/2/MP/a"), rz.gid("@ros2_lv/0/x/1/3/MP/a")
    assert len(a) == 16 and a != b and a == rz.gid("@ros2_lv/0/x/1/2/MP/a")


def test_cdr_of_a_string_by_hand() -> None:
    # encapsulation CDR_LE (00 01 00 00), uint32 length 6 including the NUL, the bytes
    assert ros.encode(ros.build("std_msgs/msg/String", data="hello")) == \
        bytes.fromhex("00010000") + (6).to_bytes(4, "little") + b"hello\x00"


def test_cdr_round_trips_of_the_bridges_types() -> None:
    pose = {"header": {"stamp": {"sec": 7, "nanosec": 9}, "frame_id": "map"},
            "pose": {"position": {"x": 1.5, "y": -2.0}, "orientation": {"z": 0.6, "w": 0.8}}}
    stamped = ros.build(ros.POSE_TYPE, **pose)
    back = ros.decode(ros.encode(stamped), ros.POSE_TYPE)
    assert back == stamped and back.pose.position.x == 1.5
    path = ros.build(ros.PATH_TYPE, header=pose["header"], poses=[stamped, stamped])
    back_path = ros.decode(ros.encode(path), ros.PATH_TYPE)
    assert len(back_path.poses) == 2 and back_path.poses[1].pose.orientation.w == 0.8
    grid = ros.build(ros.MAP_TYPE, info={"width": 3, "height": 2, "resolution": 1.0},
                     data=np.array([0, 100, -1, 0, 0, 100], dtype=np.int8))
    back_grid = ros.decode(ros.encode(grid), ros.MAP_TYPE)
    assert back_grid.info.width == 3 and back_grid.data.tolist() == [0, 100, -1, 0, 0, 100]
