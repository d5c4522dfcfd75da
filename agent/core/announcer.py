"""The one state announcer of every agent: bus.announce.Announcer (status, known deaths, the
mission verdict, re-published every announce period), plus, for agents that have some, the
robot's own knowledge (AgentState) in every reply to a state query."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from bus.announce import Announcer
from bus.bridge import Bus
from bus.messages import AgentState


class StateAnnouncer(Announcer):
    """Announcer on the robot's state key; ``state`` (if any) is asked at each query."""

    def __init__(self, bus: Bus, key: str, period: float,
                 state: Callable[[], AgentState] | None = None) -> None:
        super().__init__(bus, key, period=period)
        self._state_message = state

    def messages(self) -> list[Any]:
        held = super().messages()
        return held if self._state_message is None else [*held, self._state_message()]
