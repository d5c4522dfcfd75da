"""The one state announcer of every agent: bus.announce.Announcer (status, known deaths, the
mission verdict, re-published every announce period), plus, for agents that have some, the
robot's own knowledge (AgentState) in every reply to a state query.

Known deaths are re-published by a few robots only (``holds_deaths``): every survivor used to
re-announce its copy of every death notice, so a fleet of k heard k copies of one fact per
period (60 robots waiting for a re-plan: 33 notices a second per agent, a fifth of all it
received). Every agent still answers state queries with the deaths it knows, so a late or
cut-off robot's pull learns them from anyone.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from typing import Any

from bus import keys
from bus.announce import Announcer
from bus.bridge import Bus
from bus.messages import AgentState

# This many robots re-announce every death (the lowest ids each robot believes alive): a
# router restart or a lost notice leaves more than one robot to say it again.
DEATH_HOLDERS = 3


def holds_deaths(robot: int, alive: Iterable[int], holders: int = DEATH_HOLDERS) -> bool:
    """Whether ``robot`` re-announces known deaths: fewer than ``holders`` robots it believes
    alive (``alive``: its live peers) have a lower id. Each robot decides from its own view,
    so while a death is not yet known everywhere a few more robots hold, never fewer."""
    return sum(1 for peer in alive if peer < robot) < holders


class StateAnnouncer(Announcer):
    """Announcer on the robot's state key; ``state`` (if any) is asked at each query, and
    death notices are re-published only while ``death_holder()`` says so (default: always)."""

    def __init__(self, bus: Bus, key: str, period: float,
                 state: Callable[[], AgentState] | None = None,
                 death_holder: Callable[[], bool] | None = None) -> None:
        super().__init__(bus, key, period=period)
        self._state_message = state
        self._death_holder = death_holder

    def repeats(self, key: str) -> bool:
        if not super().repeats(key):
            return False
        if self._death_holder is None:
            return True
        parsed = keys.parse(key)
        return parsed is None or parsed.kind != "death" or self._death_holder()

    def messages(self) -> list[Any]:
        held = super().messages()
        return held if self._state_message is None else [*held, self._state_message()]
