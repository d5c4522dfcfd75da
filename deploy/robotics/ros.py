"""The scene as ROS 2 messages, CDR-encoded with rosbags' typestore (no ROS installation).

The map is a ``nav_msgs/msg/OccupancyGrid`` (0 free, 100 blocked), as every ROS 2 tool
expects; for rosbag2, where Foxglove's protobuf types do not fit, the coverage grid becomes
two more OccupancyGrids (visits capped at 100; the first visitor's id, -1 for nobody), the
robots and the tree ``visualization_msgs/msg/MarkerArray``s and the events
``rcl_interfaces/msg/Log``. Types come from the Jazzy store (ROS 2's current LTS); their CDR
layout is the same in Humble for every type used here except Marker.
"""

from __future__ import annotations

import math
from functools import cache
from typing import Any

import numpy as np
from rosbags.typesys import Stores, get_typestore
from rosbags.typesys.store import Typestore

from deploy.monitor.figures import Rgba, robot_colour
from deploy.robotics.scene import (
    FRAME,
    SUB_CELL_M,
    GridLayers,
    LogLine,
    Point,
    Scene,
)

MAP_TYPE = "nav_msgs/msg/OccupancyGrid"
MARKERS_TYPE = "visualization_msgs/msg/MarkerArray"
LOG_TYPE = "rcl_interfaces/msg/Log"
STRING_TYPE = "std_msgs/msg/String"
PATH_TYPE = "nav_msgs/msg/Path"
POSE_TYPE = "geometry_msgs/msg/PoseStamped"

_BASE_DTYPES = {"bool": np.bool_, "byte": np.uint8, "char": np.uint8, "int8": np.int8,
                "uint8": np.uint8, "int16": np.int16, "uint16": np.uint16, "int32": np.int32,
                "uint32": np.uint32, "int64": np.int64, "uint64": np.uint64,
                "float32": np.float32, "float64": np.float64}
_LOG_LEVELS = {"info": 20, "warning": 30, "error": 40}
_DEAD_RGBA: Rgba = (0.45, 0.45, 0.45, 1.0)
_MARK_RGBA: Rgba = (0.9, 0.1, 0.1, 1.0)
_BASE, _NAME, _ARRAY, _SEQUENCE = 1, 2, 3, 4  # rosbags' Nodetype values


@cache
def typestore() -> Typestore:
    return get_typestore(Stores.ROS2_JAZZY)


def msgdef(typename: str) -> str:
    """The ``ros2msg`` schema text of ``typename`` (its dependencies appended, as rosbag2's
    MCAP storage writes it)."""
    return typestore().generate_msgdef(typename, ros_version=2)[0]


def _default(node: tuple[Any, Any]) -> Any:
    kind, desc = int(node[0]), node[1]
    if kind == _BASE:
        name = desc[0]
        return "" if name in ("string", "wstring") else \
            np.dtype(_BASE_DTYPES[name]).type(0).item()
    if kind == _NAME:
        return build(str(desc))
    inner, count = desc
    if int(inner[0]) == _BASE and inner[1][0] in _BASE_DTYPES:
        return np.zeros(count if kind == _ARRAY else 0, dtype=_BASE_DTYPES[inner[1][0]])
    return [_default(inner) for _ in range(count)] if kind == _ARRAY else []


def build(typename: str, **fields: Any) -> Any:
    """A message of ``typename``: fields not given take ROS 2's defaults; a nested message
    may be given as a dict of its fields."""
    store = typestore()
    values = {}
    for name, node in store.fielddefs[typename][1]:
        if name not in fields:
            values[name] = _default(node)
            continue
        value = fields[name]
        if int(node[0]) == _NAME and isinstance(value, dict):
            value = build(str(node[1]), **value)
        values[name] = value
    return store.types[typename](**values)


def encode(message: Any) -> bytes:
    return bytes(typestore().serialize_cdr(message, message.__msgtype__))


def decode(data: bytes, typename: str) -> Any:
    return typestore().deserialize_cdr(data, typename)


def stamp(epoch_s: float) -> dict[str, int]:
    sec = math.floor(epoch_s)
    return {"sec": int(sec), "nanosec": min(round((epoch_s - sec) * 1e9), 999_999_999)}


def _header(epoch_s: float) -> dict[str, Any]:
    return {"stamp": stamp(epoch_s), "frame_id": FRAME}


def _occupancy(values: np.ndarray, epoch_s: float) -> Any:
    """An OccupancyGrid whose row 0 is at the origin (the map's bottom row), as ROS wants."""
    rows, cols = values.shape
    return build(MAP_TYPE, header=_header(epoch_s), info={
        "map_load_time": stamp(epoch_s), "resolution": SUB_CELL_M, "width": cols,
        "height": rows, "origin": {"orientation": {"w": 1.0}}},
        data=np.ascontiguousarray(values[::-1]).reshape(-1).astype(np.int8))


def map_grid(grid: GridLayers, epoch_s: float) -> bytes:
    """The map: 0 free, 100 blocked."""
    return encode(_occupancy(np.where(grid.free > 0, 0, 100), epoch_s))


