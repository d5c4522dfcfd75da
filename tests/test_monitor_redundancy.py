"""ORMSTC's redundancy accounting in the report: steps made only to sense (LookStep) and the
closing re-entry of a start are counted apart; any other revisit still fails the check.

Scripted recordings (tests/test_monitor_fixtures.py): the oracle is the scripted walk, whose
look steps are written down by hand below.
"""

from __future__ import annotations

from test_monitor_fixtures import M, open_room, run_mission
from test_monitor_report import report_of

from bus import keys
from bus.codec import decode, encode
from bus.messages import LookStep
from deploy.monitor.coverage import CoverageMap
from deploy.monitor.model import FleetModel
from deploy.monitor.redundancy import UNKNOWN_ROBOT, account_entries
from deploy.monitor.report import MissionReport
from deploy.monitor.types import Record

SubCell = tuple[int, int]
NAME = "no sub-cell covered twice by coverage moves"

# One robot, a 2 x 4 room (two cells). The STC walk goes round both cells and comes home to
# (0, 0); at (0, 1) it looks at the right cell from beside: aside to (1, 1) and back.
LOOK_WALK: list[SubCell] = [(0, 0), (0, 1), (1, 1), (0, 1), (0, 2), (0, 3), (1, 3), (1, 2),
                            (1, 1), (1, 0), (0, 0)]
LOOKS: list[SubCell] = [(1, 1), (0, 1)]  # the step aside, then the step back


def look_records(robot: int, cells: list[SubCell], incarnation: int = 1) -> list[Record]:
    return [Record(100.0 + seq, keys.look_steps(M, robot),
                   LookStep(robot, incarnation, seq, cell), "sub")
            for seq, cell in enumerate(cells, start=1)]


def ormstc_report(walk: list[SubCell], looks: list[SubCell]) -> MissionReport:
    mission = run_mission(open_room(2, 4), {0: walk}, algo="ormstc")
    return report_of([*mission.records, *look_records(0, looks)])


def invariant(report: MissionReport) -> tuple[str, str]:
    [inv] = [i for i in report.invariants if i.name.startswith(NAME)]
    return inv.status, inv.detail


def test_look_steps_and_the_closing_reentry_are_counted_not_failed() -> None:
    report = ormstc_report(LOOK_WALK, LOOKS)
    assert report.complete and report.coverage == 100.0
    # (0, 1) and (1, 1) twice each, the start twice: three visits beyond the first
    assert report.revisits == 3
    assert (report.look_steps, report.closing_reentries, report.coverage_revisits) == (2, 1, 0)
    assert report.robots[0].look_steps == 2
    assert report.look_step_share == round(2 / (len(LOOK_WALK) - 1), 4)
    assert invariant(report)[0] == "ok" and report.ok
    data = report.to_json()
    assert (data["look_steps"], data["closing_reentries"], data["coverage_revisits"]) == \
        (2, 1, 0)
    assert data["robots"][0]["look_steps"] == 2


def test_without_the_look_steps_announced_the_same_walk_fails() -> None:
    status, detail = invariant(ormstc_report(LOOK_WALK, []))
    assert status == "failed"
    assert "(0, 1) by robots [0, 0]" in detail and "(1, 1) by robots [0, 0]" in detail
    assert "(0, 0)" not in detail  # the start's closing re-entry is still excepted


def test_a_revisit_that_is_not_a_look_step_fails_beside_the_looks() -> None:
    # after covering (1, 0) the walk steps back into (1, 1) and out again before going home
    walk = [*LOOK_WALK[:-1], (1, 1), (1, 0), (0, 0)]
    report = ormstc_report(walk, LOOKS)
    status, detail = invariant(report)
    assert status == "failed" and not report.ok
    assert "2 sub-cells entered more than once by coverage moves" in detail
    assert "(1, 1) by robots [0, 0]" in detail and "(1, 0) by robots [0, 0]" in detail
    assert "(0, 1)" not in detail
    assert report.coverage_revisits == 2


def test_a_second_return_home_is_a_coverage_revisit() -> None:
    walk = [*LOOK_WALK, (0, 1), (0, 0)]
    report = ormstc_report(walk, LOOKS)
    status, detail = invariant(report)
    assert status == "failed" and "(0, 0) by robots [0, 0]" in detail
    assert report.closing_reentries == 1


def test_a_robot_entering_another_robots_start_is_not_excused() -> None:
    cover = CoverageMap()
    for robot, visits in ((0, 1), (1, 2)):
        cover.visit(robot, (0, 0), visits)
        cover.visits[(0, 0)] = visits
    account = account_entries(cover, {0: (0, 0), 1: (4, 4)})
    assert account.closings == () and account.covered_twice == (((0, 0), (0, 1)),)


def test_entries_counted_but_not_seen_made_are_attributed_to_nobody() -> None:
    # a recording that began after the placements: the world answer counts visits whose
    # CoverEvents it never heard
    cover = CoverageMap()
    cover.visits = {(0, 0): 2, (0, 1): 2}
    cover.visit(0, (0, 0), 2)
    cover.visit(0, (0, 1), 2)
    account = account_entries(cover, {0: (0, 0)})
    assert account.closings == (((0, 0), 0),)
    assert account.covered_twice == (((0, 1), (0, UNKNOWN_ROBOT)),)


def test_a_look_step_heard_twice_counts_once() -> None:
    model = FleetModel()
    step = look_records(0, [(1, 1)])[0]
    for record in (step, step, Record(101.0, step.key, LookStep(0, 2, 1, (1, 1)), "sub")):
        model.apply(record)
    assert model.robots[0].look_steps == 2  # the same step again, then another life's
    assert model.cover.looks == {(1, 1): {0: 2}}


def test_look_step_key_and_codec() -> None:
    msg = LookStep(robot=3, incarnation=2, seq=7, cell=(4, 5))
    assert decode(encode(msg), LookStep) == msg
    parsed = keys.parse(keys.look_steps("m1", 3))
    assert parsed is not None and (parsed.kind, parsed.robot) == ("look", 3)


def test_the_look_steps_among_the_revisits_are_never_more_than_the_revisits() -> None:
    """A look into a sub-cell not entered before is a first visit: of the walk below's one
    revisit (the step back to (0, 1)) one is a look step, though two look steps were made
    (the live view once said "1 revisits (2 of them look steps)")."""
    from deploy.monitor.redundancy import look_revisits
    from deploy.monitor.view import redundancy_line

    mission = run_mission(open_room(2, 4), {0: [(0, 0), (0, 1), (1, 1), (0, 1), (0, 2)]},
                          algo="ormstc")
    model = FleetModel()
    for record in [*mission.records, *look_records(0, [(1, 1), (0, 1)])]:
        model.apply(record)
    assert model.revisits() == 1 and look_revisits(model.cover) == 1
    assert redundancy_line(model, model.revisits()) == \
        "1 revisits: 1 by look steps (of 2)"
