"""One recording, three readers: `mstc up`'s summary (its tracker), `mstc report` and the
monitor's figures must agree on makespan, simulated seconds and revisits, because all three
read them off the same model with deploy.monitor.figures."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pytest
from test_monitor_fixtures import M, run_mission, snake

from bus.messages import SCHEMA_VERSION
from deploy.monitor.app import PlainScreen, Watcher
from deploy.monitor.coverage import reachable_sub_cells
from deploy.monitor.figures import mission_figures
from deploy.monitor.plain import PlainPrinter, status_line
from deploy.monitor.recorder import RecordWriter, read_recording
from deploy.monitor.report import build_report
from deploy.monitor.types import Header, Recording
from deploy.summary import MissionTracker, format_summary, summarize
from planner.types import OccupancyGrid, SubCell


def _recorded(tmp_path: Path, walks: dict[int, list[SubCell]], free: np.ndarray,
              kill: tuple[int, int] | None = None, taker: int | None = None) -> Recording:
    mission = run_mission(free, walks, kill=kill, taker=taker)
    path = tmp_path / "mission.jsonl"
    writer = RecordWriter(path, Header(M, 0.0, "up", SCHEMA_VERSION))
    for record in mission.records:
        writer.write(record)
    writer.close()
    recording = read_recording(path)
    assert not recording.errors
    return recording


def _walks_past_coverage() -> dict[int, list[SubCell]]:
    """Robot 0 walks back over three covered sub-cells after the room is covered: its final
    moves exceed the makespan, and it revisits (the 226-against-225 case)."""
    left = snake(range(4), range(4))
    return {0: left + left[-2::-1][:3], 1: snake(range(4), range(4, 8))}


@pytest.mark.parametrize("kill", [None, (1, 9)])
def test_summary_report_and_monitor_agree_on_one_recording(
        tmp_path: Path, kill: tuple[int, int] | None) -> None:
    free = np.ones((4, 8), dtype=bool)
    recording = _recorded(tmp_path, _walks_past_coverage(), free, kill=kill,
                          taker=None if kill is None else 0)

    watcher = Watcher(PlainScreen(PlainPrinter(io.StringIO())))
    watcher.feed(recording.records)
    monitor = mission_figures(watcher.model)

    report = build_report(recording)

    starts = tuple(walk[0] for walk in _walks_past_coverage().values())
    tracker = MissionTracker(reachable_sub_cells(OccupancyGrid(free), starts), robots=2)
    for record in recording.records:
        tracker.observe(record.t, record.key, record.msg, record.via)
    summary = summarize(tracker, mission=M, world="open", algo="nb", wall_seconds=1.0,
                        planned_makespan=None, outcome="test")

    if kill is None:
        assert report.complete and report.coverage_moves is not None
        assert report.coverage_moves < max(f.moves for f in report.robots)  # moved on after
        assert summary.makespan_moves == report.coverage_moves == monitor.makespan_moves
        assert summary.sim_seconds == report.coverage_sim_seconds == monitor.sim_seconds
    else:
        assert summary.makespan_moves == monitor.makespan_moves
        assert summary.sim_seconds == monitor.sim_seconds
    assert summary.revisited == report.revisits == monitor.revisits > 0
    assert summary.total_moves == sum(f.moves for f in report.robots) == monitor.total_moves
    # and what each prints
    assert f"makespan    {summary.makespan_moves} moves" in format_summary(summary)
    assert f"{summary.revisited} revisits" in format_summary(summary)
    line = status_line(watcher.model)
    assert f"makespan {monitor.makespan_moves} moves {monitor.sim_seconds:.1f} simulated s" \
        in line and f"revisits {monitor.revisits}," in line
