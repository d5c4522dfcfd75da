"""The live view laid out by the terminal's size (deploy.monitor.layout): the map uses the
width, the log the height, important events stay on screen, and the map's symbols have a
legend. Rendered headless with rich's recording console."""

from __future__ import annotations

import io

import pytest
from rich.console import Console
from test_monitor_fixtures import M, open_room, run_mission, snake

from bus import keys
from deploy.monitor.layout import EventLog, layout
from deploy.monitor.model import FleetModel
from deploy.monitor.types import MonitorEvent, Opaque, Record
from deploy.monitor.view import FeedStats, render


def _four_robots_one_killed() -> tuple[FleetModel, EventLog]:
    walks = {r: snake(range(6 * r, 6 * r + 6), range(60)) for r in range(4)}
    mission = run_mission(open_room(24, 60), walks, kill=(1, 30), taker=0)
    model, log = FleetModel(), EventLog()
    for record in mission.records:
        log.add(model.apply(record))
    return model, log


def _screen(model: FleetModel, log: EventLog, width: int, height: int,
            stats: FeedStats | None = None) -> list[str]:
    console = Console(record=True, width=width, height=height, file=io.StringIO())
    console.print(render(model, stats or FeedStats(), width=width, height=height, log=log))
    return console.export_text().splitlines()


def _map_rows(lines: list[str]) -> list[str]:
    """The map panel's inner rows, up to its legend."""
    rows: list[str] = []
    for line in lines[1:]:
        inner = line.split("│")[1] if line.startswith("│") else ""
        if "covered" in inner and "partly" in inner:
            return rows
        rows.append(inner.rstrip())
    raise AssertionError("no legend under the map")


@pytest.mark.parametrize(("width", "height"), [(80, 24), (100, 30), (150, 45), (200, 60)])
def test_the_screen_fits_the_terminal_and_the_map_uses_its_width(width: int,
                                                                 height: int) -> None:
    model, log = _four_robots_one_killed()
    lines = _screen(model, log, width, height)
    assert len(lines) <= height and max(len(line) for line in lines) <= width
    rows = _map_rows(lines)
    # 30 cells across: drawn two characters each (or with their edges) wherever that fits
    assert max(len(r.strip()) for r in rows) >= (30 if width == 100 else 59)
    assert len(rows) >= 5


def test_at_80_by_24_the_figures_go_below_a_full_width_map() -> None:
    model, log = _four_robots_one_killed()
    lines = _screen(model, log, 80, 24)
    assert lines[0].startswith("╭") and lines[0].endswith("╮") and len(lines[0]) == 80
    assert any("coverage" in line and "moves" in line for line in lines)  # two to a row
    assert any("mission complete" in line for line in lines)
    # long values are cut, never the labels
    many_drops = FeedStats(drops={f"kind{i}.decode": i for i in range(1, 9)})
    text = "\n".join(_screen(model, log, 80, 24, many_drops))
    for label in ("coverage ", "moves ", "sim time ", "robots ", "redundancy ", "claims ",
                  "messages ", "drops ", "queue ", "mission ", "source "):
        assert f"{label}" in text, label


def test_the_log_takes_the_rows_the_rest_leaves() -> None:
    model, log = _four_robots_one_killed()
    for i in range(300):  # a burst of claims
        log.add([MonitorEvent(50.0 + i / 100, "claimed", 2, f"robot 2 claims cell (0, {i})")])
    for height in (24, 40, 60):
        lines = _screen(model, log, 150, height)
        assert height - 2 <= len(lines) <= height  # no empty rows below a ten-line log


def test_deaths_and_takeovers_stay_on_screen_under_a_flood_of_claims() -> None:
    model, log = _four_robots_one_killed()
    for i in range(1000):
        event = model.apply(Record(50.0 + i / 1000, keys.ormstc_claim(M, 2), Opaque(
            "ormstc_claim", {"robot": 2, "cell": (i % 12, i // 12)})))
        log.add(event)
    text = "\n".join(_screen(model, log, 120, 40))
    assert "robot 1 declared dead by robot 0" in text and "robot 0 takes over robot 1" in text
    assert "robot 2 claims cell (3, 83)" in text  # the latest claim, below the pinned events
    pinned, others = log.lines(10)
    assert 1 <= len(pinned) <= 5 and len(pinned) + len(others) + 1 == 10


def test_pinned_events_take_every_row_when_nothing_else_happened() -> None:
    log = EventLog([MonitorEvent(float(t), "detected_dead", t, f"robot {t} dead")
                    for t in range(8)])
    pinned, others = log.lines(5)
    assert [e.robot for e in pinned] == [3, 4, 5, 6, 7] and not others


def test_narrow_tall_terminals_show_the_robot_table_too() -> None:
    assert layout(80, 60, 30, 6, (11, 60), robot_rows=5).robots_below
    assert not layout(80, 24, 30, 6, (11, 60), robot_rows=5).robots_below
    wide = layout(150, 40, 30, 6, (11, 60), robot_rows=5)
    assert wide.beside and wide.map_width == 150 - 52 - 1 - 4
