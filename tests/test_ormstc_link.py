"""The agents' shared hardware retry policy (agent/hw_link.py) and the ORMSTC receiver's
handling of restatements (agent/ormstc_wire.py: Inbound dedup, Rejoin), without processes.

The bus is a stand-in whose queries come back empty while "the router is away" (as a real
query does at once during a restart), so the tests exercise exactly what a restart does to a
command: no reply, then replies again, possibly after the motion already ran.
"""

from __future__ import annotations

from typing import Any

import pytest

from agent.core import hw_link
from agent.core.errors import HardwareError
from agent.core.hw_link import HwLink, NoReplyError, facing, standing_on
from agent.ormstc.body import Body
from agent.ormstc.wire import Inbound, Rejoin, to_wire
from bus import keys
from bus.drops import DropCounter
from bus.inbox import Received
from bus.messages import HwCommand, HwReply
from planner.ormstc.types import (
    ClaimMsg,
    CompletionMsg,
    DeadRobotMsg,
    Message,
    StartMsg,
    TreeEdgeMsg,
)


class FlakyBody:
    """A body behind a router that loses the next ``lost`` replies (the command still runs
    when ``runs_anyway``) and then answers every command."""

    mission = "unit"

    def __init__(self, lost: int, runs_anyway: bool) -> None:
        self.lost, self.runs_anyway = lost, runs_anyway
        self.pose = (0, 0, 1)  # row, col, heading (east)
        self.executed: list[str] = []

    async def query(self, key: str, request: Any, expected: Any, *,
                    timeout: float = 2.0) -> list[Received[Any]]:
        assert isinstance(request, HwCommand)
        if self.lost > 0:
            self.lost -= 1
            if self.runs_anyway:
                self._run(request.action)
            return []
        self._run(request.action)
        return [Received(key, HwReply(request.cmd_id, request.robot, "ok", "", self.pose,
                                      (0.0, 0.0), {}, False, 0.0))]

    def _run(self, action: str) -> None:
        self.executed.append(action)
        r, c, h = self.pose
        if action == "forward":
            self.pose = (r, c + 1, h)
        elif action == "turn_right":
            self.pose = (r, c, (h + 1) % 4)


@pytest.fixture(autouse=True)
def quick_polls(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(hw_link, "POLL_S", 0.001)


def link(bus: FlakyBody, timeout: float = 5.0) -> HwLink:
    return HwLink(bus, 0, 1, timeout=timeout)  # type: ignore[arg-type]


async def test_a_motion_whose_reply_was_lost_is_not_run_twice() -> None:
    bus = FlakyBody(lost=3, runs_anyway=True)
    reply = await link(bus).motion("forward", standing_on((0, 1)))
    assert reply.status == "ok" and reply.pose[:2] == (0, 1)
    assert bus.executed.count("forward") == 1, bus.executed


async def test_a_motion_that_never_reached_simhw_is_sent_again() -> None:
    bus = FlakyBody(lost=3, runs_anyway=False)
    hw = link(bus)
    reply = await hw.motion("turn_right", facing(2))
    assert reply.pose[2] == 2 and bus.executed.count("turn_right") == 1
    assert hw.lost_replies >= 1


async def test_a_query_is_asked_again_until_answered() -> None:
    bus = FlakyBody(lost=5, runs_anyway=False)
    assert (await link(bus).ask("sense", ("front",))).status == "ok"
    assert bus.executed == ["sense"]


async def test_the_deadline_error_says_how_long_it_waited() -> None:
    bus = FlakyBody(lost=10**9, runs_anyway=False)
    with pytest.raises(HardwareError, match=r"within 0.05 s \(\d+ attempts\)"):
        await link(bus, timeout=0.05).ask("pose")
    with pytest.raises(NoReplyError, match=r"after 0\.0 s"):
        await link(bus).once("pose")


async def test_the_ormstc_body_rides_out_lost_replies() -> None:
    bus = FlakyBody(lost=2, runs_anyway=True)
    body = Body(bus, 0, 1, timeout=5.0)  # type: ignore[arg-type]
    await body.wait_for_pose(1.0)
    bus.lost = 2
    assert await body.forward() and body.pose is not None and body.pose[:2] == (0, 1)
    bus.lost = 2
    await body.face(2)
    assert body.pose[2] == 2 and bus.executed.count("turn_right") == 1
    assert bus.executed.count("forward") == 1


def inbound() -> Inbound:
    return Inbound(me=0, k=3, drops=DropCounter())


def test_a_restatement_delivers_only_what_was_missed() -> None:
    rx = inbound()
    said: list[Message] = [StartMsg(1, (2, 2)), ClaimMsg(1, (1, 2), 1),
                           TreeEdgeMsg(1, (1, 1), (1, 2)), DeadRobotMsg(1, 2),
                           CompletionMsg(1, 2)]
    delivered = [m for seq, msg in enumerate(said[:3], 1)  # the router went away after these
                 for _, m in rx.accept(keys.ormstc_tree("m", 1), to_wire(msg, 1, seq))]
    assert delivered == said[:3]
    restated: list[Message] = [StartMsg(1, (2, 2)), TreeEdgeMsg(1, (1, 1), (1, 2)),
                               DeadRobotMsg(1, 2), CompletionMsg(1, 2)]
    again = [m for seq, msg in enumerate(restated, 6)
             for _, m in rx.accept(keys.ormstc_tree("m", 1), to_wire(msg, 1, seq))]
    assert again == [] and rx.gaps == 2  # seq 4 and 5 were lost: the rest waits for them
    assert rx.streams.missing(1) == [4, 5]
    resent = [m for seq in (4, 5)  # said again (a heartbeat showed them lacking)
              for _, m in rx.accept(keys.ormstc_tree("m", 1), to_wire(said[seq - 1], 1, seq))]
    assert resent == [DeadRobotMsg(1, 2), CompletionMsg(1, 2), CompletionMsg(1, 2)]
    assert rx.repeats == 3  # the restated start, edge and freed robot
    # a new life says everything afresh
    assert rx.accept(keys.ormstc_tree("m", 1), to_wire(StartMsg(1, (2, 2)), 2, 1))


def test_rejoin_restates_after_a_silence_and_merges_a_fleet_coming_back() -> None:
    rejoin = Rejoin(silence=1.0)
    for t in (0.0, 0.2, 0.4):
        assert not rejoin.heard(1, t) and not rejoin.heard(2, t)
    assert rejoin.next_due() is None, "no outage, no restatement"
    assert rejoin.heard(1, 2.0)  # 1.6 s of silence: the router was away
    assert rejoin.heard(2, 2.1)
    assert rejoin.due == [2.3, 3.5]  # robot 2's times merged into robot 1's
    assert not rejoin.take(2.2) and rejoin.take(2.3) and not rejoin.take(2.4)
    assert rejoin.take(3.6) and rejoin.next_due() is None and rejoin.count == 2
