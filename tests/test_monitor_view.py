"""The live view rendered headless (rich's recording console) for scripted messages."""

from __future__ import annotations

import io
import re

import pytest
from rich.console import Console
from test_monitor_fixtures import M, open_room, run_mission, two_robot_walks

from bus import keys
from bus.messages import CoverEvent, RobotStatus
from deploy.monitor.app import PlainScreen, Watcher, replay
from deploy.monitor.model import FleetModel
from deploy.monitor.plain import PlainPrinter
from deploy.monitor.types import Header, Record, Recording
from deploy.monitor.view import FeedStats, colour, render, render_map


def screen_text(model: FleetModel, stats: FeedStats | None = None, width: int = 150) -> str:
    console = Console(record=True, width=width, height=60, file=io.StringIO())
    console.print(render(model, stats or FeedStats(), width=width, height=60))
    return console.export_text()


def feed(records: list[Record]) -> FleetModel:
    model = FleetModel()
    for record in records:
        model.apply(record)
    return model


def test_view_shows_robots_coverage_and_events_as_they_happen() -> None:
    mission = run_mission(open_room(), two_robot_walks(), kill=(1, 5), taker=0)
    records = mission.records
    # Part-way: robot 1 is still alive and coverage is partial.
    cut = next(i for i, r in enumerate(records) if r.kind == "token" and r.msg.present is False)
    early = screen_text(feed(records[:cut]))
    covered = len({r.msg.cell for r in records[:cut] if isinstance(r.msg, CoverEvent)})
    assert f"{100 * covered / 32:.1f} % ({covered}/32)" in early
    assert "2: 2 alive, 0 dead, 0 done" in early
    assert "robot 1 joined" in early and "robot 0 joined" in early
    assert "declared dead" not in early
    final = screen_text(feed(records))
    assert "robot 1's process vanished" in final
    assert "robot 1 declared dead by robot 0 (token" in final
    assert "robot 0 takes over robot 1" in final
    assert "2: 1 alive, 1 dead, 1 done" in final
    assert re.search(r"^\W*1\W+dead\W+4\W", final, re.MULTILINE)  # robot row: id, state, moves
    assert "✖" in final  # the dead robot on the map
    assert "mission complete" in final


def test_drop_counter_is_on_screen() -> None:
    text = screen_text(FleetModel(), FeedStats(drops={"cover.decode": 3}))
    assert re.search(r"drops\s+cover\.decode 3", text)
    assert re.search(r"drops\s+0", screen_text(FleetModel()))


def test_map_draws_tree_edges_and_owners() -> None:
    model = feed(run_mission(open_room(), two_robot_walks()).records)
    text = render_map(model, 40, 20)
    rows = text.plain.splitlines()
    # 2 x 4 cells with edges between them: 3 rows of 7 characters.
    assert [len(r) for r in rows] == [7, 7, 7]
    assert sum(r.count("─") + r.count("│") for r in rows) == len(model.edges)
    style = {}
    for span in text.spans:
        for i in range(span.start, span.end):
            style[i] = str(span.style)
    # Row 0 of cells is fully covered: robot 0 left, robot 1 right, each in its colour.
    assert rows[0][::2] == "████"
    assert [style[i] for i in (0, 2, 4, 6)] == [colour(0), colour(0), colour(1), colour(1)]


def test_big_maps_are_drawn_every_sth_cell() -> None:
    model = FleetModel()
    model.apply(Record(0.0, keys.status(M, 0), RobotStatus(0, 1, (0, 0), "nb", "", "x")))
    model.apply(Record(0.0, keys.sim_cover(M, 0), CoverEvent(0, (399, 399), 0.0, 1)))
    console = Console(record=True, width=200, file=io.StringIO())
    console.print(render_map(model, 50, 20))
    lines = [r for r in console.export_text().splitlines() if r.strip()]
    assert 0 < len(lines) <= 20 and max(len(r) for r in lines) <= 50


def test_replay_prints_one_line_per_event_in_plain_mode() -> None:
    mission = run_mission(open_room(), two_robot_walks(), kill=(1, 5), taker=0)
    out = io.StringIO()
    recording = Recording(Header(M, 0.0, "test", 1), tuple(mission.records), ())
    watcher = Watcher(PlainScreen(PlainPrinter(out)))
    replay(recording, watcher, 0.0)
    lines = out.getvalue().splitlines()
    assert len(lines) == watcher.model.event_count + 1  # + the summary line
    assert lines[-1].split()[1] == "summary"
    assert any("detected_dead" in line and "robot 1" in line for line in lines)


def test_claims_and_conflicts_on_the_map() -> None:
    from deploy.monitor.types import Opaque

    model = FleetModel()
    model.apply(Record(0.0, keys.sim_cover(M, 0), CoverEvent(0, (0, 0), 0.0, 1)))
    for t, robot, cell in ((0.1, 0, (0, 1)), (0.2, 1, (0, 2)), (0.3, 0, (0, 2))):
        model.apply(Record(t, keys.ormstc_claim(M, robot),
                           Opaque("ormstc_claim", {"robot": robot, "cell": cell})))
    text = render_map(model, 40, 20)
    row = text.plain.splitlines()[0]
    assert row[2] == "?" and row[4] == "?"  # cells (0, 1) and (0, 2)
    styles = {i: str(span.style) for span in text.spans for i in range(span.start, span.end)}
    assert styles[2] == colour(0) and styles[4] == "bold magenta"


def test_replay_keeps_the_recorded_pace_scaled_by_speed() -> None:
    mission = run_mission(open_room(), two_robot_walks())
    records = tuple(mission.records)
    now = [100.0]
    slept: list[float] = []

    def sleep(seconds: float) -> None:
        slept.append(seconds)
        now[0] += seconds

    recording = Recording(Header(M, 0.0, "test", 1), records, ())
    replay(recording, Watcher(PlainScreen(PlainPrinter(io.StringIO()))), 2.0,
           clock=lambda: now[0], sleep=sleep)
    # Played from the first record to the last at twice the recorded pace.
    assert sum(slept) == pytest.approx((records[-1].t - records[0].t) / 2, abs=1e-6)


def test_rich_screen_leaves_the_last_frame_on_the_terminal() -> None:
    from deploy.monitor.app import RichScreen

    out = io.StringIO()
    screen = RichScreen(Console(file=out, width=140, height=50, force_terminal=True,
                                color_system=None))
    model = feed(run_mission(open_room(), two_robot_walks()).records)
    screen.refresh(model, FeedStats(rate=12.0))
    screen.close(model, FeedStats(rate=12.0, drops={"hb.decode": 1}))
    final = out.getvalue().split("fleet")[-1]
    assert "100.0 % (32/32)" in final and "hb.decode 1" in final and "(12/s)" in final
