"""What `mstc up` shows while a mission runs (deploy.progress, deploy.summary's tracker):
the panel's lines, robots' states as they finish, the done count, periodic lines through a
quiet stretch, and every death told."""

from __future__ import annotations

import io

import numpy as np
from rich.console import Console

from bus.messages import DeathNotice, RobotEvent, RobotStatus
from deploy.progress import QUIET_S, PlainProgress, RichProgress, render
from deploy.summary import MissionTracker


def _tracker(robots: int = 3) -> MissionTracker:
    tracker = MissionTracker(np.ones((4, 8), dtype=bool), robots)
    for r in range(robots):
        tracker.on_status(RobotStatus(r, 1, (0, 2 * r), "nb", "d", "covering"))
    return tracker


def _panel(tracker: MissionTracker) -> list[str]:
    console = Console(file=io.StringIO(), width=100, record=True, color_system=None)
    console.print(render(tracker, 3.0))
    return console.export_text().splitlines()


def test_the_bar_and_the_table_header_have_lines_of_their_own() -> None:
    lines = _panel(_tracker())
    assert lines[0].startswith("[   3.0s] coverage")
    assert lines[1].strip().endswith("0.0 %") and "robot" not in lines[1]
    assert lines[2].split() == ["robot", "state", "moves", "note"]


def test_a_robot_whose_section_is_covered_is_not_shown_covering_and_counts_as_done() -> None:
    tracker = _tracker()
    tracker.on_event(RobotEvent(1, 1, "section_complete", None, "12 moves"))
    assert tracker.done == 1
    rows = {line.split()[0]: line for line in _panel(tracker)[3:]}
    assert "section done" in rows["1"] and "section complete" in rows["1"]
    assert "covering" in rows["0"]
    assert "done 1" in _panel(tracker)[0]
    # taking over a dead robot's section is work again
    tracker.on_event(RobotEvent(1, 1, "takeover_started", 2))
    assert tracker.done == 0 and tracker.shown_state(tracker.views[1]) == "covering"
    tracker.on_event(RobotEvent(1, 1, "section_complete", None, "13 moves"))  # heard late
    assert tracker.done == 0
    tracker.on_event(RobotEvent(0, 1, "completed", None, "done"))
    assert tracker.shown_state(tracker.views[0]) == "done" and tracker.done == 1


def test_every_death_is_told_once_also_of_a_robot_known_lost() -> None:
    tracker = _tracker()
    tracker.lose(2, "agent process killed by signal 9")  # its exit was seen first
    for by in (0, 1):
        tracker.on_death(DeathNotice(2, 1, by, "token", 1.0))
    tracker.on_death(DeathNotice(1, 1, 0, "heartbeat", 1.0), " 0.40 s after it was failed")
    assert tracker.log == ["robot 2 lost: agent process killed by signal 9",
                           "robot 2 declared dead by robot 0 (token)",
                           "robot 1 lost: declared dead by robot 0 (heartbeat) 0.40 s after "
                           "it was failed"]


class _Clock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def test_plain_progress_repeats_its_line_through_a_quiet_stretch() -> None:
    out, clock = io.StringIO(), _Clock()
    view = PlainProgress(out, period=1.0, clock=clock)
    tracker = _tracker(1)
    for step in range(40):  # 20 s of a takeover walk over covered ground
        clock.now = step * 0.5
        view.update(tracker, clock.now)
    lines = out.getvalue().splitlines()
    assert len(lines) >= 20 / QUIET_S and len(lines) <= 20 / QUIET_S + 1


def test_the_terminal_panel_leaves_a_line_in_the_scroll_back_when_quiet() -> None:
    out = io.StringIO()
    view = RichProgress(Console(file=out, width=100, force_terminal=True, color_system=None))
    view.quiet.quiet = 0.0
    view.update(_tracker(1), 4.0)
    view.close()
    assert "[   4.0s] coverage" in out.getvalue()
