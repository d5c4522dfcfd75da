"""What a robot learns and when it acts on it, without processes: its own stall is never a
peer's death, a death notice after planning reaches the state machine, and the runner pulls
the others' knowledge before it decides a takeover (three mutants of issue 15 survived every
fast test before these)."""

from __future__ import annotations

import logging
from collections.abc import Callable
from types import SimpleNamespace
from typing import Any, cast

import pytest
from test_takeover_oracle import plan_of, strip_cycle

from agent.offline.peers import PeerTable
from agent.offline.runner import OfflineRunner
from bus import keys
from bus.drops import DropCounter
from bus.liveness import LivelinessService
from bus.messages import DeathNotice, Heartbeat, RobotEvent
from planner.offline.machine import MoveTo, OfflineRobot, WaitFor


class FakeBus:
    """Records what is published; always connected to a router."""

    def __init__(self) -> None:
        self.mission = "t"
        self.published: list[tuple[str, Any]] = []
        self.drops = DropCounter()
        # the tokens the router answers a census with: tests put the agent's own there (no
        # peer's: every deletion it heard is real); empty, an answer proves nothing
        self.tokens_held: set[str] = set()
        # a census is answered at once, or, with answer_at_once False, when answer() says
        self.answer_at_once = True
        self.questions: list[Callable[[frozenset[str] | None], None]] = []

    def connected(self) -> bool:
        return True

    def publish(self, key: str, msg: Any) -> None:
        self.published.append((key, msg))

    def ask_tokens(self, key: str, timeout: float,
                   on_answer: Callable[[frozenset[str] | None], None]) -> None:
        if self.answer_at_once:
            on_answer(frozenset(self.tokens_held))
        else:
            self.questions.append(on_answer)

    def answer(self) -> None:
        """The router's answer to the oldest question."""
        self.questions.pop(0)(frozenset(self.tokens_held))


class Clock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def test_a_robots_own_stall_is_never_taken_as_a_peers_death() -> None:
    bus, clock = FakeBus(), Clock()
    heard: list[DeathNotice] = []
    service = LivelinessService(cast(Any, bus), 0, 1, timeout=1.0, clock=clock,
                                on_death=heard.append)
    service.tick()
    service._on_heartbeat("mstc/t/hb/1", Heartbeat(1, 1, 0, None, "covering", 0.0))
    clock.now = 30.0  # this process was paused for half a minute: robot 1 was not silent
    assert service.tick() == [] and heard == []
    # The positive witness: with its beats really missing, robot 1 is declared dead.
    for now in (30.4, 30.8):  # ticks closer than half the timeout: no stall of our own
        clock.now = now
        assert service.tick() == []
    clock.now = 31.2
    assert [n.robot for n in service.tick()] == [1] and [n.robot for n in heard] == [1]


@pytest.mark.parametrize("stall", [0.6, 1.43])
def test_a_woken_robot_does_not_take_its_own_lost_session_for_its_peers_deaths(
        stall: float) -> None:
    """Chaos seed 4249, trial 23: a robot stopped for 1.43 s (past its 1 s lease, under half
    its 3 s timeout) woke to every peer's token deleted and declared them all dead. Half a
    lease of stall is enough to doubt those deletions; heartbeats still decide."""
    bus, clock = FakeBus(), Clock()
    bus.tokens_held = {keys.alive("t", 3, 1)}
    heard: list[DeathNotice] = []
    service = LivelinessService(cast(Any, bus), 3, 1, timeout=3.0, token_grace=0.1,
                                lease=1.0, clock=clock, on_death=heard.append)
    service.tick()
    for robot in (0, 1, 2):
        service._on_token(keys.alive("t", robot, 1), True)
        service._on_heartbeat(f"mstc/t/hb/{robot}", Heartbeat(robot, 1, 0, None, "covering", 0.0))
    clock.now = stall
    for robot in (0, 1, 2):  # handed to the loop before its first tick after the stall
        service._on_token(keys.alive("t", robot, 1), False)
    for now in (stall, stall + 0.05, stall + 0.2, stall + 0.5):
        clock.now = now
        assert service.tick() == []
    assert heard == []
    # The positive witness: with no stall of its own, a deletion is a death after the grace.
    for robot in (0, 1, 2):
        service._on_token(keys.alive("t", robot, 1), True)
    clock.now = stall + 0.55
    while clock.now < stall + 4.5:  # ticks closer than half a lease, past the doubt
        service._on_heartbeat("mstc/t/hb/0", Heartbeat(0, 1, 1, None, "covering", 0.0))
        service._on_heartbeat("mstc/t/hb/1", Heartbeat(1, 1, 1, None, "covering", 0.0))
        service._on_heartbeat("mstc/t/hb/2", Heartbeat(2, 1, 1, None, "covering", 0.0))
        service.tick()
        clock.now += 0.05
    service._on_token(keys.alive("t", 1, 1), False)
    clock.now += 0.05
    service.tick()
    clock.now += 0.1
    assert [n.robot for n in service.tick()] == [1] and [n.robot for n in heard] == [1]


