"""How the live view uses the terminal: where the map, the figures and the event log go for
a given width and height, and which events stay on screen. Pure.

- Wide terminals put the figures beside the map; narrow or short ones (80 x 24) put the map
  across the whole width and the figures below it, two to a row.
- The event log takes every row the rest leaves (never ten lines over empty rows).
- Events that matter (deaths, takeovers, re-plans, the verdict) are pinned:
  kept apart from the stream of claims and joins that would push them out within a second,
  and shown above it.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterable
from dataclasses import dataclass

from deploy.monitor.types import MonitorEvent

SIDE_WIDTH = 52  # the figures and robots beside the map
BESIDE_MIN_WIDTH = 100  # narrower terminals get the figures below the map
MIN_LOG_LINES = 3
ROOMY_LOG_LINES = 8  # what a narrow layout's log keeps when the robot table joins it
MIN_MAP_ROWS = 5
PANEL_ROWS = 2  # a panel's top and bottom border
KEPT = 200  # events of each kind of log kept for the screen

IMPORTANT_KINDS = frozenset({
    "died", "detected_dead", "takeover", "takeover_done", "replanned", "withdrawn", "fenced",
    "stopped", "mission_complete", "mission_failed",
})


@dataclass(frozen=True)
class Layout:
    beside: bool  # figures beside the map (else below it)
    map_width: int  # characters for the map itself
    map_rows: int
    log_lines: int
    robots_below: bool = False  # narrow layouts: the robot table too, when there is room


def layout(width: int, height: int, side_rows: int, figure_rows: int,
           map_shape: tuple[int, int] | None, robot_rows: int = 0,
           legend_width: int = 0) -> Layout:
    """The layout for a ``width`` x ``height`` console. ``side_rows``: the rows the figures
    and robot table take beside the map; ``figure_rows``: the rows of the figures below it
    (two to a row); ``map_shape``: the rows and columns the map would like (None: unknown);
    ``robot_rows``: the robot table's rows, shown below the figures if the log keeps enough;
    ``legend_width``: the map legend's length (two rows where the map is narrower)."""
    # beside the map only if the figures' column leaves the log its rows
    beside = width >= BESIDE_MIN_WIDTH and height >= side_rows + PANEL_ROWS + MIN_LOG_LINES + 1
    map_width = max(10, width - (SIDE_WIDTH + 1 if beside else 0) - 4)
    legend = 1 if legend_width <= map_width else 2
    chrome = PANEL_ROWS * 2 + legend  # map panel and log panel borders, the legend
    below = 0 if beside else figure_rows + PANEL_ROWS
    # the log keeps a fifth of a tall terminal; the map has the rest
    room = max(MIN_MAP_ROWS, height - chrome - below - max(MIN_LOG_LINES, height // 5))
    wanted = room if map_shape is None else min(room, max(MIN_MAP_ROWS, map_shape[0]))
    top = max(wanted + legend, side_rows - PANEL_ROWS) if beside else wanted + legend
    log_lines = max(MIN_LOG_LINES, height - top - PANEL_ROWS * 2 - below - 1)
    table = robot_rows + PANEL_ROWS
    if not beside and robot_rows and log_lines - table >= ROOMY_LOG_LINES:
        return Layout(beside, map_width, wanted, log_lines - table, True)
    return Layout(beside, map_width, wanted, log_lines)


class EventLog:
    """The events shown on screen: the important ones kept apart from the rest."""

    def __init__(self, events: Iterable[MonitorEvent] = ()) -> None:
        self.important: deque[MonitorEvent] = deque(maxlen=KEPT)
        self.other: deque[MonitorEvent] = deque(maxlen=KEPT)
        self.add(events)

    def add(self, events: Iterable[MonitorEvent]) -> None:
        for event in events:
            (self.important if event.kind in IMPORTANT_KINDS else self.other).append(event)

    def lines(self, rows: int) -> tuple[list[MonitorEvent], list[MonitorEvent]]:
        """The pinned events and the latest others for ``rows`` lines: the pinned ones take up
        to half of them (all when nothing else happened), the newest of each, in order."""
        rows = max(rows, 1)
        pinned_rows = min(len(self.important),
                          rows if not self.other else max(1, rows // 2))
        pinned = list(self.important)[len(self.important) - pinned_rows:]
        rest = rows - len(pinned) - (1 if pinned and self.other else 0)  # a separator line
        others = list(self.other)[len(self.other) - rest:] if rest > 0 else []
        return pinned, others
