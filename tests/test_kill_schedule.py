"""The launcher's kill schedule (deploy.supervisor.KillSchedule over deploy.settings'
KillOrder): each order is handed out once, when its moment has come, and not before."""

from __future__ import annotations

import argparse

import pytest

from deploy.settings import parse_kill
from deploy.supervisor import KillSchedule


def test_an_order_by_seconds_fires_once_its_moment_has_come() -> None:
    schedule = KillSchedule([parse_kill("2@3"), parse_kill("1@5s")])
    assert schedule.due(elapsed=0.0) == []
    assert schedule.due(elapsed=2.99, coverage=99.0) == []
    assert [o.robot for o in schedule.due(elapsed=3.0)] == [2]
    assert schedule.due(elapsed=4.0) == [], "handed out once"
    assert [o.robot for o in schedule.due(elapsed=60.0)] == [1]
    assert schedule.pending == []


def test_an_order_by_progress_fires_on_coverage_only() -> None:
    schedule = KillSchedule([parse_kill("0@progress=40"), parse_kill("3@25%")])
    assert schedule.due(elapsed=1e6) == [], "time alone does not fire a progress order"
    assert not schedule.waits_on_coverage(24.9)
    assert schedule.waits_on_coverage(25.0)
    assert [o.robot for o in schedule.due(coverage=30.0)] == [3]
    assert not schedule.waits_on_coverage(39.0)
    assert [o.robot for o in schedule.due(elapsed=0.0, coverage=40.0)] == [0]
    assert schedule.due(coverage=100.0) == []


def test_an_order_by_step_fires_for_tree_missions() -> None:
    schedule = KillSchedule([parse_kill("1@3").__class__(robot=1, step=4)])
    assert schedule.due(step=3) == []
    assert [o.robot for o in schedule.due(step=4)] == [1]


def test_tree_orders_passed_together_are_handed_out_one_step_at_a_time() -> None:
    """A launcher that looks late finds steps 4 and 12 both passed: it gets the step-4 orders
    (both robots of that step) and the step-12 one only on a later call."""
    order = parse_kill("1@3").__class__
    schedule = KillSchedule([order(robot=5, step=12), order(robot=2, step=4),
                             order(robot=3, step=4)])
    assert schedule.due_earliest_step(3) == []
    assert sorted(o.robot for o in schedule.due_earliest_step(13)) == [2, 3]
    assert [o.robot for o in schedule.pending] == [5]
    assert [o.robot for o in schedule.due_earliest_step(13)] == [5]
    assert schedule.due_earliest_step(99) == []


def test_progress_kills_accept_exactly_0_to_100_percent() -> None:
    assert parse_kill("0@progress=0").percent == 0.0
    assert parse_kill("0@progress=100").percent == 100.0
    assert parse_kill("0@100%").percent == 100.0
    for text in ("0@progress=100.01", "0@100.5%"):
        with pytest.raises(argparse.ArgumentTypeError, match=r"0\.\.100"):
            parse_kill(text)
