"""The ROS 2 bridge on a real Zenoh router, read by plain Zenoh sessions that look for what a
ROS 2 node on rmw_zenoh would (no ROS here): liveliness tokens of the node and publishers,
samples on the rmw_zenoh keys with the 33-byte attachment, CDR that decodes, and the map
delivered to a subscriber that arrives after it was published (transient local)."""

from __future__ import annotations

import subprocess
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np
import pytest
import zenoh
import zenoh.ext
from fleet_helpers import mstc, stop_processes
from test_monitor_fixtures import open_room, run_mission, two_robot_walks
from waiting import wait_until_sync

from bus.config import ConnectionSettings, open_session
from deploy.monitor.app import Watcher
from deploy.monitor.view import FeedStats
from deploy.robotics import rmw_zenoh as rz
from deploy.robotics import ros
from deploy.robotics.ros_bridge import RosScreen

pytestmark = pytest.mark.integration
DOMAIN = 7


@contextmanager
def session(router: str) -> Iterator[zenoh.Session]:
    with open_session(ConnectionSettings(connect=(router,))) as opened:
        yield opened


def routed(sender: zenoh.Session, receiver: zenoh.Session) -> None:
    """Return once a put of ``sender`` reaches ``receiver``: the router then knows every
    subscription ``receiver`` declared before (declarations reach it in order)."""
    arrived = threading.Event()
    probe = receiver.declare_subscriber("test-probe/ros-bridge", lambda _: arrived.set())
    try:
        wait_for(lambda: sender.put("test-probe/ros-bridge", b"probe") or arrived.wait(0.1))
    finally:
        probe.undeclare()


def wait_for(condition: Any, seconds: float = 10.0) -> None:
    wait_until_sync(condition, seconds, "the bridge's samples or tokens")


def test_the_bridge_speaks_rmw_zenoh(router: str) -> None:
    mission = run_mission(open_room(), two_robot_walks())
    with session(router) as bridge_side, session(router) as ros_side:
        screen = RosScreen(bridge_side, DOMAIN)
        try:
            poses: list[zenoh.Sample] = []
            pose_key = rz.topic_key(DOMAIN, "/mstc/robot_0/pose", ros.POSE_TYPE)
            path_key = rz.topic_key(DOMAIN, "/mstc/robot_1/path", ros.PATH_TYPE)
            paths: list[zenoh.Sample] = []
            subscribers = [ros_side.declare_subscriber(pose_key, poses.append),
                           ros_side.declare_subscriber(path_key, paths.append)]
            routed(bridge_side, ros_side)
            watcher = Watcher(screen)
            watcher.feed(mission.records[:len(mission.records) // 2])
            screen.refresh(watcher.model, FeedStats())
            watcher.feed(mission.records[len(mission.records) // 2:])
            screen.refresh(watcher.model, FeedStats())
            wait_for(lambda: len(poses) >= 2 and len(paths) >= 2)
            # A subscriber arriving after the map was published still gets it.
            late: list[zenoh.Sample] = []
            map_key = rz.topic_key(DOMAIN, "/map", ros.MAP_TYPE)
            history = zenoh.ext.HistoryConfig(detect_late_publishers=True)
            late_sub = zenoh.ext.declare_advanced_subscriber(ros_side, map_key, late.append,
                                                             history=history)
            wait_for(lambda: bool(late))
            tokens = [str(r.ok.key_expr) for r in
                      ros_side.liveliness().get(f"@ros2_lv/{DOMAIN}/**", timeout=5.0)
                      if r.ok is not None]
        finally:
            for sub in subscribers:
                sub.undeclare()
            screen.stop()
        late_sub.undeclare()
    zid = screen.node.zid
    prefix = f"@ros2_lv/{DOMAIN}/{zid}/0"
    assert f"{prefix}/0/NN/%/%/mstc_bridge" in tokens
    assert f"{prefix}/1/MP/%/%/mstc_bridge/%map/nav_msgs::msg::dds_::OccupancyGrid_/" \
           f"{rz.type_hash(ros.MAP_TYPE)}/:1:,1:,:,:,," in tokens
    assert any("/MP/%/%/mstc_bridge/%mstc%robot_1%path/nav_msgs::msg::dds_::Path_/" in t
               for t in tokens)
    assert len(tokens) == 1 + 1 + 2 * 2  # node, map, pose and path of each robot
    for samples in (poses, paths, late):
        sequences = []
        for sample in samples:
            assert sample.attachment is not None
            seq, stamp_ns, gid = rz.parse_attachment(sample.attachment.to_bytes())
            assert len(gid) == 16 and abs(stamp_ns / 1e9 - time.time()) < 120
            sequences.append(seq)
        assert sequences == list(range(1, len(sequences) + 1))
    last_pose = ros.decode(poses[-1].payload.to_bytes(), ros.POSE_TYPE)
    assert last_pose.header.frame_id == "map"
    end = mission.walks[0][-1]
    assert (last_pose.pose.position.x, last_pose.pose.position.y) == (end[1] + 0.5, 3.5 - end[0])
    last_path = ros.decode(paths[-1].payload.to_bytes(), ros.PATH_TYPE)
    assert [(p.pose.position.x, p.pose.position.y) for p in last_path.poses] == \
        [(c + 0.5, 3.5 - r) for r, c in mission.walks[1]]
    occupancy = ros.decode(late[-1].payload.to_bytes(), ros.MAP_TYPE)
    np.testing.assert_array_equal(occupancy.data.reshape(4, 8)[::-1],
                                  np.where(mission.free, 0, 100))


@pytest.mark.slow
def test_the_command_announces_its_node_and_stops_after_its_duration(router: str) -> None:
    proc = subprocess.Popen(mstc("ros-bridge", "--connect", router, "--mission", "ros-cli",
                                 "--domain", "9", "--duration", "4"),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        with session(router) as ros_side:
            def node_seen() -> bool:
                replies = ros_side.liveliness().get("@ros2_lv/9/**", timeout=1.0)
                return any(r.ok is not None and str(r.ok.key_expr).endswith("/NN/%/%/mstc_bridge")
                           for r in replies)
            wait_for(node_seen, 60.0)
        _, err = proc.communicate(timeout=60)
    finally:
        stop_processes([proc])
    assert proc.returncode == 0, err
    assert "bridging mission ros-cli to ROS 2 domain 9" in err
