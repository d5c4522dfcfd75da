"""Known deaths are re-announced by the lowest few robots alive, not by every survivor
(agent.core.announcer): pure, a recording stand-in for the bus."""

from __future__ import annotations

from typing import Any

from agent.core.announcer import DEATH_HOLDERS, StateAnnouncer, holds_deaths
from bus import keys
from bus.messages import DeathNotice, RobotStatus

MISSION = "holders"


class RecordingBus:
    mission = MISSION

    def __init__(self) -> None:
        self.published: list[str] = []

    def publish(self, key: str, msg: Any) -> None:
        self.published.append(key)


def test_the_lowest_ids_alive_hold_the_deaths() -> None:
    alive = {0, 2, 5, 7, 9}
    holders = {r for r in range(12) if holds_deaths(r, alive - {r})}
    assert DEATH_HOLDERS == 3
    assert {0, 1, 2, 3, 4, 5} <= holders  # ids 0, 2, 5 alive below: 1-5 have at most 2 lower
    assert not holders & {6, 7, 8, 9, 10, 11}


def test_a_holders_death_hands_the_deaths_to_the_next_robot() -> None:
    alive = set(range(10))
    assert not holds_deaths(3, alive - {3})
    assert holds_deaths(3, alive - {3, 1})  # robot 1 died: 3 is now among the lowest three


def test_a_robot_that_knows_no_peer_holds_the_deaths() -> None:
    assert holds_deaths(57, ())


def _announcer(bus: RecordingBus, holder: list[bool]) -> StateAnnouncer:
    announcer = StateAnnouncer(bus, keys.state(MISSION, 4), 0.5,  # type: ignore[arg-type]
                               death_holder=lambda: holder[0])
    announcer.set(keys.status(MISSION, 4), RobotStatus(4, 1, (0, 0), "opt", "d", "covering"),
                  publish=False)
    notice = DeathNotice(robot=2, incarnation=1, detected_by=4, reason="token", detected_at=1.0)
    announcer.set(keys.death(MISSION, 2), notice, publish=False)
    return announcer


def test_a_robot_that_holds_no_deaths_re_announces_its_status_only() -> None:
    bus, holder = RecordingBus(), [False]
    announcer = _announcer(bus, holder)
    announcer.announce()
    assert bus.published == [keys.status(MISSION, 4)]
    # a query still learns the death from it
    assert any(isinstance(m, DeathNotice) for m in announcer.messages())
    holder[0] = True
    announcer.announce()
    assert bus.published[1:] == [keys.status(MISSION, 4), keys.death(MISSION, 2)]


def test_without_a_holder_rule_every_held_message_is_re_announced() -> None:
    bus = RecordingBus()
    announcer = StateAnnouncer(bus, keys.state(MISSION, 4), 0.5)  # type: ignore[arg-type]
    notice = DeathNotice(robot=2, incarnation=1, detected_by=4, reason="token", detected_at=1.0)
    announcer.set(keys.death(MISSION, 2), notice, publish=False)
    announcer.announce()
    assert bus.published == [keys.death(MISSION, 2)]


def test_a_quiet_message_is_answered_to_queries_but_not_re_announced_until_set_again() -> None:
    """A survivor's re-plan report once it has re-planned (agent.offline.runner): whoever
    still misses it pulls it."""
    bus, holder = RecordingBus(), [True]
    announcer = _announcer(bus, holder)
    death = keys.death(MISSION, 2)
    announcer.quiet(death)
    announcer.announce()
    assert bus.published == [keys.status(MISSION, 4)]  # a holder, but the death is quiet
    assert any(isinstance(m, DeathNotice) for m in announcer.messages())
    notice = DeathNotice(robot=2, incarnation=2, detected_by=4, reason="token", detected_at=2.0)
    announcer.set(death, notice, publish=False)  # a new message on the key speaks again
    announcer.announce()
    assert bus.published[1:] == [keys.status(MISSION, 4), death]
    announcer.quiet(keys.death(MISSION, 9))  # nothing held there: nothing to quiet
    announcer.remove(death)
    announcer.set(death, notice, publish=False)
    announcer.announce()
    assert bus.published[3:] == [keys.status(MISSION, 4), death]
