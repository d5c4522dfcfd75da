"""``mstc foxglove``: the Foxglove WebSocket bridge, read by a plain ``websockets`` client
that decodes with foxglove-schemas-protobuf. First on a scripted mission fed straight into
the bridge's screen (late and early viewers), then on a real ``mstc up`` fleet, where the
grid a viewer gets at the end must equal simhw's ground truth."""

from __future__ import annotations

import asyncio
import json
import socket
import subprocess
from pathlib import Path

import numpy as np
import pytest
from conftest import pick_free_port
from fleet_helpers import mstc
from foxglove_client import Received, watch
from foxglove_schemas_protobuf.Grid_pb2 import Grid
from foxglove_schemas_protobuf.Log_pb2 import Log
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from test_monitor_fixtures import open_room, run_mission, two_robot_walks
from test_robotics_encoders import grid_field
from waiting import wait_until

from deploy.monitor.app import Watcher
from deploy.monitor.model import FleetModel
from deploy.monitor.view import FeedStats
from deploy.robotics import ros
from deploy.robotics.bridge import FoxgloveScreen
from planner.maps import resolve_world

TOPICS = {"/mstc/coverage": ("foxglove.Grid", "protobuf", "protobuf"),
          "/mstc/robots": ("foxglove.SceneUpdate", "protobuf", "protobuf"),
          "/mstc/tree": ("foxglove.SceneUpdate", "protobuf", "protobuf"),
          "/mstc/events": ("foxglove.Log", "protobuf", "protobuf"),
          "/map": ("nav_msgs/msg/OccupancyGrid", "cdr", "ros2msg")}


def advertised(got: Received) -> dict[str, tuple[str, str, str]]:
    return {topic: (c["schemaName"], c["encoding"], c["schemaEncoding"])
            for topic, c in got.channels.items()}


def has_state(got: Received) -> bool:
    return all(got.last(t) is not None for t in ("/mstc/coverage", "/mstc/robots", "/map"))


async def refreshing(screen: FoxgloveScreen, model: FleetModel, stop: asyncio.Event) -> None:
    """The monitor loop's refreshes, four per second as in deploy.monitor.app."""
    while not stop.is_set():
        screen.refresh(model, FeedStats())
        await asyncio.sleep(0.05)


async def test_a_late_viewer_gets_the_current_state_and_an_early_one_the_events() -> None:
    mission = run_mission(open_room(), two_robot_walks(), kill=(1, 5), taker=0)
    screen = FoxgloveScreen("test", "127.0.0.1", 0)
    try:
        watcher = Watcher(screen)
        stop = asyncio.Event()
        async with asyncio.TaskGroup() as group:
            early = group.create_task(watch(screen.port, 2.0))
            await wait_until(lambda: screen.listener.subscriptions == len(TOPICS), 10.0,
                             "the early viewer's subscriptions")
            watcher.feed(mission.records)
            group.create_task(refreshing(screen, watcher.model, stop))
            late = await watch(screen.port, 5.0, until=has_state)
            stop.set()
        before = early.result()
    finally:
        screen.stop()
    for got in (late, before):
        assert advertised(got) == TOPICS
        assert got.server_info["name"] == "mstc test"
    grid = Grid.FromString(late.last("/mstc/coverage") or b"")
    visits = np.zeros((4, 8), np.uint8)
    for cell, n in mission.visits().items():
        visits[cell] = n
    np.testing.assert_array_equal(grid_field(grid, "visits"), visits)
    np.testing.assert_array_equal(grid_field(grid, "owner"), mission.firsts()[0])
    robots = SceneUpdate.FromString(late.last("/mstc/robots") or b"")
    assert sorted(e.id for e in robots.entities) == ["robot/0", "robot/1"]
    occupancy = ros.decode(late.last("/map") or b"", ros.MAP_TYPE)
    assert (occupancy.info.width, occupancy.info.height) == (8, 4)
    # Events are sent as they happen: the early viewer has them all, in order.
    texts = [Log.FromString(data).message for _, data in before.messages["/mstc/events"]]
    assert texts == [e.text for e in watcher.model.events]


