"""``mstc foxglove``'s screen: the monitor's live loop drawing into a Foxglove WebSocket
server (foxglove-sdk) instead of a terminal.

The monitor's Watcher feeds the fleet model from the wire and calls the screen on every
event and every refresh (4 per second); the screen sends the state channels that changed.
A viewer that subscribes gets every state channel at the next refresh even if nothing
changed (the SDK keeps no latest message per channel), so a viewer connecting late, or after
the mission ended, sees the current state at once.
"""

from __future__ import annotations

import threading
import time
from typing import Any

import foxglove
from foxglove.websocket import ChannelView, Client, ServerListener, WebSocketServer

from deploy.monitor.model import FleetModel
from deploy.monitor.types import MonitorEvent
from deploy.monitor.view import FeedStats
from deploy.robotics.channels import FoxgloveSink, SceneStream
from deploy.robotics.scene import log_lines, scene

SERVER_NAME = "mstc"


class _Subscriptions(ServerListener):
    """foxglove-sdk's listener: calls arrive on the server's threads, so they only raise a
    flag the screen reads on the monitor's loop."""

    def __init__(self) -> None:
        self.resend = threading.Event()
        self.clients: set[int] = set()
        self.subscriptions = 0

    def on_subscribe(self, client: Client, channel: ChannelView) -> None:
        self.clients.add(client.id)
        self.subscriptions += 1
        self.resend.set()


class FoxgloveScreen:
    """A monitor screen serving the mission on ``host:port`` (port 0: any free port)."""

    def __init__(self, mission: str, host: str, port: int) -> None:
        self.context = foxglove.Context()
        self.listener = _Subscriptions()
        self.server: WebSocketServer = foxglove.start_server(
            name=f"{SERVER_NAME} {mission}", host=host, port=port, context=self.context,
            server_listener=self.listener)
        self.sink = FoxgloveSink(self.context, mission)
        # The model's times count from the feed's start, a moment after this.
        self.stream = SceneStream([self.sink], time.time())

    @property
    def port(self) -> int:
        return self.server.port

    def events(self, events: list[MonitorEvent]) -> None:
        self.stream.events(log_lines(events))

    def refresh(self, model: FleetModel, stats: FeedStats) -> None:
        force = self.listener.resend.is_set()
        self.listener.resend.clear()
        self.stream.scene(scene(model), force=force)

    def close(self, model: FleetModel, stats: FeedStats) -> None:
        self.refresh(model, stats)

    def stop(self) -> None:
        self.sink.close()
        self.server.stop()

    def info(self) -> dict[str, Any]:
        return {"port": self.port, "clients": len(self.listener.clients),
                "sent": dict(self.stream.sent)}
