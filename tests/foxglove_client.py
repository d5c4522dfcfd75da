"""A minimal Foxglove WebSocket client for the tests: the ``websockets`` package speaking the
SDK's subprotocol by hand (JSON control messages, binary message data), so the bridge is
checked by a client that shares no code with it."""

from __future__ import annotations

import asyncio
import json
import struct
import time
from dataclasses import dataclass, field
from typing import Any

import websockets
from websockets.typing import Subprotocol

SUBPROTOCOL = "foxglove.sdk.v1"
MESSAGE_DATA = 0x01  # binary opcode: subscription id (u32), log time (u64), payload


@dataclass
class Received:
    server_info: dict[str, Any] = field(default_factory=dict)
    channels: dict[str, dict[str, Any]] = field(default_factory=dict)  # topic -> advertised
    messages: dict[str, list[tuple[int, bytes]]] = field(default_factory=dict)

    def last(self, topic: str) -> bytes | None:
        got = self.messages.get(topic)
        return got[-1][1] if got else None


async def watch(port: int, seconds: float, *, until: Any = None) -> Received:
    """Connect, subscribe to every advertised channel and collect messages for ``seconds``
    (or until ``until(received)`` is true)."""
    got = Received()
    topics: dict[int, str] = {}
    deadline = time.monotonic() + seconds
    async with websockets.connect(f"ws://127.0.0.1:{port}", subprotocols=[Subprotocol(SUBPROTOCOL)],
                                  max_size=None) as ws:
        assert ws.subprotocol == SUBPROTOCOL
        while (left := deadline - time.monotonic()) > 0:
            try:
                raw = await asyncio.wait_for(ws.recv(), left)
            except TimeoutError:
                break
            if isinstance(raw, str):
                message = json.loads(raw)
                if message["op"] == "serverInfo":
                    got.server_info = message
                elif message["op"] == "advertise":
                    fresh = [c for c in message["channels"] if c["id"] not in topics]
                    for channel in fresh:
                        topics[channel["id"]] = channel["topic"]
                        got.channels[channel["topic"]] = channel
                    await ws.send(json.dumps({"op": "subscribe", "subscriptions": [
                        {"id": c["id"], "channelId": c["id"]} for c in fresh]}))
                continue
            opcode, subscription, log_time = struct.unpack_from("<BIQ", raw)
            if opcode == MESSAGE_DATA:
                got.messages.setdefault(topics[subscription], []).append(
                    (log_time, bytes(raw[13:])))
                if until is not None and until(got):
                    break
    return got