def coverage_grid(grid: GridLayers, epoch_s: float) -> bytes:
    """Visits per sub-cell capped at 100, -1 where blocked."""
    visits = np.minimum(grid.visits.astype(np.int16), 100)
    return encode(_occupancy(np.where(grid.free > 0, visits, -1), epoch_s))


def owner_grid(grid: GridLayers, epoch_s: float) -> bytes:
    """The first visitor's id per sub-cell, -1 for nobody (and ids above 127, which int8
    cannot hold)."""
    owner = grid.owner.astype(np.int16)
    return encode(_occupancy(np.where(owner <= 127, owner, -1), epoch_s))


def _colour(rgba: Rgba) -> dict[str, float]:
    return dict(zip("rgba", rgba, strict=True))


def _pose(x: float, y: float, yaw: float = 0.0, z: float = 0.0) -> dict[str, Any]:
    return {"position": {"x": x, "y": y, "z": z},
            "orientation": {"z": math.sin(yaw / 2), "w": math.cos(yaw / 2)}}


def _points(points: tuple[Point, ...] | list[Point], z: float = 0.0) -> list[Any]:
    return [build("geometry_msgs/msg/Point", x=x, y=y, z=z) for x, y in points]


def _marker(epoch_s: float, ns: str, ident: int, kind: int, **fields: Any) -> Any:
    return build("visualization_msgs/msg/Marker", header=_header(epoch_s), ns=ns, id=ident,
                 type=kind, **fields)


def robot_markers(scene: Scene, epoch_s: float) -> bytes:
    """Per robot an arrow (grey when dead, with a red sphere), a label and its path."""
    m: Any = typestore().types["visualization_msgs/msg/Marker"]
    markers = []
    for mark in scene.robots:
        rgba = _DEAD_RGBA if mark.dead else robot_colour(mark.robot)
        markers.append(_marker(epoch_s, "robot", mark.robot, m.ARROW,
                               pose=_pose(mark.x - 0.4 * math.cos(mark.yaw),
                                          mark.y - 0.4 * math.sin(mark.yaw), mark.yaw, 0.1),
                               scale={"x": 0.8, "y": 0.25, "z": 0.25}, color=_colour(rgba)))
        markers.append(_marker(epoch_s, "label", mark.robot, m.TEXT_VIEW_FACING,
                               pose=_pose(mark.x, mark.y, z=0.8), scale={"z": 0.45},
                               color=_colour((1.0, 1.0, 1.0, 1.0)), text=mark.label))
        markers.append(_marker(epoch_s, "path", mark.robot, m.LINE_STRIP,
                               pose=_pose(0.0, 0.0), scale={"x": 0.08},
                               color=_colour(robot_colour(mark.robot, 0.8)),
                               points=_points(mark.path, 0.05)))
        if mark.dead:
            markers.append(_marker(epoch_s, "dead", mark.robot, m.SPHERE,
                                   pose=_pose(mark.x, mark.y, z=0.3),
                                   scale={"x": 0.5, "y": 0.5, "z": 0.5},
                                   color=_colour(_MARK_RGBA)))
    return encode(build(MARKERS_TYPE, markers=markers))


def tree_markers(scene: Scene, epoch_s: float) -> bytes:
    """Per robot one line list of its tree edges, in its colour."""
    m: Any = typestore().types["visualization_msgs/msg/Marker"]
    by_robot: dict[int, list[Point]] = {}
    for seg in scene.tree:
        by_robot.setdefault(seg.robot, []).extend((seg.a, seg.b))
    markers = [_marker(epoch_s, "tree", robot, m.LINE_LIST, pose=_pose(0.0, 0.0),
                       scale={"x": 0.12}, color=_colour(robot_colour(robot)),
                       points=_points(points, 0.02))
               for robot, points in sorted(by_robot.items())]
    return encode(build(MARKERS_TYPE, markers=markers))


def _pose_stamped(x: float, y: float, yaw: float, epoch_s: float) -> Any:
    return build(POSE_TYPE, header=_header(epoch_s), pose=_pose(x, y, yaw))


def pose_stamped(x: float, y: float, yaw: float, epoch_s: float) -> bytes:
    return encode(_pose_stamped(x, y, yaw, epoch_s))


def path(points: tuple[Point, ...], epoch_s: float) -> bytes:
    """A path through ``points``; each pose faces the next point (the last keeps its own)."""
    poses, yaw = [], 0.0
    for i, (x, y) in enumerate(points):
        if i + 1 < len(points):
            yaw = math.atan2(points[i + 1][1] - y, points[i + 1][0] - x)
        poses.append(_pose_stamped(x, y, yaw, epoch_s))
    return encode(build(PATH_TYPE, header=_header(epoch_s), poses=poses))


def log_message(line: LogLine, epoch_s: float) -> bytes:
    return encode(build(LOG_TYPE, stamp=stamp(epoch_s), level=_LOG_LEVELS[line.level],
                        name=f"mstc.{line.name}", msg=line.text))


def string_message(text: str) -> bytes:
    return encode(build(STRING_TYPE, data=text))
