"""``mstc ros-bridge``'s screen: the mission as ROS 2 topics on Zenoh, in rmw_zenoh's format,
so ROS 2 nodes running rmw_zenoh_cpp on the same Zenoh network can subscribe.

Topics (node ``/mstc_bridge``): ``/map`` (nav_msgs/msg/OccupancyGrid, transient local: an
advanced publisher with a one-sample cache, so a late subscriber gets the map),
``/mstc/robot_<id>/pose`` (geometry_msgs/msg/PoseStamped) and ``/mstc/robot_<id>/path``
(nav_msgs/msg/Path, the sub-cells the robot has entered: its plan is not on the wire).
Each publisher has a liveliness token; each sample an rmw_zenoh attachment.
"""

from __future__ import annotations

import time
from typing import Any

import zenoh
import zenoh.ext

from deploy.monitor.model import FleetModel
from deploy.monitor.types import MonitorEvent
from deploy.monitor.view import FeedStats
from deploy.robotics import rmw_zenoh as rz
from deploy.robotics import ros
from deploy.robotics.scene import RobotMark, Scene, scene

NODE_NAME = "mstc_bridge"
ROBOT_QOS = rz.Qos(depth=10)
HEARTBEAT_S = 1.0  # sporadic: only when a sample was published in the last period


class RosPublisher:
    """One ROS 2 publisher: its data key, its liveliness token, sequence numbers."""

    def __init__(self, session: zenoh.Session, node: rz.NodeName, entity_id: int, topic: str,
                 typename: str, qos: rz.Qos) -> None:
        self.key = rz.topic_key(node.domain, topic, typename)
        token = rz.publisher_token(node, entity_id, topic, typename, qos)
        self.gid = rz.gid(token)
        self.sequence = 0
        self._publisher: Any
        if qos.durability == rz.TRANSIENT_LOCAL:
            # As rmw_zenoh for RELIABLE + TRANSIENT_LOCAL: a cache late subscribers query,
            # found through the publisher's detection token, and sample-miss detection
            # (sequence numbers, which also spare the session from needing timestamps).
            self._publisher = zenoh.ext.declare_advanced_publisher(
                session, self.key, cache=zenoh.ext.CacheConfig(max_samples=qos.depth),
                publisher_detection=True,
                sample_miss_detection=zenoh.ext.MissDetectionConfig(
                    heartbeat=None, sporadic_heartbeat=HEARTBEAT_S))
        else:
            self._publisher = session.declare_publisher(self.key)
        self._token = session.liveliness().declare_token(token)

    def put(self, payload: bytes) -> None:
        self.sequence += 1
        self._publisher.put(payload, attachment=rz.attachment(self.sequence, time.time_ns(),
                                                              self.gid))

    def close(self) -> None:
        self._token.undeclare()
        self._publisher.undeclare()


class RosScreen:
    """A monitor screen publishing the fleet model's picture as ROS 2 topics."""

    def __init__(self, session: zenoh.Session, domain: int, namespace: str = "/") -> None:
        self.session = session
        self.node = rz.NodeName(domain, str(session.info.zid()), 0, namespace, NODE_NAME)
        self._node_token = session.liveliness().declare_token(rz.node_token(self.node))
        self._next_id = 1
        self.map = self._publisher("/map", ros.MAP_TYPE, rz.LATCHED)
        self.poses: dict[int, RosPublisher] = {}
        self.paths: dict[int, RosPublisher] = {}
        self._last: dict[tuple[str, int], object] = {}
        self.epoch_s = time.time()  # the model's t = 0, as in the Foxglove bridge

    def _publisher(self, topic: str, typename: str, qos: rz.Qos) -> RosPublisher:
        publisher = RosPublisher(self.session, self.node, self._next_id, topic, typename, qos)
        self._next_id += 1
        return publisher

    def _changed(self, what: str, robot: int, key: object) -> bool:
        if self._last.get((what, robot)) == key:
            return False
        self._last[(what, robot)] = key
        return True

    def events(self, events: list[MonitorEvent]) -> None:
        return None

    def refresh(self, model: FleetModel, stats: FeedStats) -> None:
        self.publish(scene(model))

    def close(self, model: FleetModel, stats: FeedStats) -> None:
        self.publish(scene(model))

    def publish(self, picture: Scene) -> None:
        at = self.epoch_s + picture.t
        grid = picture.grid
        if grid is not None and self._changed("map", -1, (grid.shape, grid.free.tobytes())):
            self.map.put(ros.map_grid(grid, at))
        for mark in picture.robots:
            self._robot(mark, at)

    def _robot(self, mark: RobotMark, at: float) -> None:
        r = mark.robot
        if r not in self.poses:
            base = f"/mstc/robot_{r}"
            self.poses[r] = self._publisher(f"{base}/pose", ros.POSE_TYPE, ROBOT_QOS)
            self.paths[r] = self._publisher(f"{base}/path", ros.PATH_TYPE, ROBOT_QOS)
        if self._changed("pose", r, (mark.x, mark.y, mark.yaw)):
            self.poses[r].put(ros.pose_stamped(mark.x, mark.y, mark.yaw, at))
        if self._changed("path", r, mark.path):
            self.paths[r].put(ros.path(mark.path, at))

    def stop(self) -> None:
        for publisher in (self.map, *self.poses.values(), *self.paths.values()):
            publisher.close()
        self._node_token.undeclare()

