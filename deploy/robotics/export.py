"""A recording as MCAP (foxglove-sdk's writer) and as a rosbag2 directory (rosbags' writer).

The recording is replayed into the monitor's fleet model; each tracker event becomes one
log message at its time, the state channels are sampled every ``period`` seconds of
recording time (only those that changed) and once more at the end, and every record is
also kept verbatim on ``/mstc/wire`` (its JSON line), so the files hold exactly as many wire
messages as the recording.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import foxglove
from rosbags.interfaces import (
    Qos,
    QosDurability,
    QosHistory,
    QosLiveliness,
    QosReliability,
    QosTime,
)
from rosbags.rosbag2 import Writer
from rosbags.rosbag2.errors import WriterError

from deploy.errors import UsageError
from deploy.monitor.model import FleetModel
from deploy.monitor.recorder import record_line
from deploy.monitor.types import Record, Recording
from deploy.robotics import ros
from deploy.robotics.channels import (
    COVERAGE,
    EVENTS,
    MAP,
    ROBOTS,
    TREE,
    WIRE,
    FoxgloveSink,
    SceneStream,
    Sink,
    log_time,
)
from deploy.robotics.scene import GridLayers, LogLine, Scene, log_lines, scene

PERIOD_S = 0.1
COVERAGE_OWNERS = "/mstc/coverage_owner"  # rosbag2 only: Grid's owner field as its own grid
# The recording's line format (docs/protocol.md, "Recording schema") as a JSON schema.
WIRE_SCHEMA = {"title": "mstc.Record", "type": "object",
               "required": ["t", "key", "via", "kind", "msg"],
               "properties": {"t": {"type": "number"}, "key": {"type": "string"},
                              "via": {"enum": ["sub", "query", "token"]},
                              "kind": {"type": "string"}, "msg": {"type": "object"}}}
ROSBAG_VERSION: Literal[8, 9] = 8  # rosbag2's metadata version of Iron; later ROS 2 reads it
_FOREVER = QosTime(sec=0, nsec=0)  # rosbag2's "default" duration
# The map as a latched topic: `ros2 bag play` then offers it to late subscribers (RViz).
MAP_QOS = Qos(history=QosHistory.KEEP_LAST, depth=1, reliability=QosReliability.RELIABLE,
              durability=QosDurability.TRANSIENT_LOCAL, deadline=_FOREVER, lifespan=_FOREVER,
              liveliness=QosLiveliness.AUTOMATIC, liveliness_lease_duration=_FOREVER,
              avoid_ros_namespace_conventions=False)


@dataclass(frozen=True)
class ExportCounts:
    records: int
    sent: dict[str, int]


class McapFile:
    """The Foxglove channels written to one MCAP file."""

    def __init__(self, path: Path, mission: str) -> None:
        self.context = foxglove.Context()
        try:
            self.writer = foxglove.open_mcap(path, allow_overwrite=True, context=self.context)
        except (OSError, RuntimeError, ValueError) as error:
            raise UsageError(f"cannot write {path}: {error}") from error
        self.sink = FoxgloveSink(self.context, mission)
        self.wire_channel = foxglove.Channel(WIRE, schema=WIRE_SCHEMA, context=self.context)

    def wire(self, line: str, epoch_s: float) -> None:
        self.wire_channel.log(line.encode(), log_time=log_time(epoch_s))

    def close(self) -> None:
        self.writer.close()


class RosbagSink:
    """The same channels as ROS 2 messages in a rosbag2 directory (see deploy.robotics.ros)."""

    def __init__(self, path: Path) -> None:
        if path.exists():
            raise UsageError(f"--rosbag2 {path}: already exists (rosbag2 writes a new "
                             f"directory)")
        self.writer = Writer(path, version=ROSBAG_VERSION)
        store = ros.typestore()
        try:
            self.writer.open()
        except WriterError as error:
            raise UsageError(f"cannot write {path}: {error}") from error
        add = self.writer.add_connection
        self.topics = {
            MAP: add(MAP, ros.MAP_TYPE, typestore=store, offered_qos_profiles=(MAP_QOS,)),
            COVERAGE: add(COVERAGE, ros.MAP_TYPE, typestore=store),
            COVERAGE_OWNERS: add(COVERAGE_OWNERS, ros.MAP_TYPE, typestore=store),
            ROBOTS: add(ROBOTS, ros.MARKERS_TYPE, typestore=store),
            TREE: add(TREE, ros.MARKERS_TYPE, typestore=store),
            EVENTS: add(EVENTS, ros.LOG_TYPE, typestore=store),
            WIRE: add(WIRE, ros.STRING_TYPE, typestore=store),
        }

    def _write(self, topic: str, epoch_s: float, data: bytes) -> None:
        self.writer.write(self.topics[topic], log_time(epoch_s), data)

    def map(self, grid: GridLayers, epoch_s: float) -> None:
        self._write(MAP, epoch_s, ros.map_grid(grid, epoch_s))

    def coverage(self, grid: GridLayers, epoch_s: float) -> None:
        self._write(COVERAGE, epoch_s, ros.coverage_grid(grid, epoch_s))
        self._write(COVERAGE_OWNERS, epoch_s, ros.owner_grid(grid, epoch_s))

    def robots(self, scene: Scene, epoch_s: float) -> None:
        self._write(ROBOTS, epoch_s, ros.robot_markers(scene, epoch_s))

    def tree(self, scene: Scene, epoch_s: float) -> None:
        self._write(TREE, epoch_s, ros.tree_markers(scene, epoch_s))

    def event(self, line: LogLine, epoch_s: float) -> None:
        self._write(EVENTS, epoch_s, ros.log_message(line, epoch_s))

    def wire(self, line: str, epoch_s: float) -> None:
        self._write(WIRE, epoch_s, ros.string_message(line))

    def close(self) -> None:
        self.writer.close()


class Exporter:
    """Feeds records into a model and the model's picture into MCAP and/or rosbag2 files;
    usable as a recorder beside a live mission (``mstc up --record-mcap``) as well."""

    def __init__(self, mission: str, epoch_s: float, *, mcap: Path | None = None,
                 rosbag2: Path | None = None, period: float = PERIOD_S,
                 model: FleetModel | None = None) -> None:
        self.model = model or FleetModel()
        self.period = period
        self.records = 0
        self._mcap = McapFile(mcap, mission) if mcap is not None else None
        try:
            self._bag = RosbagSink(rosbag2) if rosbag2 is not None else None
        except UsageError:
            if self._mcap is not None:
                self._mcap.close()
            raise
        sinks: list[Sink] = [s for s in (self._mcap and self._mcap.sink, self._bag) if s]
        self.stream = SceneStream(sinks, epoch_s)
        self._sampled: float | None = None
        self.open = True

    def feed(self, record: Record) -> None:
        events = self.model.apply(record)
        self.wire(record)
        self.stream.events(log_lines(events))
        if self._sampled is None or record.t - self._sampled >= self.period:
            self._sampled = record.t
            self.stream.scene(scene(self.model))

    def wire(self, record: Record) -> None:
        """Keep ``record`` verbatim (already applied to the model by the caller)."""
        self.records += 1
        line, at = record_line(record), self.stream.epoch_s + record.t
        for sink in (self._mcap, self._bag):
            if sink is not None:
                sink.wire(line, at)

    def close(self) -> ExportCounts:
        self.open = False
        self.stream.scene(scene(self.model))
        for sink in (self._mcap, self._bag):
            if sink is not None:
                sink.close()
        return ExportCounts(self.records, dict(self.stream.sent))


class McapRecorder:
    """A live recorder writing MCAP (``mstc up --record-mcap``): the same interface as the
    JSON Lines RecordWriter (write, flush, close), fed with every record the monitor's feed
    receives, and the same file as ``mstc export`` of that mission's recording."""

    def __init__(self, path: Path, mission: str, epoch_s: float) -> None:
        self.path = path
        self.exporter = Exporter(mission, epoch_s, mcap=path)

    @property
    def lines(self) -> int:
        return self.exporter.records

    def write(self, record: Record) -> None:
        self.exporter.feed(record)

    def flush(self) -> None:
        return None  # foxglove-sdk's writer flushes its chunks itself

    def close(self) -> None:
        if self.exporter.open:
            self.exporter.close()


def export(recording: Recording, *, mcap: Path | None = None, rosbag2: Path | None = None,
           period: float = PERIOD_S) -> ExportCounts:
    """Write ``recording`` to the files asked for; the counts of what was written."""
    exporter = Exporter(recording.header.mission, recording.header.started, mcap=mcap,
                        rosbag2=rosbag2, period=period)
    for record in recording.records:
        exporter.feed(record)
    return exporter.close()
