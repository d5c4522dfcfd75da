"""The robotics encoders against scripted missions: Foxglove messages decoded with the
independent foxglove-schemas-protobuf classes, ROS 2 messages decoded back from CDR, and
both compared with the fixture's brute-force truth (visits, first visitors, walks)."""

from __future__ import annotations

import math

import numpy as np
from foxglove_schemas_protobuf.Grid_pb2 import Grid
from foxglove_schemas_protobuf.Log_pb2 import Log
from foxglove_schemas_protobuf.PackedElementField_pb2 import PackedElementField
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from test_monitor_fixtures import Mission, open_room, run_mission, snake, two_robot_walks

from deploy.monitor.model import FleetModel
from deploy.monitor.types import MonitorEvent
from deploy.robotics import fox, ros
from deploy.robotics.scene import (
    Scene,
    heading_yaw,
    log_lines,
    scene,
    sub_cell_centre,
)

EPOCH = 1_795_000_000.25


def replayed(mission: Mission) -> tuple[FleetModel, list[MonitorEvent]]:
    model, events = FleetModel(), []
    for record in mission.records:
        events += model.apply(record)
    return model, events


def killed_mission() -> Mission:
    return run_mission(open_room(), two_robot_walks(), kill=(1, 5), taker=0)


def grid_field(grid: Grid, name: str) -> np.ndarray:
    """One uint8 field of a decoded foxglove.Grid as an array in the map's row order."""
    field = next(f for f in grid.fields if f.name == name)
    assert field.type == PackedElementField.UINT8
    rows = len(grid.data) // grid.row_stride
    raw = np.frombuffer(grid.data, np.uint8).reshape(rows, grid.row_stride)
    return raw[:, field.offset::grid.cell_stride][::-1]  # Grid row 0 is the map's bottom


def test_coverage_grid_holds_visits_owners_and_the_map() -> None:
    mission = killed_mission()
    model, _ = replayed(mission)
    picture = scene(model)
    assert picture.grid is not None
    grid = Grid.FromString(fox.coverage(picture.grid, EPOCH).encode())
    truth = mission.world()
    first, _ = mission.firsts()
    expected_visits = np.zeros(mission.free.shape, np.uint8)
    for cell, n in mission.visits().items():
        expected_visits[cell] = n
    assert grid.column_count == 8 and grid.frame_id == "map"
    assert (grid.cell_size.x, grid.cell_size.y) == (1.0, 1.0)
    assert (grid.timestamp.seconds, grid.timestamp.nanos) == (1_795_000_000, 250_000_000)
    np.testing.assert_array_equal(grid_field(grid, "visits"), expected_visits)
    np.testing.assert_array_equal(grid_field(grid, "owner"), first)
    np.testing.assert_array_equal(grid_field(grid, "free"), mission.free.astype(np.uint8))
    assert truth.shape == (4, 8)


def test_robots_scene_has_arrows_labels_paths_and_marks_the_dead() -> None:
    mission = killed_mission()
    model, _ = replayed(mission)
    update = SceneUpdate.FromString(fox.robots(scene(model), EPOCH).encode())
    by_id = {e.id: e for e in update.entities}
    assert set(by_id) == {"robot/0", "robot/1"}
    for robot, walk in mission.walks.items():
        entity = by_id[f"robot/{robot}"]
        path = [(round(p.x, 6), round(p.y, 6)) for p in entity.lines[0].points]
        assert path == [sub_cell_centre(cell, 4) for cell in walk]
        assert entity.texts[0].text.startswith(f"{robot} ")
        assert len(entity.arrows) == 1
        # The arrow's quaternion turns +x to the pose's heading (the fixture's poses face E).
        q = entity.arrows[0].pose.orientation
        assert math.isclose(2 * math.atan2(q.z, q.w), heading_yaw(1), abs_tol=1e-9)
    assert "dead" in by_id["robot/1"].texts[0].text and len(by_id["robot/1"].spheres) == 1
    assert not by_id["robot/0"].spheres
    dead, alive = by_id["robot/1"].arrows[0].color, by_id["robot/0"].arrows[0].color
    assert (dead.r, dead.g, dead.b) == (dead.r, dead.r, dead.r) and alive.g != alive.r


