"""Body failures ordered at a coverage, armed in simhw (deploy/kill_orders.py): the count of
covered sub-cells an order stands for, and which armed orders a count sets off."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from bus.messages import AdminCommand, AdminReply
from deploy.fleet import RunDir
from deploy.kill_orders import ArmedOrders, KillOrders, armable, covered_for
from deploy.settings import KillOrder
from deploy.summary import MissionTracker
from deploy.supervisor import Supervisor


@pytest.mark.parametrize(("percent", "total", "covered"), [
    (50.0, 1220, 610),
    (38.7, 1220, 473),  # 472 sub-cells are 38.69 %
    (0.0, 884, 0),
    (100.0, 884, 884),
    (64.4, 250, 161),  # 64.4 * 250 / 100 is 161.00000000000003 in floats
])
def test_covered_for_is_the_first_count_at_the_percent(percent: float, total: int,
                                                       covered: int) -> None:
    assert covered_for(percent, total) == covered


@given(st.integers(1, 100_000), st.floats(0.0, 100.0, allow_nan=False))
def test_covered_for_agrees_with_the_launchers_coverage_figure(total: int,
                                                                percent: float) -> None:
    # the launcher's figure is 100 * covered / total: due exactly from covered_for on
    n = covered_for(round(percent, 3), total)
    assert 100.0 * n / total >= round(percent, 3) - 1e-9
    assert n == 0 or 100.0 * (n - 1) / total < round(percent, 3)


def test_orders_at_a_coverage_are_armed_and_fire_once() -> None:
    assert armable(KillOrder(1, percent=30.0, hw=True), 200)
    assert armable(KillOrder(1, percent=30.0), 200)  # simhw holds the world for the SIGKILL
    assert not armable(KillOrder(1, seconds=3.0, hw=True), 200)
    assert not armable(KillOrder(1, percent=100.0), 200)  # due only once all is covered
    assert armable(KillOrder(1, percent=99.5), 200)  # 199 of 200
    assert not armable(KillOrder(1, percent=99.6), 200)  # 199.2: the 200th
    held = ArmedOrders().arm(KillOrder(4, percent=10.0), 200).command()
    assert (held.action, held.robot, held.after_covered) == ("pause", None, 20)
    armed = ArmedOrders()
    second = armed.arm(KillOrder(2, percent=50.0, hw=True), 200)
    first = armed.arm(KillOrder(1, percent=20.0, hw=True), 200)
    assert (first.covered, second.covered) == (40, 100)
    assert first.command() == AdminCommand("fail", 1, after_covered=40)
    assert armed.fired(39) == []
    assert armed.fired(120) == [first, second]
    assert armed.fired(200) == [] and armed.unfired == []
    armed.arm(KillOrder(3, percent=90.0, hw=True), 200)
    armed.disarm(3)
    assert armed.unfired == []


async def test_a_kill_during_a_resume_gets_a_resume_of_its_own(tmp_path: Path) -> None:
    # simhw resumes as the request arrives; the world can reach the next pause, and its
    # SIGKILL be sent, before the answer is back: that pause must be resumed too
    orders = KillOrders([], "m", MissionTracker(np.ones((2, 2), dtype=bool), 2),
                        Supervisor(RunDir(tmp_path)), lambda _text: None)
    asked: list[str] = []

    class Bus:
        async def query(self, _key: str, cmd: AdminCommand, *_args: object,
                        **_kwargs: object) -> list[SimpleNamespace]:
            asked.append(cmd.action)
            orders.resume_due = True  # the next pause's kill, while we wait
            return [SimpleNamespace(msg=AdminReply(True, "resumed"))]

    orders.resume_due = True
    await orders.resume_if_due(Bus())  # type: ignore[arg-type]
    assert asked == ["resume"] and orders.resume_due