def test_a_live_peers_heartbeats_reach_the_agent_and_a_dead_lifes_do_not() -> None:
    # Rebalancing agents read peers' poses off the heartbeats the liveness service already
    # subscribes to (one subscription per process), never those of a life declared dead.
    bus = FakeBus()
    beats: list[Heartbeat] = []
    service = LivelinessService(cast(Any, bus), 0, 1, on_beat=beats.append)
    alive = Heartbeat(1, 1, 0, (3, 4, 0), "covering", 1.0)
    service._on_heartbeat("mstc/t/hb/1", alive)
    service._on_heartbeat("mstc/t/hb/0", Heartbeat(0, 1, 0, (0, 0, 0), "covering", 1.0))
    assert beats == [alive]  # its own are not news
    assert service.accept_notice(DeathNotice(1, 1, 0, "heartbeat", 2.0))
    service._on_heartbeat("mstc/t/hb/1", Heartbeat(1, 1, 1, (3, 5, 0), "covering", 2.5))
    assert beats == [alive]


def test_a_notice_of_this_robot_in_a_life_it_never_had_is_refused_as_forged() -> None:
    bus = FakeBus()
    heard: list[DeathNotice] = []
    service = LivelinessService(cast(Any, bus), 0, 1, on_death=heard.append)
    service._on_heartbeat("mstc/t/hb/1", Heartbeat(1, 1, 0, None, "covering", 0.0))
    # Robot 1 is a known participant, but this robot has incarnation 1, not 2: a notice
    # for life 2 would fence this robot's next life in advance.
    assert not service.accept_notice(DeathNotice(0, 2, 1, "heartbeat", 0.0))
    assert bus.drops.total("death", "forged") == 1 and heard == []
    # The positive witness: the same detector's verdict on this robot's own life is taken.
    assert service.accept_notice(DeathNotice(0, 1, 1, "heartbeat", 0.0))
    assert bus.drops.total("death", "forged") == 1


NB = [(0, [1, 2, 3]), (4, [5, 6, 7]), (8, [9, 10, 11])]


def test_a_death_notice_after_planning_reaches_the_state_machine() -> None:
    plan = plan_of(strip_cycle(3), NB)
    peers = PeerTable(robot=0, k=3, drops=DropCounter())
    machine = OfflineRobot(plan, 0)
    peers.attach(machine)
    for _ in range(3):
        machine.next_action()
        machine.on_moved()
    assert machine.next_action() == WaitFor(1)
    bus = FakeBus()
    service = LivelinessService(cast(Any, bus), 0, 1, on_death=peers.on_death)
    for robot in (1, 2):  # a notice counts only from a known participant (docs/security.md)
        service._on_heartbeat(f"mstc/t/hb/{robot}", Heartbeat(robot, 1, 0, None, "covering", 0.0))
    service._on_notice("mstc/t/death/1", DeathNotice(1, 1, 2, "heartbeat", 0.0))
    assert machine.dead == {1}
    assert machine.about_to_take_over
    assert peers.changed.is_set(), "the runner's wait is woken"


class FakeHardware:
    def __init__(self) -> None:
        self.state = SimpleNamespace(sim_time=0.0)
        self.steps: list[tuple[int, int]] = []

    async def step_to(self, sub: tuple[int, int]) -> None:
        self.steps.append(sub)


async def test_the_runner_learns_the_dead_robots_coverage_before_it_takes_over() -> None:
    # Robot 1 (region 4..11) went CCW to 11 first and died there: only 4 and 5 are left.
    # Robot 0 never heard of 7..11; the others' state (the refresh) has them.
    cycle = strip_cycle(3)
    plan = plan_of(cycle, [(0, [1, 2, 3]), (6, [7, 8, 9, 10, 11, 10, 9, 8, 7, 6, 5, 4])])
    peers = PeerTable(robot=0, k=2, drops=DropCounter())
    machine = OfflineRobot(plan, 0)
    peers.attach(machine)
    peers.on_death(DeathNotice(1, 1, 0, "token", 0.0))
    refreshes = []

    async def refresh() -> None:
        refreshes.append(machine.position)
        for index in range(7, 12):
            peers.covered_cell("mstc/t/state/1", cycle.at(index))

    bus, body = FakeBus(), FakeHardware()
    runner = OfflineRunner(cast(Any, bus), cast(Any, body), peers, machine, 1, refresh=refresh,
                           refresh_period=60.0)
    await runner.run()
    events = [m for _, m in bus.published if isinstance(m, RobotEvent)]
    started = [e.detail for e in events if e.kind == "takeover_started"]
    assert started == ["walking to cycle index 5"], started
    assert refreshes and refreshes[0] == 3, "refreshed once its own walk was done"
    assert body.steps == [cycle.at(i) for i in (1, 2, 3, 4, 5)]