def test_tree_scene_has_one_line_list_per_robot_joining_cell_centres() -> None:
    model, _ = replayed(run_mission(open_room(), two_robot_walks()))
    update = SceneUpdate.FromString(fox.tree(scene(model), EPOCH).encode())
    edges = {}
    for entity in update.entities:
        points = [(p.x, p.y) for p in entity.lines[0].points]
        robot = int(entity.id.split("/")[1])
        edges.update({(points[i], points[i + 1]): robot for i in range(0, len(points), 2)})
    # Cell (R, C) has its centre at x = 2C + 1, y = rows - 2R - 1 (rows = 4 sub-cells).
    expected = {((2 * a[1] + 1.0, 3.0 - 2 * a[0]), (2 * b[1] + 1.0, 3.0 - 2 * b[0])): robot
                for (a, b), robot in model.edges.items()}
    assert edges == expected and expected


def test_events_become_logs_with_levels() -> None:
    _, events = replayed(killed_mission())
    lines = log_lines(events)
    assert [line.text for line in lines] == [e.text for e in events]
    logs = [Log.FromString(fox.log(line, EPOCH + line.t).encode()) for line in lines]
    levels = {e.kind: log.level for e, log in zip(events, logs, strict=True)}
    assert levels["died"] == Log.WARNING and levels["joined"] == Log.INFO
    assert all(log.name.startswith("mstc.") for log in logs)


def test_ros_occupancy_grids_round_trip() -> None:
    free = open_room(4, 6)
    free[1, 2] = False
    walks = {0: [c for c in snake(range(4), range(6)) if c != (1, 2)]}
    mission = run_mission(free, walks)
    model, _ = replayed(mission)
    grid = scene(model).grid
    assert grid is not None
    occupancy = ros.decode(ros.map_grid(grid, EPOCH), ros.MAP_TYPE)
    assert (occupancy.info.width, occupancy.info.height) == (6, 4)
    assert occupancy.header.frame_id == "map"
    assert (occupancy.header.stamp.sec, occupancy.header.stamp.nanosec) == \
        (1_795_000_000, 250_000_000)
    cells = occupancy.data.reshape(4, 6)[::-1]
    np.testing.assert_array_equal(cells, np.where(free, 0, 100))
    coverage = ros.decode(ros.coverage_grid(grid, EPOCH), ros.MAP_TYPE).data.reshape(4, 6)
    assert coverage[::-1][1, 2] == -1 and (coverage[::-1][free] == 1).all()
    owners = ros.decode(ros.owner_grid(grid, EPOCH), ros.MAP_TYPE).data.reshape(4, 6)[::-1]
    assert (owners[free] == 0).all() and owners[1, 2] == -1


def test_ros_markers_and_log_round_trip() -> None:
    model, events = replayed(killed_mission())
    picture: Scene = scene(model)
    markers = ros.decode(ros.robot_markers(picture, EPOCH), ros.MARKERS_TYPE).markers
    kinds = {(m.ns, m.id): m for m in markers}
    assert set(kinds) == {("robot", 0), ("label", 0), ("path", 0), ("robot", 1),
                          ("label", 1), ("path", 1), ("dead", 1)}
    assert len(kinds[("path", 0)].points) == len(picture.robots[0].path)
    assert "dead" in kinds[("label", 1)].text
    tree = ros.decode(ros.tree_markers(picture, EPOCH), ros.MARKERS_TYPE).markers
    assert sum(len(m.points) for m in tree) == 2 * len(picture.tree)
    line = log_lines(events)[0]
    log = ros.decode(ros.log_message(line, EPOCH), ros.LOG_TYPE)
    assert (log.msg, log.level, log.name) == (line.text, 20, f"mstc.{line.name}")