def cover_truth(recording: Path, shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Visits and first visitors per sub-cell from simhw's own CoverEvents (ground truth
    published by the simulator, recorded by `mstc up --record`)."""
    visits = np.zeros(shape, np.uint8)
    owner = np.full(shape, 255, np.uint8)
    for line in recording.read_text().splitlines()[1:]:
        entry = json.loads(line)
        if entry["kind"] != "cover":
            continue
        (r, c), n = entry["msg"]["cell"], entry["msg"]["visits"]
        visits[r, c] = max(visits[r, c], n)
        if n == 1:
            owner[r, c] = entry["msg"]["robot"]
    return visits, owner


@pytest.mark.integration
@pytest.mark.slow
async def test_a_viewer_sees_a_real_mission_end_in_simhws_ground_truth(
        router: str, tmp_path: Path) -> None:
    port, mission, record = pick_free_port(), "fox-e2e", tmp_path / "up.jsonl"
    free = resolve_world("open-room").free
    common = ("--connect", router, "--mission", mission)
    bridge = await asyncio.create_subprocess_exec(
        *mstc("foxglove", "--port", str(port), "--world-period", "0.5", *common),
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        assert bridge.stderr is not None
        line = await asyncio.wait_for(bridge.stderr.readline(), 60)
        assert f"ws://127.0.0.1:{port}" in line.decode(), line
        async with asyncio.TaskGroup() as group:
            during = group.create_task(watch(port, 90.0, until=lambda got: any(
                "mission complete" in Log.FromString(d).message
                for _, d in got.messages.get("/mstc/events", ()))))
            up = await asyncio.create_subprocess_exec(
                *mstc("up", "-n", "3", "--world", "open-room", "--algo", "opt",
                      "--time-scale", "0", "--plain", "--run-dir", str(tmp_path / "run"),
                      "--record", str(record), "--stall-timeout", "30", "--lease-ms", "5000",
                      "--dead-after", "5", *common),
                stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
            out, _ = await asyncio.wait_for(up.communicate(), 120)
            assert up.returncode == 0, out.decode()
        early = during.result()
        truth_visits, truth_owner = cover_truth(record, free.shape)

        def final(got: Received) -> bool:
            data = got.last("/mstc/coverage")
            return has_state(got) and data is not None and np.array_equal(
                grid_field(Grid.FromString(data), "visits"), truth_visits)

        # A late viewer; the bridge may still be merging the mission's last messages.
        late = await watch(port, 30.0, until=final)
    finally:
        bridge.terminate()
        await asyncio.wait_for(bridge.wait(), 30)
    assert bridge.returncode in (0, -15)
    assert advertised(late) == TOPICS
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    grid = Grid.FromString(late.last("/mstc/coverage") or b"")
    visits, owner = grid_field(grid, "visits"), grid_field(grid, "owner")
    np.testing.assert_array_equal(grid_field(grid, "free"), free.astype(np.uint8))
    np.testing.assert_array_equal(visits, truth_visits)
    np.testing.assert_array_equal(owner, truth_owner)
    assert int((visits > 0).sum()) == summary["covered"] == summary["reachable"]
    assert int(visits.sum()) == summary["total_moves"] + summary["robots"]
    assert set(owner[owner != 255].tolist()) == {0, 1, 2}
    # The viewer connected from the start saw the coverage grow, not just its end.
    assert len(early.messages["/mstc/coverage"]) >= 2
    robots = SceneUpdate.FromString(late.last("/mstc/robots") or b"")
    assert sorted(e.id for e in robots.entities) == ["robot/0", "robot/1", "robot/2"]


def test_a_port_in_use_is_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    from deploy.cli import main

    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        assert main(["foxglove", "--port", str(port), "--connect", "tcp/127.0.0.1:9",
                     "--mission", "x"]) == 2
    err = capsys.readouterr().err
    assert f"cannot serve on 127.0.0.1:{port}" in err and len(err.splitlines()) == 1, err