def test_a_robots_own_death_notice_fences_it_and_is_no_peers_death() -> None:
    heard: list[DeathNotice] = []
    service = LivelinessService(cast(Any, FakeBus()), 0, 2, on_death=heard.append)
    service._on_heartbeat("mstc/t/hb/1", Heartbeat(1, 1, 0, None, "covering", 0.0))
    service._on_notice("mstc/t/death/0", DeathNotice(0, 1, 1, "heartbeat", 0.0))
    assert not service.fenced.is_set(), "an older life's death does not fence this one"
    service._on_notice("mstc/t/death/0", DeathNotice(0, 2, 1, "heartbeat", 0.0))
    assert service.fenced.is_set() and heard == []


def test_a_vanished_token_of_an_unknown_fenced_life_stays_dead() -> None:
    from bus.detector import FailureDetector

    detector = FailureDetector(timeout=1.0)
    detector.on_death_notice(DeathNotice(1, 3, 0, "token", 0.0))
    detector.on_token_deleted(1, 3, now=1.0)
    assert detector.alive() == {}, "a fenced life is not brought back by its token's end"
    detector.on_token_deleted(2, 1, now=1.0)
    assert detector.alive() == {2: 1}, "an unknown life whose token vanished is watched"


def test_the_mission_verdict_is_final_and_complete_covers_everything() -> None:
    from bus.messages import MissionStatus

    plan = plan_of(strip_cycle(3), NB)
    peers = PeerTable(robot=0, k=3, drops=DropCounter())
    peers.on_mission("mstc/t/mission", MissionStatus("running", "", {}))
    assert not peers.verdict.is_set()
    machine = OfflineRobot(plan, 0)
    peers.attach(machine)
    peers.on_mission("mstc/t/mission", MissionStatus("complete", "", {}))
    assert peers.verdict.is_set() and machine.all_covered
    peers.on_mission("mstc/t/mission", MissionStatus("running", "stale", {}))
    assert peers.mission is not None and peers.mission.state == "complete"


def test_robots_known_dead_need_no_plan_digest() -> None:
    from bus.messages import RobotStatus

    peers = PeerTable(robot=0, k=3, drops=DropCounter())
    peers.on_status("mstc/t/status/0", RobotStatus(0, 1, (0, 0), "nb", "abc", "x"))
    participants = [0, 1, 2]  # the agreed roster (agent/core/roster.py)
    assert peers.missing_digests(participants) == [1, 2]
    peers.on_death(DeathNotice(2, 1, 0, "token", 0.0))
    assert peers.missing_digests(participants) == [1]


def test_news_wakes_the_waiters() -> None:
    from bus.messages import RobotStatus

    peers = PeerTable(robot=0, k=3, drops=DropCounter())
    peers.on_status("mstc/t/status/1", RobotStatus(1, 1, (0, 0), "nb", "", "x"))
    assert peers.changed.is_set(), "a new status is news"
    peers.changed.clear()
    peers.on_death(DeathNotice(1, 1, 0, "token", 0.0))
    assert peers.changed.is_set(), "a death is news"
    peers.changed.clear()
    peers.on_death(DeathNotice(1, 1, 2, "heartbeat", 1.0))
    assert not peers.changed.is_set(), "the same life's death again is no news"


def test_a_start_changed_within_one_life_is_counted_and_ignored() -> None:
    from bus.messages import RobotStatus

    drops = DropCounter()
    peers = PeerTable(robot=0, k=3, drops=drops)
    peers.on_status("mstc/t/status/1", RobotStatus(1, 1, (0, 0), "nb", "", "x"))
    peers.on_status("mstc/t/status/1", RobotStatus(1, 1, (4, 4), "nb", "", "y"))
    assert drops.total("status", "invalid") == 1
    assert peers.statuses[1].start == (0, 0)
    peers.on_status("mstc/t/status/1", RobotStatus(1, 2, (4, 4), "nb", "", "z"))
    assert peers.statuses[1].start == (4, 4), "a new life may start elsewhere"


