"""``mstc export``: recordings of scripted missions as MCAP (read back with the mcap
package's reader, decoded with foxglove-schemas-protobuf) and rosbag2 (read back with
rosbags), compared with the recording and the fixture's brute-force truth."""

from __future__ import annotations

import json
import subprocess
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from foxglove_schemas_protobuf.Grid_pb2 import Grid
from foxglove_schemas_protobuf.Log_pb2 import Log
from mcap.reader import make_reader
from rosbags.interfaces import ConnectionExtRosbag2
from rosbags.rosbag2 import Reader
from test_monitor_fixtures import M, Mission, open_room, run_mission, two_robot_walks
from test_robotics_encoders import grid_field

from bus.messages import SCHEMA_VERSION
from deploy.cli import main
from deploy.monitor.model import FleetModel
from deploy.monitor.recorder import RecordWriter, parse_line, read_recording
from deploy.monitor.types import Header
from deploy.robotics import ros

STARTED = 1_795_317_553.5


def recorded(tmp_path: Path, mission: Mission) -> Path:
    path = tmp_path / "mission.jsonl"
    with RecordWriter(path, Header(M, STARTED, "monitor", SCHEMA_VERSION)) as writer:
        for record in mission.records:
            writer.write(record)
    return path


def truth_visits(mission: Mission) -> np.ndarray:
    visits = np.zeros(mission.free.shape, np.uint8)
    for cell, n in mission.visits().items():
        visits[cell] = n
    return visits


def model_events(mission: Mission) -> list[str]:
    model = FleetModel()
    return [e.text for r in mission.records for e in model.apply(r)]


def read_mcap(path: Path) -> tuple[dict[str, list[tuple[int, bytes]]], dict[str, str]]:
    """Messages per topic (log time, data) and each topic's schema name."""
    messages: dict[str, list[tuple[int, bytes]]] = {}
    schemas: dict[str, str] = {}
    with path.open("rb") as stream:
        reader = make_reader(stream)
        for schema, channel, message in reader.iter_messages(log_time_order=True):
            messages.setdefault(channel.topic, []).append((message.log_time, message.data))
            schemas[channel.topic] = schema.name if schema is not None else ""
    with path.open("rb") as stream:
        summary = make_reader(stream).get_summary()
    assert summary is not None and summary.statistics is not None
    counted = {summary.channels[c].topic: n
               for c, n in summary.statistics.channel_message_counts.items()}
    assert counted == {topic: len(ms) for topic, ms in messages.items()}
    return messages, schemas


@pytest.mark.parametrize("kill", [None, (1, 5)])
def test_mcap_holds_every_record_every_event_and_the_final_truth(
        tmp_path: Path, kill: tuple[int, int] | None, capsys: pytest.CaptureFixture[str]) -> None:
    mission = run_mission(open_room(), two_robot_walks(), kill=kill, taker=0)
    source, out = recorded(tmp_path, mission), tmp_path / "mission.mcap"
    assert main(["export", str(source), "--mcap", str(out)]) == 0
    assert f"{len(mission.records)} wire messages" in capsys.readouterr().out
    messages, schemas = read_mcap(out)
    assert schemas == {"/mstc/coverage": "foxglove.Grid", "/mstc/robots": "foxglove.SceneUpdate",
                       "/mstc/tree": "foxglove.SceneUpdate", "/mstc/events": "foxglove.Log",
                       "/map": "nav_msgs/msg/OccupancyGrid", "/mstc/wire": "mstc.Record"}
    wire = messages["/mstc/wire"]
    assert len(wire) == len(mission.records) == len(read_recording(source).records)
    assert [parse_line(data.decode()) for _, data in wire] == mission.records
    assert [t for t, _ in wire] == [round((STARTED + r.t) * 1e9) for r in mission.records]
    logs = [Log.FromString(data) for _, data in messages["/mstc/events"]]
    assert [log.message for log in logs] == model_events(mission)
    final = Grid.FromString(messages["/mstc/coverage"][-1][1])
    np.testing.assert_array_equal(grid_field(final, "visits"), truth_visits(mission))
    np.testing.assert_array_equal(grid_field(final, "owner"), mission.firsts()[0])
    occupancy = ros.decode(messages["/map"][-1][1], ros.MAP_TYPE)
    np.testing.assert_array_equal(occupancy.data.reshape(4, 8)[::-1],
                                  np.where(mission.free, 0, 100))
    times = [t for ms in messages.values() for t, _ in ms]
    assert min(times) >= round(STARTED * 1e9)
    assert max(times) <= round((STARTED + mission.records[-1].t) * 1e9)


