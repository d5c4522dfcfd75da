"""The participants' agreement (agent.core.roster), step by step, without processes."""

from __future__ import annotations

from agent.core.roster import Agreed, StandDown, Waiting, decide, to_wire
from bus.messages import RobotStatus

STARTS = {0: (0, 0), 1: (2, 2), 2: (4, 4)}


def status(robot: int, state: str = "gathering",
           roster: dict[int, tuple[int, int]] | None = None) -> RobotStatus:
    return RobotStatus(robot, 1, STARTS[robot], "nb", "", state, "",
                       to_wire(roster) if roster else ())


def test_every_start_heard_and_every_proposal_equal_is_an_agreement() -> None:
    waiting = decide(0, STARTS[0], 3, {1: status(1), 2: status(2)}, (), False)
    assert isinstance(waiting, Waiting) and waiting.proposal == STARTS
    assert waiting.disagreeing == (1, 2)
    agreed = decide(0, STARTS[0], 3, {1: status(1, roster=STARTS), 2: status(2, roster=STARTS)},
                    (), False)
    assert agreed == Agreed(STARTS, ())


def test_a_robot_never_heard_waits_until_the_boot_timeout_then_takes_no_part() -> None:
    pair = {0: STARTS[0], 1: STARTS[1]}
    assert decide(0, STARTS[0], 3, {1: status(1)}, (), False) == Waiting(None, (2,), ())
    assert decide(0, STARTS[0], 3, {1: status(1, roster=pair)}, (), True) == Agreed(pair, (2,))


def test_a_dead_robot_whose_start_one_peer_heard_is_taken_in_from_that_peer() -> None:
    # Robot 2 announced and died; only robot 1 heard it: its proposal restates the start.
    agreed = decide(0, STARTS[0], 3, {1: status(1, roster=STARTS)}, {2}, False)
    assert agreed == Agreed(STARTS, ())


def test_a_known_dead_robot_never_heard_settles_the_gather() -> None:
    pair = {0: STARTS[0], 1: STARTS[1]}
    assert decide(0, STARTS[0], 3, {1: status(1, roster=pair)}, {2}, False) == Agreed(pair, (2,))


def test_a_committed_set_wins_and_a_robot_left_out_stands_down() -> None:
    pair = {0: STARTS[0], 1: STARTS[1]}
    assert decide(2, STARTS[2], 3, {1: status(1, "covering", pair)}, (), False) \
        == StandDown(pair, 1)
    # robot 0 still proposes all three but robot 1 already committed to the pair
    assert decide(0, STARTS[0], 3, {1: status(1, "planned", pair), 2: status(2, roster=STARTS)},
                  (), False) == Agreed(pair, (2,))