def test_a_census_without_this_robots_own_token_proves_no_death() -> None:
    """Zenoh 1.10 now and then ends a liveliness get at once with no reply at all: such an
    answer must not confirm a deletion (it would declare every peer dead); heartbeats
    decide instead, and two answers in a row holding the robot's own token confirm it."""
    bus, clock = FakeBus(), Clock()
    heard: list[DeathNotice] = []
    service = LivelinessService(cast(Any, bus), 3, 1, timeout=1.0, token_grace=0.1,
                                clock=clock, on_death=heard.append)
    service.tick()
    service._on_token(keys.alive("t", 1, 1), True)
    service._on_token(keys.alive("t", 1, 1), False)
    for now in (0.05, 0.1, 0.2, 0.4):
        clock.now = now
        assert service.tick() == []  # every census came back empty: nothing proved
    bus.tokens_held = {keys.alive("t", 3, 1)}
    bus.answer_at_once = False
    clock.now = 0.45
    assert service.tick() == [] and len(bus.questions) == 1
    clock.now = 0.47
    bus.answer()  # one census lacking the token could be one cut short
    assert heard == [] and len(bus.questions) == 1  # the second is asked at once
    clock.now = 0.49
    bus.answer()  # the second lacks it too: the death is declared on the answer, no tick
    assert [(n.robot, n.reason) for n in heard] == [(1, "token")] and bus.questions == []
    assert [(n.robot, n.reason) for n in service.tick()] == [(1, "token")]  # reported once
    assert service.tick() == [] and len(heard) == 1


def test_a_census_answer_declares_no_silence() -> None:
    """A census answer may be handled before the tick that would see this loop's own stall:
    it declares token deaths only, and a peer that merely looks silent is left to the tick
    (which forgives a stall of its own)."""
    bus, clock = FakeBus(), Clock()
    bus.tokens_held = {keys.alive("t", 3, 1)}
    bus.answer_at_once = False
    heard: list[DeathNotice] = []
    service = LivelinessService(cast(Any, bus), 3, 1, timeout=1.0, token_grace=0.1,
                                clock=clock, on_death=heard.append)
    service.tick()
    service._on_heartbeat("mstc/t/hb/2", Heartbeat(2, 1, 0, None, "covering", 0.0))
    service._on_token(keys.alive("t", 1, 1), True)
    service._on_token(keys.alive("t", 1, 1), False)
    clock.now = 0.05
    assert service.tick() == [] and len(bus.questions) == 1
    clock.now = 5.0  # this loop was stalled: robot 2 looks silent for 5 s
    bus.answer()
    bus.answer()
    assert [(n.robot, n.reason) for n in heard] == [(1, "token")]  # robot 2 is not
    assert service.tick() == [heard[0]]  # the tick sees the stall and forgives robot 2
    assert len(heard) == 1


async def test_a_robot_that_cannot_move_says_why_and_what_it_knows(
        monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture) -> None:
    """A stalled fleet leaves the evidence in its logs: what stops the robot and where it
    believes the others are (a CI rehearsal's stall left none, 2026-12-05)."""
    import agent.offline.runner as runner_module
    from agent.offline.bodies import Bodies

    monkeypatch.setattr(runner_module, "STILL_WARN_S", 0.0)
    cycle = strip_cycle(3)
    # robot 1 is parked on the first place of robot 0's walk
    plan = plan_of(cycle, [(0, [1, 2, 3]), (1, [])])
    peers = PeerTable(robot=0, k=2, drops=DropCounter())
    machine = OfflineRobot(plan, 0, takeover=False)
    peers.attach(machine)

    async def refresh() -> None:
        return None

    runner = OfflineRunner(cast(Any, FakeBus()), cast(Any, FakeHardware()), peers, machine, 1,
                           refresh=refresh, refresh_period=60.0,
                           bodies=Bodies.of_plan(plan, 0))
    action = machine.next_action()
    assert isinstance(action, MoveTo)
    with caplog.at_level(logging.WARNING, logger="mstc.agent"):
        assert not await runner._drive(action)
    said = [r.getMessage() for r in caplog.records if "has not moved" in r.getMessage()]
    assert len(said) == 1, caplog.text
    assert "waiting for robot 1" in said[0] and f"1 at {cycle.at(1)}" in said[0], said
    with caplog.at_level(logging.WARNING, logger="mstc.agent"):
        assert not await runner._drive(machine.next_action())  # type: ignore[arg-type]
    assert len([r for r in caplog.records if "has not moved" in r.getMessage()]) == 2