def test_rosbag2_holds_the_same_channels_as_ros_types(tmp_path: Path) -> None:
    mission = run_mission(open_room(), two_robot_walks(), kill=(1, 5), taker=0)
    source, mcap, bag = recorded(tmp_path, mission), tmp_path / "m.mcap", tmp_path / "bag"
    assert main(["export", str(source), "--mcap", str(mcap), "--rosbag2", str(bag)]) == 0
    mcap_counts = Counter({t: len(ms) for t, ms in read_mcap(mcap)[0].items()})
    with Reader(bag) as reader:
        types = {c.topic: c.msgtype for c in reader.connections}
        counts = Counter({c.topic: c.msgcount for c in reader.connections})
        last: dict[str, bytes] = {}
        wire: list[str] = []
        for connection, _, data in reader.messages():
            last[connection.topic] = data
            if connection.topic == "/mstc/wire":
                wire.append(ros.decode(data, ros.STRING_TYPE).data)
    assert types == {"/map": ros.MAP_TYPE, "/mstc/coverage": ros.MAP_TYPE,
                     "/mstc/coverage_owner": ros.MAP_TYPE, "/mstc/robots": ros.MARKERS_TYPE,
                     "/mstc/tree": ros.MARKERS_TYPE, "/mstc/events": ros.LOG_TYPE,
                     "/mstc/wire": ros.STRING_TYPE}
    with Reader(bag) as reader:
        exts = {c.topic: c.ext for c in reader.connections}
    qos = {topic: ext.offered_qos_profiles for topic, ext in exts.items()
           if isinstance(ext, ConnectionExtRosbag2)}
    assert [(q.durability.name, q.depth) for q in qos["/map"]] == [("TRANSIENT_LOCAL", 1)]
    owners = counts.pop("/mstc/coverage_owner")
    assert counts == mcap_counts and owners == counts["/mstc/coverage"]
    assert [parse_line(line) for line in wire] == mission.records
    coverage = ros.decode(last["/mstc/coverage"], ros.MAP_TYPE).data.reshape(4, 8)[::-1]
    np.testing.assert_array_equal(coverage, truth_visits(mission))
    owner = ros.decode(last["/mstc/coverage_owner"], ros.MAP_TYPE).data.reshape(4, 8)[::-1]
    first = mission.firsts()[0].astype(np.int16)
    np.testing.assert_array_equal(owner, np.where(first == 255, -1, first))


def test_export_mistakes_are_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    source = recorded(tmp_path, run_mission(open_room(), two_robot_walks()))
    (tmp_path / "bag").mkdir()
    cases = [([str(source)], "nothing to write"),
             ([str(source), "--mcap", str(tmp_path / "no" / "x.mcap")], "does not exist"),
             ([str(source), "--rosbag2", str(tmp_path / "bag")], "already exists"),
             ([str(tmp_path / "none.jsonl"), "--mcap", str(tmp_path / "x.mcap")],
              "cannot read")]
    for argv, text in cases:
        assert main(["export", *argv]) == 2
        err = capsys.readouterr().err
        assert text in err and "Traceback" not in err and len(err.splitlines()) == 1, err


def test_wire_lines_are_json_records(tmp_path: Path) -> None:
    mission = run_mission(open_room(), two_robot_walks())
    out = tmp_path / "m.mcap"
    assert main(["export", str(recorded(tmp_path, mission)), "--mcap", str(out)]) == 0
    first = json.loads(read_mcap(out)[0]["/mstc/wire"][0][1])
    assert set(first) == {"t", "key", "via", "kind", "msg"}


@pytest.mark.integration
@pytest.mark.slow
def test_up_records_the_same_mcap_as_an_export_of_its_recording(tmp_path: Path) -> None:
    from conftest import pick_free_port
    from fleet_helpers import mstc

    jsonl, live, exported = tmp_path / "up.jsonl", tmp_path / "up.mcap", tmp_path / "x.mcap"
    up = subprocess.run(
        mstc("up", "-n", "3", "--world", "open-room", "--algo", "opt", "--time-scale", "0",
             "--plain", "--listen", f"tcp/127.0.0.1:{pick_free_port()}", "--run-dir",
             str(tmp_path / "run"), "--stall-timeout", "30", "--lease-ms", "5000",
             "--dead-after", "5", "--record", str(jsonl), "--record-mcap", str(live)),
        capture_output=True, text=True, timeout=240)
    assert up.returncode == 0, up.stdout + up.stderr
    assert main(["export", str(jsonl), "--mcap", str(exported)]) == 0
    recorded_live, schemas = read_mcap(live)
    from_file, _ = read_mcap(exported)
    assert schemas["/mstc/coverage"] == "foxglove.Grid"
    wire = [data for _, data in recorded_live["/mstc/wire"]]
    assert wire == [data for _, data in from_file["/mstc/wire"]]
    assert len(wire) == len(read_recording(jsonl).records) > 100
    assert {t: len(ms) for t, ms in recorded_live.items()} == \
        {t: len(ms) for t, ms in from_file.items()}
    final = Grid.FromString(recorded_live["/mstc/coverage"][-1][1])
    assert final.data == Grid.FromString(from_file["/mstc/coverage"][-1][1]).data
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert int((grid_field(final, "visits") > 0).sum()) == summary["covered"]
    events = [Log.FromString(d).message for _, d in recorded_live["/mstc/events"]]
    assert any(text.startswith("mission complete") for text in events)


def test_record_mcap_into_a_missing_directory_is_one_line(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["up", "-n", "2", "--world", "open-room", "--record-mcap",
                 str(tmp_path / "no" / "up.mcap")]) == 2
    err = capsys.readouterr().err
    assert "--record-mcap" in err and "does not exist" in err and len(err.splitlines()) == 1


def test_a_missing_extra_is_one_line(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                     capsys: pytest.CaptureFixture[str]) -> None:
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "rosbags" else real(name, *a))
    source = recorded(tmp_path, run_mission(open_room(), two_robot_walks()))
    assert main(["export", str(source), "--mcap", str(tmp_path / "x.mcap")]) == 2
    err = capsys.readouterr().err
    assert err == "mstc export: error: needs rosbags: pip install 'mstc-swarm[robotics]'\n"
