"""Re-learnable state: what a process must not lose to a late joiner or a router restart.

Zenoh's reliability is hop-by-hop: whatever is published while the router is down is lost,
and a process that joins late never heard the past. An Announcer keeps a process's current
state messages (its status, its latest events, known deaths, ...), re-publishes them every
``period`` seconds on their own keys, and answers queries on one state key with all of them.
"""

from __future__ import annotations

import asyncio
from typing import Any

from bus.bridge import Bus


class Announcer:
    """Holds ``key -> message`` for one process; ``await run()`` inside a TaskGroup."""

    def __init__(self, bus: Bus, query_key: str, *, period: float = 1.0) -> None:
        if period <= 0:
            raise ValueError("Announcer period must be positive")
        self.bus = bus
        self.query_key = query_key
        self.period = period
        self._state: dict[str, Any] = {}
        self._quiet: set[str] = set()

    def set(self, key: str, msg: Any, *, publish: bool = True) -> None:
        """Remember ``msg`` as the current message on ``key`` (and publish it now); it is
        re-published each period again if it was :meth:`quiet`."""
        self._state[key] = msg
        self._quiet.discard(key)
        if publish:
            self.bus.publish(key, msg)

    def quiet(self, key: str) -> None:
        """Stop re-publishing the message held on ``key``; queries are still answered with
        it (for a message those who still need it pull, and the others no longer do)."""
        if key in self._state:
            self._quiet.add(key)

    def remove(self, key: str) -> None:
        self._state.pop(key, None)
        self._quiet.discard(key)

    def messages(self) -> list[Any]:
        return list(self._state.values())

    def repeats(self, key: str) -> bool:
        """Whether the message held on ``key`` is re-published each period (it is answered
        to queries either way): every one not made :meth:`quiet`; a subclass may hold more
        back."""
        return key not in self._quiet

    def announce(self) -> None:
        """Publish every held message that :meth:`repeats` once more."""
        for key, msg in list(self._state.items()):
            if self.repeats(key):
                self.bus.publish(key, msg)

    async def run(self) -> None:
        """Serve the state queryable and re-announce periodically until cancelled."""
        handle = self.bus.declare_queryable(self.query_key, lambda _request: self.messages())
        try:
            while True:
                await asyncio.sleep(self.period)
                self.announce()
        finally:
            handle.close()
