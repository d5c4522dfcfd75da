"""Missions whose robots publish no mission status (ORMSTC, tree coverage) still get a
verdict, read off the robots' completions and the ground truth; a published one stands."""

from __future__ import annotations

import io

from test_monitor_fixtures import M, open_room, run_mission, two_robot_walks
from test_monitor_tree import _reports, _status

from bus import keys
from bus.messages import (
    DeathNotice,
    MissionStatus,
    OrmstcCompletion,
    RobotEvent,
    RobotStatus,
)
from deploy.monitor.app import GONE_GRACE_S, PlainScreen, Watcher, replay
from deploy.monitor.plain import PlainPrinter, status_line
from deploy.monitor.types import Header, Record, Recording, TokenChange
from deploy.monitor.verdict import mission_verdict


def _ormstc_records(complete: bool = True) -> list[Record]:
    """A scripted two-robot mission as ORMSTC robots tell it: no mission status, each robot
    announcing its own completion on ormstc/done (robot 1 never does when not ``complete``,
    and dies instead)."""
    mission = run_mission(open_room(), two_robot_walks(), algo="ormstc",
                          kill=None if complete else (1, 3), taker=0)
    out = []
    for record in mission.records:
        if isinstance(record.msg, MissionStatus):
            continue
        if isinstance(record.msg, RobotEvent) and record.msg.kind == "completed":
            r = record.msg.robot
            record = Record(record.t, keys.ormstc_done(M, r), OrmstcCompletion(r, 1, 9, 4))
        out.append(record)
    return out


def _watch(records: list[Record]) -> tuple[Watcher, str]:
    out = io.StringIO()
    watcher = Watcher(PlainScreen(PlainPrinter(out)))
    for record in records:
        watcher.feed([record])
    return watcher, out.getvalue()


def test_an_ormstc_mission_is_complete_once_every_robot_completed_and_all_is_covered() -> None:
    records = _ormstc_records()
    last_done = max(i for i, r in enumerate(records) if isinstance(r.msg, OrmstcCompletion))
    watcher, _ = _watch(records[:last_done])
    assert mission_verdict(watcher.model) is None and not watcher.settled()
    assert "mission running" in status_line(watcher.model)
    watcher, printed = _watch(records)
    verdict = mission_verdict(watcher.model)
    assert verdict is not None and verdict.state == "complete" and not verdict.published
    assert "every robot completed (2); every reachable sub-cell is covered" in verdict.message
    assert watcher.settled()
    assert printed.count("mission_complete") == 1  # told once, not per record
    assert "mission complete" in status_line(watcher.model)


def test_an_ormstc_mission_with_cells_left_when_every_robot_ended_has_failed() -> None:
    records = _ormstc_records(complete=False)
    watcher, printed = _watch(records)
    verdict = mission_verdict(watcher.model)
    assert verdict is not None and verdict.state == "failed"
    assert "1 of 2 robots completed" in verdict.message
    assert "reachable sub-cells uncovered" in verdict.message
    assert "mission_failed" in printed and watcher.settled()


def test_without_a_world_the_robots_completions_are_the_verdict() -> None:
    records = [r for r in _ormstc_records() if r.kind not in ("world", "cover")]
    verdict = mission_verdict(_watch(records)[0].model)
    assert verdict is not None and verdict.state == "complete"
    assert "coverage unknown" in verdict.message


def test_a_published_verdict_stands() -> None:
    records = [*_ormstc_records()[:5],
               Record(9.0, keys.mission_status(M), MissionStatus("failed", "cannot plan"))]
    verdict = mission_verdict(_watch(records)[0].model)
    assert verdict is not None and (verdict.state, verdict.message, verdict.published) == \
        ("failed", "cannot plan", True)


def test_a_tree_mission_is_complete_when_every_node_was_visited() -> None:
    watcher, printed = _watch([_status(), *_reports()])
    verdict = mission_verdict(watcher.model)
    assert verdict is not None and verdict.state == "complete"
    assert "every node of tree perfect:N=2,H=3 visited by step" in verdict.message
    assert "mission_complete" in printed


def test_replaying_an_ormstc_recording_ends_with_its_verdict() -> None:
    out = io.StringIO()
    recording = Recording(Header(M, 0.0, "up", 4), tuple(_ormstc_records()), ())
    watcher = Watcher(PlainScreen(PlainPrinter(out)))
    replay(recording, watcher, 0.0)
    lines = out.getvalue().splitlines()
    assert "mission_complete" in "".join(lines) and lines[-1].endswith("mission complete")


def test_a_robot_status_of_done_counts_as_its_completion() -> None:
    records = [Record(0.1, keys.status(M, 0), RobotStatus(0, 1, (0, 0), "ormstc", "", "done"))]
    verdict = mission_verdict(_watch(records)[0].model)
    assert verdict is not None and "coverage unknown" in verdict.message


def test_a_verdict_on_robots_gone_only_by_their_tokens_ends_a_watch_after_a_grace() -> None:
    """A link between hosts that drops for a moment takes every far token with it: a
    monitor with ``--exit-when-done`` ended a live mission at 11.2 s that way, most likely
    (docs/operations.md, "Slow links between hosts"). A verdict that counts a robot over
    only by its vanished token now ends the watch once it has held GONE_GRACE_S; a token
    back in time undoes it, and a death notice needs no wait."""
    now = [100.0]
    watcher = Watcher(PlainScreen(PlainPrinter(io.StringIO())), clock=lambda: now[0])
    for record in _ormstc_records()[:6]:  # both robots joined, nothing covered yet
        watcher.feed([record])
    gone = [Record(2.0, keys.alive(M, r, 1), TokenChange(r, 1, False), "token")
            for r in (0, 1)]
    watcher.feed(gone)
    assert watcher.verdict is not None and watcher.verdict.state == "failed"
    assert not watcher.settled()
    now[0] += GONE_GRACE_S - 0.1
    assert not watcher.settled()
    watcher.feed([Record(3.0, keys.alive(M, 0, 1), TokenChange(0, 1, True), "token")])
    assert watcher.verdict is None and not watcher.settled()  # robot 0 is back
    watcher.feed([gone[0]])
    now[0] += GONE_GRACE_S
    assert watcher.settled()
    # a robot declared dead by a peer ends the watch at once
    watcher = Watcher(PlainScreen(PlainPrinter(io.StringIO())), clock=lambda: now[0])
    for record in _ormstc_records()[:6]:
        watcher.feed([record])
    watcher.feed([*gone, *(Record(2.1, keys.death(M, r), DeathNotice(r, 1, None, "token", 2.1))
                           for r in (0, 1))])
    assert watcher.settled()
