"""Tree missions in the monitor's model and in `mstc report`: the launcher's set-up from its
mission status, the robots' own reports into the TeamObserver, and the launcher's verdict
recomputed from a recording."""

from __future__ import annotations

import pytest

from bus import keys
from bus.messages import MissionStatus, TreeReport
from deploy.errors import RecordingError
from deploy.monitor.model import FleetModel
from deploy.monitor.plain import status_line
from deploy.monitor.tree_report import build_tree_report, tree_model
from deploy.monitor.types import Header, Record, Recording
from planner.treecover.sim import run_coverage
from planner.treecover.team import TeamReplica
from planner.treecover.trees import tree_from_spec

M, SPEC, ROBOTS = "t", "perfect:N=2,H=3", 3


def _status() -> Record:
    return Record(0.0, keys.mission_status(M), MissionStatus(
        "running", "tree coverage", {"tree": SPEC, "algo": "cocta", "robots": ROBOTS}))


def _reports() -> list[Record]:
    """Every robot's own report of every step of the lockstep walk, plus a relayed copy on
    an inbox (which must not count as a position)."""
    replica, out = TeamReplica(tree_from_spec(SPEC), ROBOTS, "cocta"), []
    while True:
        for robot, node in enumerate(replica.positions):
            report = TreeReport(robot, 1, replica.step, node, robot)
            out.append(Record(0.1, keys.tree_outbox(M, robot), report))
            out.append(Record(0.1, keys.tree_inbox(M, (robot + 1) % ROBOTS), report))
        if replica.done():
            return out
        replica.advance()


def _recording(records: list[Record]) -> Recording:
    return Recording(Header(M, 0.0, "tree-fleet", 3), tuple(records), ())


@pytest.mark.parametrize("status_first", [True, False])
def test_a_recorded_tree_mission_gets_the_launchers_verdict(status_first: bool) -> None:
    reports = _reports()
    records = [_status(), *reports] if status_first else [*reports[:6], _status(), *reports[6:]]
    model = tree_model(_recording(records))
    assert model is not None
    summary = build_tree_report(model)
    lockstep = run_coverage(tree_from_spec(SPEC), ROBOTS, "cocta")
    assert summary["verdict"] == "ok" and summary["coverage_time"] == lockstep.time
    assert f"covered at step {lockstep.time}" in status_line(model)


def test_a_late_joiner_sees_the_tree_but_the_report_refuses_to_judge() -> None:
    reports = _reports()
    model = FleetModel()
    for record in [_status(), *reports[2 * ROBOTS * 3:]]:  # from step 3 on
        model.apply(record)
    assert model.tree.joined_at == 3 and "heard from step 3 on" in status_line(model)
    with pytest.raises(RecordingError, match="starts at step 3"):
        tree_model(_recording([_status(), *reports[2 * ROBOTS * 3:]]))
    with pytest.raises(RecordingError, match="without the launcher's mission status"):
        tree_model(_recording(reports))


def test_a_grid_recording_is_not_a_tree_mission() -> None:
    assert tree_model(_recording([])) is None
