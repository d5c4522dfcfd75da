"""The channels a robotics viewer gets, and when each is sent.

``SceneStream`` decides what to send: the state channels (map, coverage, robots, tree) each
time they changed, or all of them when forced (a viewer subscribed and must see the current
state at once), the events as they happen. ``FoxgloveSink`` sends to foxglove-sdk channels
of one context, so the same code feeds the WebSocket server (``mstc foxglove``) and an MCAP
file (``mstc export``, ``mstc up --record-mcap``); the rosbag2 sink is in
``deploy.robotics.export``.
"""

from __future__ import annotations

from typing import Protocol

import foxglove
from foxglove.channels import GridChannel, LogChannel, SceneUpdateChannel

from deploy.robotics import fox, ros
from deploy.robotics.scene import GridLayers, LogLine, Scene

COVERAGE = "/mstc/coverage"
ROBOTS = "/mstc/robots"
TREE = "/mstc/tree"
EVENTS = "/mstc/events"
MAP = "/map"
WIRE = "/mstc/wire"  # every recorded message as its JSON line (files only)


def log_time(epoch_s: float) -> int:
    return round(epoch_s * 1e9)


class Sink(Protocol):
    """Where a SceneStream's messages go; times are Unix seconds."""

    def map(self, grid: GridLayers, epoch_s: float) -> None: ...

    def coverage(self, grid: GridLayers, epoch_s: float) -> None: ...

    def robots(self, scene: Scene, epoch_s: float) -> None: ...

    def tree(self, scene: Scene, epoch_s: float) -> None: ...

    def event(self, line: LogLine, epoch_s: float) -> None: ...


class SceneStream:
    """Sends each state channel when it changed; ``epoch_s`` is the Unix time of t = 0."""

    def __init__(self, sinks: list[Sink], epoch_s: float) -> None:
        self.sinks = sinks
        self.epoch_s = epoch_s
        self.sent: dict[str, int] = {"map": 0, "coverage": 0, "robots": 0, "tree": 0,
                                     "events": 0}
        self._last: dict[str, object] = {}

    def _changed(self, name: str, key: object, force: bool) -> bool:
        if not force and self._last.get(name) == key:
            return False
        self._last[name] = key
        self.sent[name] += 1
        return True

    def events(self, lines: list[LogLine]) -> None:
        for line in lines:
            self.sent["events"] += 1
            for sink in self.sinks:
                sink.event(line, self.epoch_s + line.t)

    def scene(self, scene: Scene, *, force: bool = False) -> None:
        at = self.epoch_s + scene.t
        grid = scene.grid
        if grid is not None:
            if self._changed("map", (grid.shape, grid.free.tobytes()), force):
                for sink in self.sinks:
                    sink.map(grid, at)
            if self._changed("coverage", (grid.shape, fox.grid_data(grid)), force):
                for sink in self.sinks:
                    sink.coverage(grid, at)
        if self._changed("robots", scene.robots, force):
            for sink in self.sinks:
                sink.robots(scene, at)
        if self._changed("tree", scene.tree, force):
            for sink in self.sinks:
                sink.tree(scene, at)


class FoxgloveSink:
    """The channels on one foxglove-sdk context (None: the SDK's global context)."""

    def __init__(self, context: foxglove.Context | None, mission: str) -> None:
        meta = {"mission": mission}
        self.coverage_channel = GridChannel(COVERAGE, metadata=meta, context=context)
        self.robots_channel = SceneUpdateChannel(ROBOTS, metadata=meta, context=context)
        self.tree_channel = SceneUpdateChannel(TREE, metadata=meta, context=context)
        self.events_channel = LogChannel(EVENTS, metadata=meta, context=context)
        self.map_channel = foxglove.Channel(
            MAP, schema=foxglove.Schema(name=ros.MAP_TYPE, encoding="ros2msg",
                                        data=ros.msgdef(ros.MAP_TYPE).encode()),
            message_encoding="cdr", metadata=meta, context=context)

    def map(self, grid: GridLayers, epoch_s: float) -> None:
        self.map_channel.log(ros.map_grid(grid, epoch_s), log_time=log_time(epoch_s))

    def coverage(self, grid: GridLayers, epoch_s: float) -> None:
        self.coverage_channel.log(fox.coverage(grid, epoch_s), log_time=log_time(epoch_s))

    def robots(self, scene: Scene, epoch_s: float) -> None:
        self.robots_channel.log(fox.robots(scene, epoch_s), log_time=log_time(epoch_s))

    def tree(self, scene: Scene, epoch_s: float) -> None:
        self.tree_channel.log(fox.tree(scene, epoch_s), log_time=log_time(epoch_s))

    def event(self, line: LogLine, epoch_s: float) -> None:
        self.events_channel.log(fox.log(line, epoch_s), log_time=log_time(epoch_s))

    def close(self) -> None:
        for channel in (self.coverage_channel, self.robots_channel, self.tree_channel,
                        self.events_channel, self.map_channel):
            channel.close()
