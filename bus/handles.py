"""Loop-side handles of Zenoh declarations: liveliness watches and queryables (the bridge's
pattern: their samples and queries reach them through bus.handoff, which only queues them;
callbacks, responders and replies run on the event loop). ``bus.bridge.Bus`` declares
them."""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Callable
from typing import Any

import zenoh

from bus import keys
from bus.drops import DropCounter
from bus.inbox import BoundedFifo, Inbox

_log = logging.getLogger("mstc.bus")


class LivelinessWatch:
    """Calls ``on_put(key)`` / ``on_delete(key)`` on the loop for matching tokens, starting
    with the tokens that already exist (Zenoh's liveliness history)."""

    def __init__(self, loop: asyncio.AbstractEventLoop, drops: DropCounter, key: str,
                 on_put: Callable[[str], None], on_delete: Callable[[str], None]) -> None:
        self.key = key
        self._on_put = on_put
        self._on_delete = on_delete
        self._inbox: Inbox[bool] = Inbox(
            loop, BoundedFifo(65536), self._on_wake,
            lambda k: drops.count(keys.kind_of(k), "overflow", "liveliness backlog"))
        self._zenoh: zenoh.Subscriber[None] | None = None

    def _on_sample(self, sample: zenoh.Sample) -> None:
        self._inbox.push(str(sample.key_expr), sample.kind == zenoh.SampleKind.PUT)

    def _on_wake(self) -> None:
        while (item := self._inbox.pop()) is not None:
            key, is_put = item
            try:
                (self._on_put if is_put else self._on_delete)(key)
            except Exception:  # noqa: BLE001 - one bad callback must not hide later changes
                _log.exception("liveliness callback failed for %s", key)

    def close(self) -> None:
        self._inbox.close()
        if self._zenoh is not None:
            self._zenoh.undeclare()
            self._zenoh = None


Responder = Callable[[Any], Any]


class QueryableHandle:
    """A declared queryable; replies are computed on the loop by the responder."""

    def __init__(self, loop: asyncio.AbstractEventLoop, drops: DropCounter, key: str,
                 max_queue: int, answer: Callable[[zenoh.Query], None]) -> None:
        self.key = key
        self._answer = answer
        self._inbox: Inbox[zenoh.Query] = Inbox(
            loop, BoundedFifo(max_queue), self._on_wake,
            lambda k: drops.count(keys.kind_of(k), "overflow", "query backlog"))
        self._zenoh: zenoh.Queryable[None] | None = None

    def _on_query(self, query: zenoh.Query) -> None:
        self._inbox.push(str(query.key_expr), query)

    def _on_wake(self) -> None:
        while (item := self._inbox.pop()) is not None:
            self._answer(item[1])

    def close(self) -> None:
        self._inbox.close()
        if self._zenoh is not None:
            self._zenoh.undeclare()
            self._zenoh = None
