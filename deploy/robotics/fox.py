"""The scene as Foxglove's well-known messages (foxglove-sdk types, protobuf on the wire).

- coverage: a ``foxglove.Grid`` over the sub-cells with three uint8 fields per cell,
  ``owner`` (the robot that entered first, 255 nobody), ``visits`` (saturating at 255) and
  ``free`` (1 free, 0 blocked); colour it by ``owner`` or ``visits`` in the 3D panel;
- robots: a ``foxglove.SceneUpdate`` with one entity per robot: an arrow at its pose in its
  colour (grey, with a red sphere, once dead), a label (id, state, moves) and its path as a
  line strip;
- tree: a ``foxglove.SceneUpdate`` with one entity per robot holding its tree edges;
- events: one ``foxglove.Log`` per tracker event (warnings for deaths and takeovers).

Pure: these build messages, the channels (``deploy.robotics.channels``) send them.
"""

from __future__ import annotations

import math

import numpy as np
from foxglove.messages import (
    ArrowPrimitive,
    Color,
    Grid,
    LinePrimitive,
    LinePrimitiveLineType,
    Log,
    LogLevel,
    PackedElementField,
    PackedElementFieldNumericType,
    Point3,
    Pose,
    Quaternion,
    SceneEntity,
    SceneUpdate,
    SpherePrimitive,
    TextPrimitive,
    Timestamp,
    Vector2,
    Vector3,
)

from deploy.monitor.figures import Rgba, robot_colour
from deploy.robotics.scene import (
    FRAME,
    SUB_CELL_M,
    GridLayers,
    LogLine,
    Point,
    RobotMark,
    Scene,
)

GRID_FIELDS = ("owner", "visits", "free")  # byte offsets 0, 1, 2 of each cell
_DEAD_RGBA: Rgba = (0.45, 0.45, 0.45, 1.0)
_MARK_RGBA: Rgba = (0.9, 0.1, 0.1, 1.0)
_LEVELS = {"info": LogLevel.Info, "warning": LogLevel.Warning, "error": LogLevel.Error}


def timestamp(epoch_s: float) -> Timestamp:
    return Timestamp.from_epoch_secs(epoch_s)


def _colour(rgba: Rgba) -> Color:
    return Color(r=rgba[0], g=rgba[1], b=rgba[2], a=rgba[3])


def _pose(x: float = 0.0, y: float = 0.0, z: float = 0.0, yaw: float = 0.0) -> Pose:
    return Pose(position=Vector3(x=x, y=y, z=z),
                orientation=Quaternion(z=math.sin(yaw / 2), w=math.cos(yaw / 2)))


def _points(points: tuple[Point, ...] | list[Point], z: float) -> list[Point3]:
    return [Point3(x=x, y=y, z=z) for x, y in points]


def grid_data(grid: GridLayers) -> bytes:
    """The cells packed as ``GRID_FIELDS`` per cell, Grid row 0 = the map's bottom row."""
    packed = np.stack([grid.owner, grid.visits, grid.free], axis=-1)[::-1]
    return np.ascontiguousarray(packed, dtype=np.uint8).tobytes()


def coverage(grid: GridLayers, epoch_s: float) -> Grid:
    cols = grid.shape[1]
    fields = [PackedElementField(name=name, offset=i, type=PackedElementFieldNumericType.Uint8)
              for i, name in enumerate(GRID_FIELDS)]
    return Grid(timestamp=timestamp(epoch_s), frame_id=FRAME, pose=_pose(),
                column_count=cols, cell_size=Vector2(x=SUB_CELL_M, y=SUB_CELL_M),
                row_stride=len(GRID_FIELDS) * cols, cell_stride=len(GRID_FIELDS),
                fields=fields, data=grid_data(grid))


def _robot_entity(mark: RobotMark, epoch_s: float) -> SceneEntity:
    rgba = _DEAD_RGBA if mark.dead else robot_colour(mark.robot)
    back_x, back_y = mark.x - 0.4 * math.cos(mark.yaw), mark.y - 0.4 * math.sin(mark.yaw)
    arrow = ArrowPrimitive(pose=_pose(back_x, back_y, 0.1, mark.yaw), shaft_length=0.5,
                           shaft_diameter=0.15, head_length=0.3, head_diameter=0.35,
                           color=_colour(rgba))
    label = TextPrimitive(pose=_pose(mark.x, mark.y, 0.8), billboard=True, font_size=14.0,
                          scale_invariant=True, color=_colour((1.0, 1.0, 1.0, 1.0)),
                          text=mark.label)
    path = LinePrimitive(type=LinePrimitiveLineType.LineStrip, pose=_pose(), thickness=0.08,
                         points=_points(mark.path, 0.05),
                         color=_colour(robot_colour(mark.robot, 0.8)))
    spheres = [SpherePrimitive(pose=_pose(mark.x, mark.y, 0.3),
                               size=Vector3(x=0.5, y=0.5, z=0.5), color=_colour(_MARK_RGBA))
               ] if mark.dead else []
    return SceneEntity(timestamp=timestamp(epoch_s), frame_id=FRAME, id=f"robot/{mark.robot}",
                       arrows=[arrow], texts=[label], lines=[path], spheres=spheres)


def robots(scene: Scene, epoch_s: float) -> SceneUpdate:
    return SceneUpdate(entities=[_robot_entity(m, epoch_s) for m in scene.robots])


def tree(scene: Scene, epoch_s: float) -> SceneUpdate:
    by_robot: dict[int, list[Point]] = {}
    for seg in scene.tree:
        by_robot.setdefault(seg.robot, []).extend((seg.a, seg.b))
    return SceneUpdate(entities=[
        SceneEntity(timestamp=timestamp(epoch_s), frame_id=FRAME, id=f"tree/{robot}",
                    lines=[LinePrimitive(type=LinePrimitiveLineType.LineList, pose=_pose(),
                                         thickness=0.12, points=_points(points, 0.02),
                                         color=_colour(robot_colour(robot)))])
        for robot, points in sorted(by_robot.items())])


def log(line: LogLine, epoch_s: float) -> Log:
    return Log(timestamp=timestamp(epoch_s), level=_LEVELS[line.level], message=line.text,
               name=f"mstc.{line.name}")
